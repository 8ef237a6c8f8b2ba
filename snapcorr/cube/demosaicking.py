"""Full-resolution cubes from snapshot-mosaic frames: every band at every pixel.

A mosaic frame holds one band per pixel; :func:`mosaic_to_cube` gives one spectrum per tile.
:func:`demosaic` estimates every band at every pixel, by a method of
:data:`DEMOSAIC_METHODS` (:mod:`snapcorr.cube.msfa`, one module per published method):

=============  ====================================================================  ========
method         what                                                                  source
=============  ====================================================================  ========
``nearest``    tile replication: each band's value of the tile holding the pixel    --
``bilinear``   weighted bilinear: each band from its own samples (WB)               [1]_
``ppid``       each band's difference from the pseudo-panchromatic image (PPI)      [2]_
``ri``         residual interpolation: a local linear model of each band against    [3]_ [4]_
               the PPI, its residuals interpolated (the default, the most accurate)
=============  ====================================================================  ========

The band layout is the sensor's (its tile, band offsets and filter area), wherever the frame
starts; the frame is cut to the filter area. Every method keeps each measured value where it
was measured; a missing (NaN) value is left out of every estimate and stays NaN in its own
band (the ``mask``), and at the frame's edges the samples that exist are used. The cube
records each pixel's sensor position (the same for every band), so :func:`correct_cube`
computes every pixel's own chief-ray angle.

References
----------
.. [1] J. Brauers, T. Aach, "A color filter array based multispectral camera", 12. Workshop
   Farbbildverarbeitung, Ilmenau (2006).
.. [2] S. Mihoubi, O. Losson, B. Mathon, L. Macaire, "Multispectral demosaicing using
   pseudo-panchromatic image", IEEE Trans. Comput. Imaging 3, 982-995 (2017).
.. [3] D. Kiku, Y. Monno, M. Tanaka, M. Okutomi, "Residual interpolation for color image
   demosaicking", Proc. IEEE ICIP, 2304-2308 (2013).
.. [4] Y. Monno, D. Kiku, M. Tanaka, M. Okutomi, "Adaptive residual interpolation for color
   and multispectral image demosaicking", Sensors 17, 2787 (2017).
"""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from .._validation import renamed_keywords, validate_method
from ..files.datasets import COMPUTED_WITH
from .model import check_dtype, make_cube, with_positions
from .mosaic import frame_area
from .sensor import Sensor

__all__ = ["DEMOSAIC_METHODS", "DEMOSAIC_REACH_TILES", "demosaic", "demosaic_array",
           "demosaicking_error"]

def _method(name):
    """The kernel ``snapcorr.cube.msfa.<name>``, imported at its first call (numba loads then,
    not with ``snapcorr.cube``)."""
    def run(frame, y0, x0, n, m, **options):
        from . import msfa

        return getattr(msfa, name)(frame, y0, x0, n, m, **options)

    run.__name__ = run.__qualname__ = name
    run.__doc__ = f"snapcorr.cube.msfa.{name}, imported at its first call."
    return run


#: The methods by name: ``f(frame, y0, x0, n, m, *, fill_missing=False) -> (rows, cols,
#: bands)``.
DEMOSAIC_METHODS = {
    "nearest": _method("tile_replication"),
    "bilinear": _method("weighted_bilinear"),
    "ppid": _method("ppid"),
    "ri": _method("residual_interpolation"),
}
#: How far (in tiles) a pixel's estimate reaches into the frame, by method: the halo a block
#: of a chunked frame needs from its neighbours for the same result as the whole frame. Two
#: tiles for a sample and the next one where it is missing; five for the pseudo-panchromatic
#: image (its average, widened over a hole, and the sharpening a tile away); and the guided
#: filter's two windows of ``msfa.monno2017.RADIUS`` (1) samples each (a test checks it).
DEMOSAIC_REACH_TILES = {"nearest": 2, "bilinear": 2, "ppid": 7, "ri": 7 + 2 * 1}


def _dtype(dtype):
    """float32 for float32 and integers of up to 16 bits (exact there); float64 otherwise."""
    dtype = np.dtype(dtype)
    exact = dtype == np.float32 or dtype == np.float16 or (dtype.kind in "iu"
                                                           and dtype.itemsize <= 2)
    return np.float32 if exact else np.float64


