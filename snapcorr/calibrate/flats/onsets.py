"""Onset of optical vignetting from a radial profile: the paper's discontinuity, located.

Goossens et al. 2019 (Sec. 3.2) divide each vignetting profile by the profile at the highest
f-number and mark by eye where the ratio starts to fall. Here that point is a change point
found by least squares: the ratio is flat up to the onset ``theta_0`` and then falls as
``a (1 - b (theta - theta_0)^p)``. Just after the onset the pupil loses a thin lens-shaped
sliver whose area grows as the 3/2 power of its depth, so ``p`` starts near 1.5 and is left
free in [1, 2.5]; the fit window ends 2 degrees past the onset, where that shape
holds. The fit (scipy ``least_squares``) gives the onset's standard error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

__all__ = ["Onset", "detect_onset"]

#: Degrees past the onset used by the change-point fit.
WINDOW_DEG = 2.0
#: A fall counts as found when the change-point model lowers chi-square by this much (times
#: the reduced chi-square, when above 1) against a constant: about 5 standard deviations.
SIGNIFICANCE_CHI2 = 25.0
#: Added in quadrature to the onset's standard error: the change-point shape is not the exact
#: fall-off, which biases onsets by up to 0.044 deg on exact ratio profiles of the paper's lens
#: (f/1.4-f/4 against f/8, measured).
SYSTEMATIC_DEG = 0.05


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
    a, b, t0, p, c = params
    return a * (1.0 + c * theta**2) * (1.0 - b * np.maximum(theta - t0, 0.0) ** p)


def detect_onset(cra_deg, value, stderr, *, window_deg=WINDOW_DEG):
    """Locate the onset of vignetting in a ratio profile (flat, then falling).

    Parameters
    ----------
    cra_deg, value, stderr : array_like
        The profile (e.g. :func:`~snapcorr.calibrate.radial_profile` of a flat divided by the
        flat at the highest f-number).
    window_deg : float
        The refining fit uses the bins up to this far past the scan's best onset, degrees.

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

    # Scan the whole profile: for each candidate onset and exponent the model (without the
    # baseline's cross term) is linear in a, a*c and a*b. Then refine all five parameters in
    # a window that ends ``window_deg`` past the best candidate.
    th2 = theta**2
    best, best_sse = None, np.inf
    for pw in (1.0, 1.5, 2.0):
        for t0 in theta[: max(theta.size - 3, 1)]:
            xk = np.maximum(theta - t0, 0.0) ** pw
            A = np.column_stack([np.ones_like(xk), th2, -xk]) / s[:, None]
            coef, *_ = np.linalg.lstsq(A, y / s, rcond=None)
            sse = float(np.sum((A @ coef - y / s) ** 2))
            if coef[2] > 0 and coef[0] > 0 and sse < best_sse:
                best_sse = sse
                best = (coef[0], coef[2] / coef[0], t0, pw, coef[1] / coef[0])
    if best is None:  # no window shows a fall
        return Onset(float("nan"), float("inf"), False, tmax)
    a0, b0, t00, pw0, c0 = best
    sel = theta <= t00 + window_deg
    lo = [-np.inf, 0.0, 0.0, 1.0, -np.inf]
    hi = [np.inf, np.inf, tmax, 2.5, np.inf]
    p0 = np.clip(np.array([a0, max(b0, 1e-9), t00, pw0, c0]), lo, hi)

    def resid(p, th, yy, ss):
        return (_hinge(p, th) - yy) / ss

    fit = least_squares(resid, p0, bounds=(lo, hi), args=(theta[sel], y[sel], s[sel]),
                        x_scale="jac")
    _, b, t0, _, _ = fit.x
    J = fit.jac
    dof = max(sel.sum() - 5, 1)
    chi2 = float(fit.fun @ fit.fun) / dof
    cov = np.linalg.pinv(J.T @ J) * max(chi2, 1.0)
    t0_err = float(np.sqrt(max(cov[2, 2], 0.0)))
    # Significance of the fall, over the whole profile: the scan's best hinge against the
    # baseline alone (a short window cannot tell an onset near 0 from a curved baseline).
    B = np.column_stack([np.ones_like(theta), th2]) / s[:, None]
    coef, *_ = np.linalg.lstsq(B, y / s, rcond=None)
    chi2_base = float(np.sum((B @ coef - y / s) ** 2))
    scale = max(best_sse / max(theta.size - 5, 1), 1.0)
    found = bool(chi2_base - best_sse > SIGNIFICANCE_CHI2 * scale and b > 0
                 and t0 < tmax - 0.2)
    if not found:
        return Onset(float("nan"), float("inf"), False, tmax)
    if t0 <= theta[0] + 1e-6:
        # at the start of the profile: the fall begins at or before the first bin, and the
        # fit's bound hides how far before; no standard error can be given
        return Onset(float(theta[0]), float("inf"), True, tmax)
    err = float(np.hypot(t0_err, SYSTEMATIC_DEG)) if np.isfinite(t0_err) else float("inf")
    return Onset(float(t0), err, True, tmax)
