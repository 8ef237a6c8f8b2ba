"""Fit a filter's effective index from centre wavelengths measured at several angles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["NeffFit", "fit_n_eff"]


@dataclass(frozen=True)
class NeffFit:
    """Result of :func:`fit_n_eff`: values, standard errors and residuals (nm)."""

    n_eff: float
    cwl_nm: float
    n_eff_stderr: float
    cwl_stderr_nm: float
    residuals_nm: np.ndarray

    def __repr__(self):
        return (
            f"NeffFit(n_eff={self.n_eff:.4f} +- {self.n_eff_stderr:.4f}, "
            f"cwl_nm={self.cwl_nm:.3f} +- {self.cwl_stderr_nm:.3f}, "
            f"max |residual|={np.abs(self.residuals_nm).max():.3g} nm)"
        )


def _law(aoi_deg, cwl, n):
    s = np.sin(np.deg2rad(aoi_deg)) / n
    return cwl * np.sqrt(1.0 - s * s)


def fit_n_eff(aoi_deg, center_nm, *, sigma_nm=None):
    """Least-squares ``cwl`` and ``n_eff`` of ``lambda(phi) = cwl sqrt(1 - sin^2 phi / n^2)``.

    The law is linear in ``lambda^2`` against ``sin^2 phi`` (intercept ``cwl^2``, slope
    ``-cwl^2 / n^2``), which gives the start; the final fit is nonlinear least squares on the
    wavelengths themselves (``scipy.optimize.curve_fit``), with standard errors from its
    covariance (scaled by the residuals unless ``sigma_nm`` is given).

    Parameters
    ----------
    aoi_deg, center_nm : array_like
        Angles of incidence (degrees) and the measured centre wavelengths (nm); at least two
        distinct non-zero angles are needed.
    sigma_nm : array_like, optional
        Measurement uncertainty of each centre wavelength.

    Returns
    -------
    NeffFit
    """
    phi = np.asarray(aoi_deg, float).ravel()
    lam = np.asarray(center_nm, float).ravel()
    if phi.shape != lam.shape or phi.size < 2:
        raise ValueError("aoi_deg and centre_nm must have the same length (>= 2)")
    if np.unique(np.abs(phi)).size < 2:
        raise ValueError("n_eff needs centre wavelengths at two or more different angles")
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(lam))):
        raise ValueError("aoi_deg and centre_nm must be finite")
    s2 = np.sin(np.deg2rad(phi)) ** 2
    slope, icept = np.polyfit(s2, lam**2, 1)
    if icept <= 0 or slope >= 0:
        raise ValueError(
            "centre wavelengths do not move to the blue with angle; cannot fit an effective index"
        )
    p0 = (np.sqrt(icept), np.sqrt(-icept / slope))
    from scipy.optimize import curve_fit  # here: not a cost of every import of optics

    (cwl, n), cov = curve_fit(
        _law, phi, lam, p0=p0, sigma=sigma_nm, absolute_sigma=sigma_nm is not None
    )
    err = np.sqrt(np.clip(np.diag(cov), 0, None)) if np.all(np.isfinite(cov)) else (np.nan,) * 2
    return NeffFit(float(n), float(cwl), float(err[1]), float(err[0]), lam - _law(phi, cwl, n))
