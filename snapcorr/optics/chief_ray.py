"""The chief-ray angle of a pixel: ``tan(CRA) = d / x`` (Goossens et al. 2019, Eq. 8).

``d`` is the pixel's distance from the optical centre on the sensor and ``x`` the distance
from the sensor to the exit pupil. This is the one place the map from pixels to angles is
written; simulation, calibration and correction all use it.

Pixel (row ``i``, column ``j``) has its centre at ``(row, col) = (i, j)``; the optical
centre is given the same way, ``center_rc = (row, col)``, and may be fractional or outside the
image (:mod:`snapcorr._coords`). Inside, too, the centre is ``center_rc``; the x-first
``center_px=(cx, cy)`` is the deprecated form, turned into it at the entry points.
"""

from __future__ import annotations

import operator
import warnings

import numpy as np

from .._coords import CENTER_PX_DEPRECATION, accepts_center_rc, called_from_outside
from .._validation import check_center, check_center_rc, check_positive

__all__ = ["cra_deg", "cra_map", "image_shape", "pixel_cra_deg", "pixel_tangents"]


def pixel_cra_deg(rows, cols, center_rc, pixel_pitch_um, exit_pupil_mm):
    """Chief-ray angle (degrees) of pixels at sensor ``rows`` and ``cols`` (Eq. 8).

    Parameters
    ----------
    rows, cols : array_like
        Sensor row and column of each pixel (fractional allowed); they broadcast.
    center_rc : (row, col)
        Optical centre, pixels.
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
    >>> round(float(pixel_cra_deg(0, 4, (0, 0), 5.5, 21.0)), 4)  # 22 um off axis
    0.06
    """
    return _cra_deg_rc(rows, cols, center_rc, pixel_pitch_um, exit_pupil_mm)


def cra_deg(rows, cols, center_px, pixel_pitch_um, exit_pupil_mm):
    """Deprecated: :func:`pixel_cra_deg` with the optical centre x first, ``(cx, cy)``.

    Parameters
    ----------
    rows, cols, pixel_pitch_um, exit_pupil_mm
        As for :func:`pixel_cra_deg`.
    center_px : (cx, cy)
        Optical centre, pixels, x first.
    """
    cx, cy = check_center(center_px)
    if called_from_outside(2):
        warnings.warn(CENTER_PX_DEPRECATION.format(row=cy, col=cx).replace(
            "center_rc=", "pixel_cra_deg(rows, cols, center_rc=") + "; cra_deg will be removed",
            FutureWarning, stacklevel=2)
    return _cra_deg_rc(rows, cols, (cy, cx), pixel_pitch_um, exit_pupil_mm)


def _cra_deg_rc(rows, cols, center_rc, pixel_pitch_um, exit_pupil_mm):
    """:func:`pixel_cra_deg`, the centre ``(row, col)`` checked here."""
    cy, cx = check_center_rc(center_rc)
    scale = _tan_per_pixel(pixel_pitch_um, exit_pupil_mm)
    dy = (np.asarray(rows, float) - cy) * scale
    dx = (np.asarray(cols, float) - cx) * scale
    r = np.square(dy) + np.square(dx)  # (tan^2: far from overflow for any field)
    if r.ndim == 0:
        return np.rad2deg(np.arctan(np.sqrt(r)))
    # in place: one array the size of the image (twice as fast at 2048^2 as four)
    np.sqrt(r, out=r)
    np.arctan(r, out=r)
    return np.rad2deg(r, out=r)


@accepts_center_rc
def cra_map(shape, pixel_pitch_um, exit_pupil_mm, center_px=None, *, center_rc=None):
    """Chief-ray angle of every pixel of an image, degrees.

    Parameters
    ----------
    shape : (ny, nx)
        Image size, pixels.
    pixel_pitch_um : float
        Pixel pitch, micrometres.
    exit_pupil_mm : float
        Distance ``x`` from the sensor to the exit pupil, mm.
    center_rc, center_px : (row, col), optional
        Optical centre, pixels, row first; ``center_px=(cx, cy)`` is the deprecated x-first
        form. Default: the image centre ``((ny - 1) / 2, (nx - 1) / 2)``.

    Returns
    -------
    ndarray
        float64, shape ``(ny, nx)``: ``arctan(d / x)`` with ``d = pitch * hypot(j - cx,
        i - cy)``.

    Examples
    --------
    >>> cra = cra_map((3, 5), 5.5, 21.0, center_rc=(0, 0))
    >>> cra.shape, float(cra[0, 0])
    ((3, 5), 0.0)
    >>> round(float(cra[0, 4]), 4)  # 22 um off axis
    0.06
    """
    tx, ty = pixel_tangents(shape, pixel_pitch_um, exit_pupil_mm, center_rc=center_rc)
    return np.rad2deg(np.arctan(np.hypot(ty[:, None], tx[None, :])))


@accepts_center_rc
def pixel_tangents(shape, pixel_pitch_um, exit_pupil_mm, center_px=None, *, center_rc=None):
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
    center_rc, center_px : (row, col), optional
        Optical centre, pixels, row first; ``center_px=(cx, cy)`` is the deprecated x-first
        form. Default: the image centre.

    Returns
    -------
    tx, ty : ndarray
        Shapes ``(nx,)`` and ``(ny,)``; signed (negative left of and above the centre).
    """
    ny, nx = image_shape(shape)
    cy, cx = (((ny - 1) / 2.0, (nx - 1) / 2.0) if center_rc is None
              else check_center_rc(center_rc))
    scale = _tan_per_pixel(pixel_pitch_um, exit_pupil_mm)
    return (np.arange(nx) - cx) * scale, (np.arange(ny) - cy) * scale


def _tan_per_pixel(pixel_pitch_um, exit_pupil_mm):
    return check_positive("pixel_pitch_um", pixel_pitch_um) * 1e-3 / check_positive(
        "exit_pupil_mm", exit_pupil_mm)


def image_shape(shape):
    """``(ny, nx)`` as two positive ints, or a clear ``ValueError``."""
    try:
        ny, nx = (operator.index(n) for n in shape)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"shape must be two positive integers (ny, nx), got {shape!r}") from None
    if ny < 1 or nx < 1:
        raise ValueError(f"shape must be two positive integers (ny, nx), got {shape!r}")
    return ny, nx
