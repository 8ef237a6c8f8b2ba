"""What flats cannot tell: the lens's magnifications, and the spread an assumed one leaves.

The flats at several f-numbers see the exit pupil only through its radius
``R = x / (2 f_W)`` with the working f-number ``f_W = (1 + m / m_P) f`` (Goossens et al.
2019, Eq. 27-28), m the linear magnification and m_P the pupil magnification. Circle ``i``
is a disc of radius ``P_i`` centred at ``h_i tan(CRA)`` in the exit-pupil plane (Eq. 9), and
the light a pixel gets is the area the discs share over ``pi R^2`` (Eq. 33), times
``cos^4(CRA)``. Scaling R, every P and every h by one factor leaves that fraction unchanged
at every CRA and every f-number, so the flats fix ``P (1 + m / m_P)`` and
``h (1 + m / m_P)``, never ``1 + m / m_P`` itself: m and m_P cannot be fitted from flats, at
any number of f-numbers (a degeneracy of the model, not a shortage of data). A calibration
with the wrong ratio gives P and h off by the ratio of ``1 + m / m_P`` and a mean shift off
(Eq. 22-23: the rays' angles are lengths over x), for a fit that is as good as the true one.

So where the caller gives no magnifications, the calibration keeps its assumption (m = 0:
focused at infinity, m_P = 1) and

- warns (:class:`MagnificationWarning`) and says so in its notes;
- records the assumption and the range it was judged over in the profile's ``[calibration]``
  table (``magnification``);
- adds the spread over that range to the reported errors of P, h and the mean shift.

Why the spread rather than a refusal: a lens engineer calibrating on an integrating sphere
mostly has the lens focused at or near infinity, where m = 0 is right and m_P does not
matter; refusing would stop the common, correct case to guard the rarer one. But an error
bar that takes the assumption as exact is a confident wrong answer, so the assumption's
cost is in the error bars, and the note says the one thing that removes it: give m and m_P
(``--magnification``, ``--pupil-magnification``; m = 0 alone suffices at infinity focus).

The plausible range, stated (:data:`MAX_M_OVER_M_P`, :data:`PUPIL_MAGNIFICATION_RANGE`):

- neither given: ``m / m_P`` in ``[0, 0.1]``, a lens focused no closer than about ten focal
  lengths with ``m_P >= 1`` (twenty with ``m_P >= 0.5``);
- m given (> 0), m_P not: ``m_P`` in ``[0.5, 2]`` (telephoto to retrofocus designs), so
  ``m / m_P`` in ``[m / 2, 2 m]``;
- m_P given, m not: ``m`` in ``[0, 0.1 m_P]``, the same ratio range;
- m = 0 given: exact whatever m_P (``f_W = f``).

The error added is the root-mean-square deviation from the assumption with ``m / m_P``
uniform over its range (three-point Gauss-Legendre, exact for a deviation linear in the
ratio), in quadrature with the fit's error; the deviation itself is exact, not linearised: P
and h scale by the ratio of ``1 + m / m_P``, and the mean shift is that of the rescaled lens
(:func:`~snapcorr.calibrate.lens.choice.shift_difference_nm`). A circle held at ``h = x``
(pixel vignetting) keeps its h; only its P is rescaled.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from . import choice
from .table import _circle_stderrs

__all__ = [
    "ASSUMED_MAGNIFICATION",
    "ASSUMED_PUPIL_MAGNIFICATION",
    "MAX_M_OVER_M_P",
    "PUPIL_MAGNIFICATION_RANGE",
    "MagnificationSpread",
    "MagnificationWarning",
    "account_for_magnifications",
    "ratio_range",
]

#: What a calibration assumes when neither magnification is given: focused at infinity.
ASSUMED_MAGNIFICATION = 0.0
ASSUMED_PUPIL_MAGNIFICATION = 1.0
#: Largest ``m / m_P`` judged plausible when m is not given.
MAX_M_OVER_M_P = 0.1
#: Range of m_P judged plausible when it is not given (and m > 0 is).
PUPIL_MAGNIFICATION_RANGE = (0.5, 2.0)

_GL_X, _GL_W = np.polynomial.legendre.leggauss(3)


class MagnificationWarning(UserWarning):
    """A calibration assumed the lens's magnifications (none given): its errors include the
    spread over a plausible range, and P, h and the mean shift are only as good as it."""


@dataclasses.dataclass(frozen=True)
class MagnificationSpread:
    """The magnifications assumed, the range judged and the spread it leaves.

    Attributes
    ----------
    given : str
        ``"both"``, ``"m = 0"``, ``"m only"``, ``"m_P only"`` or ``"neither"``.
    ratio : float
        ``m / m_P`` used.
    ratio_range : (float, float)
        Range of ``m / m_P`` judged (equal ends: nothing assumed).
    P_mm, h_mm : tuple
        RMS deviation of each circle's P and h over the range, mm.
    shift_nm : ndarray
        RMS deviation of the predicted mean shift (largest over the field) at each f-number.
    """

    given: str
    ratio: float
    ratio_range: tuple
    P_mm: tuple = ()
    h_mm: tuple = ()
    shift_nm: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))

    @property
    def assumed(self) -> bool:
        """True if the range is not a single value (a magnification was assumed)."""
        return self.ratio_range[1] > self.ratio_range[0]


def _given(value):
    return value is not None


def ratio_range(magnification=None, pupil_magnification=None, lens=None):
    """How much of m and m_P was given, ``m / m_P`` used and its plausible range.

    A ``lens``'s values count as given (a lens file states them), unless its own record
    says they were assumed (``[calibration.magnification]``, ``assumed = true``; a profile
    whose ``[lens]`` table states neither gets that record when loaded): then only the one
    its ``given`` names, if any, counts.

    Parameters
    ----------
    magnification, pupil_magnification : float, optional
        m and m_P as given (None: not given).
    lens : Lens, optional
        The lens given to the calibration, whose m and m_P stand in for those not given.

    Returns
    -------
    (str, float, (float, float))
        What was given (as :attr:`MagnificationSpread.given`), the ratio used, its range.
    """
    if lens is not None:
        stated = _lens_stated(lens)
        if magnification is None and "m" in stated:
            magnification = lens.magnification
        if pupil_magnification is None and "m_P" in stated:
            pupil_magnification = lens.pupil_magnification
    m = ASSUMED_MAGNIFICATION if magnification is None else float(magnification)
    mp = (ASSUMED_PUPIL_MAGNIFICATION if pupil_magnification is None
          else float(pupil_magnification))
    r = m / mp
    if _given(magnification) and m == 0:
        return "m = 0", r, (r, r)
    if _given(magnification) and _given(pupil_magnification):
        return "both", r, (r, r)
    if _given(magnification):
        lo, hi = PUPIL_MAGNIFICATION_RANGE
        return "m only", r, (m / hi, m / lo)
    if _given(pupil_magnification):
        return "m_P only", r, (0.0, MAX_M_OVER_M_P)
    return "neither", r, (0.0, MAX_M_OVER_M_P)


def _lens_stated(lens):
    """Which of m and m_P a ``lens`` states as its own: both, unless its record says some
    were assumed (``[calibration.magnification]``, ``assumed = true``: by a calibration
    that was not given them, or by a profile that does not state them); ``given`` there
    names those that were."""
    rec = lens.calibration.get("magnification")
    if not (isinstance(rec, dict) and rec.get("assumed") is True):
        return {"m", "m_P"}
    return {"m only": {"m"}, "m_P only": {"m_P"}}.get(rec.get("given"), set())


def _rescaled(lens, ratio, held):
    """``lens`` as the flats would have it with ``m / m_P = ratio``: every P and h scaled by
    the ratio of ``1 + m / m_P`` (a held h stays)."""
    k = (1.0 + lens.magnification / lens.pupil_magnification) / (1.0 + ratio)
    circles = tuple((P * k, h if i in held else h * k)
                    for i, (P, h) in enumerate(lens.vignetting))
    return dataclasses.replace(lens, vignetting=circles, magnification=ratio,
                               pupil_magnification=1.0, calibration={})


def _held(res):
    if res.method != "joint":
        return set()
    held = res.fits[res.model].extra.get("held", {})
    return {i for i in range(len(res.lens.vignetting))
            if f"h{i + 1 if i else ''}_mm" in held}


def _spread(res, given, ratio, rng):
    """:class:`MagnificationSpread` of a calibration ``res`` made with ``m / m_P = ratio``
    over ``rng``."""
    lo, hi = rng
    if not hi > lo:
        return MagnificationSpread(given, ratio, (lo, hi))
    lens, held = res.lens, _held(res)
    nodes = lo + (hi - lo) * (_GL_X + 1.0) / 2.0
    w = _GL_W / 2.0
    dP, dh, ds = [], [], []
    for r in nodes:
        other = _rescaled(lens, r, held)
        dP.append([a[0] - b[0] for a, b in zip(other.vignetting, lens.vignetting, strict=True)])
        dh.append([a[1] - b[1] for a, b in zip(other.vignetting, lens.vignetting, strict=True)])
        ds.append(choice.shift_difference_nm(lens, other, res.f_numbers, res.max_cra_deg))
    rms = lambda d: np.sqrt(np.tensordot(w, np.square(np.asarray(d, float)), axes=1))  # noqa: E731
    return MagnificationSpread(given, ratio, (lo, hi), tuple(rms(dP)) if dP[0] else (),
                               tuple(rms(dh)) if dh[0] else (), np.nan_to_num(rms(ds)))


def _note(sp, fit_nm):
    """The note of an assumption ``sp``, with the flats' own shift errors ``fit_nm``."""
    lo, hi = sp.ratio_range
    worst = float(np.max(sp.shift_nm)) if sp.shift_nm.size else 0.0
    k = int(np.argmax(sp.shift_nm)) if sp.shift_nm.size else 0
    flats = float(fit_nm[k]) if fit_nm.size > k and np.isfinite(fit_nm[k]) else 0.0
    sets = ("; it, not the flats' noise, sets the error: more frames do not lower it"
            if worst > flats else "")
    what = {"neither": "no magnifications given: m = 0 (focused at infinity) and m_P = 1 "
                       f"assumed; m / m_P judged over [{lo:g}, {hi:g}]",
            "m only": f"no pupil magnification given: m_P = 1 assumed; m_P judged over "
                      f"[{PUPIL_MAGNIFICATION_RANGE[0]:g}, {PUPIL_MAGNIFICATION_RANGE[1]:g}]",
            "m_P only": "no magnification given: m = 0 (focused at infinity) assumed; "
                        f"m / m_P judged over [{lo:g}, {hi:g}]"}[sp.given]
    return (f"{what}. The flats cannot tell 1 + m / m_P (the working f-number, Eq. 27) from "
            "a common scale of P and h, so P, h and the mean shift are only as good as the "
            f"assumption: their errors include its spread (mean shift up to {worst:.3g} nm"
            f"{sets}); "
            "give m and m_P (--magnification, --pupil-magnification; m = 0 alone if the "
            "lens was focused at infinity) to remove this term")


