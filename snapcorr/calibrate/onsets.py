"""Onset of optical vignetting from a radial profile: the paper's discontinuity, located.

Goossens et al. 2019 (Sec. 3.2) divide each vignetting profile by the profile at the highest
f-number and mark by eye where the ratio starts to fall. Here that point is a change point
found by least squares: the ratio is flat up to the onset ``theta_0`` and then falls as
``a (1 - b (theta - theta_0)^p)``. Just after the onset the pupil loses a thin lens-shaped
sliver whose area grows as the 3/2 power of its depth, so ``p`` starts near 1.5 and is left
free in [1, 2.5]; the fit window is limited to a few degrees past the onset, where that shape
holds. The fit (scipy ``least_squares``) gives the onset's standard error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

__all__ = ["Onset", "detect_onset"]

#: Degrees past the onset used by the change-point fit.
WINDOW_DEG = 5.0
#: A fall counts as found when the change-point model lowers chi-square by this much (times
#: the reduced chi-square, when above 1) against a constant: about 5 standard deviations.
SIGNIFICANCE_CHI2 = 25.0


@dataclass(frozen=True)
class Onset:
    """A located onset.

    Attributes
    ----------
    cra_deg : float
        Onset angle; NaN when no onset was found inside the field.
    stderr_deg : float
        Its standard error (scaled by the fit's reduced chi-square when that exceeds 1).
    found : bool
        False when the profile shows no significant fall inside the field.
    max_cra_deg : float
        The largest chief-ray angle checked.
    """

    cra_deg: float
    stderr_deg: float
    found: bool
    max_cra_deg: float


def _hinge(params, theta):
    a, b, t0, p = params
    return a * (1.0 - b * np.maximum(theta - t0, 0.0) ** p)


def detect_onset(cra_deg, value, stderr, *, window_deg=WINDOW_DEG):
    """Locate the onset of vignetting in a ratio profile (flat, then falling).

    Parameters
    ----------
    cra_deg, value, stderr : array_like
        The profile (e.g. :func:`~snapcorr.calibrate.radial_profile` of a flat divided by the
        flat at the highest f-number).

    Returns
    -------
    Onset

    Examples
    --------
    >>> theta = np.linspace(0, 20, 201)
    >>> ratio = 1 - 0.01 * np.clip(theta - 8, 0, None) ** 1.5
    >>> round(detect_onset(theta, ratio, np.full(201, 1e-3)).cra_deg, 2)
    8.0
    """
    theta = np.asarray(cra_deg, float)
    y = np.asarray(value, float)
    s = np.asarray(stderr, float)
    ok = np.isfinite(theta) & np.isfinite(y) & np.isfinite(s) & (s > 0)
    theta, y, s = theta[ok], y[ok], s[ok]
    if theta.size < 8:
        raise ValueError("a profile needs at least 8 bins to locate an onset")
    tmax = float(theta.max())
    s = np.maximum(s, 1e-6 * np.abs(y).max())

    # Scan over the whole profile: for each candidate onset and exponent the model is linear
    # in a and a*b. Then refine in a window past the best candidate.
    best, best_sse = None, np.inf
    for pw in (1.0, 1.5, 2.0):
        for t0 in theta[: max(theta.size - 3, 1)]:
            xk = np.maximum(theta - t0, 0.0) ** pw
            A = np.column_stack([np.ones_like(xk), -xk]) / s[:, None]
            coef, *_ = np.linalg.lstsq(A, y / s, rcond=None)
            sse = float(np.sum((A @ coef - y / s) ** 2))
            if sse < best_sse and coef[1] >= 0:
                best_sse, best = sse, (coef[0], coef[1] / coef[0] if coef[0] else 0.0, t0, pw)
    if best is None:  # only rising fits: nothing falls
        return Onset(float("nan"), float("inf"), False, tmax)
    a0, b0, t00, pw0 = best
    p0 = np.array([a0, max(b0, 1e-9), t00, pw0])
    sel = theta <= t00 + window_deg
    lo = [-np.inf, 0.0, 0.0, 1.0]
    hi = [np.inf, np.inf, tmax, 2.5]
    p0 = np.clip(p0, lo, hi)

    def resid(p, th, yy, ss):
        return (_hinge(p, th) - yy) / ss

    fit = least_squares(resid, p0, bounds=(lo, hi), args=(theta[sel], y[sel], s[sel]),
                        x_scale="jac")
    _, b, t0, _ = fit.x
    J = fit.jac
    dof = max(sel.sum() - 4, 1)
    chi2 = float(fit.fun @ fit.fun) / dof
    cov = np.linalg.pinv(J.T @ J) * max(chi2, 1.0)
    t0_err = float(np.sqrt(max(cov[2, 2], 0.0)))
    # Significance of the fall: chi-square of the hinge against a constant in the window.
    w = 1.0 / s[sel] ** 2
    const = np.sum(w * y[sel]) / np.sum(w)
    chi2_const = float(np.sum(w * (y[sel] - const) ** 2))
    gain = chi2_const - float(fit.fun @ fit.fun)
    found = bool(gain > SIGNIFICANCE_CHI2 * max(chi2, 1.0) and b > 0 and t0 < tmax - 0.2)
    if not found:
        return Onset(float("nan"), float("inf"), False, tmax)
    return Onset(float(t0), t0_err if np.isfinite(t0_err) else float("inf"), True, tmax)
