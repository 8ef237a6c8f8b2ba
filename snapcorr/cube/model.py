"""The cube: an ``xarray.DataArray`` with dims ``(y, x, band)`` and wavelengths in nm.

A cube carries ``wavelength(band)`` in nm (attrs ``units = "nm"``), ``fwhm(band)`` where known,
and, where it came from a sensor, the sensor position of every pixel and band:
``sensor_row(y, band)`` and ``sensor_col(x, band)`` in pixels (for a Snapscan-like layout all
bands of a pixel share one position; in a mosaic each band sits at its own offset in the tile).
Works the same backed by numpy or dask.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

__all__ = ["DIMS", "check_cube", "make_cube"]

DIMS = ("y", "x", "band")


def make_cube(data, wavelength_nm, *, fwhm_nm=None, attrs=None, name="radiance"):
    """Wrap a ``(y, x, band)`` array (numpy or dask) as a cube.

    Parameters
    ----------
    data : array_like, shape (y, x, band)
    wavelength_nm : array_like, shape (band,)
        Nominal central wavelength of each band, nm (finite, > 0).
    fwhm_nm : array_like, optional
        Band widths, nm, a scalar or one per band.
    attrs : dict, optional
        Acquisition metadata (f-number, exposure, sensor name, ...).

    Returns
    -------
    xarray.DataArray
    """
    if not hasattr(data, "ndim"):
        data = np.asarray(data)
    if data.ndim != 3:
        raise ValueError(f"a cube needs 3 dimensions (y, x, band), got shape {data.shape}")
    wl = np.asarray(wavelength_nm, dtype=float)
    if wl.shape != (data.shape[2],):
        raise ValueError(f"the cube has {data.shape[2]} bands but {wl.size} wavelengths")
    if not (np.all(np.isfinite(wl)) and np.all(wl > 0)):
        raise ValueError("wavelengths must be finite and > 0 (nm)")
    coords = {"wavelength": ("band", wl, {"units": "nm", "long_name": "nominal wavelength"})}
    if fwhm_nm is not None:
        fw = np.broadcast_to(np.asarray(fwhm_nm, dtype=float), wl.shape).copy()
        if not (np.all(np.isfinite(fw)) and np.all(fw > 0)):
            raise ValueError("fwhm must be finite and > 0 (nm)")
        coords["fwhm"] = ("band", fw, {"units": "nm"})
    return xr.DataArray(data, dims=DIMS, coords=coords, attrs=dict(attrs or {}), name=name)


def check_cube(cube):
    """Raise ``ValueError`` unless ``cube`` is a DataArray with the cube's dims and wavelengths."""
    if not isinstance(cube, xr.DataArray):
        raise TypeError(f"a cube is an xarray.DataArray, got {type(cube).__name__}")
    if tuple(cube.dims) != DIMS:
        raise ValueError(f"a cube has dims {DIMS}, got {tuple(cube.dims)}; "
                         "use cube.transpose('y', 'x', 'band')")
    if "wavelength" not in cube.coords:
        raise ValueError("a cube needs a wavelength(band) coordinate in nm")
    return cube