def demosaic_array(frame, y0, x0, n, m, method="ri", *, fill_missing=False):
    """The numpy core: every band at every pixel of a 2-D frame.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        Real values (counts or flat-fielded); NaN where missing.
    y0, x0 : array_like of int, shape (n_bands,)
        Each band's first sample row and column in the frame (``0 <= y0 < n``).
    n, m : int
        Tile rows and columns.
    method : str
        A name of :data:`DEMOSAIC_METHODS`.
    fill_missing : bool
        Estimate a missing sample's own band from the samples around it, as every other pixel
        is estimated, instead of leaving it NaN (the cross-validation of
        :func:`demosaicking_error` holds samples out so).

    Returns
    -------
    ndarray, shape (rows, cols, n_bands)
        float32 (float64 for a float64 frame or integers wider than 16 bits, which float32
        would round); each band's own samples unchanged, NaN where the frame was NaN or
        infinite (unless ``fill_missing``).

    Raises
    ------
    TypeError
        Not real numbers (complex, boolean, text).
    ValueError
        ``ppid`` or ``ri`` on a tile with positions that hold no band.
    """
    method = validate_method(method, DEMOSAIC_METHODS)
    check_dtype(np.asarray(frame).dtype, "a mosaic frame")
    data = np.ascontiguousarray(frame, _dtype(np.asarray(frame).dtype))
    if np.isinf(data).any():  # an infinity means nothing: missing, as NaN is
        data = np.where(np.isinf(data), np.nan, data)
    y0, x0 = np.asarray(y0, np.int64), np.asarray(x0, np.int64)
    if method in ("ppid", "ri") and y0.size != int(n) * int(m):
        raise ValueError(f"{method} needs every position of the {n} x {m} tile to hold a band "
                         f"(the pseudo-panchromatic image averages them), got {y0.size} bands; "
                         "use bilinear or nearest")
    # every method keeps each band's samples as measured (missing ones missing)
    return DEMOSAIC_METHODS[method](data, y0, x0, int(n), int(m),
                                    fill_missing=bool(fill_missing))


