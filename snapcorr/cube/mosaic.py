"""Snapshot mosaic frames to cubes, keeping each band's true sensor position."""

from __future__ import annotations

import numpy as np

from .._validation import check_integers, renamed_keywords
from .model import make_cube, with_positions
from .sensor import Sensor

__all__ = ["frame_area", "frame_saturation", "mosaic_to_cube", "sensor_positions"]


@renamed_keywords(origin_px="sensor_origin_px")
def mosaic_to_cube(raw, sensor: Sensor, *, sensor_origin_px=None, attrs=None):
    """Extract the bands of a raw mosaic frame into a ``(y, x, band)`` cube.

    The frame is first cut to the sensor's filter area (``filter_area_px``, e.g. a vendor
    file's active area), then to whole tiles from the first pixel it keeps. Cube pixel
    ``(y, x)`` is the tile-sized window whose corner is that pixel plus ``(y, x)`` tiles; the
    window holds every band once, at the place the tile grid puts it, so a frame may start
    anywhere, on or off the grid (the band layout follows the offset modulo the tile). Rows
    and columns that do not fill a whole tile at the far edges are left out. The cube records
    every band's sensor row and column (``sensor_row(y, band)``, ``sensor_col(x, band)``) and
    the sensor area it covers (attribute ``mosaic_area_px``: row, column, rows, columns), so
    the chief-ray angle of each band can be computed exactly.

    Parameters
    ----------
    raw : array_like, shape (rows, cols)
        Raw frame (numpy or dask), at least one tile.
    sensor : Sensor
        A ``layout = "mosaic"`` sensor.
    sensor_origin_px : (int, int), optional
        Sensor row and column of the frame's first pixel (a crop or a camera's region of
        interest). Default: the frame is the whole sensor, and must have the sensor's
        ``size_px`` when the sensor gives it.
    attrs : dict, optional
        Extra attributes of the cube, merged over ``sensor`` (the sensor's name).

    Returns
    -------
    xarray.DataArray
        ``(y, x, band)`` with ``wavelength``, ``fwhm``, ``sensor_row`` and ``sensor_col``.

    Raises
    ------
    ValueError
        Not a mosaic sensor, not a 2-D frame, a frame of another size than the sensor's
        without ``sensor_origin_px``, or no whole tile inside the filter area.
    """
    if sensor.layout != "mosaic":
        raise ValueError(f"sensor {sensor.name!r} is not a mosaic (layout {sensor.layout!r})")
    if not hasattr(raw, "ndim"):
        raw = np.asarray(raw)
    if raw.ndim != 2:
        hint = (" (a cube is already split into bands: give its raw 2-D frame)"
                if raw.ndim == 3 else "")
        raise ValueError(f"a raw mosaic frame is 2-D, got shape {raw.shape}{hint}")
    r0, c0 = _origin(raw.shape, sensor, sensor_origin_px)
    tr, tc = sensor.mosaic_shape
    (lo_r, lo_c), (ny, nx) = _whole_tiles(raw.shape, sensor, r0, c0)
    sub = raw[lo_r - r0:lo_r - r0 + ny * tr, lo_c - c0:lo_c - c0 + nx * tc]
    if not isinstance(sub, np.ndarray):  # blocks of whole tiles, for the reshape below
        rows = max(tr, sub.chunks[0][0] // tr * tr)
        sub = sub.rechunk({0: rows})
    tiles = sub.reshape(ny, tr, nx, tc)
    off = sensor.band_offsets_at((lo_r, lo_c))
    # (ny, tr, nx, tc) -> pick each band's (row, col) in the window.
    bands = [tiles[:, r, :, c] for r, c in off]
    stack = (np.stack if isinstance(raw, np.ndarray) else _dask_stack)(bands, axis=-1)
    cube = make_cube(stack, sensor.cwl_nm, fwhm_nm=sensor.fwhm_nm,
                     attrs={"sensor": sensor.name, **(attrs or {}),
                            "mosaic_area_px": [lo_r, lo_c, ny * tr, nx * tc]})
    rows, cols = sensor_positions(sensor, ny, nx, (lo_r, lo_c))
    return with_positions(cube, rows, cols).assign_coords(sensor.band_coords())


def _origin(shape, sensor, sensor_origin_px):
    """The frame's first pixel on the sensor: given, or (0, 0) for a whole-sensor frame."""
    if sensor_origin_px is not None:
        o = check_integers("sensor_origin_px", sensor_origin_px)
        if o.shape != (2,) or np.any(o < 0):
            raise ValueError("sensor_origin_px must be a sensor row and column (whole numbers "
                             f">= 0), got {sensor_origin_px!r}")
        r0, c0 = int(o[0]), int(o[1])
        if sensor.size_px is not None and (r0 + shape[0] > sensor.size_px[0]
                                           or c0 + shape[1] > sensor.size_px[1]):
            raise ValueError(
                f"a frame of {shape[0]} x {shape[1]} px at sensor row {r0}, column {c0} reaches "
                f"beyond the sensor {sensor.name!r} ({sensor.size_px[0]} x "
                f"{sensor.size_px[1]} px): check sensor_origin_px= (row, col) and the sensor")
        return r0, c0
    if sensor.size_px is not None and tuple(shape) != tuple(sensor.size_px):
        raise ValueError(
            f"the frame is {shape[0]} x {shape[1]} px but the sensor {sensor.name!r} is "
            f"{sensor.size_px[0]} x {sensor.size_px[1]} px: for a crop or a region of interest "
            "give the sensor row and column of its first pixel, sensor_origin_px= (row, col)")
    return 0, 0


@renamed_keywords(origin_px="sensor_origin_px")
def frame_area(shape, sensor, sensor_origin_px=None):
    """Where a frame sits and which part of it carries filters.

    Parameters
    ----------
    shape : (int, int)
        The frame's rows and columns.
    sensor : Sensor
        A mosaic sensor.
    sensor_origin_px : (int, int), optional
        Sensor row and column of the frame's first pixel (default: the frame is the whole
        sensor, of its ``size_px``).

    Returns
    -------
    (r0, c0) : the first sensor pixel kept (inside the filter area)
    (rows, cols) : how many rows and columns are kept
    (y0, x0) : ndarray of int, shape (n_bands,)
        Each band's first sample row and column in the kept part.

    Raises
    ------
    ValueError
        Of another size than the sensor's without ``sensor_origin_px``, or holding less than one
        tile inside the filter area.
    """
    r0, c0 = _origin(shape, sensor, sensor_origin_px)
    (lo_r, lo_c), (hi_r, hi_c) = _filter_part(shape, sensor, r0, c0)
    off = sensor.band_offsets_at((lo_r, lo_c))
    return (lo_r, lo_c), (hi_r - lo_r, hi_c - lo_c), (off[:, 0].copy(), off[:, 1].copy())


def _filter_part(shape, sensor, r0, c0):
    """First and last-plus-one sensor row and column of a frame at ``(r0, c0)`` that lie in
    the sensor's filter area; refused unless they hold a whole tile."""
    tr, tc = sensor.mosaic_shape
    lo_r, lo_c, hi_r, hi_c = r0, c0, r0 + shape[0], c0 + shape[1]
    if sensor.filter_area_px is not None:
        ar, ac, an, am = sensor.filter_area_px
        lo_r, lo_c = max(lo_r, ar), max(lo_c, ac)
        hi_r, hi_c = min(hi_r, ar + an), min(hi_c, ac + am)
    if hi_r - lo_r < tr or hi_c - lo_c < tc:
        where = ("" if sensor.filter_area_px is None else
                 f" inside the filter area (rows {sensor.filter_area_px[0]}-"
                 f"{sensor.filter_area_px[0] + sensor.filter_area_px[2] - 1}, columns "
                 f"{sensor.filter_area_px[1]}-"
                 f"{sensor.filter_area_px[1] + sensor.filter_area_px[3] - 1})")
        raise ValueError(f"the frame ({shape[0]} x {shape[1]} px at sensor row {r0}, column "
                         f"{c0}) holds no whole {tr} x {tc} tile{where}")
    return (lo_r, lo_c), (hi_r, hi_c)


def _whole_tiles(shape, sensor, r0, c0):
    """First sensor pixel kept and the number of whole tiles (rows, columns) of a frame at
    ``(r0, c0)``, inside the sensor's filter area."""
    (lo_r, lo_c), (hi_r, hi_c) = _filter_part(shape, sensor, r0, c0)
    tr, tc = sensor.mosaic_shape
    return (lo_r, lo_c), ((hi_r - lo_r) // tr, (hi_c - lo_c) // tc)


def _dask_stack(arrays, axis):
    import dask.array as da

    return da.stack(arrays, axis=axis)


@renamed_keywords(origin_px="sensor_origin_px")
def sensor_positions(sensor: Sensor, ny, nx, sensor_origin_px=(0, 0)):
    """Sensor row ``(ny, band)`` and column ``(nx, band)`` of every cube pixel and band.

    Parameters
    ----------
    sensor : Sensor
        Its layout; for a mosaic also its tile shape and ``band_offset``.
    ny, nx : int
        Cube rows and columns (tiles, for a mosaic).
    sensor_origin_px : (int, int)
        Sensor row and column of the cube's first pixel (for a mosaic, the corner of its first
        tile-sized window, on or off the tile grid: :meth:`Sensor.band_offsets_at`).

    Returns
    -------
    rows : ndarray of int, shape (ny, n_bands)
    cols : ndarray of int, shape (nx, n_bands)
        Sensor pixel indices; every band the same for a Snapscan-like layout, each at its own
        offset in the tile for a mosaic.
    """
    r0, c0 = sensor_origin_px
    if sensor.layout == "mosaic":
        tr, tc = sensor.mosaic_shape
        off = sensor.band_offsets_at((r0, c0))
        rows = r0 + np.arange(ny)[:, None] * tr + off[None, :, 0]
        cols = c0 + np.arange(nx)[:, None] * tc + off[None, :, 1]
    else:
        rows = np.repeat((r0 + np.arange(ny))[:, None], sensor.n_bands, axis=1)
        cols = np.repeat((c0 + np.arange(nx))[:, None], sensor.n_bands, axis=1)
    size = sensor.size_px
    if r0 < 0 or c0 < 0 or (size is not None and (rows.max() >= size[0]
                                                  or cols.max() >= size[1])):
        reach = f"{int(rows.max()) + 1} x {int(cols.max()) + 1} px"
        raise ValueError(f"a cube of {ny} x {nx} {'tiles' if sensor.layout == 'mosaic' else 'px'} "
                         f"at sensor row {r0}, column {c0} reaches beyond the sensor "
                         f"{sensor.name!r} ({size[0]} x {size[1]} px; it would need {reach}): "
                         "check sensor_origin_px= (row, col) and the sensor"
                         if size is not None else
                         f"sensor_origin_px ({r0}, {c0}) must be >= 0")
    return rows, cols


def frame_saturation(sensor, whites, saturation=None, *, what="the white"):
    """The digital number at or above which a raw pixel is saturated.

    ``saturation`` where given; else the sensor's largest code (``2**bit_depth - 1``, a
    vendor file's bit depth), refused where a white holds larger values (frames scaled to
    other units, or a camera mode of another depth: a wrong level would mask every bright
    pixel, or none); else, for whites all stored as one integer type, that type's largest
    code (65535 for uint16: a pixel there was clipped by the file if not by the sensor).

    Parameters
    ----------
    sensor : Sensor or None
    whites : sequence of array_like
        The white frames (or cubes) as read, numpy or dask.
    saturation : float, optional
        The level given by the user.
    what : str
        What the whites are, for the message.

    Returns
    -------
    float or None
    """
    if saturation is not None:
        return saturation
    if sensor is None or sensor.full_scale_dn is None:
        types = {np.dtype(getattr(w, "dtype", np.asarray(w).dtype)) for w in whites}
        if len(types) == 1 and np.issubdtype(next(iter(types)), np.integer):
            return float(np.iinfo(next(iter(types))).max)
        return None  # floats, or whites of several types: no one code is the largest
    full = sensor.full_scale_dn
    for w in whites:
        values = np.asarray(getattr(w, "data", w))
        values = values[np.isfinite(values)]
        top = float(values.max()) if values.size else 0.0
        if top > full:
            raise ValueError(
                f"{what} holds values up to {top:g}, above the largest {sensor.bit_depth}-bit "
                f"code ({full}) of the sensor {sensor.name!r}: the frames are in other units "
                "(scaled, or another camera mode); give the saturation level in DN "
                "(saturation=) or bit_depth in a sensor TOML")
    return float(full)