def account_for_magnifications(res, magnification=None, pupil_magnification=None, lens=None,
                               *, stacklevel=2):
    """Add the assumed magnifications' spread to a calibration's errors; warn and record.

    ``magnification``, ``pupil_magnification`` and ``lens`` are what the caller gave
    :func:`~snapcorr.calibrate.lens.calibration.calibrate_lens` (None: not given). Where
    both are given (or m = 0), ``res`` is returned unchanged and nothing is said. Else
    ``res.shift_stderr_nm`` (and the profile's) include the spread in quadrature, the
    profile's ``[calibration.magnification]`` table records the assumption, the range, the
    spread and P's and h's errors with it, a note is added and a
    :class:`MagnificationWarning` issued. A second call on the same ``res`` changes
    nothing.

    Parameters
    ----------
    res : LensCalibration
        The calibration made with m and m_P as given or assumed; changed in place.
    magnification, pupil_magnification : float, optional
        As given to the calibration (None: not given).
    lens : Lens, optional
        As given to the calibration.
    stacklevel : int
        Of the warning.

    Returns
    -------
    LensCalibration
        ``res``.
    """
    if getattr(res, "magnification_spread", None) is not None:
        return res  # accounted for already: the spread enters once
    given, ratio, rng = ratio_range(magnification, pupil_magnification, lens)
    sp = _spread(res, given, ratio, rng)
    if not sp.assumed:
        return res
    note = _note(sp, res.shift_stderr_nm)
    warnings.warn(note, MagnificationWarning, stacklevel=stacklevel)
    if sp.shift_nm.size:
        base = (res.shift_stderr_nm if res.shift_stderr_nm.size
                else np.zeros_like(sp.shift_nm))
        res.shift_stderr_nm = np.hypot(base, sp.shift_nm)
    res.notes = [*res.notes, note]
    res.magnification_spread = sp
    cal = dict(res.lens.calibration)
    cal["magnification"] = _table(res, sp)
    if sp.shift_nm.size:
        cal["shift_stderr_nm"] = [_clean(v) for v in res.shift_stderr_nm]
        cal.setdefault("shift_stderr_filter", [choice.REFERENCE_CWL_NM, choice.REFERENCE_N_EFF])
    cal["notes"] = [*cal.get("notes", []), note]
    res.lens = dataclasses.replace(res.lens, calibration=cal)
    return res