@renamed_keywords(origin_px="sensor_origin_px")
def demosaic(frame, sensor: Sensor, method="ri", *, sensor_origin_px=None, name=None):
    """A full-resolution ``(y, x, band)`` cube from a mosaic frame (module docstring).

    Parameters
    ----------
    frame : array_like, xarray.DataArray or xarray.Dataset, shape (rows, cols)
        A raw or flat-fielded frame (numpy or dask; a DataArray as
        :func:`~snapcorr.cube.read_frame` gives it); or the Dataset
        :func:`~snapcorr.cube.flatfield` gives for a frame, whose result is demosaicked and
        returned as a Dataset with its ``mask`` (where the cube is NaN) and the ``raw`` frame
        cut to the same area.
    sensor : Sensor
        A mosaic sensor (its layout places the bands).
    method : str
        A name of :data:`DEMOSAIC_METHODS` (default ``"ri"``).
    sensor_origin_px : (int, int), optional
        Sensor row and column of the frame's first pixel (default: the frame is the whole
        sensor, of its ``size_px``).
    name : str, optional
        The cube's name (default: ``reflectance`` for a flat-fielded frame, units "1", else
        ``radiance``).

    Returns
    -------
    xarray.DataArray
        ``(y, x, band)`` with ``wavelength``, ``fwhm``, ``sensor_row(y, band)`` and
        ``sensor_col(x, band)`` (every band at the pixel's own position); attrs
        ``demosaic_method`` and ``mosaic_area_px``. Dask-backed for a dask frame (blocks
        with a halo of :data:`DEMOSAIC_REACH_TILES` tiles: the same values as in memory).

    Warns
    -----
    MaskedWarning
        In memory: missing values left NaN beyond their own samples (a hole wider than a few
        tiles), where :func:`numpy.isnan` of the result counts more than the frame's missing
        values.

    Raises
    ------
    ValueError
        Not a mosaic sensor, not a 2-D frame (a cube is already split into bands), smaller
        than a tile, or of another size than the sensor's without ``sensor_origin_px``.
    """
    if isinstance(frame, xr.Dataset):
        return _demosaic_dataset(frame, sensor, method, sensor_origin_px, name)
    if sensor.layout != "mosaic":
        raise ValueError(f"sensor {sensor.name!r} is not a mosaic (layout {sensor.layout!r})")
    method = validate_method(method, DEMOSAIC_METHODS, "demosaic method")
    attrs = dict(frame.attrs) if isinstance(frame, xr.DataArray) else {}
    data = frame.data if isinstance(frame, xr.DataArray) else frame
    if not hasattr(data, "ndim"):
        data = np.asarray(data)
    if isinstance(frame, xr.DataArray) and tuple(frame.dims) not in (("y", "x"),
                                                                     ("frame", "y", "x")):
        raise ValueError(f"demosaic takes a frame of dims (y, x), or a stream (frame, y, x); "
                         f"got dims {tuple(frame.dims)}"
                         + (" (a cube is already split into bands)" if "band" in frame.dims
                            else ""))
    stream = isinstance(frame, xr.DataArray) and data.ndim == 3
    if data.ndim != 2 and not stream:
        raise ValueError(f"demosaic takes a 2-D mosaic frame, got shape {data.shape}"
                         + (" (a cube is already split into bands; a stream of frames is a "
                            "DataArray of dims (frame, y, x))" if data.ndim == 3 else ""))
    check_dtype(data.dtype, "a mosaic frame")
    n, m = sensor.mosaic_shape
    if method in ("ppid", "ri") and sensor.n_bands != n * m:
        raise ValueError(f"{method} needs every position of the {n} x {m} tile to hold a band "
                         f"(the pseudo-panchromatic image averages them); sensor "
                         f"{sensor.name!r} has {sensor.n_bands}: use bilinear or nearest")
    (r0, c0), (rows, cols), (y0, x0) = frame_area(data.shape[-2:], sensor, sensor_origin_px)
    o0 = (0, 0) if sensor_origin_px is None else tuple(int(v) for v in sensor_origin_px)
    data = data[..., r0 - o0[0]:r0 - o0[0] + rows, c0 - o0[1]:c0 - o0[1] + cols]
    if isinstance(data, np.ndarray):
        cube_data = np.empty((*data.shape, y0.size), _dtype(data.dtype))
        for i in np.ndindex(data.shape[:-2]):
            cube_data[i] = demosaic_array(data[i], y0, x0, n, m, method)
            _check_spread(data[i], cube_data[i])
    else:
        cube_data = _lazy(data, y0, x0, n, m, method)
    if name is None:
        name = "reflectance" if str(attrs.get("units", "")).strip() == "1" else "radiance"
    first = cube_data[0] if stream else cube_data
    cube = make_cube(first, sensor.cwl_nm, fwhm_nm=sensor.fwhm_nm, name=name,
                     attrs={"sensor": sensor.name, **attrs, "demosaic_method": method,
                            "mosaic_area_px": [r0, c0, rows, cols]})
    nb = sensor.n_bands
    rows_px = np.repeat((r0 + np.arange(rows))[:, None], nb, axis=1)
    cols_px = np.repeat((c0 + np.arange(cols))[:, None], nb, axis=1)
    cube = with_positions(cube, rows_px, cols_px).assign_coords(sensor.band_coords())
    if stream:  # the same coordinates, each frame a cube, and the frames' own (times, ...)
        along = {c: frame[c] for c in frame.coords if frame[c].dims == ("frame",)}
        cube = xr.DataArray(cube_data, dims=("frame", *cube.dims),
                            coords={**cube.coords, **along}, attrs=cube.attrs, name=cube.name)
    return cube


def _check_spread(frame, cube):
    """Warn where a missing value's NaN reached beyond its own sample."""
    missing = int(np.isnan(frame).sum())
    if missing:
        found = int(np.isnan(cube).sum())
        if found > missing:
            from .flatfield import MaskedWarning

            warnings.warn(f"{missing} missing values in the frame left {found} values NaN in "
                          "the cube: a hole several tiles wide leaves some bands without a "
                          "sample near it", MaskedWarning, stacklevel=3)


