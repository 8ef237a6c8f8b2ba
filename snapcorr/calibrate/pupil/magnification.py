"""The magnifications a target fit was not given: the spread they leave in x and n_eff.

A target's cubes see the exit pupil through the rays' angles: every pixel's chief ray
(``tan CRA = d / x``) and the cone about it, whose half-angle follows the working f-number
``f_W = (1 + m / m_P) f`` (Goossens et al. 2019, Eq. 27-28). The field's shift fixes about
``x * n_eff`` and the centre's move between f-numbers about ``tan(theta_cone) / n_eff``
(:mod:`~snapcorr.calibrate.pupil.locate`), so a wrong ``1 + m / m_P`` moves n_eff by its
ratio and x by the inverse: assuming ``m = 0`` for a lens at ``m / m_P = 0.046`` moves x by
about -4 % (n_eff fitted), far outside the noise's error. And circles from flats
(:mod:`snapcorr.calibrate.lens.magnification`) are fixed only as ``P (1 + m / m_P)`` and
``h (1 + m / m_P)``, so they move with the assumption too.

So where m or m_P is not given, the fit is made again at the nodes of the ratio's plausible
range (:func:`~snapcorr.calibrate.lens.magnification.ratio_range`), each with the lens the
flats would give at that ratio (P and h rescaled, :func:`at_ratio`), and the root-mean-square
deviation from the fit at the assumed ratio, with the ratio uniform over its range, enters
the errors (and the covariance: the deviations of x and n_eff are one systematic, their
outer product keeps the correlation). Two Gauss-Legendre nodes integrate it exactly for a
deviation linear in the ratio (the refits are the cost: one target fit each).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from ..lens.magnification import MagnificationWarning

#: Nodes of the ratio's range at which the target is fitted again (Gauss-Legendre).
N_NODES = 2

_GL_X, _GL_W = np.polynomial.legendre.leggauss(N_NODES)

__all__ = [
    "N_NODES",
    "account_for_pupil_magnifications",
    "at_ratio",
    "range_nodes",
    "recorded_errors",
    "rms_covariance",
    "widen_by_deviations",
    "with_given",
]


def range_nodes(rng):
    """``(ratios, weights)``: the Gauss-Legendre nodes of ``m / m_P`` over ``rng`` and their
    weights (summing to 1: the mean over a uniform ratio).

    Parameters
    ----------
    rng : (float, float)
        The range of ``m / m_P`` judged.

    Returns
    -------
    (ndarray, ndarray)
    """
    lo, hi = float(rng[0]), float(rng[1])
    return lo + (hi - lo) * (_GL_X + 1.0) / 2.0, _GL_W / 2.0


def rms_covariance(deviations, weights):
    """The covariance of a systematic of these ``deviations`` (one row per node) with these
    ``weights``: ``sum_j w_j d_j d_j^T``.

    Parameters
    ----------
    deviations : array_like, shape (n_nodes, n)
    weights : array_like, shape (n_nodes,)

    Returns
    -------
    ndarray, shape (n, n)
    """
    d = np.nan_to_num(np.asarray(deviations, float))
    w = np.asarray(weights, float)
    return np.einsum("j,ja,jb->ab", w, d, d)


def with_given(lens, magnification=None, pupil_magnification=None):
    """``lens`` with the m and m_P given in place of its own. Circles found from flats at an
    assumed ratio (its ``[calibration.magnification]`` says so) are rescaled to the ratio
    given: the flats fixed ``P (1 + m / m_P)`` and ``h (1 + m / m_P)``.

    Parameters
    ----------
    lens : Lens
    magnification, pupil_magnification : float, optional
        As given (None: the lens's).

    Returns
    -------
    Lens
    """
    if magnification is None and pupil_magnification is None:
        return lens
    m = lens.magnification if magnification is None else float(magnification)
    mp = lens.pupil_magnification if pupil_magnification is None else float(pupil_magnification)
    rec = lens.calibration.get("magnification")
    k = 1.0
    if isinstance(rec, dict) and rec.get("assumed") is True:
        k = (1.0 + lens.magnification / lens.pupil_magnification) / (1.0 + m / mp)
    circles = tuple((P * k, h * k) for P, h in lens.vignetting)
    return dataclasses.replace(lens, vignetting=circles, magnification=m,
                               pupil_magnification=mp)


def at_ratio(lens, ratio):
    """``lens`` as flats would give it at ``m / m_P = ratio`` (every P and h scaled by the
    ratio of ``1 + m / m_P``; m = ratio, m_P = 1), its record kept.

    Parameters
    ----------
    lens : Lens
    ratio : float

    Returns
    -------
    Lens
    """
    k = (1.0 + lens.magnification / lens.pupil_magnification) / (1.0 + float(ratio))
    return dataclasses.replace(lens, vignetting=tuple((P * k, h * k) for P, h in lens.vignetting),
                               magnification=float(ratio), pupil_magnification=1.0)


def account_for_pupil_magnifications(fit, given, rng, refit, *, stacklevel=2):
    """Widen a :class:`~snapcorr.calibrate.pupil.locate.PupilFit` made with an assumed
    ``m / m_P`` by the spread over ``rng``: the target fitted again at the range's nodes
    (``refit(ratio)``), the RMS deviation of x, n_eff and ``x n_eff`` added in quadrature (and
    to the covariance); warned, noted and recorded in the profile. Changed in place.

    Parameters
    ----------
    fit : PupilFit
    given : str
        What was given (:func:`~snapcorr.calibrate.lens.magnification.ratio_range`).
    rng : (float, float)
        The range of ``m / m_P`` judged.
    refit : callable
        ``refit(ratio) -> PupilFit``.
    stacklevel : int
        Of the warning.

    Returns
    -------
    PupilFit
        ``fit``.
    """
    nodes, w = range_nodes(rng)
    fits = [refit(float(r)) for r in nodes]
    sx, sn = widen_by_deviations(fit, fits, w)
    note = _note(given, rng, sx, sn)
    warnings.warn(note, MagnificationWarning, stacklevel=stacklevel)
    fit.notes.append(note)
    fit.lens = _recorded(fit, given, rng, nodes, [f.exit_pupil_mm for f in fits], note)
    return fit


def widen_by_deviations(fit, others, weights=None):
    """Add to a :class:`~snapcorr.calibrate.pupil.locate.PupilFit`'s errors and covariance
    the spread of ``others``, the same fit made under other assumptions (magnifications, an
    optical centre moved): the weighted RMS deviation of x, n_eff and ``x n_eff``, in
    quadrature. Changed in place.

    Parameters
    ----------
    fit : PupilFit
    others : sequence of PupilFit
    weights : array_like, optional
        One per fit of ``others`` (default: 1 each, a sum of squares).

    Returns
    -------
    sx : float
        x's part, mm.
    sn : float or None
        n_eff's largest part (None where n_eff has no error).
    """
    w = np.ones(len(others)) if weights is None else np.asarray(weights, float)
    n0 = np.asarray(fit.n_eff, float)
    dx = np.array([f.exit_pupil_mm - fit.exit_pupil_mm for f in others])
    dn = np.array([np.asarray(f.n_eff, float) - n0 if np.shape(f.n_eff) == n0.shape
                   else np.full(n0.shape, np.mean(f.n_eff) - np.mean(n0)) for f in others])
    dxn = np.array([f.x_n_eff_mm - fit.x_n_eff_mm for f in others])
    sx, sxn = float(np.sqrt(w @ dx**2)), float(np.sqrt(w @ dxn**2))
    sn = np.sqrt(np.tensordot(w, dn**2, axes=1))
    cov = np.array(fit.covariance, float)
    dev = [dx]
    if cov.shape[0] > 1 and fit.n_eff_stderr is not None and fit.n_eff_stderr[0] > 0:
        dev.append(dn[:, 0] * np.sqrt(cov[1, 1]) / float(fit.n_eff_stderr[0]))  # as the scale
    cov[:len(dev), :len(dev)] += rms_covariance(np.transpose(dev), w)
    fit.covariance = cov
    fit.exit_pupil_stderr_mm = float(np.hypot(fit.exit_pupil_stderr_mm, sx))
    fit.x_n_eff_stderr_mm = float(np.hypot(fit.x_n_eff_stderr_mm, sxn))
    if fit.n_eff_stderr is None:
        return sx, None
    fit.n_eff_stderr = np.hypot(np.asarray(fit.n_eff_stderr, float), sn)
    return sx, float(np.max(sn))


def recorded_errors(fit, calibration):
    """``calibration`` (a profile's table) with the fit's errors as they now are: x's,
    ``x n_eff``'s and n_eff's (where the table has them), three digits."""
    def r(v):
        return float(f"{float(v):.3g}")

    cal = dict(calibration)
    cal["exit_pupil_stderr_mm"] = r(fit.exit_pupil_stderr_mm)
    cal["x_times_n_eff_stderr_mm"] = r(fit.x_n_eff_stderr_mm)
    if fit.n_eff_stderr is not None and "n_eff_stderr" in cal:
        e = fit.n_eff_stderr
        cal["n_eff_stderr"] = (r(e[0]) if not isinstance(cal["n_eff_stderr"], list)
                               else [r(v) for v in e])
    return cal


def _note(given, rng, sx, sn):
    lo, hi = rng
    what = {"neither": "no magnifications given: m = 0 (focused at infinity) and m_P = 1 "
                       f"assumed; m / m_P judged over [{lo:g}, {hi:g}]",
            "m only": "no pupil magnification given: m_P = 1 assumed; m / m_P judged over "
                      f"[{lo:g}, {hi:g}]",
            "m_P only": "no magnification given: m = 0 (focused at infinity) assumed; "
                        f"m / m_P judged over [{lo:g}, {hi:g}]"}[given]
    index = f", n_eff +- {sn:.2g}" if sn is not None else ""
    return (f"{what}. The target cannot tell 1 + m / m_P (the working f-number, Eq. 27): "
            "it fixes about x n_eff and the cone over n_eff, so x and n_eff are only as good "
            f"as the assumption: their errors include its spread (x +- {sx:.3g} mm{index}; "
            "more frames do not lower it); give m and m_P (--magnification, "
            "--pupil-magnification, or a lens profile that states them; m = 0 alone if the "
            "lens was focused at infinity) to remove this term")


def _recorded(fit, given, rng, nodes, xs, note):
    def r(v, d=3):
        return float(f"{float(v):.{d}g}")

    lens = fit.lens
    cal = recorded_errors(fit, lens.calibration)
    cal["magnification"] = {
        "assumed": True, "given": given, "magnification": lens.magnification,
        "pupil_magnification": lens.pupil_magnification,
        "m_over_m_P_range": [float(rng[0]), float(rng[1])],
        "rule": ("the target fixes about x n_eff and the cone over n_eff, not m / m_P: fitted "
                 "again at the range's Gauss-Legendre nodes (circles rescaled as flats give "
                 "them); the RMS deviation (m / m_P uniform) is in the errors, in quadrature"),
        "m_over_m_P_nodes": [float(v) for v in nodes],
        "exit_pupil_mm_at_nodes": [r(v, 8) for v in xs]}
    cal["notes"] = [*cal.get("notes", []), note]
    return dataclasses.replace(lens, calibration=cal)