def _clean(v):
    v = float(v)
    return v if math.isfinite(v) else ("nan" if math.isnan(v) else "inf")


def _table(res, sp):
    """The ``[calibration.magnification]`` record of the assumption and its spread."""
    t = {"assumed": True, "given": sp.given,
         "magnification": res.lens.magnification,
         "pupil_magnification": res.lens.pupil_magnification,
         "m_over_m_P_range": [sp.ratio_range[0], sp.ratio_range[1]],
         "rule": ("the flats fix P (1 + m / m_P) and h (1 + m / m_P), not m / m_P: errors "
                  "include the RMS deviation over the range (m / m_P uniform), in "
                  "quadrature"),
         "shift_stderr_magnification_nm": [_clean(v) for v in sp.shift_nm]}
    if sp.P_mm:
        sP, sh = _circle_stderrs(res)
        t["P_spread_mm"] = [_clean(v) for v in sp.P_mm]
        t["h_spread_mm"] = [_clean(v) for v in sp.h_mm]
        t["P_stderr_mm"] = [_clean(math.hypot(a, b)) for a, b in zip(sP, sp.P_mm, strict=True)]
        t["h_stderr_mm"] = [_clean(math.hypot(a, b)) for a, b in zip(sh, sp.h_mm, strict=True)]
    return t
