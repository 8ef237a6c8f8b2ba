"""Rienstra's discrete ray-bundle transform of a measured filter curve.

The converging bundle is split into rings of (nearly) equal incidence angle ``theta_j``; each
ring scales the wavelength axis by a shift factor ``S_j`` (Eq. 4, with an optional temperature
factor) and carries a weight ``W_j``, the ring's share of the bundle's area (App. A-1..A-9).
The transformed curve is the weighted sum of the scaled curves, each linearly interpolated back
onto the original wavelengths (Eq. 5-7).

Rienstra's cold-shield bundle is an unvignetted circle; with a vignetted lens the arc angle
``alpha_j`` is replaced by Goossens' ``gamma`` (Eq. 18) and the full area by the vignetted area
(Eq. 33), which reduces to App. A-9 when nothing is cut off.

References
----------
.. [1] J. L. Rienstra, "Transformation of filter transmission data for f-number and chief ray
   angle", SAND98-0667C, Sandia National Laboratories (1998).
.. [2] T. Goossens et al., Appl. Opt. 58, 1789 (2019), Eq. (18) and (33).
"""

from __future__ import annotations

import numpy as np

from .._validation import check_curve, check_positive
from .aperture import gamma, max_radius_mm, vignetted_area_mm2
from .goossens2019 import PupilCutOffError
from .shift import check_n_eff

__all__ = ["arc_half_angle", "ray_bundle_weights", "shift_factors", "transform"]

#: Rienstra: "an angle increment between one quarter and one half degree usually gives
#: sufficient accuracy such that the sum of all weighting factors is very close to unity".
DEFAULT_STEP_DEG = 0.25


def arc_half_angle(R_j, A, D):
    """Half-angle ``alpha_j`` of the arc of radius ``R_j`` inside the bundle circle, App. A-6..A-8.

    The bundle circle has radius ``A``; the arcs of equal incidence are centred ``D`` away.
    ``x_j = (A^2 + D^2 - R_j^2) / (2 D)``, ``y_j = sqrt(A^2 - x_j^2)``,
    ``alpha_j = atan(y_j / (D - x_j))`` taken in the right quadrant (``arctan2``), with
    Rienstra's limiting cases: ``pi`` for an arc wholly inside, 0 wholly outside.

    Parameters
    ----------
    R_j : array_like
        Arc radius, ``tan(theta_j)`` in units of the filter height (A-3).
    A : array_like
        Bundle-circle radius, ``1 / (2 f#)`` in the same units (A-2).
    D : array_like
        Offset of the bundle's centre, ``tan(CRA)`` in the same units (A-5).

    Returns
    -------
    ndarray
        Radians in [0, pi], the broadcast shape.
    """
    R_j, A, D = np.broadcast_arrays(*(np.asarray(v, float) for v in (R_j, A, D)))
    with np.errstate(divide="ignore", invalid="ignore"):
        xj = (A * A + D * D - R_j * R_j) / (2.0 * D)
        yj = np.sqrt(A * A - xj * xj)
        alpha = np.arctan2(yj, D - xj)
    alpha = np.where((D < A) & (R_j <= A - D), np.pi, alpha)
    alpha = np.where(((D > A) & (R_j <= D - A)) | (R_j >= A + D), 0.0, alpha)
    return np.where(np.isfinite(alpha), alpha, 0.0)