def _demosaic_dataset(ds, sensor, method, sensor_origin_px, name):
    """A flat-fielded frame's Dataset demosaicked: the cube, its mask and the raw frame."""
    names = [v for v in ds.data_vars if tuple(ds[v].dims)[-2:] == ("y", "x")
             and ds[v].ndim <= 3 and v not in ("mask", "raw")]
    if len(names) != 1:
        raise ValueError("demosaic takes a frame, or flatfield's Dataset of a frame (one "
                         f"(y, x) variable besides mask and raw); got variables "
                         f"{list(ds.data_vars)}")
    var = names[0]
    frame = ds[var]
    cube = demosaic(frame, sensor, method, sensor_origin_px=sensor_origin_px, name=name or var)
    r0, c0, rows, cols = cube.attrs["mosaic_area_px"]
    o0 = (0, 0) if sensor_origin_px is None else tuple(int(v) for v in sensor_origin_px)
    cut = {"y": slice(r0 - o0[0], r0 - o0[0] + rows), "x": slice(c0 - o0[1], c0 - o0[1] + cols)}
    method = cube.attrs["demosaic_method"]
    out = xr.Dataset(attrs={**ds.attrs, "demosaic_method": method,
                            "mosaic_area_px": [r0, c0, rows, cols]})
    out[cube.name] = cube
    mask = cube.isnull()  # where a missing value left no estimate
    if "mask" in ds:  # and each value masked in the frame, in its own band
        (_, _), (_, _), (y0, x0) = frame_area(frame.shape[-2:], sensor, sensor_origin_px)
        n, m = sensor.mosaic_shape
        table = np.full((n, m), -1, np.int16)
        table[y0, x0] = np.arange(y0.size)
        own = xr.DataArray(table[np.arange(rows)[:, None] % n, np.arange(cols)[None, :] % m],
                           dims=("y", "x"))
        frame_mask = ds["mask"].isel(cut).drop_vars(list(ds["mask"].coords))
        mask = mask | (frame_mask & (own == xr.DataArray(np.arange(y0.size, dtype=np.int16),
                                                         dims="band"))).transpose(*cube.dims)
    # written in the cube's pass (COMPUTED_WITH): the cube is computed once
    mask.attrs = {"units": "1", "long_name": "value not meaningful (masked in the frame, in its "
                  "own band; or no sample of the band near it): the cube is NaN there",
                  COMPUTED_WITH: cube.name}
    out["mask"] = mask.drop_vars([c for c in mask.coords if c not in cube.coords])
    if "raw" in ds:
        out["raw"] = ds["raw"].isel(cut)  # the same pixels as the cube's
    out["n_masked"] = mask.sum().assign_attrs(long_name="number of masked values", units="1",
                                              **{COMPUTED_WITH: cube.name})
    return out


def _tile_chunks(chunks, tile, size):
    """Chunks near the given ones, each a whole number of tiles (so every block sees the same
    tile grid as the whole frame, to the last bit) and at least ``size`` (so it can lend a
    full halo); the last takes the remainder."""
    total, prev, out = sum(chunks), 0, []
    for b in np.cumsum(chunks)[:-1].tolist():
        b = round(b / tile) * tile
        if b - prev >= size and total - b >= size:
            out.append(b - prev)
            prev = b
    return (*out, total - prev)


def _lazy(data, y0, x0, n, m, method):
    """Block by block with a halo of the method's reach (the frame's edges stay edges)."""
    import dask.array as da

    reach = DEMOSAIC_REACH_TILES[method]
    ay, ax = data.ndim - 2, data.ndim - 1  # after any leading (frame) axes
    depth = {a: 0 for a in range(ay)} | {ay: reach * n, ax: reach * m}
    dtype = _dtype(data.dtype)
    data = data.astype(dtype)
    data = data.rechunk({ay: _tile_chunks(data.chunks[ay], n, depth[ay]),
                         ax: _tile_chunks(data.chunks[ax], m, depth[ax])})
    for a in (ay, ax):  # an axis in one block needs no halo (and a small frame has none)
        if len(data.chunks[a]) == 1:
            depth[a] = 0
    starts = [np.cumsum((0, *c)) for c in data.chunks[-2:]]
    last = [len(c) - 1 for c in data.chunks[-2:]]
    # no padding beyond the frame: its edges are handled as in memory
    padded = da.overlap.overlap(data, depth=depth, boundary="none")

    def block(a, block_info=None):
        i, j = block_info[0]["chunk-location"][-2:]
        top, left = (depth[ay] if i else 0), (depth[ax] if j else 0)
        bottom, right = (depth[ay] if i < last[0] else 0), (depth[ax] if j < last[1] else 0)
        ys, xs = starts[0][i] - top, starts[1][j] - left  # the padded block's corner
        rows, cols = a.shape[-2] - top - bottom, a.shape[-1] - left - right
        out = np.empty((*a.shape[:-2], rows, cols, y0.size), dtype)
        for k in np.ndindex(a.shape[:-2]):
            cube = demosaic_array(a[k], (y0 - ys) % n, (x0 - xs) % m, n, m, method)
            out[k] = cube[top:top + rows, left:left + cols]
        return out

    return da.map_blocks(block, padded, new_axis=data.ndim,
                         chunks=(*data.chunks, (y0.size,)), dtype=dtype)


