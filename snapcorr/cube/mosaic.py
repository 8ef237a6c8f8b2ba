"""Snapshot mosaic frames to cubes, keeping each band's true sensor position."""

from __future__ import annotations

import numpy as np

from .model import make_cube, with_positions
from .sensor import Sensor

__all__ = ["mosaic_to_cube", "sensor_positions"]


def mosaic_to_cube(raw, sensor: Sensor, *, origin_px=(0, 0), attrs=None):
    """Extract the bands of a raw mosaic frame into a ``(y, x, band)`` cube.

    Cube pixel ``(y, x)`` is tile ``(y, x)``; band ``b`` comes from raw pixel
    ``(y * rows + row_b, x * cols + col_b)`` (``band_offset``). The cube records every band's
    sensor row and column (``sensor_row(y, band)``, ``sensor_col(x, band)``, in pixels of the
    full sensor, ``origin_px`` being the raw frame's top-left corner on the sensor), so the
    chief-ray angle of each band can be computed exactly.

    Parameters
    ----------
    raw : array_like, shape (rows, cols)
        Raw frame (numpy or dask); its size must be a whole number of tiles.
    sensor : Sensor
        A ``layout = "mosaic"`` sensor.
    origin_px : (int, int)
        Row and column of the frame's first pixel on the sensor (for crops); on a tile
        boundary.
    attrs : dict, optional
        Extra attributes of the cube, merged over ``sensor`` (the sensor's name).

    Returns
    -------
    xarray.DataArray
        ``(y, x, band)`` with ``wavelength``, ``fwhm``, ``sensor_row`` and ``sensor_col``.
    """
    if sensor.layout != "mosaic":
        raise ValueError(f"sensor {sensor.name!r} is not a mosaic (layout {sensor.layout!r})")
    if not hasattr(raw, "ndim"):
        raw = np.asarray(raw)
    if raw.ndim != 2:
        raise ValueError(f"a raw mosaic frame is 2-D, got shape {raw.shape}")
    tr, tc = sensor.mosaic_shape
    if raw.shape[0] % tr or raw.shape[1] % tc:
        raise ValueError(
            f"the frame ({raw.shape[0]} x {raw.shape[1]}) is not a whole number of "
            f"{tr} x {tc} tiles; crop it, e.g. raw[:{raw.shape[0] - raw.shape[0] % tr}, "
            f":{raw.shape[1] - raw.shape[1] % tc}]"
        )
    if origin_px[0] % tr or origin_px[1] % tc:
        raise ValueError(
            f"the origin {tuple(origin_px)} (origin_px, --sensor-origin-px) is not on a "
            f"{tr} x {tc} tile boundary, so the bands' tile offsets would be misread; crop the "
            "frame to start at a tile (both numbers multiples of the tile's size)"
        )
    ny, nx = raw.shape[0] // tr, raw.shape[1] // tc
    tiles = raw.reshape(ny, tr, nx, tc)
    off = np.asarray(sensor.band_offset)
    # (ny, tr, nx, tc) -> (ny, nx, tr, tc) -> pick each band's (row, col) in the tile.
    bands = [tiles[:, r, :, c] for r, c in off]
    stack = (np.stack if isinstance(raw, np.ndarray) else _dask_stack)(bands, axis=-1)
    cube = make_cube(stack, sensor.cwl_nm, fwhm_nm=sensor.fwhm_nm,
                     attrs={"sensor": sensor.name, **(attrs or {})})
    rows, cols = sensor_positions(sensor, ny, nx, origin_px)
    return with_positions(cube, rows, cols)


def _dask_stack(arrays, axis):
    import dask.array as da

    return da.stack(arrays, axis=axis)


def sensor_positions(sensor: Sensor, ny, nx, origin_px=(0, 0)):
    """Sensor row ``(ny, band)`` and column ``(nx, band)`` of every cube pixel and band.

    Parameters
    ----------
    sensor : Sensor
        Its layout; for a mosaic also its tile shape and ``band_offset``.
    ny, nx : int
        Cube rows and columns (tiles, for a mosaic).
    origin_px : (int, int)
        Sensor row and column of the cube's first pixel (for a mosaic, the top-left pixel of
        its first tile).

    Returns
    -------
    rows : ndarray of int, shape (ny, n_bands)
    cols : ndarray of int, shape (nx, n_bands)
        Sensor pixel indices; every band the same for a Snapscan-like layout, each at its own
        offset in the tile for a mosaic.
    """
    r0, c0 = origin_px
    if sensor.layout == "mosaic":
        tr, tc = sensor.mosaic_shape
        off = np.asarray(sensor.band_offset)
        rows = r0 + np.arange(ny)[:, None] * tr + off[None, :, 0]
        cols = c0 + np.arange(nx)[:, None] * tc + off[None, :, 1]
        return rows, cols
    rows = np.repeat((r0 + np.arange(ny))[:, None], sensor.n_bands, axis=1)
    cols = np.repeat((c0 + np.arange(nx))[:, None], sensor.n_bands, axis=1)
    return rows, cols
