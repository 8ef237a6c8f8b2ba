"""Where each pixel and band of a cube sits behind the lens: sensor position and chief-ray angle.

A cube pixel ``(y, x)`` of band ``b`` was exposed at sensor row ``sensor_row(y, b)`` and column
``sensor_col(x, b)`` (a mosaic keeps them per band, see :func:`~snapcorr.cube.mosaic_to_cube`;
a Snapscan cube has every band at the same position). Its distance from the optical centre on
the sensor, times the pixel pitch, gives the chief-ray angle ``tan CRA = d / x`` (Goossens et
al. 2019, Eq. 8).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = ["CenterWarning", "cube_cra_deg", "optical_center"]


class CenterWarning(UserWarning):
    """The lens profile's optical centre could not be used for this cube."""


def _positions(cube):
    """Sensor rows (ny, nb or 1) and columns (nx, nb or 1) of the cube's pixels."""
    ny, nx = cube.sizes["y"], cube.sizes["x"]
    if "sensor_row" in cube.coords and "sensor_col" in cube.coords:
        rows = np.asarray(cube["sensor_row"].transpose("y", "band").values, float)
        cols = np.asarray(cube["sensor_col"].transpose("x", "band").values, float)
        if np.all(rows == rows[:, :1]) and np.all(cols == cols[:, :1]):
            rows, cols = rows[:, :1], cols[:, :1]  # every band at the same position
        return rows, cols
    r0, c0 = cube.attrs.get("sensor_origin_px", (0, 0))
    return (float(r0) + np.arange(ny, dtype=float))[:, None], \
        (float(c0) + np.arange(nx, dtype=float))[:, None]


def optical_center(cube, lens, sensor, center_px=None):
    """The optical centre in sensor pixels (column, row), and where it came from.

    Given explicitly; else the lens profile's ``[calibration] center_px`` when it was measured
    with this sensor's pixel pitch; else the centre of the sensor area the cube covers.
    """
    if center_px is not None:
        cx, cy = (float(v) for v in center_px)
        if not (math.isfinite(cx) and math.isfinite(cy)):
            raise ValueError(f"center_px must be finite, got {center_px!r}")
        return (cx, cy), "given"
    cal = getattr(lens, "calibration", {}) or {}
    if "center_px" in cal and cal.get("pixel_pitch_um") is not None:
        if abs(float(cal["pixel_pitch_um"]) - sensor.pixel_pitch_um) < 1e-9:
            cx, cy = (float(v) for v in cal["center_px"])
            return (cx, cy), "lens calibration"
        warnings.warn(
            f"the lens profile's optical centre was measured with {cal['pixel_pitch_um']} um "
            f"pixels, this sensor has {sensor.pixel_pitch_um} um: the image centre is used; "
            "pass center_px to override", CenterWarning, stacklevel=3)
    rows, cols = _positions(cube)
    return ((float(cols.min()) + float(cols.max())) / 2.0,
            (float(rows.min()) + float(rows.max())) / 2.0), "image centre"


def cube_cra_deg(cube, lens, sensor, center_px=None):
    """Chief-ray angle of every pixel (and band, for mosaics), degrees.

    Returns
    -------
    cra : ndarray, shape (ny, nx, nb) or (ny, nx, 1)
        The last axis is 1 when every band shares its pixel's position (Snapscan).
    center : (float, float)
    center_source : str
    """
    (cx, cy), source = optical_center(cube, lens, sensor, center_px)
    rows, cols = _positions(cube)
    pitch_mm = sensor.pixel_pitch_um * 1e-3
    dy = (rows - cy)[:, None, :] * pitch_mm  # (ny, 1, nb)
    dx = (cols - cx)[None, :, :] * pitch_mm  # (1, nx, nb)
    d = np.hypot(dy, dx)
    return np.rad2deg(np.arctan(d / lens.exit_pupil_mm)), (cx, cy), source
