"""Reading and writing cubes, frames and results, through the libraries that own each format.

=============  =================================================  ===========================
extension      format                                             library
=============  =================================================  ===========================
``.hdr``       ENVI header + data (``.raw``, ``.img``, ...);      Spectral Python
               BSQ, BIL or BIP; ``wavelength`` and ``fwhm`` in
               the header's ``wavelength units``
``.tif(f)``    TIFF: one page with a channel per band, or one     OpenImageIO
               single-channel page per band; metadata in the
               image description (JSON)
``.exr``       OpenEXR in the spectral layout of Fichet et al.    OpenImageIO
               2021 (``S0.<nm>nm`` emissive, ``T.<nm>nm``
               reflective channels, ``spectralLayoutVersion``)
``.nc``        netCDF 4                                           xarray (h5netcdf)
``.zarr``      Zarr (a folder), consolidated metadata, chunked    xarray (zarr)
               for larger-than-memory work
``.npy``       array; snapcorr writes a JSON sidecar              numpy
               (``cube.npy.json``) with wavelengths, fwhm, name,
               attrs and sensor positions; a bare ``.npy`` needs
               ``wavelength_nm``
=============  =================================================  ===========================

Reading
    :func:`read_cube` (a ``(y, x, band)`` cube), :func:`read_frame` (a raw 2-D frame) and
    :func:`read_dataset` (a whole result written by :func:`write_dataset`) share one reader
    per format, as does :func:`snapcorr.calibrate.read_flat`. A path is examined before it is
    opened (a FIFO, socket, device, symbolic link loop, or a folder where a file is expected is
    refused, see :func:`snapcorr._io.check_input`); ENVI headers are validated before use.
    Wavelengths come back in nm (``attrs["units"] = "nm"``) whatever the file's units
    (ENVI ``wavelength units``, the ``units`` attribute of a netCDF or Zarr ``wavelength``):
    nanometres, micrometres, millimetres and metres are converted, anything else refused, and
    the result must pass :func:`snapcorr._validation.check_wavelengths_nm`. With ``chunks``,
    ENVI and ``.npy`` data stay memory-mapped and are read block by block through dask.

Sensor positions
    ``sensor_row(y, band)`` and ``sensor_col(x, band)`` survive every format: native
    coordinates in netCDF and Zarr; elsewhere per band an offset and one step when
    ``position = offset_b + index * step`` exactly, else every value. In ENVI headers these are
    ``snapcorr sensor row offset = {...}`` with ``snapcorr sensor row step = N`` (or
    ``snapcorr sensor row = {...}``, row-major ``(y, band)``), the same for ``col``; in the
    JSON of TIFF, EXR and ``.npy`` sidecars ``{"offset": [...], "step": N}`` or
    ``{"values": [[...], ...]}``.

Attributes
    netCDF cannot store every attribute type, so :func:`write_dataset` (and :func:`write_cube`
    to ``.nc`` and ``.zarr``) writes strings, integers and floats (and 1-D numeric arrays of 2
    or more values) as themselves and everything else (booleans, None, lists, tuples, dicts,
    strings that start with ``json:``) as a string ``json:<JSON>``; :func:`read_dataset` and
    :func:`read_cube` decode them (a tuple comes back as a list). Other types are refused.
    TIFF, OpenEXR and ``.npy`` sidecars keep a cube's attributes in their JSON, ENVI headers
    in one field, ``snapcorr attrs = json:{...}``.
    Variables and coordinates whose attrs hold ``derived_from`` are not written; the file
    lists them in ``derived_variables`` and :func:`read_dataset` rebuilds them
    (:func:`snapcorr.cube.derived.restore`). Every file carries a mark of its writer (the
    attribute ``written_by = "snapcorr <version>"``, the header field ``snapcorr version``,
    ``"written_by"`` in the JSON of TIFF, EXR and sidecars).

Writing
    Writers check everything (dtype, sizes, wavelengths, attributes, the format's limits)
    before writing anything, write atomically (a hidden temporary name next to the target,
    then renamed) and never write over, into or around an input (an ENVI header and its data
    file, a ``.npy`` and its sidecar count as one). An existing target is replaced only with
    ``overwrite=True`` and only if snapcorr wrote it (its mark); a Zarr store also must hold
    nothing but Zarr metadata and arrays at its top level.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import re
import stat
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from .._io import (
    atomic_write,
    atomic_write_dir,
    atomic_write_files,
    check_input,
    file_kind,
    refuse_inputs,
)
from .._validation import check_wavelengths_nm
from .blockfile import RowBlockFile, lazy_file_array
from .model import (
    DIMS,
    FWHM_LONG_NAME,
    POSITION_ATTRS,
    POSITION_DIMS,
    check_cube,
    check_dtype,
    make_cube,
)

__all__ = ["BLOCK_BYTES", "FORMATS", "read_cube", "read_dataset", "read_frame", "row_blocks",
           "write_cube", "write_dataset"]

FORMATS = {".hdr": "envi", ".tif": "tiff", ".tiff": "tiff", ".exr": "exr", ".nc": "netcdf",
           ".zarr": "zarr", ".npy": "npy"}
#: Data-file names Spectral Python looks for next to a header, in its order (then the
#: interleave's name, then all of them in upper case).
_ENVI_EXTS = ("", ".img", ".dat", ".sli", ".hyspex", ".raw", ".bin")
#: Data files given instead of their header.
_ENVI_DATA = (".raw", ".img", ".dat", ".bsq", ".bil", ".bip", ".bin", ".sli", ".hyspex")
#: ENVI ``data type`` codes a cube can hold (ENVI also defines 6 and 9, complex).
_ENVI_DTYPES = {1: np.uint8, 2: np.int16, 3: np.int32, 4: np.float32, 5: np.float64,
                12: np.uint16, 13: np.uint32, 14: np.int64, 15: np.uint64}
_ENVI_COMPLEX = {6: "complex64", 9: "complex128"}
_REFLECTIVE = ("reflectance", "transmittance")
#: dtypes an OpenEXR float channel holds exactly (float32 has a 24-bit significand).
_EXR_EXACT = tuple(np.dtype(t) for t in (np.uint8, np.int8, np.uint16, np.int16, np.float16,
                                         np.float32))
_TIFF_TYPES = {np.dtype(np.uint8): "uint8", np.dtype(np.uint16): "uint16",
               np.dtype(np.int16): "int16", np.dtype(np.float16): "half",
               np.dtype(np.float32): "float", np.dtype(np.float64): "double"}
_CHANNEL = re.compile(r"^(S0|T)\.(\d+(?:,\d*)?)nm$")
_PLAIN_CHANNEL = re.compile(r"^(\d+(?:\.\d*)?)nm$")
#: Attribute values written as JSON carry this prefix.
JSON_PREFIX = "json:"
#: Length units of wavelengths and their factor to nanometres ("unknown" or none: nm).
UNITS_TO_NM = {
    **dict.fromkeys(("nanometers", "nanometer", "nanometres", "nanometre", "nm"), 1.0),
    **dict.fromkeys(("micrometers", "micrometer", "micrometres", "micrometre", "microns",
                     "micron", "um", "\u00b5m", "\u03bcm"), 1e3),
    **dict.fromkeys(("millimeters", "millimeter", "millimetres", "millimetre", "mm"), 1e6),
    **dict.fromkeys(("meters", "meter", "metres", "metre", "m"), 1e9),
}
_ZARR_META = {"zarr.json", ".zgroup", ".zattrs", ".zmetadata"}

#: Target size of the blocks a cube is streamed in (``snapcorr correct``, ``flatfield``).
BLOCK_BYTES = 16 * 2**20


def _mark():
    from .. import __version__

    return f"snapcorr {__version__}"


def _version():
    from .. import __version__

    return __version__


def row_blocks(cube, target_bytes=BLOCK_BYTES):
    """``cube`` in dask blocks of whole rows (every x and band) of about ``target_bytes``:
    memory stays bounded whatever the cube's size, and each spectrum stays in one block."""
    row_bytes = cube.sizes["x"] * cube.sizes["band"] * max(cube.dtype.itemsize, 4)
    return cube.chunk({"y": max(1, target_bytes // row_bytes), "x": -1, "band": -1})


def _format(path, what="cube"):
    """``(format, main path, data file or None)``: an ENVI data file given instead of its
    header names the header as main path and itself as the data file."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in _ENVI_DATA:
        if not os.path.lexists(path.with_suffix(".hdr")):
            raise ValueError(f"{path} looks like ENVI data but has no header "
                             f"{path.with_suffix('.hdr').name} next to it; an ENVI {what} is "
                             "read through its header")
        return "envi", path.with_suffix(".hdr"), path
    if suffix not in FORMATS:
        known = ", ".join(sorted(FORMATS))
        raise ValueError(f"unknown {what.replace(' ', '-')} format {path.suffix or '(none)'!r} "
                         f"for {path}; snapcorr reads and writes {known}")
    return FORMATS[suffix], path, None


def _sidecar(path):
    """The JSON sidecar of a ``.npy`` file: ``cube.npy.json``."""
    path = Path(path)
    return path.with_name(path.name + ".json")


def _one_line(text):
    return " ".join(str(text).split())


# -- attributes ------------------------------------------------------------------------------


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(type(value).__name__)


def _to_json(value, where):
    try:
        return json.dumps(value, default=_json_default, ensure_ascii=False)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{where} holds a {_one_line(err)} value, which snapcorr cannot store; "
                        "convert it to a string, number, boolean, None, list or dict") from None


def _encode_value(value, where):
    if value is None or isinstance(value, bool | np.bool_ | list | tuple | dict):
        return JSON_PREFIX + _to_json(value, where)
    if isinstance(value, str):
        return JSON_PREFIX + _to_json(value, where) if value.startswith(JSON_PREFIX) else value
    if isinstance(value, int | np.integer):
        return value if -2**63 <= int(value) < 2**63 else JSON_PREFIX + str(int(value))
    if isinstance(value, float | np.floating):
        return value
    if isinstance(value, np.ndarray):
        if value.ndim == 1 and value.size >= 2 and value.dtype.kind in "iuf":
            return value
        return JSON_PREFIX + _to_json(value.tolist(), where)
    raise TypeError(f"{where} is a {type(value).__name__} ({value!r:.60}), which snapcorr "
                    "cannot store; convert it to a string, number, boolean, None, list or dict")


def encode_attrs(attrs, where="the dataset"):
    """``attrs`` as netCDF and Zarr can store them (see the module docstring); an error names
    an attribute that cannot be stored."""
    out = {}
    for key, value in attrs.items():
        if not isinstance(key, str):
            raise TypeError(f"{where}: attribute names are strings, got {key!r}")
        out[key] = _encode_value(value, f"{where}: attribute {key!r}")
    return out


def decode_attrs(attrs):
    """Attributes as :func:`encode_attrs` had them in memory (``json:`` strings decoded)."""
    out = {}
    for key, value in attrs.items():
        if isinstance(value, bytes):
            value = value.decode("utf-8", "replace")
        if isinstance(value, str) and value.startswith(JSON_PREFIX):
            with contextlib.suppress(ValueError):
                value = json.loads(value[len(JSON_PREFIX):])
        out[key] = value
    return out


def _json_attrs(attrs, where):
    """Attributes for a JSON document (TIFF, EXR, sidecars, ENVI): checked, numpy to Python."""
    return json.loads(_to_json(dict(attrs), where))


# -- sensor positions ------------------------------------------------------------------------


def _encode_positions(values):
    """``{"offset": [...], "step": n}`` when ``values[i, b] == offset[b] + i * step`` exactly
    (integers), else ``{"values": [[...], ...]}``."""
    v = np.asarray(values)
    if v.dtype.kind in "iu":
        v = v.astype(np.int64)
        step = int(v[1, 0] - v[0, 0]) if v.shape[0] > 1 else 1
        if np.array_equal(v, v[0][None, :] + step * np.arange(v.shape[0])[:, None]):
            return {"offset": v[0].tolist(), "step": step}
    return {"values": v.tolist()}


def _decode_positions(spec, shape, name, where):
    """The ``shape`` array described by ``spec`` (from :func:`_encode_positions`)."""
    try:
        if "offset" in spec:
            offset = np.asarray(spec["offset"])
            step = np.asarray(spec.get("step", 1))
            if offset.ndim != 1 or step.ndim != 0:
                raise ValueError
            values = offset[None, :] + step * np.arange(shape[0])[:, None]
        else:
            values = np.asarray(spec["values"])
        if values.dtype.kind not in "iuf":
            raise ValueError
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{where}: {name} is not a list of sensor positions") from None
    if values.shape != tuple(shape):
        raise ValueError(f"{where}: {name} has shape {values.shape} but the cube needs "
                         f"{tuple(shape)}")
    return values.astype(np.int64 if values.dtype.kind in "iu" else np.float64)


def _positions(cube):
    return {name: _encode_positions(cube[name].values) for name in POSITION_DIMS
            if name in cube.coords}


# -- reading ---------------------------------------------------------------------------------


@dataclass
class _File:
    """What a reader found: data ``(y, x, band)`` (numpy, dask, or an xarray variable for
    netCDF and Zarr) and the metadata as the file has it (wavelengths in the file's units)."""

    path: Path
    fmt: str
    data: object
    file_ndim: int = 3
    wavelength: object = None
    units: object = None
    fwhm: object = None
    fwhm_units: object = None
    name: object = None
    attrs: dict = field(default_factory=dict)
    positions: dict = field(default_factory=dict)  # name -> array or encoded dict


def _read_file(path, *, chunks=None, what="cube", drop_alpha=False):
    """The one reader behind :func:`read_cube`, :func:`read_frame` and ``read_flat``."""
    fmt, path, data_file = _format(path, what)
    check_input(path, directory=fmt == "zarr", what=what)
    try:
        if fmt == "envi":
            found = _read_envi(path, data_file, chunks, what)
        elif fmt in ("tiff", "exr"):
            found = _read_oiio(path, fmt, drop_alpha, what)
        elif fmt == "npy":
            found = _read_npy(path, chunks)
        else:
            found = _read_xarray(path, fmt, chunks)
    except (ValueError, TypeError, FileNotFoundError) as err:
        if str(err).startswith(str(path)) or str(err).startswith("no such file"):
            raise
        raise ValueError(f"{path}: cannot read it as {fmt}: {_one_line(err)}") from None
    except Exception as err:  # the libraries raise their own types; all mean a bad file
        raise ValueError(f"{path}: cannot read it as {fmt}: {type(err).__name__}: "
                         f"{_one_line(err)}") from None
    dtype = found.data.dtype
    if dtype.kind not in "iuf":
        try:
            check_dtype(dtype, f"{path}: a {what}")
        except TypeError as err:
            raise ValueError(str(err)) from None
    return found


class _Blocks:
    """A memory map as dask reads it: block by block, each block copied (and brought to the
    machine's byte order) only when computed. ``dask.array.from_array`` copies whole any
    array that has a ``copy`` method, which would read the whole file; this has none."""

    def __init__(self, array, dtype, token):
        self._array, self.dtype, self._token = array, np.dtype(dtype), token
        self.shape, self.ndim = array.shape, array.ndim

    def __getitem__(self, key):
        return np.array(self._array[key], dtype=self.dtype)

    def __dask_tokenize__(self):
        return self._token


def _lazy_or_loaded(array, chunks, dims=DIMS, source=None):
    """A dask array over ``array`` (a memory map stays one: blocks are read when computed)
    when chunks are asked for, else a native-order copy in memory. ``source`` is the file
    the memory map reads (it names the dask graph without reading the data)."""
    native = array.dtype.newbyteorder("=") if array.dtype.byteorder not in ("=", "|") \
        else array.dtype
    if chunks is None:
        return np.array(array, dtype=native)
    import dask.array as da

    st = os.stat(source) if source is not None else None
    token = ("snapcorr-file", str(source), st and st.st_mtime_ns, st and st.st_size,
             array.shape, array.strides, str(array.dtype), getattr(array, "offset", 0))
    sizes = tuple(chunks.get(d, -1) for d in dims)
    return da.from_array(_Blocks(array, native, token), chunks=sizes, asarray=False,
                         meta=np.empty((0,) * array.ndim, native))


def _to_nm(values, units, where):
    """Wavelengths (or widths) in nm from the file's ``units`` (none or "unknown": nm)."""
    key = "nm" if units is None else str(units).strip().lower()
    if key in ("", "unknown"):
        key = "nm"
    scale = UNITS_TO_NM.get(key)
    if scale is None:
        raise ValueError(f"{where}: units {units!r} are not a length (nm, um, mm or m and "
                         "their spellings); pass wavelength_nm or fix the file's units")
    try:
        v = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"{where}: values must be numbers, got {values!r:.80}") from None
    return v if scale == 1.0 else np.round(v * scale, 9)


def read_cube(path, *, wavelength_nm=None, chunks=None):
    """Read a cube from any supported format (see the module table).

    Parameters
    ----------
    path : str or Path
        A file (a folder for ``.zarr``); an ENVI cube by its header or its data file.
    wavelength_nm : array_like, optional
        Band wavelengths, nm, for files that carry none (a bare ``.npy``, a plain TIFF) or
        carry them in no length unit (ENVI ``wavelength units = Index``); a file's own
        wavelengths win, and a mismatch in length is an error.
    chunks : dict, optional
        Dask chunks (e.g. ``{"y": 512}``): the cube is read lazily (ENVI and ``.npy`` stay
        memory-mapped).

    Returns
    -------
    xarray.DataArray
        dims ``(y, x, band)``, ``wavelength`` (and ``fwhm``) in nm, ``sensor_row`` and
        ``sensor_col`` when the file has them.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not a regular file (or folder for ``.zarr``), an unreadable or invalid file, wavelengths
        missing, in no length unit or not plausible in nm, values that are not real numbers.
    """
    f = _read_file(path, chunks=chunks, what="cube")
    try:
        cube = _to_cube(f, wavelength_nm)
    except (TypeError, ValueError) as err:
        if str(err).startswith(str(f.path)):
            raise
        raise type(err)(f"{f.path}: {err}") from None
    if chunks is not None and cube.chunks is None:
        cube = cube.chunk(chunks)
    return cube


def _cube_wavelengths(f, given, n_bands):
    wl = None
    if f.wavelength is not None:
        try:
            wl = _to_nm(f.wavelength, f.units, f"{f.path}: wavelength")
        except ValueError:
            if given is None:
                raise
    if wl is None:
        if given is None:
            raise ValueError(f"{f.path} carries no wavelengths; pass wavelength_nm")
        try:
            wl = np.atleast_1d(np.asarray(given, dtype=float))
        except (TypeError, ValueError):
            raise ValueError(f"wavelength_nm must be numbers, got {given!r:.80}") from None
    if wl.shape != (n_bands,):
        raise ValueError(f"{f.path} has {n_bands} bands but {wl.size} wavelengths")
    wl = check_wavelengths_nm("wavelengths", wl, where=str(f.path))
    fw = None
    if f.fwhm is not None:
        fw = _to_nm(f.fwhm, f.fwhm_units, f"{f.path}: fwhm")
        if fw.size == 1:
            fw = np.full(n_bands, fw[0])
        if fw.shape != (n_bands,):
            raise ValueError(f"{f.path}: {fw.size} fwhm values for {n_bands} bands")
    return wl, fw


def _to_cube(f, given):
    if f.file_ndim != 3:
        raise ValueError(f"{f.path} holds a {f.file_ndim}-D array; a cube is (y, x, band) "
                         "(read a 2-D frame with read_frame)")
    ny, nx, nb = f.data.shape
    wl, fw = _cube_wavelengths(f, given, nb)
    attrs = {k: v for k, v in f.attrs.items() if k not in ("written_by", "derived_variables")}
    wl_attrs = {"units": "nm", "long_name": "nominal wavelength"}
    if isinstance(f.data, xr.DataArray):
        cube = f.data.drop_vars([c for c in ("wavelength", "fwhm") if c in f.data.coords])
        wl_attrs = {**f.data["wavelength"].attrs, **wl_attrs} \
            if "wavelength" in f.data.coords else wl_attrs
        cube = cube.assign_coords(wavelength=("band", wl, wl_attrs))
        if fw is not None:
            cube = cube.assign_coords(
                fwhm=("band", fw, {"units": "nm", "long_name": FWHM_LONG_NAME}))
        cube.attrs = attrs
        cube.name = f.name
        return check_cube(cube)
    # a file that names nothing: whole numbers are a camera's raw counts (make_cube)
    cube = make_cube(f.data, wl, fwhm_nm=fw, attrs=attrs, name=f.name)
    sizes = {"y": ny, "x": nx, "band": nb}
    for name, spec in f.positions.items():
        dims = POSITION_DIMS[name]
        values = _decode_positions(spec, tuple(sizes[d] for d in dims), name, str(f.path))
        cube = cube.assign_coords({name: (dims, values, POSITION_ATTRS[name])})
    return check_cube(cube)


def read_frame(path, *, chunks=None):
    """Read a raw 2-D frame (a mosaic sensor's image, a flat, a dark).

    Parameters
    ----------
    path : str or Path
        A 2-D ``.npy`` (or ``(y, x, 1)``), a single-channel single-page TIFF or OpenEXR (an
        alpha channel is ignored), a single-band ENVI file, or a ``(y, x, 1)`` (or ``(y, x)``)
        variable in ``.nc`` or ``.zarr``.
    chunks : dict, optional
        Dask chunks (e.g. ``{"y": 512}``): read lazily (ENVI and ``.npy`` stay memory-mapped).

    Returns
    -------
    xarray.DataArray
        dims ``("y", "x")``, named ``"frame"``; attrs ``source`` (and ``data_ignore_value``
        from an ENVI header).

    Raises
    ------
    ValueError
        A file holding more than one band (the message says how many), or any error of
        :func:`read_cube`'s readers.
    """
    f = _read_file(path, chunks=chunks, what="frame", drop_alpha=True)
    nb = f.data.shape[2]
    if nb != 1:
        raise ValueError(f"{f.path} holds {nb} bands; a frame is one 2-D image: read it with "
                         "read_cube, or save the one band you need")
    attrs = {k: v for k, v in f.attrs.items() if k in ("source", "data_ignore_value")}
    attrs.setdefault("source", str(f.path))
    if isinstance(f.data, xr.DataArray):
        data = f.data.isel(band=0).data
    else:
        data = f.data[:, :, 0]
    frame = xr.DataArray(data, dims=("y", "x"), attrs=attrs, name="frame")
    if chunks is not None and frame.chunks is None:
        frame = frame.chunk({k: v for k, v in chunks.items() if k in ("y", "x")})
    return frame


# ENVI -------------------------------------------------------------------------------------


@contextlib.contextmanager
def _quiet_spectral():
    """Spectral Python logs (its own handler prints to stderr) and warns about headers; the
    errors snapcorr raises say it all, so both are silenced around its calls."""
    logger = logging.getLogger("spectral")
    disabled = logger.disabled
    logger.disabled = True
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logger.disabled = disabled


def _envi_int(h, key, hdr, *, minimum, default=None, what="a whole number"):
    if key not in h:
        if default is not None:
            return default
        raise ValueError(f"{hdr}: the header has no '{key}'; add it (ENVI needs samples, "
                         "lines, bands, data type, interleave and byte order)")
    raw = h[key]
    text = raw if isinstance(raw, str) else ", ".join(map(str, raw))
    try:
        value = int(text.strip())
    except ValueError:
        value = None
    if value is None or value < minimum:
        raise ValueError(f"{hdr}: '{key} = {text}' must be {what}; fix the header")
    return value


def _envi_header(hdr):
    """The header as Spectral Python parses it, validated; raises one clear line otherwise."""
    from spectral.io import envi

    try:
        with _quiet_spectral():
            h = envi.read_envi_header(str(hdr))
    except Exception as err:  # Spectral Python raises several types for a bad header
        msg = _one_line(err) or type(err).__name__
        raise ValueError(f"{hdr}: cannot read it as ENVI: {msg}") from None
    if h.get("file type", "").strip().lower() == "envi spectral library":
        raise ValueError(f"{hdr} is an ENVI spectral library, not an image cube")
    twice = _envi_repeated_keys(hdr)
    if twice:
        raise ValueError(f"{hdr}: the header gives {', '.join(repr(k) for k in twice)} more "
                         "than once, and readers disagree on which holds; keep one of each")
    lines = _envi_int(h, "lines", hdr, minimum=1, what="a whole number > 0")
    samples = _envi_int(h, "samples", hdr, minimum=1, what="a whole number > 0")
    bands = _envi_int(h, "bands", hdr, minimum=1, what="a whole number > 0")
    offset = _envi_int(h, "header offset", hdr, minimum=0, default=0,
                       what="a whole number >= 0")
    order = _envi_int(h, "byte order", hdr, minimum=0,
                      what="0 (little-endian) or 1 (big-endian)")
    if order not in (0, 1):
        raise ValueError(f"{hdr}: 'byte order = {h['byte order']}' must be 0 (little-endian) "
                         "or 1 (big-endian); fix the header")
    code = _envi_int(h, "data type", hdr, minimum=0, what="an ENVI data type code")
    if code in _ENVI_COMPLEX:
        raise ValueError(f"{hdr}: 'data type = {code}' is {_ENVI_COMPLEX[code]}; a cube holds "
                         "real numbers (convert the data to its magnitude or real part)")
    if code not in _ENVI_DTYPES:
        codes = ", ".join(map(str, _ENVI_DTYPES))
        raise ValueError(f"{hdr}: 'data type = {h['data type']}' is not an ENVI data type "
                         f"snapcorr can read ({codes}: integers and floats); fix the header")
    if "interleave" not in h:
        raise ValueError(f"{hdr}: the header has no 'interleave'; add it (bsq, bil or bip)")
    interleave = str(h["interleave"]).strip().lower()
    if interleave not in ("bsq", "bil", "bip"):
        raise ValueError(f"{hdr}: 'interleave = {h['interleave']}' must be bsq, bil or "
                         "bip; fix the header")
    for key in ("major frame offsets", "minor frame offsets"):
        if key in h:
            vals = h[key] if isinstance(h[key], list) else [h[key]]
            if any(str(v).strip() not in ("0", "") for v in vals):
                raise ValueError(f"{hdr}: '{key}' are not supported; remove them from the "
                                 "data or the header")
    dtype = np.dtype(_ENVI_DTYPES[code]).newbyteorder(">" if order else "<")
    return {"header": h, "lines": lines, "samples": samples, "bands": bands, "offset": offset,
            "dtype": dtype, "interleave": interleave}


def _envi_repeated_keys(hdr):
    """Keys the header's text gives more than once (at the top level, case-insensitive)."""
    try:
        text = Path(hdr).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return []
    keys, depth = [], 0
    for line in text.splitlines()[1:]:  # the first line is "ENVI"
        if depth == 0 and "=" in line:
            keys.append(line.split("=", 1)[0].strip().lower())
        depth = max(depth + line.count("{") - line.count("}"), 0)
    return sorted({k for k in keys if k and keys.count(k) > 1})


def _envi_values(h, hdr, bands):
    """What the header says the stored numbers mean, per band: ``(gain, offset, scale, bad)``
    (value = (stored * gain + offset) / scale; ``bad`` the bands ``bbl`` marks 0), or None
    when it says nothing (the stored numbers are the values)."""
    def per_band(key, default):
        v = _envi_list(h, key, hdr)
        if v is None:
            return np.full(bands, default)
        if v.size == 1:
            return np.full(bands, float(v[0]))
        if v.size != bands:
            raise ValueError(f"{hdr}: '{key}' has {v.size} values for {bands} bands; fix the "
                             "header")
        return v

    keys = ("data gain values", "data offset values", "reflectance scale factor", "bbl")
    if not any(k in h for k in keys):
        return None
    gain, offset = per_band("data gain values", 1.0), per_band("data offset values", 0.0)
    scale = _envi_list(h, "reflectance scale factor", hdr)
    scale = 1.0 if scale is None or scale.size == 0 else float(scale[0])
    bbl = per_band("bbl", 1.0)
    if not (np.all(np.isfinite(gain)) and np.all(np.isfinite(offset))
            and math.isfinite(scale) and scale > 0 and np.all(np.isin(bbl, (0.0, 1.0)))):
        raise ValueError(f"{hdr}: the data gain / offset values, reflectance scale factor or "
                         "bbl are not finite numbers (gains and offsets), a number > 0 (the "
                         "scale factor) and 0 or 1 per band (bbl); fix the header")
    if np.all(gain == 1) and np.all(offset == 0) and scale == 1 and np.all(bbl == 1):
        return None  # as stored
    return gain, offset, scale, bbl == 0


def _apply_envi_values(data, values, ignore):
    """The stored numbers as the header says to read them: ``(stored * gain + offset) /
    scale``, bad bands (bbl 0) and pixels equal to the data ignore value (in stored units) NaN.
    ``data`` is a numpy or dask array, ``(y, x, band)``."""
    import dask.array as da

    gain, offset, scale, bad = values
    kind = np.result_type(data.dtype, np.float32)
    out = (data.astype(kind) * gain.astype(kind) + offset.astype(kind)) / kind.type(scale)
    if not np.any(bad) and ignore is None:
        return out
    drop = bad if ignore is None else (data == ignore) | bad
    where = da.where if isinstance(out, da.Array) else np.where
    return where(drop, kind.type(np.nan), out)


def _envi_data_file(hdr, interleave):
    names = [*_ENVI_EXTS, f".{interleave}"]
    candidates = [hdr.with_suffix(e) for e in names] + \
                 [hdr.with_suffix(e.upper()) for e in names if e]
    for c in candidates:
        if os.path.lexists(c) and not os.path.isdir(c) and c != hdr:
            return c
    looked = ", ".join(c.name for c in candidates[:len(names)])
    raise ValueError(f"{hdr}: cannot read the data: no data file next to the header (looked "
                     f"for {looked}); put the data file beside it")


def _envi_list(h, key, hdr):
    if key not in h:
        return None
    raw = h[key]
    items = raw if isinstance(raw, list) else [raw]
    try:
        return np.array([float(v) for v in items if str(v).strip() != ""])
    except ValueError:
        raise ValueError(f"{hdr}: '{key}' holds something that is not a number: "
                         f"{', '.join(map(str, items))[:80]}") from None


def _read_envi(hdr, data_file, chunks, what="cube"):

    p = _envi_header(hdr)
    h = p["header"]
    data_file = data_file or _envi_data_file(hdr, p["interleave"])
    try:
        check_input(data_file, what="ENVI data file")
    except FileNotFoundError as err:
        raise ValueError(f"{hdr}: cannot read the data: {err}") from None
    except ValueError as err:
        raise ValueError(f"{hdr}: cannot read the data: {err}") from None
    try:
        with open(data_file, "rb"):
            pass
    except OSError as err:
        raise ValueError(f"{hdr}: cannot read its data file {data_file.name}: "
                         f"{err.strerror or err}; check that it is readable (chmod u+r)") from None
    rows, cols, bands, dtype = p["lines"], p["samples"], p["bands"], p["dtype"]
    expected = p["offset"] + rows * cols * bands * dtype.itemsize
    size = os.path.getsize(data_file)
    if size != expected:
        raise ValueError(
            f"{hdr}: the data file {data_file.name} has {size} bytes but the header "
            f"({rows} x {cols} x {bands}, {dtype.name}, offset {p['offset']}) needs "
            f"{expected}; it is truncated or the header does not describe it"
        )
    # Spectral Python parsed and checked the header (_envi_header); the data are read in row
    # blocks with plain file reads (blockfile), never through a whole-file memory map
    data = _from_file(data_file, dtype, (rows, cols, bands), p["offset"], p["interleave"],
                      chunks)
    ignore = None
    if "data ignore value" in h:
        try:
            ignore = float(h["data ignore value"])
        except (TypeError, ValueError):
            raise ValueError(f"{hdr}: 'data ignore value = {h['data ignore value']}' is not a "
                             "number; fix the header") from None
    values = _envi_values(h, hdr, bands)
    if values is not None and what != "cube":
        raise ValueError(f"{hdr}: its data gain / offset values, reflectance scale factor or "
                         f"bbl change the stored numbers, and a {what} is used as stored (its "
                         "saturation is in stored numbers; flat-fielding cancels a gain and "
                         "offset shared with the references): remove them from the header")
    attrs = {"source": str(hdr), "envi_interleave": p["interleave"]}
    if values is not None:  # applied as the header says, the ignored pixels NaN
        data = _apply_envi_values(data, values, ignore)
        attrs["envi_values_applied"] = ("(stored * data gain values + data offset values) / "
                                        "reflectance scale factor; bbl 0 bands and the data "
                                        "ignore value NaN")
    elif ignore is not None:
        attrs["data_ignore_value"] = ignore
    found = _File(hdr, "envi", data, wavelength=_envi_list(h, "wavelength", hdr),
                  units=h.get("wavelength units"), fwhm=_envi_list(h, "fwhm", hdr),
                  fwhm_units=h.get("wavelength units"), name=h.get("snapcorr name"))
    stored = h.get("snapcorr attrs")
    if isinstance(stored, str) and stored.startswith(JSON_PREFIX):
        try:
            attrs.update(json.loads(stored[len(JSON_PREFIX):]))
        except ValueError:
            raise ValueError(f"{hdr}: 'snapcorr attrs' is not valid JSON") from None
    found.attrs = attrs
    for name in POSITION_DIMS:
        key = "snapcorr " + name.replace("_", " ")
        if f"{key} offset" in h:
            found.positions[name] = {"offset": _envi_numbers(h, f"{key} offset", hdr),
                                     "step": _envi_numbers(h, f"{key} step", hdr, scalar=True)}
        elif key in h:
            values = _envi_numbers(h, key, hdr)
            n = rows if name == "sensor_row" else cols
            if len(values) != n * bands:
                raise ValueError(f"{hdr}: '{key}' has {len(values)} values; {n} x {bands} "
                                 "are needed")
            found.positions[name] = {"values": np.reshape(values, (n, bands)).tolist()}
    return found


def _envi_numbers(h, key, hdr, scalar=False):
    raw = h.get(key)
    items = raw if isinstance(raw, list) else [raw]
    try:
        values = [int(v) if re.fullmatch(r"\s*[-+]?\d+\s*", str(v)) else float(v)
                  for v in items]
    except (TypeError, ValueError):
        raise ValueError(f"{hdr}: '{key}' must hold numbers, got {raw!r:.80}") from None
    if scalar:
        if len(values) != 1:
            raise ValueError(f"{hdr}: '{key}' must be one number, got {raw!r:.80}")
        return values[0]
    return values


# TIFF, OpenEXR -----------------------------------------------------------------------------


def _description(attrs):
    """The JSON a TIFF's ImageDescription (or an EXR's ``snapcorr`` attribute) holds, or {}."""
    desc = attrs.get("ImageDescription") or attrs.get("snapcorr")
    if not (isinstance(desc, str) and desc.startswith("{")):
        return {}
    try:
        meta = json.loads(desc)
    except ValueError:
        return {}
    return meta if isinstance(meta, dict) else {}


def _check_tifffile_shape(path, meta, shape):
    """tifffile records the array it was given (``{"shape": [...]}``) and stores a 3-D one
    whose last axis is long as planes of its last two axes: ``(4, 5, 6)`` becomes 4 planes of
    5 x 6. Read as the file's own layout that is 5 x 6 pixels of 4 bands, where the writer may
    have meant 4 x 5 pixels of 6 bands. Which it meant cannot be told: refused."""
    given = meta.get("shape") if "written_by" not in meta else None
    if not (isinstance(given, list) and len(given) == 3):
        return
    given = tuple(int(v) for v in given)
    if given != tuple(shape) and given == (shape[2], shape[0], shape[1]):
        raise ValueError(
            f"{path}: tifffile was given an array of shape {given} and stored it as {given[0]} "
            f"planes of {given[1]} x {given[2]}; whether its bands are the first axis or the "
            "last cannot be told from the file. Write the cube (y, x, band) with "
            "tifffile.imwrite(path, cube, photometric='minisblack', planarconfig='contig'), or "
            "as .npy or .nc")


_NUMBERED = re.compile(r"^(.*?)(\d+)$")


def _exr_channel_order(path, names):
    """The bands' order of EXR channels not named by wavelength. OpenEXR keeps channels sorted
    by name (band1, band10, band11, band2, ...), not as written: channels named by one prefix
    and a number are put in the number's order, R, G, B (A) stay so (OpenImageIO's own order);
    any other naming is refused, as no order can be read from it."""
    if names == ["R", "G", "B", "A"][:len(names)]:  # OpenImageIO puts these first, in order
        return list(range(len(names)))
    parts = [_NUMBERED.match(n) for n in names]
    if all(parts) and len({m.group(1) for m in parts}) == 1:
        numbers = [int(m.group(2)) for m in parts]
        if len(set(numbers)) == len(numbers):
            return list(np.argsort(numbers, kind="stable"))
    shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
    raise ValueError(f"{path}: OpenEXR keeps channels sorted by name, and these ({shown}) do "
                     "not say the bands' order; name them by wavelength (e.g. 'S0.550nm' or "
                     "'550nm') or by one prefix and the band's number (band1, band2, ...)")


def open_image(path):
    """``OpenImageIO.ImageInput`` open on ``path`` with the values as stored: an unassociated
    alpha channel (PIL's RGBA and LA TIFFs) is kept as it is, where OpenImageIO by default
    multiplies every other channel by it. None if it cannot be opened (``oiio.geterror()``)."""
    import OpenImageIO as oiio

    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    return oiio.ImageInput.open(str(path), config)


def _read_oiio(path, fmt, drop_alpha, what="cube"):
    import OpenImageIO as oiio

    inp = open_image(path)
    if inp is None:
        raise ValueError(f"{path}: cannot read it as {fmt}: "
                         f"{_one_line(oiio.geterror()) or 'OpenImageIO cannot open it'}")
    pages = []
    try:
        sub = 0
        while inp.seek_subimage(sub, 0):  # a multi-page TIFF: one band per page
            spec = inp.spec()
            pixels = inp.read_image(sub, 0, 0, spec.nchannels, "unknown")
            if pixels is None:
                raise ValueError(f"{path}: cannot read page {sub + 1}: "
                                 f"{_one_line(inp.geterror()) or 'no pixels'}")
            pixels = np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)
            names = list(spec.channelnames)
            if drop_alpha and len(names) > 1:
                keep = [i for i, n in enumerate(names) if n.upper() not in ("A", "ALPHA")]
                pixels, names = pixels[:, :, keep], [names[i] for i in keep]
            attrs = {a.name: a.value for a in spec.extra_attribs} if sub == 0 else {}
            pages.append((pixels, names, attrs))
            sub += 1
    finally:
        inp.close()
    if len(pages) > 1:
        return _oiio_pages(path, fmt, pages, what)
    data, names, attrs = pages[0]
    wl, keep, name = None, list(range(len(names))), None
    parsed = [_CHANNEL.match(n) for n in names]
    if any(parsed):
        keep = [i for i, m in enumerate(parsed) if m]
        wl = np.array([float(parsed[i].group(2).replace(",", ".")) for i in keep])
        name = "reflectance" if parsed[keep[0]].group(1) == "T" else "radiance"
        order = np.argsort(wl, kind="stable")  # EXR stores channels sorted by name
        keep, wl = [keep[i] for i in order], wl[order]
    meta = _description(attrs)
    if what == "cube":
        _check_tifffile_shape(path, meta, data.shape)
    written = meta.get("wavelength_nm")
    if isinstance(written, list) and len(written) == len(keep):
        written = np.asarray(written, dtype=float)
        if wl is None:
            wl = written
        elif np.array_equal(np.sort(written), wl):
            # EXR keeps channels sorted by name: put the bands back in the written order.
            order = np.argsort(np.argsort(written, kind="stable"), kind="stable")
            keep, wl = [keep[i] for i in order], wl[order]
    elif wl is None and names and all(_PLAIN_CHANNEL.match(n) for n in names):
        wl = np.array([float(_PLAIN_CHANNEL.match(n).group(1)) for n in names])
    elif wl is None and fmt == "exr" and len(keep) > 1:
        keep = [keep[i] for i in _exr_channel_order(path, [names[i] for i in keep])]
    data = data[..., keep]
    dtype = meta.get("dtype")
    if dtype is not None:
        try:
            dtype = np.dtype(dtype)
        except TypeError:
            raise ValueError(f"{path}: the description names an unknown dtype {dtype!r}") \
                from None
        data = data.astype(dtype)
    cube_attrs = meta.get("attrs", {})
    found = _File(path, fmt, data, wavelength=wl, fwhm=meta.get("fwhm_nm"),
                  name=meta.get("name") or name,
                  attrs={"source": str(path), **(cube_attrs if isinstance(cube_attrs, dict)
                                                 else {})})
    for key in POSITION_DIMS:
        if isinstance(meta.get(key), dict):
            found.positions[key] = meta[key]
    return found


def _oiio_pages(path, fmt, pages, what):
    """A multi-page file: every page one channel (one band), all the same size and type."""
    first = pages[0][0]
    for i, (pixels, _, _) in enumerate(pages, start=1):
        if pixels.shape[2] != 1:
            raise ValueError(f"{path}: page {i} has {pixels.shape[2]} channels; a multi-page "
                             f"{fmt.upper()} holds one band per page, each of one channel")
        if pixels.shape[:2] != first.shape[:2] or pixels.dtype != first.dtype:
            raise ValueError(f"{path}: page {i} is {pixels.shape[1]} x {pixels.shape[0]} "
                             f"{pixels.dtype} but page 1 is {first.shape[1]} x {first.shape[0]} "
                             f"{first.dtype}; every page (band) must match")
    data = np.concatenate([p[0] for p in pages], axis=2)
    if what == "cube":  # a stack of frames or flats: pages are pages
        _check_tifffile_shape(path, _description(pages[0][2]), data.shape)
    names = [p[1][0] for p in pages]
    wl = None
    if all(_PLAIN_CHANNEL.match(n) for n in names):
        wl = np.array([float(_PLAIN_CHANNEL.match(n).group(1)) for n in names])
    return _File(path, fmt, data, wavelength=wl, attrs={"source": str(path)})


# numpy -------------------------------------------------------------------------------------


def _npy_layout(path):
    """``(shape, dtype, offset)`` of a C-ordered numeric ``.npy`` from its header, else None
    (numpy then reads it: Fortran order, structured or object arrays, a bad file)."""
    try:
        with open(path, "rb") as fh:
            version = np.lib.format.read_magic(fh)
            read = {(1, 0): np.lib.format.read_array_header_1_0,
                    (2, 0): np.lib.format.read_array_header_2_0}.get(version)
            if read is None:
                return None
            shape, fortran, dtype = read(fh)
            offset = fh.tell()
    except (OSError, ValueError):
        return None
    if fortran or dtype.kind not in "iuf" or len(shape) not in (2, 3) or 0 in shape:
        return None
    if os.path.getsize(path) < offset + int(np.prod(shape)) * dtype.itemsize:
        raise ValueError(f"{path}: the file is shorter than its header's {shape} "
                         f"{dtype.name} array; it is truncated")
    return shape, dtype, offset


def _from_file(path, dtype, shape, offset, interleave, chunks):
    """The values of a raw file, ``(y, x, band)`` in the machine's byte order: all of them
    (``chunks`` None), or a dask array reading blocks of whole rows as they are computed."""
    source = RowBlockFile(path, dtype, shape, offset, interleave)
    if chunks is None:
        return source[:]
    rows = chunks.get("y", -1)
    if rows in (-1, None) or chunks.get("x", -1) not in (-1, None) \
            or chunks.get("band", -1) not in (-1, None):
        # other blocks than whole rows: read as the chunks ask (each block still on its own)
        import dask.array as da

        sizes = tuple(chunks.get(d, -1) for d in DIMS)
        return da.from_array(source, chunks=sizes, asarray=False, fancy=False,
                             meta=np.empty((0, 0, 0), source.dtype),
                             name=f"read-{_file_token(path, shape, dtype, offset)}")
    return lazy_file_array(path, dtype, shape, offset=offset, interleave=interleave,
                           rows_per_block=rows)


def _file_token(path, shape, dtype, offset):
    st = os.stat(path)
    return abs(hash((str(path), st.st_mtime_ns, st.st_size, tuple(shape), str(dtype),
                     offset)))


def _read_npy(path, chunks):
    layout = _npy_layout(path)
    if layout is not None:  # read in row blocks, not through a memory map
        shape, dtype, offset = layout
        file_ndim = len(shape)
        data = _from_file(path, dtype, shape if file_ndim == 3 else (*shape, 1), offset, "bip",
                          None if chunks is None else {**chunks, "band": -1})
        return _npy_found(path, data, file_ndim)
    try:
        data = np.load(path, mmap_mode="r", allow_pickle=False)
    except Exception as err:  # numpy raises several types for a bad or empty file
        raise ValueError(f"{path}: not a numpy array file ({type(err).__name__}: "
                         f"{_one_line(err)})") from None
    if not isinstance(data, np.ndarray):
        raise ValueError(f"{path}: not a numpy array file (a .npz archive?); save one array")
    if data.ndim not in (2, 3):
        raise ValueError(f"{path} holds a {data.ndim}-D array; a cube is (y, x, band) and a "
                         "frame (y, x)")
    file_ndim = data.ndim
    if data.dtype.kind in "iuf":
        data = _lazy_or_loaded(data, chunks, DIMS[:data.ndim], source=path)
    if file_ndim == 2:
        data = data[:, :, None]
    return _npy_found(path, data, file_ndim)


def _npy_found(path, data, file_ndim):
    """The ``.npy``'s array with what its sidecar (if any) says about it."""
    found = _File(path, "npy", data, file_ndim=file_ndim, attrs={"source": str(path)})
    side = _sidecar(path)
    if os.path.lexists(side):
        meta = _read_sidecar(side, path)
        shape = meta.get("shape")
        if shape is not None and list(shape) != list(data.shape[:file_ndim]):
            raise ValueError(f"{path}: its sidecar {side.name} describes shape {shape} but the "
                             f"array is {list(data.shape[:file_ndim])}; the two files do not "
                             "belong together (remove or fix the sidecar)")
        found.wavelength = meta.get("wavelength_nm")
        found.fwhm = meta.get("fwhm_nm")
        found.name = meta.get("name")
        if isinstance(meta.get("attrs"), dict):
            found.attrs.update(meta["attrs"])
        for key in POSITION_DIMS:
            if isinstance(meta.get(key), dict):
                found.positions[key] = meta[key]
    return found


def _read_sidecar(side, path):
    check_input(side, what="sidecar")
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise ValueError(f"{path}: its sidecar {side.name} is not readable JSON "
                         f"({_one_line(err)}); fix or remove it") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: its sidecar {side.name} is not a JSON object; fix or "
                         "remove it")
    return meta


# netCDF, Zarr ------------------------------------------------------------------------------


def _zarr_consolidated(path):
    """Whether the store has consolidated metadata (Zarr 3 inline, or Zarr 2 .zmetadata)."""
    meta = Path(path) / "zarr.json"
    if meta.is_file():
        try:
            return json.loads(meta.read_text(encoding="utf-8")).get(
                "consolidated_metadata") is not None
        except (OSError, ValueError, AttributeError):
            return False
    return (Path(path) / ".zmetadata").is_file()


def _open_dataset(path, fmt, chunks):
    if fmt == "netcdf":
        return xr.open_dataset(path, engine="h5netcdf", chunks=chunks)
    # Zarr: opened in the store's own chunks, then rechunked lazily as asked (asked for
    # directly, chunks that split the stored ones make xarray warn).
    ds = xr.open_zarr(path, consolidated=_zarr_consolidated(path),
                      chunks=None if chunks is None else {})
    if chunks:
        ds = ds.chunk({d: c for d, c in chunks.items() if d in ds.dims})
    return ds


def _read_xarray(path, fmt, chunks):
    ds = _open_dataset(path, fmt, chunks)
    for var in ds.variables.values():
        var.attrs = decode_attrs(var.attrs)
    cubes = [v for v in ds.data_vars if tuple(ds[v].dims) == DIMS]
    if cubes:
        preferred = [n for n in ("radiance", "reflectance", "transmittance") if n in cubes]
        var = ds[(preferred or cubes)[0]]
    else:
        frames = [v for v in ds.data_vars if tuple(ds[v].dims) == ("y", "x")]
        if any(tuple(ds[v].dims) == ("frame", *DIMS) for v in ds.data_vars):
            raise ValueError(f"{path} holds a stream of cubes (frame, y, x, band): open it with "
                             "read_dataset; snapcorr stream --lens LENS --f-number F corrects "
                             "a stream")
        if not frames:
            raise ValueError(f"{path} holds no (y, x, band) variable")
        var = ds[frames[0]].expand_dims("band", axis=2)
    attrs = {**decode_attrs(ds.attrs), **var.attrs}  # the variables' are decoded above
    found = _File(path, fmt, var, name=var.name, attrs=attrs)
    if "wavelength" in var.coords:
        found.wavelength = var["wavelength"].values
        found.units = var["wavelength"].attrs.get("units")
    if "fwhm" in var.coords:
        found.fwhm = var["fwhm"].values
        found.fwhm_units = var["fwhm"].attrs.get("units", found.units)  # else as wavelength
    return found


def read_dataset(path, *, chunks=None):
    """Open a result written by :func:`write_dataset` (``.nc`` or ``.zarr``).

    Attributes of the Dataset, its variables and coordinates come back as they were in
    memory (``json:`` strings decoded), the variables the file lists in
    ``derived_variables`` are rebuilt (:func:`snapcorr.cube.derived.restore`), and the
    writer's marks (``written_by``, ``derived_variables``) are removed from the attributes.

    Parameters
    ----------
    path : str or Path
    chunks : dict, optional
        Dask chunks (e.g. ``{}`` for the file's own): read lazily.

    Returns
    -------
    xarray.Dataset
    """
    from .derived import restore

    path = Path(path)
    if path.suffix.lower() not in (".nc", ".zarr"):
        raise ValueError(f"results are .nc or .zarr files, got {path.suffix or '(none)'!r} "
                         f"for {path}")
    fmt = FORMATS[path.suffix.lower()]
    check_input(path, directory=fmt == "zarr", what="result")
    try:
        ds = _open_dataset(path, fmt, chunks)
    except Exception as err:  # the libraries' own error types: report them plainly
        raise ValueError(f"{path}: cannot read it as {fmt}: {type(err).__name__}: "
                         f"{_one_line(err)}") from None
    ds.attrs = decode_attrs(ds.attrs)
    for var in ds.variables.values():
        var.attrs = decode_attrs(var.attrs)
    ds = restore(ds)
    for key in ("written_by", "derived_variables"):
        ds.attrs.pop(key, None)
    return ds


# -- writing ---------------------------------------------------------------------------------


def _targets(fmt, path):
    """Every path a format writes: an ENVI header and its data, a ``.npy`` and its sidecar."""
    if fmt == "envi":
        return [path, path.with_suffix(".raw")]
    if fmt == "npy":
        return [path, _sidecar(path)]
    return [path]


def _input_family(inputs):
    """The inputs with the files that belong to them (an ENVI header's data file and the
    header of a data file, a ``.npy``'s sidecar)."""
    out = []
    for src in inputs:
        if src is None:
            continue
        p = Path(src)
        out.append(p)
        suffix = p.suffix.lower()
        if suffix == ".hdr":
            names = [*_ENVI_EXTS, ".bsq", ".bil", ".bip"]
            out += [c for e in names for c in {p.with_suffix(e), p.with_suffix(e.upper())}
                    if c != p and c.is_file()]
        elif suffix in _ENVI_DATA:
            out.append(p.with_suffix(".hdr"))
        elif suffix == ".npy":
            out.append(_sidecar(p))
    return out


def _is_mark(value):
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return isinstance(value, str) and value.startswith("snapcorr")


def _written_by_snapcorr(target, role):
    """``(True, "")`` if snapcorr wrote ``target`` (its mark is there), else ``(False, what
    was found)``."""
    if role == "zarr":
        return _zarr_is_ours(target)
    if role == "netcdf":
        import h5py

        try:
            with h5py.File(target, "r") as fh:
                attrs = dict(fh.attrs)
        except Exception:  # not HDF5 at all: h5py raises OSError and others
            return False, "a file that is not netCDF 4"
        if _is_mark(attrs.get("written_by")) or "snapcorr_version" in attrs:
            return True, ""
        return False, "a netCDF file without snapcorr's 'written_by' attribute"
    if role == "envi":
        try:
            with _quiet_spectral():
                from spectral.io import envi

                h = envi.read_envi_header(str(target))
        except Exception:
            return False, "a file that is not an ENVI header"
        if "snapcorr version" in h:
            return True, ""
        return False, "an ENVI header without snapcorr's 'snapcorr version' field"
    if role == "envi-data":
        hdr = target.with_suffix(".hdr")
        if not hdr.is_file():
            return False, f"a data file without its header {hdr.name}"
        ours, _ = _written_by_snapcorr(hdr, "envi")
        return (True, "") if ours else (False, f"the data of {hdr.name}, a header snapcorr "
                                               "did not write")
    if role in ("tiff", "exr"):
        import OpenImageIO as oiio

        inp = open_image(target)
        if inp is None:
            oiio.geterror()
            return False, f"a file that is not {role.upper()}"
        try:
            desc = inp.spec().getattribute("ImageDescription")
        finally:
            inp.close()
        try:
            meta = json.loads(desc) if isinstance(desc, str) else {}
        except ValueError:
            meta = {}
        if isinstance(meta, dict) and (_is_mark(meta.get("written_by"))
                                       or {"wavelength_nm", "dtype"} <= set(meta)):
            return True, ""
        return False, f"a {role.upper()} image snapcorr did not write"
    if role == "npy":
        side = _sidecar(target)
        if side.is_file():
            return _written_by_snapcorr(side, "sidecar")
        return False, f"a .npy file without snapcorr's sidecar {side.name}"
    if role == "sidecar":
        try:
            meta = json.loads(target.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            return False, "a file that is not JSON"
        if isinstance(meta, dict) and _is_mark(meta.get("written_by")):
            return True, ""
        return False, "a JSON file snapcorr did not write"
    return False, "a file snapcorr does not recognise"


def _zarr_is_ours(target):
    strays = []
    for entry in os.scandir(target):
        if entry.name in _ZARR_META:
            continue
        if entry.is_dir(follow_symlinks=False) and any(
                (Path(entry.path) / m).is_file() for m in ("zarr.json", ".zarray", ".zgroup")):
            continue
        strays.append(entry.name)
    if strays:
        shown = ", ".join(sorted(strays)[:3]) + (", ..." if len(strays) > 3 else "")
        return False, f"a folder holding other things than a Zarr store ({shown})"
    attrs = None
    for meta, key in (("zarr.json", "attributes"), (".zattrs", None)):
        f = Path(target) / meta
        if f.is_file():
            try:
                doc = json.loads(f.read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError, ValueError):
                return False, f"a folder whose {meta} is not JSON"
            attrs = doc.get(key, {}) if key else doc
            break
    if attrs is None:
        return False, "a folder that is not a Zarr store"
    if isinstance(attrs, dict) and (_is_mark(attrs.get("written_by"))
                                    or "snapcorr_version" in attrs):
        return True, ""
    return False, "a Zarr store without snapcorr's 'written_by' attribute"


_ROLES = {"envi": "envi", "tiff": "tiff", "exr": "exr", "netcdf": "netcdf", "zarr": "zarr",
          "npy": "npy"}


def _check_targets(fmt, targets, *, overwrite, inputs):
    """Refuse, before anything is written, a target that is or holds an input, or that exists
    (without ``overwrite``, or when snapcorr did not write it)."""
    refuse_inputs(targets, _input_family(inputs))
    for i, target in enumerate(targets):
        if not os.path.lexists(target):
            continue
        if not overwrite:
            raise FileExistsError(f"{target} exists; choose another name or pass "
                                  "overwrite=True (--overwrite)")
        try:
            st = os.stat(target)
        except OSError as err:
            raise ValueError(f"{target} exists but cannot be examined ({err.strerror}); "
                             "move it away or choose another name") from None
        role = _ROLES[fmt] if i == 0 else ("envi-data" if fmt == "envi" else "sidecar")
        directory = role == "zarr"
        if directory != stat.S_ISDIR(st.st_mode) or not (
                stat.S_ISDIR(st.st_mode) or stat.S_ISREG(st.st_mode)):
            raise ValueError(f"{target} exists and is {file_kind(st.st_mode)}; overwrite "
                             f"replaces only a {'Zarr store' if directory else 'file'} "
                             "snapcorr wrote: move it away or choose another name")
        ours, found = _written_by_snapcorr(target, role)
        if not ours:
            raise ValueError(f"{target} exists and is {found}; overwrite replaces only what "
                             "snapcorr wrote: move it away or choose another name")


def _check_writable(fmt, cube, path, interleave):
    """The format's own limits, before anything is written."""
    dtype = cube.dtype
    if fmt == "envi":
        from spectral.io import envi

        if interleave not in ("bsq", "bil", "bip"):
            raise ValueError(f"interleave must be bsq, bil or bip, got {interleave!r}")
        if dtype.char not in envi.dtype_to_envi:
            kind = "16-bit float" if dtype == np.float16 else str(dtype)
            raise ValueError(f"ENVI has no {kind} type; convert the cube "
                             "(cube.astype('float32')) or write .exr, .nc or .zarr")
        others = [path.with_suffix(e) for e in _ENVI_EXTS if e != ".raw"]
        others = [o for o in others if os.path.lexists(o) and not os.path.isdir(o)]
        if others:
            raise ValueError(f"{others[0]} exists next to {path.name}, and ENVI readers would "
                             f"take it as the header's data instead of {path.stem}.raw; move "
                             "it away or choose another name")
    elif fmt == "exr" and dtype not in _EXR_EXACT:
        raise ValueError(
            f"OpenEXR stores 16- and 32-bit floats, so a {dtype} cube would not come back "
            "unchanged; convert it (cube.astype('float32')) or write .nc, .zarr or .tif"
        )
    elif fmt == "tiff" and dtype not in _TIFF_TYPES:
        raise ValueError(f"snapcorr writes TIFF cubes as 8/16-bit integers or 16/32/64-bit "
                         f"floats, not {dtype}; convert it or write .nc or .zarr")


def write_cube(cube, path, *, overwrite=False, inputs=(), interleave="bsq"):
    """Write a cube; the format follows the extension (see the module table).

    Everything is checked before anything is written: the cube (:func:`check_cube`: real
    values, no empty dim, wavelengths in nm without repeats), its attributes, the format's
    limits, the inputs and an existing target.

    Parameters
    ----------
    cube : xarray.DataArray
    path : str or Path
    overwrite : bool
        Replace an existing output snapcorr wrote (never one of ``inputs``, nor another file).
    inputs : sequence of paths
        Files the cube came from; writing over, into or around any of them is refused.
    interleave : {"bsq", "bil", "bip"}
        ENVI band interleave.

    Returns
    -------
    Path
        The path written (an ENVI cube: its header).
    """
    check_cube(cube)
    path = Path(path)
    if path.suffix.lower() in _ENVI_DATA:
        raise ValueError(f"an ENVI cube is written by its header's name: "
                         f"{path.with_suffix('.hdr')} (its data go to "
                         f"{path.with_suffix('.raw').name}), not {path.name}")
    fmt, path, _ = _format(path)
    _check_writable(fmt, cube, path, interleave)
    name = cube.name or "radiance"
    if fmt in ("netcdf", "zarr"):
        ds = _encoded(_to_dataset(cube))
    else:
        meta = _cube_meta(cube, name)
    _check_targets(fmt, _targets(fmt, path), overwrite=overwrite, inputs=inputs)
    if fmt in ("netcdf", "zarr"):
        _store(ds, path, fmt)
    else:
        _WRITERS[fmt](cube, path, meta, interleave=interleave)
    return path


def _cube_meta(cube, name):
    meta = {"written_by": _mark(), "name": name, "dtype": str(cube.dtype),
            "shape": list(cube.shape),
            "attrs": _json_attrs(cube.attrs, f"cube {name!r}"),
            "wavelength_nm": [float(v) for v in cube.wavelength.values]}
    if "fwhm" in cube.coords:
        meta["fwhm_nm"] = [float(v) for v in cube.fwhm.values]
    meta.update(_positions(cube))
    return meta


def _envi_position_keys(meta):
    """The sensor positions of ``meta`` (see :func:`_positions`) as ENVI header keys."""
    header = {}
    for name in POSITION_DIMS:
        if name in meta:
            key = "snapcorr " + name.replace("_", " ")
            spec = meta[name]
            if "offset" in spec:
                header[f"{key} offset"] = spec["offset"]
                header[f"{key} step"] = spec["step"]
            else:
                header[key] = [v for row in spec["values"] for v in row]
    return header


def _write_envi(cube, path, meta, *, interleave):
    from spectral.io import envi

    header = {"description": f"snapcorr cube {meta['name']}",
              "wavelength": meta["wavelength_nm"], "wavelength units": "nm",
              "snapcorr version": _version(), "snapcorr name": meta["name"],
              "snapcorr attrs": JSON_PREFIX + json.dumps(meta["attrs"], ensure_ascii=True)}
    if "fwhm_nm" in meta:
        header["fwhm"] = meta["fwhm_nm"]
    ignore = meta["attrs"].get("data_ignore_value")
    if isinstance(ignore, int | float) and not isinstance(ignore, bool) and math.isfinite(ignore):
        header["data ignore value"] = ignore
    header.update(_envi_position_keys(meta))
    data = np.asarray(cube.values)

    def write(folder):
        with _quiet_spectral():
            envi.save_image(str(folder / path.name), data, dtype=data.dtype,
                            interleave=interleave, ext=".raw", metadata=header, force=True)

    atomic_write_files([path.with_suffix(".raw"), path], write)


def _channel_name(prefix, wavelength):
    return f"{prefix}.{float(wavelength)!r}nm".replace(".", ",").replace(",", ".", 1)


def _write_oiio(cube, path, meta, *, interleave):
    import OpenImageIO as oiio

    exr = path.suffix.lower() == ".exr"
    data = np.ascontiguousarray(cube.values)
    if exr:
        prefix = "T" if cube.name in _REFLECTIVE else "S0"
        names = [_channel_name(prefix, w) for w in cube.wavelength.values]
        store = data.astype(np.float16 if data.dtype == np.float16 else np.float32)
        typedesc = "half" if data.dtype == np.float16 else "float"
    else:
        names = [f"{float(w)!r}nm" for w in cube.wavelength.values]
        store, typedesc = data, _TIFF_TYPES[data.dtype]
    ny, nx, nb = store.shape
    spec = oiio.ImageSpec(nx, ny, nb, typedesc)
    spec.channelnames = tuple(names)
    spec.alpha_channel = -1
    spec.attribute("ImageDescription", json.dumps(meta))
    spec.attribute("compression", "zip")
    if exr:
        spec.attribute("spectralLayoutVersion", "1.0")
        if prefix == "S0":
            spec.attribute("emissiveUnits", "W.m^-2.sr^-1")
    else:
        spec.attribute("tiff:PlanarConfiguration", "contig")

    def write(tmp):
        out = oiio.ImageOutput.create(str(path))
        if out is None or not out.open(str(tmp), spec):
            raise ValueError(f"cannot write {path}: {_one_line(oiio.geterror())}")
        try:
            if not out.write_image(store):
                raise ValueError(f"cannot write {path}: {_one_line(out.geterror())}")
        finally:
            out.close()

    atomic_write(path, write)


def _write_npy(cube, path, meta, *, interleave):
    data = np.asarray(cube.values)
    text = json.dumps(meta, indent=1)

    def write(folder):
        np.save(folder / path.name, data, allow_pickle=False)
        (folder / _sidecar(path).name).write_text(text, encoding="utf-8")

    atomic_write_files([path, _sidecar(path)], write)


_WRITERS = {"envi": _write_envi, "tiff": _write_oiio, "exr": _write_oiio, "npy": _write_npy}


def _to_dataset(cube):
    name = cube.name or "radiance"
    ds = cube.to_dataset(name=name)
    ds.attrs = dict(cube.attrs)
    ds[name].attrs = {}
    return ds


#: Variables :func:`write_dataset` stores when ``store_derived`` is set keep their formula
#: under this attribute (``derived_from`` would make :func:`read_dataset` expect to rebuild them).
STORED_FROM = "computed_from"


def _encoded(ds, store_derived=False):
    """A copy of ``ds`` ready to store: derived variables left out (and listed) or, with
    ``store_derived``, stored as plain data variables; every attribute encoded, the writer's
    mark added. ``ds`` itself is not changed."""
    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"write_dataset writes an xarray.Dataset, got {type(ds).__name__}; "
                        "for a cube use write_cube or cube.to_dataset()")
    derived = [n for n, v in ds.variables.items() if "derived_from" in v.attrs]
    listed = ds.attrs.get("derived_variables", [])
    if isinstance(listed, str):
        listed = listed.replace(",", " ").split()
    attrs = dict(ds.attrs)
    if store_derived:
        # plain variables for readers without snapcorr; data variables rather than
        # coordinates, so that they are written block by block like the cube
        out = ds.reset_coords([n for n in derived if n in ds.coords]).copy()
        for name in derived:
            var_attrs = dict(out[name].attrs)
            var_attrs[STORED_FROM] = var_attrs.pop("derived_from")
            out[name].attrs = var_attrs
        names = [n for n in listed if n not in derived]
    else:
        out = ds.drop_vars(derived).copy()
        names = list(dict.fromkeys([*listed, *derived]))
    attrs.pop("derived_variables", None)
    if names:
        attrs["derived_variables"] = names
    attrs["written_by"] = _mark()
    out.attrs = encode_attrs(attrs, "the dataset")
    for name, var in out.variables.items():
        var.attrs = encode_attrs(var.attrs, f"variable {name!r}")
    return out


#: ``compression`` of :func:`write_dataset`.
COMPRESSIONS = ("auto", "all", "none")


def write_dataset(ds, path, *, overwrite=False, inputs=(), compression="auto",
                  store_derived=False):
    """Write a Dataset (a corrected cube with its mask, raw data and provenance) to ``.nc`` or
    ``.zarr``, atomically.

    Every attribute of the Dataset, its variables and coordinates is written (see the module
    docstring for how netCDF and Zarr hold those they cannot store natively; other types are
    refused before anything is written); variables and coordinates whose attrs hold
    ``derived_from`` are left out and listed in ``derived_variables``, for
    :func:`read_dataset` to rebuild, unless ``store_derived``. Zarr stores get consolidated
    metadata.

    Parameters
    ----------
    ds : xarray.Dataset
        Not changed.
    path : str or Path
        ``.nc`` or ``.zarr``.
    overwrite : bool
        Replace an existing output snapcorr wrote (never one of ``inputs``, nor another file
        or folder).
    inputs : sequence of paths
        Files the data came from; writing over, into or around any of them is refused.
    compression : {"auto", "all", "none"}
        ``"auto"`` compresses where it pays: every numeric variable of a Zarr store (Blosc LZ4,
        about as fast as writing plainly); in netCDF, DEFLATE (level 1, byte shuffle) for
        integer and boolean variables (raw counts, masks: about 0.6 and under 0.05 of their
        size) and stored derived variables (smooth: about 0.25), while noisy floating-point
        cubes stay plain (about 0.75 of their size for 6 x the writing time). ``"all"`` also
        compresses those; ``"none"`` compresses nothing.
    store_derived : bool
        Write the derived variables (``wavelength_corrected``, ``fwhm_corrected``) as plain
        data variables, with their formula in ``computed_from``, for readers without snapcorr.

    Returns
    -------
    Path
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".nc", ".zarr"):
        raise ValueError(f"results are written as .nc or .zarr, got {path.suffix or '(none)'!r}")
    if compression not in COMPRESSIONS:
        raise ValueError(f"compression must be one of {', '.join(COMPRESSIONS)}, got "
                         f"{compression!r}")
    fmt = FORMATS[suffix]
    out = _encoded(ds, store_derived=store_derived)
    _check_targets(fmt, [path], overwrite=overwrite, inputs=inputs)
    return _store(out, path, fmt, compression)


def _store(ds, path, fmt, compression="auto"):
    try:
        return _store_dataset(ds, path, fmt, compression)
    except (OSError, ValueError, TypeError):
        raise
    except Exception as err:  # the libraries' own error types: report them plainly
        raise ValueError(f"cannot write {path}: {type(err).__name__}: {_one_line(err)}") \
            from None


def _compressible(ds):
    """Numeric variables of two or more dims without a compression of their own."""
    own = ("compressors", "compressor", "zlib", "compression")
    return [name for name, v in ds.variables.items()
            if v.dtype.kind in "biuf" and v.ndim >= 2 and not any(k in v.encoding for k in own)]


def _zarr_encoding(ds, compression="auto"):
    """Blosc LZ4 with bit shuffling for numeric variables without an encoding of their own:
    on cubes it writes about 4 x faster than zarr's default Zstandard for files about a tenth
    larger (measured on flat-fielded reflectance, raw counts and masks), and the writing is
    what a file-to-file run spends its time on. ``compression="none"``: no compressor."""
    from zarr.codecs import BloscCodec

    if compression == "none":
        return {name: {"compressors": None} for name in _compressible(ds)}
    codec = BloscCodec(cname="lz4", clevel=5, shuffle="bitshuffle")
    return {name: {"compressors": [codec]} for name in _compressible(ds)}


def _netcdf_encoding(ds, compression="auto"):
    """DEFLATE level 1 with byte shuffling (readable by every netCDF-4 reader) where it pays:
    integer and boolean variables and stored derived ones for ``"auto"``, every numeric one
    for ``"all"`` (see :func:`write_dataset`)."""
    if compression == "none":
        return {}
    return {name: {"zlib": True, "complevel": 1, "shuffle": True}
            for name in _compressible(ds)
            if compression == "all" or ds[name].dtype.kind in "biu"
            or STORED_FROM in ds[name].attrs}


#: A lazy variable whose attrs name another in this key (``mask`` computed from
#: ``reflectance``, say) is written in the same pass as that one: both come from one
#: computation, which would otherwise run twice. The key itself is not written.
COMPUTED_WITH = "computed_with"


def _write_groups(ds, lazy):
    """The lazy variables in writing passes: each alone, or with those computed with it."""
    groups = {v: [v] for v in lazy}
    for v in lazy:
        host = ds[v].attrs.get(COMPUTED_WITH)
        if host in groups and host != v and v in groups:
            groups[host].extend(groups.pop(v))
    return list(groups.values())


def _store_dataset(ds, path, fmt, compression="auto"):
    # Dask-backed variables are written one at a time: computed together, a block read once
    # for two variables (a cube and its resampled copy) stays in memory until both are done,
    # which can hold the whole cube. Apart, each streams through in bounded memory.
    lazy = [v for v in ds.data_vars if ds[v].chunks is not None]
    groups = _write_groups(ds, lazy)
    ds = ds.copy()
    for v in ds.data_vars:  # a writing instruction, not a property of the data
        ds[v].attrs.pop(COMPUTED_WITH, None)
    first = ds.drop_vars(lazy)
    if fmt == "netcdf":
        def write(tmp):
            first.to_netcdf(tmp, engine="h5netcdf",
                            encoding=_netcdf_encoding(first, compression))
            for group in groups:
                part = ds[group]
                part.to_netcdf(tmp, mode="a", engine="h5netcdf",
                               encoding={k: e for k, e in
                                         _netcdf_encoding(part, compression).items()
                                         if k not in first.variables})

        atomic_write(path, write)
        return path

    def write_zarr(tmp):
        import zarr

        first.to_zarr(tmp, mode="w", consolidated=False,
                      encoding=_zarr_encoding(first, compression))
        for group in groups:
            # the coordinates went in with the first pass (sensor positions, the corrected
            # wavelengths' compact form): zarr refuses an encoding for a variable that already
            # exists, so later passes give one for their own variables only
            part = ds[group]
            part.to_zarr(tmp, mode="a", consolidated=False,
                         encoding={k: e for k, e in _zarr_encoding(part, compression).items()
                                   if k not in first.variables})
        # Zarr 3 keeps consolidated metadata in zarr.json as an extension that other readers
        # may ignore ("must_understand": false); it lets xr.open_zarr(path) open the store
        # with its default arguments, quickly and without a warning.
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*[Cc]onsolidated metadata")
            zarr.consolidate_metadata(str(tmp))

    atomic_write_dir(path, write_zarr)
    return path
