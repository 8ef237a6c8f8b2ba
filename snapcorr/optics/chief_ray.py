"""The chief-ray angle of a pixel: ``tan(CRA) = d / x`` (Goossens et al. 2019, Eq. 8).

``d`` is the pixel's distance from the optical centre on the sensor and ``x`` the distance
from the sensor to the exit pupil. This is the one place the map from pixels to angles is
written; simulation, calibration and correction all use it.

Pixel (row ``i``, column ``j``) has its centre at image coordinates ``(x=j, y=i)``, as in
OpenCV and scikit-image; an optical centre ``center_px = (cx, cy)`` is in the same coordinates
and may be fractional or outside the image.
"""

from __future__ import annotations

import operator

import numpy as np

from .._validation import check_center, check_positive

__all__ = ["cra_deg", "cra_map", "image_shape", "pixel_tangents"]


def cra_deg(rows, cols, center_px, pixel_pitch_um, exit_pupil_mm):
    """Chief-ray angle (degrees) of pixels at sensor ``rows`` and ``cols`` (Eq. 8).

    Parameters
    ----------
    rows, cols : array_like
        Sensor row and column of each pixel (fractional allowed); they broadcast.
    center_px : (cx, cy)
        Optical centre, pixels (column, row).
    pixel_pitch_um : float
        Pixel pitch, micrometres.
    exit_pupil_mm : float
        Distance ``x`` from the sensor to the exit pupil, mm.

    Returns
    -------
    ndarray
        float64, the broadcast shape of ``rows`` and ``cols``.

    Examples
    --------
    >>> round(float(cra_deg(0, 4, (0, 0), 5.5, 21.0)), 4)  # 22 um off axis
    0.06
    """
    cx, cy = check_center(center_px)
    scale = _tan_per_pixel(pixel_pitch_um, exit_pupil_mm)
    dy = (np.asarray(rows, float) - cy) * scale
    dx = (np.asarray(cols, float) - cx) * scale
    return np.rad2deg(np.arctan(np.hypot(dy, dx)))


def cra_map(shape, pixel_pitch_um, exit_pupil_mm, center_px=None):
    """Chief-ray angle of every pixel of an image, degrees.

    Parameters
    ----------
    shape : (ny, nx)
        Image size, pixels.
    pixel_pitch_um : float
        Pixel pitch, micrometres.
    exit_pupil_mm : float
        Distance ``x`` from the sensor to the exit pupil, mm.
    center_px : (cx, cy), optional
        Optical centre, pixels (column, row). Default: the image centre
        ``((nx - 1) / 2, (ny - 1) / 2)``.

    Returns
    -------
    ndarray
        float64, shape ``(ny, nx)``: ``arctan(d / x)`` with ``d = pitch * hypot(j - cx,
        i - cy)``.

    Examples
    --------
    >>> cra = cra_map((3, 5), 5.5, 21.0, center_px=(0, 0))
    >>> cra.shape, float(cra[0, 0])
    ((3, 5), 0.0)
    >>> round(float(cra[0, 4]), 4)  # 22 um off axis
    0.06
    """
    tx, ty = pixel_tangents(shape, pixel_pitch_um, exit_pupil_mm, center_px)
    return np.rad2deg(np.arctan(np.hypot(ty[:, None], tx[None, :])))


def pixel_tangents(shape, pixel_pitch_um, exit_pupil_mm, center_px=None):
    """``tan`` of the chief ray's components along the columns and the rows, 1-D each.

    ``tan(CRA) = hypot(ty[:, None], tx[None, :])``: the separable form of :func:`cra_map`, for
    work done on an image's rows in blocks (Eq. 8).

    Parameters
    ----------
    shape : (ny, nx)
        Image size, pixels.
    pixel_pitch_um : float
        Pixel pitch, micrometres.
    exit_pupil_mm : float
        Distance ``x`` from the sensor to the exit pupil, mm.
    center_px : (cx, cy), optional
        Optical centre, pixels (column, row). Default: the image centre.

    Returns
    -------
    tx, ty : ndarray
        Shapes ``(nx,)`` and ``(ny,)``; signed (negative left of and above the centre).
    """
    ny, nx = image_shape(shape)
    cx, cy = (((nx - 1) / 2.0, (ny - 1) / 2.0) if center_px is None
              else check_center(center_px))
    scale = _tan_per_pixel(pixel_pitch_um, exit_pupil_mm)
    return (np.arange(nx) - cx) * scale, (np.arange(ny) - cy) * scale


def _tan_per_pixel(pixel_pitch_um, exit_pupil_mm):
    return check_positive("pixel_pitch_um", pixel_pitch_um) * 1e-3 / check_positive(
        "exit_pupil_mm", exit_pupil_mm)


def image_shape(shape):
    """``(ny, nx)`` as two positive ints, or a clear ``ValueError``."""
    try:
        ny, nx = (operator.index(n) for n in shape)
    except (TypeError, ValueError):
        raise ValueError(f"shape must be two positive integers (ny, nx), got {shape!r}") from None
    if ny < 1 or nx < 1:
        raise ValueError(f"shape must be two positive integers (ny, nx), got {shape!r}")
    return ny, nx
