"""Central-wavelength shift of a tilted thin-film filter (the effective-index law).

References
----------
.. [1] T. Goossens, B. Geelen, A. Lambrechts, C. Van Hoof, "Vignetted-aperture correction for
   spectral cameras with integrated thin-film Fabry-Perot filters", Appl. Opt. 58, 1789 (2019),
   Eq. (3) and (40).
.. [2] J. L. Rienstra, "Transformation of filter transmission data for f-number and chief ray
   angle", SAND98-0667C (1998), Eq. (2)-(3).
.. [3] D. N. Mishev, K. P. Bakalova, "Multispectral imagery and interference filter effects",
   Eq. (3).
"""

from __future__ import annotations

import warnings

import numpy as np

from .._validation import N_EFF_MAX

__all__ = [
    "AOI_VALIDITY_DEG",
    "EffectiveIndexWarning",
    "aoi_from_shift_deg",
    "check_n_eff",
    "shift_nm",
    "tilted_cwl_nm",
]

#: Largest angle of incidence for which a multilayer filter is known to behave like an ideal
#: Fabry-Perot etalon with an effective index (Goossens 2019, Sec. 2.2, citing Pidgeon & Smith).
AOI_VALIDITY_DEG = 40.0


class EffectiveIndexWarning(UserWarning):
    """Rays beyond :data:`AOI_VALIDITY_DEG` reach the filter: the effective-index law is
    extrapolated there, so results are those of the model, not necessarily of the filter."""


def check_n_eff(n_eff):
    """Return ``n_eff`` as float array, raising if any value is not a finite index > 1."""
    n = np.asarray(n_eff, dtype=float)
    ok = np.isfinite(n) & (n > 1.0) & (n < N_EFF_MAX)
    if not np.all(ok):
        bad = n[~ok].ravel()[:3]
        raise ValueError(
            f"n_eff must be a finite effective refractive index in (1, {N_EFF_MAX:g}) (got "
            f"{bad.tolist()}); typical thin-film Fabry-Perot filters have n_eff between 1.4 "
            "and 2.4."
        )
    return n


def _check_aoi(aoi_deg):
    aoi = np.abs(np.asarray(aoi_deg, dtype=float))
    if not np.all(np.isfinite(aoi)) or np.any(aoi >= 90.0):
        bad = aoi[~(np.isfinite(aoi) & (aoi < 90.0))].ravel()[:3]
        raise ValueError(f"angle of incidence must be finite and below 90 deg (got {bad.tolist()})")
    if np.any(aoi > AOI_VALIDITY_DEG):
        warn_validity(float(aoi.max()))
    return aoi


def warn_validity(max_aoi_deg, stacklevel=3):
    """Warn that rays up to ``max_aoi_deg`` exceed the effective-index model's validity."""
    warnings.warn(
        f"rays reach the filter at up to {max_aoi_deg:.1f} deg; the effective-index law is "
        f"validated up to about {AOI_VALIDITY_DEG:.0f} deg (Goossens 2019, Sec. 2.2), so the "
        "result is the model's extrapolation.",
        EffectiveIndexWarning,
        stacklevel=stacklevel,
    )


def shift_nm(cwl_nm, n_eff, aoi_deg):
    """Shift of a filter's central wavelength at angle of incidence ``aoi_deg``.

    Eq. (3) in [1]_: ``Delta(phi) = -cwl * (1 - sqrt(1 - sin^2(phi) / n_eff^2))``. It is the
    same law as Eq. (3) in [2]_ (``lambda = lambda_0 cos(asin(sin(phi) / n_eff))``) and
    Eq. (3) in [3]_, written as a shift.

    Parameters
    ----------
    cwl_nm : array_like
        Central wavelength at normal incidence, nm.
    n_eff : array_like
        Effective refractive index of the filter (> 1).
    aoi_deg : array_like
        Angle of incidence, degrees (the sign is ignored).

    Returns
    -------
    shift : ndarray
        Shift in nm, negative (towards the blue). Arguments broadcast.

    Raises
    ------
    ValueError
        If ``n_eff <= 1`` or an angle is not below 90 deg.

    Warns
    -----
    EffectiveIndexWarning
        Angles above :data:`AOI_VALIDITY_DEG`.

    Examples
    --------
    >>> round(float(shift_nm(700.0, 1.7, 10.0)), 4)
    -3.6614
    """
    n = check_n_eff(n_eff)
    s = np.sin(np.deg2rad(_check_aoi(aoi_deg))) / n
    q = s * s
    # 1 - sqrt(1 - q) written as q / (1 + sqrt(1 - q)): no cancellation at small angles.
    return -np.asarray(cwl_nm, dtype=float) * q / (1.0 + np.sqrt(1.0 - q))


def tilted_cwl_nm(cwl_nm, n_eff, aoi_deg):
    """Central wavelength of a filter tilted by ``aoi_deg``: ``cwl + shift_nm(...)`` (Eq. 3).

    Parameters
    ----------
    cwl_nm : array_like
        Central wavelength at normal incidence, nm.
    n_eff : array_like
        Effective refractive index of the filter (> 1).
    aoi_deg : array_like
        Angle of incidence, degrees (the sign is ignored).

    Returns
    -------
    ndarray
        Tilted central wavelength in nm; arguments broadcast.
    """
    return np.asarray(cwl_nm, dtype=float) + shift_nm(cwl_nm, n_eff, aoi_deg)


def aoi_from_shift_deg(shift, cwl_nm, n_eff):
    """Angle of incidence that produces ``shift`` (nm, <= 0): the inverse of Eq. (3), Eq. (40).

    ``phi = asin(n_eff * sqrt(-(shift/cwl) * (2 + shift/cwl)))``.

    Parameters
    ----------
    shift : array_like
        Shift of the central wavelength, nm (<= 0, no bluer than grazing incidence gives).
    cwl_nm : array_like
        Central wavelength at normal incidence, nm.
    n_eff : array_like
        Effective refractive index of the filter (> 1).

    Returns
    -------
    ndarray
        Angle of incidence in degrees, [0, 90]; arguments broadcast.

    Raises
    ------
    ValueError
        A positive shift, or one beyond grazing incidence.
    """
    n = check_n_eff(n_eff)
    u = np.asarray(shift, dtype=float) / np.asarray(cwl_nm, dtype=float)
    arg = n * np.sqrt(np.clip(-u * (2.0 + u), 0.0, None))
    if np.any(u > 0) or np.any(arg > 1.0):
        raise ValueError(
            "shift must lie between -cwl * (1 - sqrt(1 - 1/n_eff^2)) and 0; a positive shift or "
            "one beyond grazing incidence has no angle of incidence."
        )
    return np.rad2deg(np.arcsin(arg))
