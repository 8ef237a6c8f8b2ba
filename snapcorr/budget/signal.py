"""The signal of a filter band for a source spectrum, at any shift of the filter.

``P(cwl + shift) = integral of T(lambda - cwl - shift) S(lambda)``: Flittner & Slater's
quantity. The profile's running moments are tabulated once (:class:`_FilterMoments`), so every
shift on a grid costs two interpolations per source sample; sources sampled on a regular
lattice take a faster exact path.

References
----------
.. [1] D. E. Flittner, P. N. Slater, "Stability of narrow-band filter radiometers in the
   solar-reflective range", Photogramm. Eng. Remote Sens. 57, 165 (1991).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from ..optics.profiles import Gaussian, MultiLorentzian, PiShaped

__all__ = ["PROFILES", "SIGNAL_PROFILES", "band_signal", "relative_signal", "shift_error"]

#: Transmission below this fraction of the peak is left out of a profile's support (a
#: Gaussian's tails beyond 2.7 FWHM from its centre: 1e-9 of the signal at most).
_NEGLIGIBLE = 1e-9
#: Filter-profile models for a band of given centre and FWHM (a sensor's ``gaussian`` filters
#: are the default shape of its bands, Flittner & Slater's multi-Lorentzian and Mishev &
#: Bakalova's Pi-shaped the papers'): name -> class, a subset of
#: :data:`snapcorr.optics.profiles.FILTER_PROFILES`.
SIGNAL_PROFILES = {"gaussian": Gaussian, "multi_lorentzian": MultiLorentzian, "pi": PiShaped}
#: The earlier name of :data:`SIGNAL_PROFILES`.
PROFILES = SIGNAL_PROFILES


@dataclass(frozen=True)
class _FilterMoments:
    """``C0(u) = int_-inf^u T`` and ``C1(u) = int_-inf^u u' T(u') du'`` of a profile in its own
    frame (``u`` = wavelength - centre), tabulated finely over its support."""

    u: np.ndarray
    c0: np.ndarray
    c1: np.ndarray

    @classmethod
    def of(cls, profile):
        """The moments of ``profile`` (cached: in its own frame a profile depends on its shape
        and width, not on its centre, so a sensor's equal bands share one table)."""
        try:
            return cls._of(dataclasses.replace(profile, cwl_nm=1000.0))
        except (TypeError, ValueError, OverflowError):  # not a dataclass profile: no caching
            return cls._of.__wrapped__(cls, profile)

    @classmethod
    @functools.lru_cache(maxsize=64)
    def _of(cls, profile, fine=8):
        fwhm = float(profile.fwhm_nm)
        # integrated on a grid `fine` times finer than the table, which has fwhm/5000 steps:
        # linear between its nodes, a jump of the profile (the multi-Lorentzian's 5 % cut, a
        # Pi band's edges) costs at most ~1e-5 (5e-5 for a Pi band) of P
        h = fwhm / (5000.0 * fine)
        u = np.arange(-8.0 * fwhm, 8.0 * fwhm + h / 2, h)
        t = np.asarray(profile(profile.cwl_nm + u), float)
        nz = np.flatnonzero(t > _NEGLIGIBLE * t.max())  # a Gaussian's tails: none to speak of
        if nz.size == 0:
            raise ValueError("the filter profile is zero everywhere")
        a = max((nz[0] - 1) // fine * fine, 0)
        b = min(-(-(nz[-1] + 2) // fine) * fine + 1, u.size)
        u, t = u[a:b], t[a:b]
        c0 = np.concatenate([[0.0], np.cumsum(0.5 * h * (t[1:] + t[:-1]))])
        ut = u * t
        c1 = np.concatenate([[0.0], np.cumsum(0.5 * h * (ut[1:] + ut[:-1]))])
        return cls(u[::fine], c0[::fine], c1[::fine])

    def at(self, u):
        """``C0(u)``, ``C1(u)`` on the uniform table (no search); ``u`` within the table.

        ``C0`` is linear between nodes and ``C1`` follows from ``dC1 = u dC0``, so both are
        exact where the profile is constant across a cell: a sharp edge in the source then
        costs nothing extra.
        """
        h = self.u[1] - self.u[0]
        pos = (u - self.u[0]) / h
        i = np.clip(pos.astype(np.int64), 0, self.u.size - 2)
        f = pos - i
        c0 = self.c0[i] + f * (self.c0[i + 1] - self.c0[i])
        c1 = self.c1[i] + 0.5 * (self.u[i] + u) * (c0 - self.c0[i])
        return c0, c1


def _lattice(source, max_knots=2_000_000):
    """``(lambda0, delta, values)`` of the source on a uniform grid holding all its knots
    (the same piecewise-linear function, exactly), or None if there is none small enough."""
    lam = source.wavelength_nm
    steps = np.diff(lam)
    delta = float(steps.min())
    ratio = steps / delta
    if np.max(np.abs(ratio - np.round(ratio))) > 1e-6:
        return None
    n = round((lam[-1] - lam[0]) / delta) + 1
    if n > max_knots:
        return None
    grid = lam[0] + np.arange(n) * delta
    return float(lam[0]), delta, np.interp(grid, lam, source.values)


def _signals_lattice(lattice, profile, moments, k_phase, q):
    """``P`` at the shifts ``(k * q + p) * delta / q`` for a source on a uniform lattice, by
    correlations: each filter position sees the same knot offsets, so the moments are looked
    up once per phase ``p``. ``k_phase`` maps each phase to its (k_min, k_max).

    Written by parts like ``_signals``: a flat source gives ``s * C0(end)`` for every shift,
    exactly (its differences and slopes are exact zeros).
    """
    lam0, delta, s = lattice
    d = delta / q
    lo, hi = moments.u[0], moments.u[-1]
    ds = np.diff(s)
    g = ds / delta  # slope of segment n (knots n, n + 1)
    out = {}
    for p, (k0, k1) in k_phase.items():
        base = profile.cwl_nm + p * d  # the filter's centre for k = 0
        v0 = lam0 - base  # offset of knot 0 from it
        m_lo = int(np.floor((lo - v0) / delta))
        m_hi = int(np.ceil((hi - v0) / delta))
        n_first, n_last = m_lo + k0, m_hi + k1  # knots needed over all k of this phase
        if n_first < 0 or n_last > s.size - 1:
            have = f"{lam0:g}-{lam0 + delta * (s.size - 1):g} nm"
            need = f"{lam0 + n_first * delta:g}-{lam0 + n_last * delta:g} nm"
            raise ValueError(f"the spectrum ({have}) does not cover the band at "
                             f"{profile.cwl_nm:g} nm and its shifts ({need})")
        m = np.arange(m_lo, m_hi + 1)
        v = v0 + m * delta
        C0, C1 = moments.at(np.clip(v, lo, hi))
        nk = k1 - k0 + 1

        def corr(x, first, w, k0=k0, k1=k1, nk=nk):
            # sum_j x[first + k + j] w[j] for k = k0..k1 (by FFT where that is faster: a
            # source sampled every 0.008 nm has thousands of knots under a band)
            return _correlate(x[first + k0:first + k1 + w.size], w)[:nk]

        # segments m_lo..m_hi-1: n = m + k; interior knots m_lo+1..m_hi-1
        inner = slice(1, m.size - 1)
        # a_m = s[m+k] - g[m+k] v_m;  P = a_{m_hi-1} C0_{m_hi} - a_{m_lo} C0_{m_lo}
        #   - sum_{interior} C0_m (a_m - a_{m-1}) + sum_segments g[m+k] (C1_{m+1} - C1_m)
        last = m_hi - 1
        kk = np.arange(k0, k1 + 1)
        a_last = s[last + kk] - g[last + kk] * v[-2]
        a_first = s[m_lo + kk] - g[m_lo + kk] * v[0]
        P = a_last * C0[-1] - a_first * C0[0]
        if m.size > 2:
            # a_m - a_{m-1} = ds[m+k-1] - g[m+k] v_m + g[m+k-1] v_{m-1}
            P -= corr(ds, m_lo, C0[inner])
            P += corr(g, m_lo + 1, C0[inner] * v[inner])
            P -= corr(g, m_lo, C0[inner] * v[:-2])
        P += corr(g, m_lo, np.diff(C1))
        out[p] = P
    return out


#: An irregular source of more knots than this is put on a lattice of half its mean spacing
#: (linear between its own knots) for the correlations: knot by knot, each shift's window
#: holds thousands of them.
DENSE_KNOTS = 20_000


def _dense_on_a_lattice(source, max_knots=2_000_000):
    """``(lambda0, delta, values)`` of an irregular source of more than :data:`DENSE_KNOTS`
    knots on a lattice holding its piecewise-linear curve at every node, whose running
    integral stays within :data:`LATTICE_REL` of the source's mean over 1 nm of the
    source's own: half the mean spacing, or half the spacing of its densest part where the
    knots crowd (a narrow feature among sparse knots, which a coarser lattice lost: P 55 %
    off); None where no lattice of ``max_knots`` does, and for a smaller source (summed knot
    by knot, exactly). ``snapcorr budget`` with 100 000 random knots over 300-1100 nm took
    235 s knot by knot."""
    lam, val = source.wavelength_nm, source.values
    if lam.size <= DENSE_KNOTS:
        return None
    span = float(lam[-1] - lam[0])
    tol = LATTICE_REL * max(float(np.mean(np.abs(val))), 1e-300) * 1.0  # over 1 nm
    own = _running_integral(lam, val)
    for step in (span / (lam.size - 1) / 2, float(np.quantile(np.diff(lam), 0.01)) / 2):
        if not step > 0 or span / step + 1 > max_knots:
            continue
        grid = lam[0] + np.arange(math.floor(span / step) + 1) * step
        vals = np.interp(grid, lam, val)
        if np.max(np.abs(np.interp(lam, grid, _running_integral(grid, vals)) - own)) <= tol:
            return float(lam[0]), step, vals
    return None


def _running_integral(lam, val):
    return np.concatenate([[0.0], np.cumsum(0.5 * (val[1:] + val[:-1]) * np.diff(lam))])


#: A lattice's running integral must stay within this share of the source's mean over 1 nm.
LATTICE_REL = 1e-3


def _signals_on_grid(source, profile, moments, j0, j1, d, lattice=False):
    """``P`` at the shifts ``j * d``, ``j = j0..j1``: by correlations where the source lies on
    a lattice whose step is a whole number of ``d`` (fast), else as ``_signals``.
    ``lattice``: ``_lattice(source)`` if already known."""
    js = np.arange(j0, j1 + 1)
    lat = _lattice(source) if lattice is False else lattice
    if lat is None:
        lat = _dense_on_a_lattice(source)
    if lat is not None:
        q = round(lat[1] / d)
        if q > 16 and (lat[2].size - 1) * q < 2_000_000:
            # a coarse lattice: refine it to the shifts' step (the same function, exactly)
            lam0, delta, vals = lat
            n = (vals.size - 1) * q + 1
            fine = lam0 + np.arange(n) * d
            lat, q = (lam0, d, np.interp(fine, lam0 + np.arange(vals.size) * delta, vals)), 1
        if q == 0:  # the source finer than the shifts' step
            return _signals_between_knots(lat, profile, moments, js * d)
        if 1 <= q <= 16 and math.isclose(q * d, lat[1], rel_tol=1e-9):
            phases = {}
            for p in range(q):
                ks = (js[(js - p) % q == 0] - p) // q
                if ks.size:
                    phases[p] = (int(ks.min()), int(ks.max()))
            got = _signals_lattice(lat, profile, moments, phases, q)
            out = np.empty(js.size)
            for p, (k0, _) in phases.items():
                sel = (js - p) % q == 0
                out[sel] = got[p][(js[sel] - p) // q - k0]
            return out
    return _signals(source, profile, js * d, moments)


def _correlate(x, w):
    """``np.correlate(x, w, "valid")``, by FFT where ``x`` and ``w`` are long (scipy picks the
    faster; both exact to rounding). Zero input gives exact zeros either way."""
    if w.size < 64 or x.size < 256:
        return np.correlate(x, w, mode="valid")
    from scipy import signal

    return signal.correlate(x, w, mode="valid", method="auto")


def _signals_between_knots(lattice, profile, moments, shifts):
    """``P`` at ``shifts`` for a source on a lattice finer than the shifts' own spacing
    (whose step is no whole fraction of the lattice's): ``P`` at every lattice step over the
    shifts' span, by correlations, then linear between them. ``P`` is smooth on the scale of
    the band, so between steps of ``delta`` the interpolation is off by ``delta^2 / 8`` of its
    curvature: against the knot-by-knot sum, a source every 0.008 nm differed by 2e-6 of ``P``
    under a 3 nm Gaussian band, 4e-7 under a 10 nm Pi band and 1.5e-5 under a 10 nm
    multi-Lorentzian (its cut at 5 % is a kink in ``P``). ``snapcorr budget`` with such a
    source of 100 000 knots took 262 s knot by knot, 8.8 s so."""
    delta = lattice[1]
    lo, hi = float(np.min(shifts)), float(np.max(shifts))
    k0, k1 = math.floor(lo / delta), math.ceil(hi / delta)
    try:
        got = _signals_lattice(lattice, profile, moments, {0: (k0, k1)}, 1)[0]
    except ValueError:  # the steps beyond the shifts' ends reach past the source: inside them
        k0, k1 = math.ceil(lo / delta), math.floor(hi / delta)
        if k1 - k0 < 1:
            raise
        got = _signals_lattice(lattice, profile, moments, {0: (k0, k1)}, 1)[0]
        # the shifts beyond the steps inside, within one step of them: the exact source's
        # curve there is the lattice's own, read linearly from the two nearest steps
        slope = np.array([(got[1] - got[0]), (got[-1] - got[-2])]) / delta
        grid = np.arange(k0, k1 + 1) * delta
        out = np.interp(shifts, grid, got)
        out = np.where(shifts < grid[0], got[0] + slope[0] * (shifts - grid[0]), out)
        return np.where(shifts > grid[-1], got[-1] + slope[1] * (shifts - grid[-1]), out)
    return np.interp(shifts, np.arange(k0, k1 + 1) * delta, got)


def _signals(source, profile, shifts, moments=None, chunk=256):
    """``P(cwl + shift) = int T(lambda - cwl - shift) S(lambda) dlambda`` for each shift,
    exact for the piecewise-linear source (each source segment against the profile's
    tabulated moments), so sharp edges in the source cost nothing extra.

    Summed by parts, ``P = sum_j C0(u_j) (a_{j-1} - a_j) + ...`` with ``a_j`` the segment's
    value at ``u = 0``: a flat source gives the same ``P`` for every shift, bit for bit.
    """
    m = _FilterMoments.of(profile) if moments is None else moments
    lo, hi = m.u[0], m.u[-1]
    lam, val = source.wavelength_nm, source.values
    shifts = np.asarray(shifts, float)
    out = np.empty(shifts.size)
    order = np.argsort(shifts, kind="stable")
    srt = shifts[order]
    for start in range(0, srt.size, chunk):
        d = srt[start:start + chunk]
        c = profile.cwl_nm + d  # the filter's centres
        need_lo, need_hi = c[0] + lo, c[-1] + hi
        if need_lo < lam[0] - 1e-9 or need_hi > lam[-1] + 1e-9:
            raise ValueError(f"the spectrum {source.name!r} covers {lam[0]:g}-{lam[-1]:g} nm; "
                             f"{need_lo:.4g}-{need_hi:.4g} nm is needed")
        i0 = max(int(np.searchsorted(lam, need_lo, "right")) - 1, 0)
        i1 = min(int(np.searchsorted(lam, need_hi, "left")) + 1, lam.size)
        kl, kv = lam[i0:i1], val[i0:i1]  # knots spanning every window of this chunk
        g = np.diff(kv) / np.diff(kl)  # segment slopes
        uk = kl[:, None] - c[None, :]  # knots in each filter's frame
        a = kv[:-1, None] - g[:, None] * uk[:-1]  # segment value at u = 0
        uc = np.clip(uk, lo, hi)
        C0, C1 = m.at(uc)
        # sum_j a_j (C0_{j+1} - C0_j) by parts, + sum_j g_j (C1_{j+1} - C1_j)
        p = a[-1] * C0[-1] - a[0] * C0[0]
        if a.shape[0] > 1:
            p -= np.sum(C0[1:-1] * (a[1:] - a[:-1]), axis=0)
        p += np.sum(g[:, None] * (C1[1:] - C1[:-1]), axis=0)
        out[order[start:start + chunk]] = p
    return out.reshape(shifts.shape)


def relative_signal(source, profile, shifts_nm):
    """``P(cwl + shift) / P(cwl)`` of a filter ``profile`` (at normal incidence) moved by each
    shift, for a ``source`` Spectrum: Flittner & Slater's P, as a ratio.

    The integral is exact for the piecewise-linear source (see ``_signals``); a flat source
    gives exactly 1 for any shift.

    Parameters
    ----------
    source : Spectrum
        The source; it must cover the profile's support at every shift.
    profile : profile
        A filter profile (:mod:`snapcorr.optics.profiles`) with ``cwl_nm`` and ``fwhm_nm``.
    shifts_nm : array_like
        Shifts of the filter, nm (finite; any shape).

    Returns
    -------
    ndarray
        The ratio for each shift, shape of ``shifts_nm``.
    """
    s = np.asarray(shifts_nm, float)
    if not np.all(np.isfinite(s)):
        raise ValueError("shifts must be finite")
    source = source.peak_normalised()  # a ratio: the scale goes, and with it any overflow
    m = _FilterMoments.of(profile)
    p = _signals(source, profile, np.concatenate([[0.0], s.ravel()]), m)
    if not p[0] > 0:
        raise ValueError(f"the source {source.name!r} has no signal in the band at "
                         f"{profile.cwl_nm:g} nm")
    return (p[1:] / p[0]).reshape(s.shape)


def band_signal(source, profile, aoi_deg=0.0, *, step_nm=None):
    """``integral profile(lambda, aoi) * source(lambda) dlambda`` of a filter tilted by
    ``aoi_deg`` in collimated light (Mishev & Bakalova's ``I(theta)``; their Pi-shaped filter
    also widens and dims with the tilt). Trapezoid rule on a grid of ``step_nm``.

    Parameters
    ----------
    source : Spectrum
        The source; it must cover the tilted profile's support.
    profile : profile
        A filter profile (:mod:`snapcorr.optics.profiles`), called as
        ``profile(wavelength_nm, aoi_deg)``.
    aoi_deg : array_like
        Angle(s) of incidence, degrees.
    step_nm : float, optional
        Integration step, nm (default: a 200th of the FWHM, at most half the source's median
        sampling step).

    Returns
    -------
    ndarray
        The signal (source units x nm) for each angle, shape of ``aoi_deg``.
    """
    fwhm = float(profile.fwhm_nm)
    h = min(source.step_nm / 2, fwhm / 200) if step_nm is None else float(step_nm)
    out = []
    for a in np.atleast_1d(np.asarray(aoi_deg, float)):
        lo = profile.cwl_nm - 8 * fwhm / max(np.cos(np.deg2rad(2 * a)), 0.1) - 1.0
        lam = np.arange(lo, profile.cwl_nm + 8 * fwhm + 1.0, h)
        t = np.asarray(profile(lam, a), float)
        nz = np.flatnonzero(t > 0)
        lam = lam[max(nz[0] - 1, 0):nz[-1] + 2] if nz.size else lam[:2]
        out.append(np.trapezoid(np.asarray(profile(lam, a), float) * source(lam), lam))
    return np.asarray(out).reshape(np.shape(aoi_deg))


def shift_error(source, profile, shift_nm):
    """Flittner & Slater's ``ERROR(cwl, shift)`` as a fraction (x 100 for percent):
    :func:`relative_signal` minus 1.

    Parameters
    ----------
    source : Spectrum
        The source; it must cover the profile's support at every shift.
    profile : profile
        A filter profile (:mod:`snapcorr.optics.profiles`) with ``cwl_nm`` and ``fwhm_nm``.
    shift_nm : array_like
        Shifts of the filter, nm (finite; any shape).

    Returns
    -------
    ndarray
        The error for each shift, shape of ``shift_nm``.
    """
    return relative_signal(source, profile, shift_nm) - 1.0