#: Cross-validation of a demosaicked cube (:func:`demosaicking_error`), in passes
#: ``r < HOLDOUT_PERIOD``: band ``b``'s samples (sub-grid ``(i, j)``) are held out where
#: ``(I + 2 J + b + r) % HOLDOUT_PERIOD == 0``, with ``(I, J) = (i, j)`` (single samples, each
#: a tile from the nearest one left) or ``(i // 3, j // 3)`` (3 x 3 blocks, whose centre is two
#: tiles from it). A tile loses about one band in five either way.
HOLDOUT_PERIOD = 5
#: At most this many patches are cross-validated, spread over the cube, each
#: ``ERROR_PATCH_TILES`` tiles a side inside a halo of the method's reach.
ERROR_PATCHES = 6
ERROR_PATCH_TILES = 24


def _patches(size, inner, halo, count):
    """Up to ``count`` windows ``(start, stop, lo, hi)`` along an axis of ``size``: the
    window read, and inside it the part held out (a halo of the method's reach from any
    side that is not the cube's own edge). One window for a short axis."""
    if size <= inner + 2 * halo or count == 1:
        return [(0, size, 0, size)]
    out = []
    for c in np.linspace(halo + inner / 2, size - halo - inner / 2, count):
        lo = round(float(c) - inner / 2)
        out.append((lo - halo, lo + inner + halo, halo, halo + inner))
    return out


def _held_out(values, y0, x0, n, m, method, area):
    """Squared errors of the held-out samples of one patch, by band: ``(sum, count)`` for
    single samples and for the centres of 3 x 3 blocks (:data:`HOLDOUT_PERIOD`)."""
    nb = y0.size
    own = np.full(values.shape[:2], -1)
    for b in range(nb):
        own[y0[b]::n, x0[b]::m] = b
    yy, xx = np.indices(own.shape)
    i, j = (yy - y0[own]) // n, (xx - x0[own]) // m  # each pixel's place on its sub-grid
    raw = np.take_along_axis(values, own[..., None], axis=2)[..., 0]
    keep = area & np.isfinite(raw)
    out = np.zeros((2, 2, nb))
    for k, (bi, bj, centre) in enumerate(((i, j, keep), (i // 3, j // 3,
                                                          keep & (i % 3 == 1) & (j % 3 == 1)))):
        for r in range(HOLDOUT_PERIOD):
            hole = (bi + 2 * bj + own + r) % HOLDOUT_PERIOD == 0
            held = hole & centre
            est = demosaic_array(np.where(hole, np.nan, raw), y0, x0, n, m, method,
                                 fill_missing=True)
            d = est[held, own[held]].astype(float) - raw[held]
            ok = np.isfinite(d)
            np.add.at(out[k, 0], own[held][ok], d[ok] ** 2)
            np.add.at(out[k, 1], own[held][ok], 1)
    return out


def _distance_factor(n, m, exponent):
    """Mean over a tile's pixels other than a band's own of ``(d / s)^exponent``: ``d`` the
    distance to the band's nearest sample, ``s = sqrt(n m)`` a held-out sample's."""
    dy, dx = np.meshgrid(np.minimum(np.arange(n), n - np.arange(n)),
                         np.minimum(np.arange(m), m - np.arange(m)), indexing="ij")
    d = np.hypot(dy, dx).ravel()[1:] / np.sqrt(n * m)
    return float(np.mean(d**exponent))


