"""The cube: an ``xarray.DataArray`` with dims ``(y, x, band)`` and wavelengths in nm.

A cube carries ``wavelength(band)`` in nm (attrs ``units = "nm"``), ``fwhm(band)`` where known,
and, where it came from a sensor, the sensor position of every pixel and band:
``sensor_row(y, band)`` and ``sensor_col(x, band)`` in pixels (for a Snapscan-like layout all
bands of a pixel share one position; in a mosaic each band sits at its own offset in the tile).
Works the same backed by numpy or dask.

Its values are real numbers (integers or floats): complex, boolean, text and object arrays are
refused, as are cubes with no rows, columns or bands and wavelengths that repeat (two bands at
one wavelength cannot be told apart).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .._validation import check_positive_array, check_wavelengths_nm

__all__ = ["DIMS", "POSITION_ATTRS", "POSITION_DIMS", "check_cube", "check_dtype", "make_cube",
           "with_positions"]

DIMS = ("y", "x", "band")
#: The sensor-position coordinates a cube may carry and their dims.
POSITION_DIMS = {"sensor_row": ("y", "band"), "sensor_col": ("x", "band")}
FWHM_LONG_NAME = "band width (full width at half maximum)"
#: CF attributes of the sensor positions (a pixel index has no physical unit: "1").
POSITION_ATTRS = {
    "sensor_row": {"long_name": "sensor row of the cube pixel, per band", "units": "1"},
    "sensor_col": {"long_name": "sensor column of the cube pixel, per band", "units": "1"},
}


def with_positions(cube, rows, cols):
    """``cube`` with its sensor positions: ``rows`` ``(y, band)`` and ``cols`` ``(x, band)``.

    Parameters
    ----------
    cube : xarray.DataArray
        Dims ``(y, x, band)``.
    rows : array_like, shape (ny, nb)
        Sensor row of every cube row and band, pixels (coordinate ``sensor_row``).
    cols : array_like, shape (nx, nb)
        Sensor column of every cube column and band, pixels (coordinate ``sensor_col``).

    Returns
    -------
    xarray.DataArray
        A new cube; ``cube`` is not changed.
    """
    return cube.assign_coords(
        sensor_row=(POSITION_DIMS["sensor_row"], rows, POSITION_ATTRS["sensor_row"]),
        sensor_col=(POSITION_DIMS["sensor_col"], cols, POSITION_ATTRS["sensor_col"]))


def check_dtype(dtype, what="a cube"):
    """Raise ``TypeError`` unless ``dtype`` holds real numbers (integers or floats)."""
    dtype = np.dtype(dtype)
    if dtype.kind in "iuf":
        return dtype
    hint = {"c": "keep its magnitude or real part, e.g. abs(cube).astype('float32')",
            "b": "convert it, e.g. cube.astype('uint8')"}.get(
                dtype.kind, "convert it to numbers, e.g. cube.astype('float32')")
    raise TypeError(f"{what} holds real numbers (integers or floats), not {dtype} values; "
                    f"{hint}")


def _check_sizes(shape):
    empty = [d for d, n in zip(DIMS, shape, strict=True) if n == 0]
    if empty:
        raise ValueError(f"a cube needs at least one value along every dim, got shape "
                         f"{tuple(shape)} (no {', '.join(empty)}); an empty cube holds nothing")


#: Units and name of integer data that nobody named: a camera's raw counts, not a ratio.
RAW_ATTRS = {"units": "count", "long_name": "raw digital numbers (DN)"}


def make_cube(data, wavelength_nm, *, fwhm_nm=None, attrs=None, name=None):
    """Wrap a ``(y, x, band)`` array (numpy or dask) as a cube.

    Parameters
    ----------
    data : array_like, shape (y, x, band)
        Real numbers, at least one value along every dim.
    wavelength_nm : array_like, shape (band,)
        Nominal central wavelength of each band, nm (finite, 100-1e5, no repeats).
    fwhm_nm : array_like, optional
        Band widths, nm, a scalar or one per band.
    attrs : dict, optional
        Acquisition metadata (f-number, exposure, sensor name, ...).
    name : str, optional
        Default: ``"raw"`` (with units "count", unless ``attrs`` give others) for integer
        data, a camera's digital numbers; ``"radiance"`` otherwise.

    Returns
    -------
    xarray.DataArray

    Raises
    ------
    TypeError
        Complex, boolean, text or object values.
    ValueError
        Not 3-D, an empty dim, or wavelengths that are not one plausible value in nm per band.
    """
    if not hasattr(data, "ndim"):
        data = np.asarray(data)
    if data.ndim != 3:
        raise ValueError(f"a cube needs 3 dimensions (y, x, band), got shape {data.shape}")
    check_dtype(data.dtype)
    _check_sizes(data.shape)
    try:
        wl = np.atleast_1d(np.asarray(wavelength_nm, dtype=float))
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"wavelengths must be numbers (nm), got {wavelength_nm!r}") from None
    if wl.shape != (data.shape[2],):
        raise ValueError(f"the cube has {data.shape[2]} bands but {wl.size} wavelengths")
    wl = check_wavelengths_nm("wavelengths", wl)
    coords = {"wavelength": ("band", wl, {"units": "nm", "long_name": "nominal wavelength"})}
    if fwhm_nm is not None:
        fw = np.asarray(fwhm_nm, dtype=float)
        if fw.ndim and fw.shape != wl.shape:
            raise ValueError(f"the cube has {wl.size} bands but {fw.size} fwhm values; give "
                             "one per band or a single value")
        fw = np.broadcast_to(fw, wl.shape).copy()
        check_positive_array("fwhm", fw, "nm")
        coords["fwhm"] = ("band", fw, {"units": "nm", "long_name": FWHM_LONG_NAME})
    attrs = dict(attrs or {})
    if name is None:
        name = "raw" if np.dtype(data.dtype).kind in "iu" else "radiance"
        if name == "raw":
            attrs = {**RAW_ATTRS, **attrs}
    return xr.DataArray(data, dims=DIMS, coords=coords, attrs=attrs, name=name)


def check_cube(cube):
    """Raise unless ``cube`` is a valid cube; return it.

    Checks the type, dims, that its values are real numbers, that no dim is empty, its
    ``wavelength(band)`` (nm: finite, plausible, no repeats) and, when present, ``fwhm`` and
    the sensor positions ``sensor_row(y, band)`` and ``sensor_col(x, band)``.
    """
    if not isinstance(cube, xr.DataArray):
        raise TypeError(f"a cube is an xarray.DataArray, got {type(cube).__name__}")
    if tuple(cube.dims) != DIMS:
        raise ValueError(f"a cube has dims {DIMS}, got {tuple(cube.dims)}; "
                         "use cube.transpose('y', 'x', 'band')")
    check_dtype(cube.dtype)
    _check_sizes(cube.shape)
    if "wavelength" not in cube.coords:
        raise ValueError("a cube needs a wavelength(band) coordinate in nm")
    if cube["wavelength"].dims != ("band",):
        raise ValueError(f"wavelength is a coordinate along band, got dims "
                         f"{cube['wavelength'].dims}")
    check_wavelengths_nm("wavelengths", cube["wavelength"].values)
    if "fwhm" in cube.coords:
        fw = np.asarray(cube["fwhm"].values, dtype=float)
        if cube["fwhm"].dims != ("band",):
            raise ValueError("fwhm must be a coordinate along band")
        check_positive_array("fwhm", fw, "nm")
    for name, dims in POSITION_DIMS.items():
        if name in cube.coords:
            pos = cube[name]
            if pos.dims != dims:
                raise ValueError(f"{name} has dims {pos.dims}; a cube's {name} has dims {dims}")
            if pos.dtype.kind not in "iuf":
                raise TypeError(f"{name} holds sensor pixel positions (numbers), not "
                                f"{pos.dtype} values")
    return cube
