"""The whole filter response behind a lens, not only its mean shift.

``filter_response`` transforms a transmission curve ``T(lambda)`` for f-number, chief-ray angle
and lens, either by the kernel convolution of Goossens et al. 2019 (Eq. 13 with the
closed-form kernel Eq. 37) or by Rienstra's discrete ray-bundle transform (1998, Eq. 5-7).
"""

from __future__ import annotations

import numpy as np

from .._validation import check_curve, validate_method
from . import rienstra1998
from .goossens2019 import _gauss_legendre, kernel
from .lens import Lens
from .mean import _geometry
from .pupil import max_radius_mm

__all__ = ["RESPONSE_METHODS", "filter_response", "kernel_bins"]

RESPONSE_METHODS = ("kernel", "rienstra")


def kernel_bins(cwl_nm, n_eff, f_number, cra_deg, lens: Lens, *, step_nm=0.05, nodes=6):
    """The kernel of Eq. (37) as point masses: bin centroids ``mu_k`` (nm) and masses ``w_k``.

    Each ``step_nm`` bin between ``lambda_min`` (Eq. 44-45) and 0 is integrated with
    Gauss-Legendre; the masses are normalised to sum to 1 (the raw sum is 1 up to the
    quadrature error of the kernel's square-root kinks) and each centroid is the bin's own first
    moment, so the mean of the masses is the kernel mean.
    """
    x, R, d, P, dv = _geometry(f_number, cra_deg, lens)
    rmax = float(max_radius_mm(d, R, dv, P))
    s2 = np.sin(np.arctan(rmax / x)) ** 2 / n_eff**2
    lam_min = -cwl_nm * s2 / (1 + np.sqrt(1 - s2))
    nbins = max(1, int(np.ceil(-lam_min / step_nm)))
    edges = np.linspace(lam_min, 0.0, nbins + 1)
    xi, w = _gauss_legendre(nodes)
    half = 0.5 * np.diff(edges)
    lam = (edges[:-1] + half)[:, None] + half[:, None] * xi
    K = kernel(lam, cwl_nm, n_eff, x, R, d, P, dv)
    mass = (K * w).sum(axis=1) * half
    moment = (K * lam * w).sum(axis=1) * half
    keep = mass > 0
    mu = moment[keep] / mass[keep]
    return mu, mass[keep] / mass[keep].sum()


def filter_response(
    wavelength_nm,
    transmission,
    *,
    cwl_nm,
    n_eff,
    f_number,
    cra_deg,
    lens: Lens,
    method="kernel",
    step_nm=0.05,
    step_deg=0.25,
    temperature_factor=1.0,
):
    """Transmission of a filter behind ``lens`` at ``f_number`` and ``cra_deg``.

    Parameters
    ----------
    wavelength_nm, transmission : array_like, shape (m,)
        The filter's curve at normal, collimated incidence (wavelength increasing).
    cwl_nm : float
        Central wavelength at which the kernel's shift is evaluated (Eq. 3).
    n_eff, f_number, cra_deg : float
        Effective index, nominal f-number (Eq. 27 gives the working one) and chief-ray angle.
    lens : Lens
    method : {"kernel", "rienstra"}
        ``"kernel"``: ``T_hat = K * T`` (Goossens 2019 Eq. 13; every wavelength shifted by the
        same kernel). ``"rienstra"``: ``sum_j W_j T(lambda / S_j)`` (Rienstra 1998 Eq. 5-7;
        every wavelength scaled by ``S_j``), weights normalised to sum to 1.
    step_nm : float
        Kernel bin width for ``"kernel"``.
    step_deg : float
        Ring angle increment for ``"rienstra"``.
    temperature_factor : float
        Rienstra's temperature shift factor (``"rienstra"`` only; 1 means none).

    Returns
    -------
    ndarray, shape (m,)
        The transformed curve on the input wavelengths. Centroids agree between the methods to
        ``~ cwl * Var(S)``: scaling (Rienstra) and shifting (Goossens) differ at second order.
    """
    validate_method(method, RESPONSE_METHODS)
    p, t = check_curve(wavelength_nm, transmission)
    if method == "rienstra":
        return rienstra1998.transform(
            p,
            t,
            n_eff,
            float(lens.working_f_number(f_number)),
            cra_deg,
            step_deg=step_deg,
            temperature_factor=temperature_factor,
            lens=lens,
            normalize=True,
        )
    if temperature_factor != 1.0:
        raise ValueError("temperature_factor applies to method='rienstra' only")
    mu, w = kernel_bins(cwl_nm, n_eff, f_number, cra_deg, lens, step_nm=step_nm)
    # Eq. (13): T_hat(lambda) = sum_k w_k T(lambda - mu_k), zero outside the measured range.
    shifted = np.interp(p[:, None] - mu[None, :], p, t, left=0.0, right=0.0)
    return shifted @ w
