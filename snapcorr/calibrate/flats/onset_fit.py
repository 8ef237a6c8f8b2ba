"""Vignetting-circle radius P and distance h from the onset angles of vignetting.

At the onset of optical vignetting the vignetting circle touches the exit pupil's edge,
``P - h tan(CRA_onset) = R`` (Goossens et al. 2019, Eq. 24-25). One such equation per f-number
gives the (possibly overdetermined) linear system of Eq. (26), solved here by least squares
(the paper uses the Moore-Penrose inverse, which is the same solution), with residuals and
standard errors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OnsetFit", "solve_vignetting_circle"]


@dataclass(frozen=True)
class OnsetFit:
    """Least-squares solution of Eq. (26).

    Attributes
    ----------
    P_mm, h_mm : float
        Radius and distance of the vignetting circle.
    P_stderr_mm, h_stderr_mm : float
        Standard errors from the residual variance (NaN with only two equations).
    residuals_mm : ndarray
        ``A (P, h) - R`` for each f-number.
    """

    P_mm: float
    h_mm: float
    P_stderr_mm: float
    h_stderr_mm: float
    residuals_mm: np.ndarray
    #: 2 x 2 covariance of (P, h), scaled as the standard errors (NaN with two equations)
    covariance: np.ndarray | None = None


def solve_vignetting_circle(onset_cra_deg, exit_pupil_radius_mm, onset_stderr_deg=None):
    """Solve Eq. (26), ``[1, -tan(CRA_i)] (P, h)^T = R_i``, for P and h.

    Parameters
    ----------
    onset_cra_deg : array_like, shape (n,)
        Chief-ray angle where vignetting starts at each f-number, degrees.
    exit_pupil_radius_mm : array_like, shape (n,)
        Exit-pupil radius R_i at each f-number (Eq. 28, from the working f-number Eq. 27).
    onset_stderr_deg : array_like, shape (n,), optional
        Standard errors of the onsets. With them the equations are weighted by the error each
        onset puts on its row (``dR_i = h sec^2(CRA_i) dCRA_i``; the paper's Moore-Penrose
        solution is the equal-weight case), and the standard errors of P and h come from the
        onsets' errors, scaled up by the reduced chi-square when the residuals exceed them.

    Returns
    -------
    OnsetFit

    Raises
    ------
    ValueError
        Fewer than two f-numbers, non-finite values, or onsets that do not tell P from h
        (all the same angle).

    Examples
    --------
    The paper's Eq. (30) gives Eq. (31):

    >>> fit = solve_vignetting_circle([0.38, 9, 13, 15.4], [7.1715, 5.0201, 3.5858, 2.5100])
    >>> f"P = {fit.P_mm:.4f} mm, h = {fit.h_mm:.2f} mm"
    'P = 7.4236 mm, h = 16.99 mm'

    (h = 16.9915: the paper prints 16.991.)
    """
    t = np.tan(np.deg2rad(np.asarray(onset_cra_deg, dtype=float))).ravel()
    R = np.asarray(exit_pupil_radius_mm, dtype=float).ravel()
    if t.shape != R.shape or t.size < 2:
        raise ValueError("need one onset angle per exit-pupil radius, for two or more "
                         "f-numbers")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(R)) and np.all(R > 0)):
        raise ValueError("onset angles and exit-pupil radii must be finite (radii > 0)")
    if np.ptp(t) == 0:
        raise ValueError("all onsets are at the same angle: P and h cannot be told apart; "
                         "measure at f-numbers whose onsets differ")
    A = np.column_stack([np.ones_like(t), -t])
    (P, h), *_ = np.linalg.lstsq(A, R, rcond=None)
    dof = t.size - 2
    if onset_stderr_deg is None:
        residuals = A @ np.array([P, h]) - R
        if dof > 0:
            cov = np.linalg.inv(A.T @ A) * (residuals @ residuals) / dof
        else:
            cov = np.full((2, 2), np.nan)
        P_err, h_err = np.sqrt(np.diag(cov))
        return OnsetFit(float(P), float(h), float(P_err), float(h_err), residuals, cov)
    e = np.asarray(onset_stderr_deg, float).ravel()
    if e.shape != t.shape or not np.all(e > 0):
        raise ValueError("need one positive onset standard error per onset angle")
    for _ in range(2):  # weights depend on h: start from the unweighted solution
        sig_R = np.maximum(abs(h) * (1.0 + t * t) * np.deg2rad(e), 1e-12)  # dR = h sec^2 dCRA
        Aw, Rw = A / sig_R[:, None], R / sig_R
        (P, h), *_ = np.linalg.lstsq(Aw, Rw, rcond=None)
    residuals = A @ np.array([P, h]) - R
    try:
        cov = np.linalg.inv(Aw.T @ Aw)
    except np.linalg.LinAlgError:  # weights of 1e12 beside others (h ~ 0): no P and h
        raise ValueError("the onsets' weights do not tell P from h (the fitted h is about "
                         "0): their angles fit no circle") from None
    chi2 = float(np.sum((residuals / sig_R) ** 2)) / dof if dof > 0 else 1.0
    cov = cov * max(chi2, 1.0)
    P_err, h_err = np.sqrt(np.diag(cov))
    return OnsetFit(float(P), float(h), float(P_err), float(h_err), residuals, cov)