def demosaicking_error(cube, sensor, *, noise_var=0.0):
    """Each band's mean square demosaicking error over a demosaicked cube, measured on the
    cube itself by cross-validation at the band's own samples.

    A demosaicked cube keeps every band's measured samples, so the raw mosaic is in it. Each
    band's samples are held out in turn (:data:`HOLDOUT_PERIOD`) and filled in by the cube's
    own method from the samples left (``demosaic_array(..., fill_missing=True)``); the
    squared differences from the held-out values, less the held-out sample's own noise, are
    the error of estimating the band a tile from its nearest sample (leave-out
    cross-validation, Stone 1974 [5]_). A pixel the cube estimated is nearer one: its error is
    scaled by the mean of ``(d / tile)^beta`` over the tile's pixels, ``d`` its distance to
    the band's nearest sample, with ``beta`` the growth of the error with distance measured
    on the cube by holding out 3 x 3 blocks of samples as well (their centres two tiles from
    the nearest sample): ``beta = log2(mse(2 tiles) / mse(1 tile))``, within [0, 2] (0: an
    error that does not shrink near a sample; 2: a smooth field's). The interpolation error
    of a field whose increments grow as a power of the distance grows with the same power (a
    power-law variogram; natural images' power spectra are power laws, Field 1987 [6]_). Each
    band is measured at one pixel in ``n_bands``, where its error is its noise.

    Parameters
    ----------
    cube : xarray.DataArray
        ``(y, x, band)`` from :func:`demosaic` (its ``demosaic_method`` and
        ``mosaic_area_px``), numpy or dask (a few patches are read).
    sensor : Sensor
        The mosaic sensor it was demosaicked for.
    noise_var : float
        The samples' noise variance (the held-out value's own noise is taken off).

    Returns
    -------
    mse : ndarray, shape (n_bands,)
        Each band's mean square error over the cube's pixels (its values' units squared).
    count : int
        How many samples were held out.

    References
    ----------
    .. [5] M. Stone, "Cross-validatory choice and assessment of statistical predictions",
       J. R. Stat. Soc. B 36, 111-147 (1974).
    .. [6] D. J. Field, "Relations between the statistics of natural images and the response
       properties of cortical cells", J. Opt. Soc. Am. A 4, 2379-2394 (1987).
    """
    method = cube.attrs.get("demosaic_method")
    if method not in DEMOSAIC_METHODS or "mosaic_area_px" not in cube.attrs:
        raise ValueError("demosaicking_error takes a cube made by demosaic (its "
                         "demosaic_method and mosaic_area_px attributes)")
    n, m = sensor.mosaic_shape
    r0, c0 = (int(v) for v in cube.attrs["mosaic_area_px"][:2])
    off = sensor.band_offsets_at((r0, c0))
    ny, nx = cube.sizes["y"], cube.sizes["x"]
    reach = DEMOSAIC_REACH_TILES[method]
    total = 0.0
    for ys, ye, ylo, yhi in _patches(ny, ERROR_PATCH_TILES * n, reach * n, 2):
        for xs, xe, xlo, xhi in _patches(nx, ERROR_PATCH_TILES * m, reach * m,
                                         ERROR_PATCHES // 2):
            values = np.asarray(cube.isel(y=slice(ys, ye), x=slice(xs, xe)).values, float)
            area = np.zeros(values.shape[:2], bool)
            area[ylo:yhi, xlo:xhi] = True
            total = total + _held_out(values, (off[:, 0] - ys) % n, (off[:, 1] - xs) % m, n,
                                      m, method, area)
    if np.any(total[:, 1] == 0):
        raise ValueError("too small a cube to cross-validate its demosaicking: every band "
                         "needs samples, and 3 x 3 blocks of them, away from its edges")
    near, far = np.clip(total[:, 0] / total[:, 1] - float(noise_var), 1e-30, None)
    beta = float(np.clip(np.log2(far.sum() / near.sum()), 0.0, 2.0))
    nb = off.shape[0]
    mse = _distance_factor(n, m, beta) * near
    return (1.0 - 1.0 / nb) * mse + float(noise_var) / nb, int(total[:, 1].sum())
