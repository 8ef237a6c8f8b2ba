"""Flittner & Slater's Table 1: where a band's centre may sit for a shift to stay harmless.

References
----------
.. [1] D. E. Flittner, P. N. Slater, "Stability of narrow-band filter radiometers in the
   solar-reflective range", Photogramm. Eng. Remote Sens. 57, 165 (1991), Table 1.
"""

from __future__ import annotations

import math

import numpy as np

from .._validation import validate_method
from .signal import SIGNAL_PROFILES, _FilterMoments, _signals_on_grid

__all__ = ["tolerance_ranges"]


def tolerance_ranges(source, cwl_nm, fwhm_nm, *, n_eff=1.7, profile="multi_lorentzian",
                     criteria=((1.0, 0.5), (5.0, 2.0)), search_nm=150.0, step_nm=0.1):
    """Flittner & Slater's Table 1: for each band, the range of centre positions around the
    nominal one where a shift of +-``shift`` nm changes the signal by less than ``limit_pct``.

    Centres are tried every ``step_nm`` (the shifts must be multiples of it) up to
    ``search_nm`` either side, and no further than the source reaches. A range that reaches
    the end of the search ends there.

    Parameters
    ----------
    source : Spectrum
        The source spectrum; it must cover every band, its shifts and its tried centres.
    cwl_nm : array_like
        Nominal band centres, nm (scalar or 1-D).
    fwhm_nm : array_like
        Band FWHMs, nm; broadcast against ``cwl_nm``.
    n_eff : float
        Effective index handed to the profile (which is evaluated at normal incidence here).
    profile : {"multi_lorentzian", "pi"}
        The band shape (:data:`~snapcorr.budget.signal.SIGNAL_PROFILES`).
    criteria : sequence of (float, float)
        ``(shift, limit_pct)`` pairs: a shift of +-``shift`` nm (a whole multiple of
        ``step_nm``, at least one step) must change the signal by less than ``limit_pct``
        percent. The default is Flittner & Slater's (1 nm, 0.5 %) and (5 nm, 2 %).
    search_nm : float
        How far either side of the nominal centre to look, nm.
    step_nm : float
        Spacing of the tried centres, nm.

    Returns
    -------
    list of list of (float, float) or None
        One list per band, one entry per criterion: the ``(lo, hi)`` range of centres in nm,
        or ``None`` where the nominal centre itself fails ("NA" in their table).
    """
    validate_method(profile, SIGNAL_PROFILES, "profile")
    source = source.peak_normalised()  # ratios only: the scale goes, and any overflow
    cwl = np.atleast_1d(np.asarray(cwl_nm, float))
    fwhm = np.broadcast_to(np.asarray(fwhm_nm, float), cwl.shape)
    ms = []
    for shift, _ in criteria:
        m = round(shift / step_nm)
        if m < 1 or not math.isclose(m * step_nm, shift, rel_tol=1e-9):
            raise ValueError(f"a shift of {shift:g} nm is not a multiple of step_nm "
                             f"({step_nm:g} nm)")
        ms.append(m)
    m_max = max(ms)
    out = []
    for c, fw in zip(cwl, fwhm, strict=True):
        prof = SIGNAL_PROFILES[profile](c, fw, n_eff)
        mom = _FilterMoments.of(prof)
        # centre offsets -kl..kh steps, with room for the largest shift inside the source
        room_lo = (c + mom.u[0] - source.wavelength_nm[0]) / step_nm - m_max
        room_hi = (source.wavelength_nm[-1] - c - mom.u[-1]) / step_nm - m_max
        kl = math.floor(min(search_nm / step_nm, room_lo) + 1e-9)
        kh = math.floor(min(search_nm / step_nm, room_hi) + 1e-9)
        if kl < 0 or kh < 0:
            raise ValueError(f"the source {source.name!r} does not cover the band at {c:g} nm "
                             "and its shifts")
        P = _signals_on_grid(source, prof, mom, -kl - m_max, kh + m_max, step_nm)
        idx = m_max + np.arange(kl + kh + 1)  # P[idx] at centre offsets -kl..kh
        row = []
        for m, (_, limit) in zip(ms, criteria, strict=True):
            base = P[idx]
            ok = ((np.abs(P[idx + m] / base - 1) < limit / 100)
                  & (np.abs(P[idx - m] / base - 1) < limit / 100))
            if not ok[kl]:
                row.append(None)
                continue
            bad_lo = np.flatnonzero(~ok[:kl])
            bad_hi = np.flatnonzero(~ok[kl:])
            lo = bad_lo[-1] + 1 if bad_lo.size else 0
            hi = kl + bad_hi[0] - 1 if bad_hi.size else ok.size - 1
            row.append((round(float(c + (lo - kl) * step_nm), 6),
                        round(float(c + (hi - kl) * step_nm), 6)))
        out.append(row)
    return out
