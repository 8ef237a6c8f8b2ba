"""The whole filter response behind a lens, not only its mean shift.

``filter_response`` transforms a transmission curve ``T(lambda)`` for f-number, chief-ray angle
and lens, either by the kernel convolution of Goossens et al. 2019 (Eq. 13 with the
closed-form kernel Eq. 37) or by Rienstra's discrete ray-bundle transform (1998, Eq. 5-7).
"""

from __future__ import annotations

import numpy as np

from .._validation import check_curve, check_positive, validate_method
from . import rienstra1998
from .aperture import max_radius_mm, min_radius_mm
from .goossens2019 import _gauss_legendre, kernel, mean_shift_contour
from .lens import Lens
from .mean import _geometry
from .shift import check_n_eff, shift_nm

__all__ = ["RESPONSE_METHODS", "filter_response", "kernel_bins", "kernel_bins_batch"]

RESPONSE_METHODS = ("kernel", "rienstra")


def kernel_bins(cwl_nm, n_eff, f_number, cra_deg, lens: Lens, *, step_nm=0.05, nodes=6):
    """The kernel of Eq. (37) as point masses: bin centroids ``mu_k`` (nm) and masses ``w_k``.

    The kernel's support, from the largest to the smallest incidence angle that reaches the
    pixel (Eq. 44-45 and its counterpart), is cut into bins of at most ``step_nm`` (at least
    8); each bin is integrated with Gauss-Legendre and placed at its own first moment. The
    masses are normalised to sum to 1, and the centroids are shifted together by the (tiny)
    difference between their mean and the exact kernel mean, so the discrete kernel has exactly
    the mean of :func:`~snapcorr.optics.goossens2019.mean_shift_contour`.

    Parameters
    ----------
    cwl_nm : float
        Central wavelength at normal incidence, nm.
    n_eff : float
        Effective refractive index (> 1).
    f_number : float
        Nominal f-number.
    cra_deg : float
        Chief-ray angle, degrees.
    lens : Lens
    step_nm : float
        Largest bin width, nm.
    nodes : int
        Gauss-Legendre nodes per bin.

    Returns
    -------
    mu : ndarray
        Bin centroids, shifts in nm (<= 0).
    w : ndarray
        Their masses, summing to 1. A single mass at the exact mean when the kernel is too
        narrow for the nodes to see.

    Raises
    ------
    PupilCutOffError
        If no light reaches the pixel.
    """
    cra = np.asarray(cra_deg, float)
    if cra.size != 1:
        raise ValueError(f"cra_deg must be one angle, got {cra.size}")
    return kernel_bins_batch(cwl_nm, n_eff, f_number, cra.reshape(1), lens, step_nm=step_nm,
                             nodes=nodes)[0]


#: Kernel evaluations (bins times nodes) per pass of :func:`kernel_bins_batch` (one angle at
#: least): arrays of a quarter megabyte stay in cache, and passes of this size were the
#: fastest measured.
_BATCH_POINTS = 1 << 15


def kernel_bins_batch(cwl_nm, n_eff, f_number, cra_deg, lens: Lens, *, step_nm=0.05, nodes=6):
    """:func:`kernel_bins` at every chief-ray angle of ``cra_deg`` at once.

    The same bins, masses and centroids, angle by angle, as :func:`kernel_bins` (which calls
    this with one angle); the kernel is evaluated for several angles in one pass.

    Parameters
    ----------
    cwl_nm, n_eff, f_number : float
    cra_deg : array_like, shape (n,)
        Chief-ray angles, degrees.
    lens : Lens
    step_nm : float
    nodes : int

    Returns
    -------
    list of (mu, w)
        One pair per angle, as :func:`kernel_bins` returns.

    Raises
    ------
    PupilCutOffError
        If no light reaches the pixel at one of the angles.
    """
    check_positive("step_nm", step_nm)
    n_eff = float(check_n_eff(n_eff))
    cra = np.asarray(cra_deg, float).ravel()
    x, R, d, P, dv = _geometry(f_number, cra, lens)
    exact = np.broadcast_to(mean_shift_contour(cwl_nm, n_eff, x, R, d, P, dv,  # raises if cut off
                                               pupil=lens.pupil_radiance), cra.shape)
    rmin = np.broadcast_to(min_radius_mm(R, d, P, dv), cra.shape)
    rmax = np.broadcast_to(max_radius_mm(R, d, P, dv), cra.shape)
    xi, w = _gauss_legendre(nodes)
    edges = []
    for k in range(cra.size):
        lo, hi = (float(shift_nm(cwl_nm, n_eff, np.rad2deg(np.arctan(r / x))))
                  for r in (rmax[k], rmin[k]))
        edges.append(np.linspace(lo, hi, max(8, int(np.ceil((hi - lo) / step_nm))) + 1))
    counts = np.array([e.size - 1 for e in edges])
    out = [None] * cra.size
    # Angles with about as many bins together, as rows of a (angles, bins, nodes) array padded
    # to the most bins: each angle's geometry (and the area of its pupil) broadcasts along its
    # row, and passes hold at most _BATCH_POINTS evaluations.
    order = np.argsort(counts, kind="stable")
    first = 0
    while first < order.size:
        last = first + 1
        while last < order.size and (last + 1 - first) * counts[order[last]] * xi.size \
                <= _BATCH_POINTS:
            last += 1
        which = order[first:last]
        width = int(counts[which].max())
        mid = np.empty((which.size, width))
        half = np.zeros((which.size, width))  # padding: no mass
        for row, k in enumerate(which):
            e = edges[k]
            half[row, :e.size - 1] = 0.5 * np.diff(e)
            mid[row, :e.size - 1] = e[:-1] + half[row, :e.size - 1]
            mid[row, e.size - 1:] = e[-1]  # padding inside the kernel's support
        lam = mid[..., None] + half[..., None] * xi
        at = which[:, None, None]
        K = kernel(lam, cwl_nm, n_eff, x, R, d[at], *_circles_at(P, dv, at))
        # the Lambertian pupil weights each ray by cos^4(phi) = (1 - sin^2 phi)^2 per area
        if lens.ray_weight == "cos4":
            sin2 = np.clip(n_eff * n_eff * (1.0 - (1.0 + lam / cwl_nm) ** 2), 0.0, 1.0)
            K = K * (1.0 - sin2) ** 2
        mass = (K @ w) * half  # Gauss-Legendre over each bin
        moment = ((K * lam) @ w) * half
        for row, k in enumerate(which):
            m = mass[row, :counts[k]]
            keep = m > 0
            if not np.any(keep):  # narrower than the nodes can see: a Dirac at the mean
                out[k] = np.array([float(exact[k])]), np.array([1.0])
                continue
            mu = moment[row, :counts[k]][keep] / m[keep]
            weights = m[keep] / m[keep].sum()
            out[k] = mu + (float(exact[k]) - mu @ weights), weights
        first = last
    return out


def _circles_at(P, dv, which):
    """The circles' ``P_mm, dv_mm`` arguments at the angles ``which`` (an index array)."""
    if P is None:
        return None, None
    if isinstance(P, (list, tuple)):
        return P, [np.asarray(v)[which] for v in dv]
    return P, np.asarray(dv)[which]


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
        if lens.pupil_radiance != "paper":
            raise ValueError("Rienstra's ray bundle (1998) weights the paper's pupil; for the "
                             f"{lens.pupil_radiance} one use method='kernel'")
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