def ray_bundle_weights(f_number_w, cra_deg, *, step_deg=DEFAULT_STEP_DEG, lens=None):
    """Incidence angles ``theta_j`` and weights ``W_j`` of App. A-9.

    Lengths are in units of the filter height ``h_f`` (it cancels): bundle radius
    ``A = 1 / (2 f#)`` (A-2), arc radii ``R_j = tan(theta_j)`` (A-3), ring widths
    ``Delta R_j = tan(theta_j + Delta/2) - tan(theta_j - Delta/2)`` (A-4), offset
    ``D = tan(CRA)`` (A-5) and ``W_j = 2 alpha_j R_j Delta R_j / (pi A^2)`` (A-9).

    Parameters
    ----------
    f_number_w : float
        Working f-number of the bundle.
    cra_deg : float
        Chief-ray angle, degrees.
    step_deg : float
        Angle increment ``Delta theta``.
    lens : Lens, optional
        With vignetting circles, ``alpha_j`` becomes ``gamma`` (Goossens Eq. 18; for several
        circles the arc kept by all) and ``pi A^2`` the vignetted area; the bundle geometry
        then comes from the lens (units x).

    Returns
    -------
    theta_deg, W : ndarray
    """
    check_positive("step_deg", step_deg)
    check_positive("f_number_w", f_number_w)
    if lens is not None and lens.pupil_radiance != "paper":
        raise ValueError("Rienstra's ray bundle (1998) weights the paper's pupil (uniform per "
                         f"area); the lens's pupil is {lens.pupil_radiance!r}: use "
                         "snapcorr.optics.filter_response(method='kernel')")
    if not (np.isfinite(cra_deg) and abs(cra_deg) < 90):
        raise ValueError(f"cra_deg must be finite and between -90 and 90, got {cra_deg!r}")
    A = 1.0 / (2.0 * float(f_number_w))
    D = np.tan(np.deg2rad(abs(float(cra_deg))))
    vign = lens is not None and lens.has_vignetting
    if vign:
        x = lens.exit_pupil_mm
        P, dv = lens.vignetting_args(D)  # mm at tan(CRA) = D; to units of x below
        if isinstance(P, list):
            P, dv = [p / x for p in P], [v / x for v in dv]
        else:
            P, dv = P / x, dv / x
        r_max = float(max_radius_mm(A, D, P, dv))
    else:
        r_max = A + D
    theta_max = np.rad2deg(np.arctan(r_max))
    theta = np.arange(0.0, theta_max + step_deg, step_deg)
    half = np.deg2rad(step_deg) / 2
    t = np.deg2rad(theta)
    R_j = np.tan(t)
    dR = np.tan(t + half) - np.tan(np.clip(t - half, 0.0, None))  # the first ring starts at 0
    if vign:
        arc = gamma(R_j, A, D, P, dv)
        area = vignetted_area_mm2(A, P, dv)
        if area <= 0:
            raise PupilCutOffError(
                f"at CRA {cra_deg} deg the vignetting circles cut off the whole bundle; "
                "no light reaches the filter"
            )
    else:
        arc = arc_half_angle(R_j, A, D)
        area = np.pi * A * A
    return theta, 2.0 * arc * R_j * dR / area


def shift_factors(theta_deg, n_eff, temperature_factor=1.0):
    """Eq. (4): ``S_j = temperature_factor * cos(asin(sin(theta_j) / n_eff))``.

    Parameters
    ----------
    theta_deg : array_like
        Incidence angles ``theta_j``, degrees.
    n_eff : float
        Effective refractive index (> 1).
    temperature_factor : float
        Factor for the filter's temperature (1: none).

    Returns
    -------
    ndarray
        ``S_j``, dimensionless: each ring's wavelength scale.
    """
    n = check_n_eff(n_eff)
    s = np.sin(np.deg2rad(np.asarray(theta_deg, float))) / n
    return float(temperature_factor) * np.sqrt(1.0 - s * s)


def transform(
    wavelength_nm,
    transmission,
    n_eff,
    f_number_w,
    cra_deg,
    *,
    step_deg=DEFAULT_STEP_DEG,
    temperature_factor=1.0,
    lens=None,
    normalize=False,
):
    """Transform a measured transmission curve for f-number and CRA, Eq. (5)-(7).

    ``L = p S^T`` (shifted wavelengths), ``K = t W^T`` (weighted transmissions), and
    ``t_trans_i = sum_j linterp(L_j, K_j, p_i)``.

    Parameters
    ----------
    wavelength_nm, transmission : array_like, shape (m,)
        The measured curve ``p``, ``t`` (wavelength increasing).
    n_eff, f_number_w, cra_deg : float
        Effective index, working f-number and chief-ray angle.
    step_deg : float
        Angle increment of the ray-bundle rings.
    temperature_factor : float
        Multiplies every ``S_j`` (Rienstra: 0.992 for his MWIR filter at 80 K).
    lens : Lens, optional
        Vignetting circle to cut the bundle with (see :func:`ray_bundle_weights`).
    normalize : bool
        Divide by ``sum(W_j)`` so the weights sum exactly to 1 (Rienstra sums them as they are).

    Returns
    -------
    ndarray, shape (m,)
    """
    p, t = check_curve(wavelength_nm, transmission)
    theta, W = ray_bundle_weights(f_number_w, cra_deg, step_deg=step_deg, lens=lens)
    S = shift_factors(theta, n_eff, temperature_factor)
    if normalize:
        W = W / W.sum()
    L = np.outer(p, S)  # Eq. (5)
    K = np.outer(t, W)  # Eq. (6)
    # Eq. (7); outside a shifted column's range the curve is zero (no extrapolation).
    return sum(np.interp(p, L[:, j], K[:, j], left=0.0, right=0.0) for j in range(S.size))
