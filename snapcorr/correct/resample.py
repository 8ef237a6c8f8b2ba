"""Each pixel's spectrum, sampled at its corrected wavelengths, back onto the nominal grid.

Band ``b`` of pixel ``(y, x)`` sits at ``cwl_b * s(y, x, b)`` with ``s = 1 + mean_shift / cwl``
(Goossens et al. 2019, Eq. 23). Linear interpolation in wavelength brings the spectrum back to
the nominal wavelengths; a nominal wavelength outside the pixel's corrected range would need
extrapolation and is NaN instead (reported, not invented).

The work is one pass over the cube, compiled with Numba and parallel over rows: the corrected
wavelengths are formed on the fly from the small scale array instead of being stored, so the
run costs little more than copying the cube (``benchmarks/``).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import xarray as xr

from ..cube.flatfield import cf_attrs
from ._spectra import sort_samples, spectra_pass

__all__ = ["resample_cube", "resample_to_nominal", "sort_samples"]


@numba.njit(parallel=True, fastmath=True, boundscheck=False, cache=True)
def _resample_uniform(data, scale, c, out):  # pragma: no cover - compiled
    # Evenly spaced nominal wavelengths cwl_k = dl (c + k) and one scale s per pixel: the
    # nominal wavelength k sits at fractional band u = k / s + c (1 / s - 1), no search.
    ny, nx, nb = data.shape
    nan = np.float32(np.nan)
    for y in numba.prange(ny):
        for x in range(nx):
            inv = np.float32(1.0 / scale[y, x, 0])
            a = (inv - np.float32(1.0)) * c
            d = data[y, x]
            o = out[y, x]
            klo = max(0, int(math.ceil(-a / inv)))  # noqa: RUF046 (numba)
            khi = min(nb - 1, int(math.floor((np.float32(nb - 1) - a) / inv)))  # noqa: RUF046
            for k in range(klo):
                o[k] = nan
            for k in range(klo, khi + 1):
                u = np.float32(k) * inv + a
                j = min(max(int(u), 0), nb - 2)
                w = u - np.float32(j)
                o[k] = d[j] + w * (d[j + 1] - d[j])
            for k in range(khi + 1, nb):
                o[k] = nan


def resample_to_nominal(data, scale, column, cwl_nm, out=None):
    """Interpolate spectra from their corrected wavelengths onto the nominal ones.

    Parameters
    ----------
    data : ndarray, shape (ny, nx, nb)
        The cube's values, bands sorted by increasing nominal wavelength.
    scale : ndarray, shape (ny, nx, m)
        ``corrected / nominal`` wavelength; band ``b`` uses column ``column[b]``.
    column : ndarray of int, shape (nb,)
    cwl_nm : ndarray, shape (nb,)
        Nominal wavelengths, increasing.
    out : ndarray, optional
        Where to write (same shape as ``data``, float32 or float64).

    Returns
    -------
    ndarray
        NaN where a nominal wavelength lies outside the pixel's corrected range. Corrected
        wavelengths that cross (measured filters a few nm apart shifting differently) are
        taken in increasing order (:func:`sort_samples`).

    Examples
    --------
    >>> data = np.array([[[0.0, 10.0, 20.0]]])
    >>> resample_to_nominal(data, np.full((1, 1, 1), 0.99), np.zeros(3, int),
    ...                     np.array([500.0, 600.0, 700.0]))[0, 0].round(3)
    array([ 0.505, 10.606,    nan])
    """
    data = np.asarray(data)
    cwl = np.asarray(cwl_nm, float)
    if data.ndim != 3 or data.shape[2] != cwl.size:
        raise ValueError(f"data must be (ny, nx, {cwl.size}), got {data.shape}")
    if cwl.size < 2 or not np.all(np.diff(cwl) > 0):
        raise ValueError("nominal wavelengths must be at least two and increasing")
    if out is None:
        out = np.empty(data.shape, np.float32 if data.dtype == np.float32 else np.float64)
    scale = np.ascontiguousarray(scale, dtype=np.float64)
    column = np.ascontiguousarray(column, dtype=np.int64)
    if scale.shape[:2] != data.shape[:2] or column.shape != (cwl.size,) or (
            column.size and (column.min() < 0 or column.max() >= scale.shape[2])):
        raise ValueError("scale must be (ny, nx, m) with column indices into its last axis")
    step = np.diff(cwl)
    uniform = (scale.shape[2] == 1 and data.dtype == np.float32 and out.dtype == np.float32
               and np.all(np.abs(step - step.mean()) <= 1e-6 * step.mean()))
    if uniform:
        _resample_uniform(data, scale, np.float32(cwl[0] / step.mean()), out)
    else:  # the pass harmonising shares, with no widening (a zero-stride view, not a cube)
        spectra_pass(data, scale, column, cwl, np.broadcast_to(np.float64(0.0), data.shape),
                     out, False)
    return out


def resample_cube(cube, scale, column, cwl_nm):
    """A cube's spectra on the nominal wavelengths (:func:`resample_to_nominal` block by block).

    Parameters
    ----------
    cube : xarray.DataArray
        (y, x, band), numpy- or dask-backed.
    scale : ndarray, shape (ny, nx, m)
        ``wavelength_scale`` of a correction (:func:`~snapcorr.correct.correct_cube`).
    column : ndarray of int, shape (nb,)
        ``scale_index``.
    cwl_nm : ndarray, shape (nb,)
        Nominal wavelengths, in the cube's band order (any order).

    Returns
    -------
    xarray.DataArray
        ``resampled`` (y, x, band), lazily for a dask cube; NaN where a nominal wavelength lies
        outside the pixel's corrected range.
    """
    cwl = np.asarray(cwl_nm, float)
    order = np.argsort(cwl, kind="stable")
    inverse = np.argsort(order, kind="stable")
    dtype = _output_dtype(cube)

    in_order = np.array_equal(order, np.arange(order.size))

    def block(data, sc):
        data = np.asarray(data, dtype)
        if in_order:  # the usual case: no reordering copies of the cube
            return resample_to_nominal(data, sc, column, cwl)
        out = resample_to_nominal(data[..., order], sc, column[order], cwl[order])
        return out[..., inverse]

    sc = xr.DataArray(scale, dims=("y", "x", "m"))
    if cube.chunks is not None:
        # a spectrum is resampled whole: one chunk along band (chunks stay bounded in y, x)
        cube = cube.chunk({"band": -1})
        sc = sc.chunk({"y": cube.chunks[0], "x": cube.chunks[1], "m": -1})
    out = xr.apply_ufunc(block, cube, sc, input_core_dims=[["band"], ["m"]],
                         output_core_dims=[["band"]], dask="parallelized",
                         output_dtypes=[dtype])
    out = out.transpose("y", "x", "band")
    name = cube.name or "radiance"
    attrs = {**cf_attrs(name), **cube.attrs}
    out.attrs = {**_units_of(cube),
                 "long_name": f"{attrs.get('long_name', name)} on the nominal wavelengths",
                 "source": f"{name} interpolated linearly from wavelength_corrected onto "
                           "wavelength",
                 "note": "NaN where the nominal wavelength lies outside the pixel's corrected "
                         "range (extrapolation is not done)"}
    return out


def _output_dtype(cube):
    """Float32 for float32 and small-integer cubes, else float64."""
    return np.float32 if cube.dtype in (np.float32, np.float16, np.uint8, np.int8, np.uint16,
                                        np.int16) else np.float64


def _units_of(cube):
    """``{"units": ...}`` of a spectrum computed from ``cube``: the cube's own (or what its
    name says, :func:`~snapcorr.cube.flatfield.cf_attrs`), none when nothing says ("1" is for
    ratios only)."""
    units = {**cf_attrs(cube.name or "radiance"), **cube.attrs}.get("units")
    return {} if units is None else {"units": units}
