"""Compatibility re-exports: the vignetted-aperture geometry lives in
:mod:`snapcorr.optics.aperture` ("pupil" in snapcorr is the exit pupil alone).

The functions that take the pixel's distance and the circles keep here their earlier argument
order, ``(d, R, dv, P)``, and warn (``FutureWarning``) when called from outside snapcorr:
:mod:`snapcorr.optics.aperture` takes them in the paper's order, ``(R, d, P, dv)``, as
:mod:`snapcorr.optics.goossens2019` does. This module will be removed in snapcorr 0.3.
"""

from __future__ import annotations

from .._validation import called_from_outside, warn_renamed
from . import aperture as _aperture
from .aperture import (
    lens_area,
    lens_boundary_arcs,
    nu,
    overlap_area_mm2,
    overlap_irradiance_mm2,
    relative_irradiance,
    vignetted_area_mm2,
)

_MOVED_TO = "snapcorr.optics.aperture"

__all__ = [
    "eta",
    "gamma",
    "lens_area",
    "lens_boundary_arcs",
    "max_radius_eq44",
    "max_radius_mm",
    "min_radius_mm",
    "nu",
    "overlap_area_mm2",
    "overlap_irradiance_mm2",
    "relative_irradiance",
    "vignetted_area_mm2",
]


def _warn(old, new):
    if called_from_outside(3):
        warn_renamed(f"snapcorr.optics.pupil.{old}", f"snapcorr.optics.aperture.{new}",
                     stacklevel=4)


def eta(r_mm, d_mm, R_mm):
    """:func:`snapcorr.optics.aperture.eta` in the earlier order ``(r, d, R)``.

    Parameters
    ----------
    r_mm, d_mm, R_mm
        As for :func:`snapcorr.optics.aperture.eta`.
    """
    _warn("eta(r_mm, d_mm, R_mm)", "eta(r_mm, R_mm, d_mm)")
    return _aperture.eta(r_mm, R_mm, d_mm)


def gamma(r_mm, d_mm, R_mm, dv_mm=None, P_mm=None, *, h_ge_x=None):
    """:func:`snapcorr.optics.aperture.gamma` in the earlier order ``(r, d, R, dv, P)``.

    Parameters
    ----------
    r_mm, d_mm, R_mm, dv_mm, P_mm, h_ge_x
        As for :func:`snapcorr.optics.aperture.gamma`.
    """
    _warn("gamma(r_mm, d_mm, R_mm, dv_mm, P_mm)", "gamma(r_mm, R_mm, d_mm, P_mm, dv_mm)")
    return _aperture.gamma(r_mm, R_mm, d_mm, P_mm, dv_mm, h_ge_x=h_ge_x)


def max_radius_eq44(d_mm, R_mm, dv_mm=None, P_mm=None):
    """:func:`snapcorr.optics.aperture.max_radius_eq44` in the earlier order ``(d, R, dv, P)``.

    Parameters
    ----------
    d_mm, R_mm, dv_mm, P_mm
        As for :func:`snapcorr.optics.aperture.max_radius_eq44`.
    """
    _warn("max_radius_eq44(d_mm, R_mm, dv_mm, P_mm)", "max_radius_eq44(R_mm, d_mm, P_mm, dv_mm)")
    return _aperture.max_radius_eq44(R_mm, d_mm, P_mm, dv_mm)


def max_radius_mm(d_mm, R_mm, dv_mm=None, P_mm=None):
    """:func:`snapcorr.optics.aperture.max_radius_mm` in the earlier order ``(d, R, dv, P)``.

    Parameters
    ----------
    d_mm, R_mm, dv_mm, P_mm
        As for :func:`snapcorr.optics.aperture.max_radius_mm`.
    """
    _warn("max_radius_mm(d_mm, R_mm, dv_mm, P_mm)", "max_radius_mm(R_mm, d_mm, P_mm, dv_mm)")
    return _aperture.max_radius_mm(R_mm, d_mm, P_mm, dv_mm)


def min_radius_mm(d_mm, R_mm, dv_mm=None, P_mm=None):
    """:func:`snapcorr.optics.aperture.min_radius_mm` in the earlier order ``(d, R, dv, P)``.

    Parameters
    ----------
    d_mm, R_mm, dv_mm, P_mm
        As for :func:`snapcorr.optics.aperture.min_radius_mm`.
    """
    _warn("min_radius_mm(d_mm, R_mm, dv_mm, P_mm)", "min_radius_mm(R_mm, d_mm, P_mm, dv_mm)")
    return _aperture.min_radius_mm(R_mm, d_mm, P_mm, dv_mm)
