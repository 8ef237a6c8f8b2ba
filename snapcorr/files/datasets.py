"""netCDF and Zarr through xarray: opening a file, finding its cube, storing a Dataset.

- reading: :func:`_open_dataset` (netCDF with h5netcdf, Zarr in its own chunks) and
  :func:`_read_xarray` (the cube, or a frame, among a file's variables);
- writing: :func:`_encoded` (a Dataset ready to store: derived variables left out and listed,
  attributes encoded by :func:`snapcorr.files.attrs.encode_attrs`, the writer's mark) and
  :func:`_store` (lazy variables one pass at a time, :data:`COMPUTED_WITH` grouping those
  computed together; the compression of :data:`COMPRESSIONS`).
"""

from __future__ import annotations

import warnings

import numpy as np
import xarray as xr

from .._threads import dask_threads
from .._validation import outside_stacklevel, shown
from ..cube.derived import rebuildable, with_fwhm_table
from ..cube.model import DIMS
from .attrs import _one_line, decode_attrs, encode_attrs
from .chunks import (
    STORED_TYPE,
    _damaged_input_error,
    _float16_widened,
    _refuse_incomplete_zarr,
    _refuse_unwritten_hdf5_chunks,
    damaged_input,
)
from .marks import writer_mark as _mark
from .safety import atomic_write, atomic_write_dir
from .storage import FileFormat, _File, _Rows, _zarr_row_blocks, _zarr_row_chunks

__all__ = ["COMPRESSIONS", "COMPUTED_WITH", "STORAGE_DTYPES", "STORED_FROM",
           "PackingClipWarning", "check_storage", "refuse_packed_counts", "which_cube"]


# -- reading ---------------------------------------------------------------------------------


def _netcdf_engine(path):
    """h5netcdf for netCDF-4 (HDF5), SciPy's reader for netCDF-3 (classic, 64-bit offset
    and CDF-5 files begin with ``CDF``), which h5netcdf cannot open."""
    with open(path, "rb") as f:
        return "scipy" if f.read(3) == b"CDF" else "h5netcdf"


def _open_dataset(path, fmt, chunks):
    """The file's Dataset, lazily. ``chunks``: None (each variable read whole when used), a
    dict by dim (dask: netCDF in those chunks, Zarr in its own chunks then rechunked), or
    :class:`~snapcorr.files.storage._Rows`: opened without dask and without caching, for the
    caller to chunk the variable it reads once it knows its shape (opened with ``chunks={}``
    instead, a contiguous netCDF variable would be one dask chunk, read whole by every block
    cut from it)."""
    if fmt == "zarr":
        _refuse_incomplete_zarr(path)
    elif _netcdf_engine(path) == "h5netcdf":
        _refuse_unwritten_hdf5_chunks(path)
    if isinstance(chunks, _Rows):
        if fmt == "netcdf":
            return xr.open_dataset(path, engine=_netcdf_engine(path), chunks=None, cache=False)
        return _unpacked_as_stored(xr.open_dataset(
            path, engine="zarr", consolidated=False, chunks=None, cache=False,
            mask_and_scale=False))
    if fmt == "netcdf":
        with warnings.catch_warnings():
            # blocks that split the file's own chunks read some of them twice: a cost, not an
            # error (opened in the file's chunks instead, a contiguous variable would be one
            # block, read whole by every block cut from it)
            warnings.filterwarnings("ignore", message="The specified chunks separate")
            return xr.open_dataset(path, engine=_netcdf_engine(path), chunks=chunks)
    # Zarr: opened in the store's own chunks, then rechunked as asked (asked for directly,
    # chunks that split the stored ones make xarray warn); each array's own metadata, never a
    # consolidated copy a later write may have left stale (3 frames said, 4 stored)
    ds = _unpacked_as_stored(xr.open_zarr(path, consolidated=False,
                                          chunks=None if chunks is None else {},
                                          mask_and_scale=False))
    if chunks:
        ds = ds.chunk({d: c for d, c in chunks.items() if d in ds.dims})
    return ds


def _unpacked_as_stored(ds):
    """A Zarr store opened without unpacking (``mask_and_scale=False``), unpacked lazily as
    netCDF's reader does it: a uint16 variable's ``scale_factor`` and ``add_offset`` in
    float32, the type they were written in, so it reads back as float32 with netCDF's values
    (Zarr keeps attributes as JSON, where they became float64, and xarray unpacked to float64:
    twice the memory). Fill values of every variable are masked as before."""
    for var in ds.variables.values():
        if var.dtype == np.uint16 and "scale_factor" in var.attrs:
            for key in ("scale_factor", "add_offset"):
                if key in var.attrs:
                    var.attrs[key] = np.float32(var.attrs[key])
    return xr.decode_cf(ds, mask_and_scale=True, decode_times=False, decode_coords=False)


#: CF attributes by which a reader turns stored numbers into others (unpacking, and fill
#: values made NaN).
PACKING = ("scale_factor", "add_offset", "_FillValue", "missing_value")
#: Units that say a variable holds a camera's numbers (none at all says the same).
COUNT_UNITS = ("", "count", "counts", "dn", "digital number", "digital numbers", "adu")


def refuse_packed_counts(var, path, *, counts=False):
    """Refuse a camera's numbers that xarray would unpack or mask on reading.

    A variable stored as integers with CF packing or fill values is decoded by xarray into
    floats (scaled, fill values made NaN): for physical values that is what the file means,
    but a camera's raw counts would then no longer be the camera's numbers, and the result's
    ``raw`` would keep others. Such a variable is refused where it holds counts: ``counts``
    (a stream of frames), or units of counts or none.

    Parameters
    ----------
    var : xarray.DataArray
        As opened (its ``encoding`` says how it is stored).
    path : str or Path
        The file, for the message.
    counts : bool
        The variable is known to hold a camera's numbers.
    """
    import numpy as np

    stored = np.dtype(var.encoding.get("dtype", var.dtype))
    packing = {k: var.encoding[k] for k in PACKING if k in var.encoding}
    units = str(var.attrs.get("units", "")).strip().lower()
    if stored.kind not in "iu" or not packing or not (counts or units in COUNT_UNITS):
        return
    said = ", ".join(f"{k} {shown(np.asarray(v).tolist())}" for k, v in packing.items())
    raise ValueError(f"{path}: {var.name} is stored as {stored} with {said}, which a reader "
                     "applies (scaled, or fill values made NaN), so the camera's numbers would "
                     "not be read as they are; store the counts without them, or give the "
                     "variable the units of the physical values it holds")


#: The ``(y, x, band)`` variables snapcorr writes beside a cube (the input's copies, the
#: results computed from it, the angles and masks): never the cube a file is read as while
#: another is there.
_BESIDE_THE_CUBE = ("raw", "filter_white_raw", "resampled", "harmonised", "wavelength_corrected",
                   "fwhm_corrected", "wavelength_scale", "cra", "cra_deg", "mask",
                   "transmittance_mask")


def which_cube(path, cubes, what="cubes (y, x, band)"):
    """Which of the variables ``cubes`` (of one shape: ``what``) is the cube: ``radiance``,
    ``reflectance`` or ``transmittance`` (or ``frame``), else the one that is none of
    :data:`_BESIDE_THE_CUBE`; two or more such are refused (which one is meant cannot be
    told), naming them and ``path`` (a file, or what holds them).

    Parameters
    ----------
    path : str or Path
        The file (or what holds the variables), for the message.
    cubes : sequence of str
        The names of the variables of one shape.
    what : str
        What they are, for the message (``"frames (y, x)"``).

    Returns
    -------
    str
        The name of the cube.

    Examples
    --------
    >>> which_cube("a.nc", ["raw", "reflectance"])
    'reflectance'
    >>> which_cube("a.nc", ["raw", "sample"])
    'sample'
    """
    preferred = [n for n in ("radiance", "reflectance", "transmittance", "frame") if n in cubes]
    if "radiance" in preferred and "reflectance" in preferred:  # two cubes, neither beside
        raise ValueError(f"{path} holds a radiance and a reflectance cube; which one to read "
                         "cannot be told: save the one you need alone")
    if preferred:  # a flat-field result's transmittance is its filter's, beside reflectance
        return preferred[0]
    unknown = [n for n in cubes if n not in _BESIDE_THE_CUBE]
    if len(unknown) > 1:
        raise ValueError(f"{path} holds {len(unknown)} {what}: "
                         f"{', '.join(sorted(map(str, unknown)))}; which one to read cannot "
                         "be told: save the one you need alone (or name it radiance, "
                         "reflectance or transmittance)")
    return (unknown or cubes)[0]


def _read_xarray(path, fmt, chunks):
    """The cube of a netCDF file or Zarr store (a ``(y, x)`` frame as one band): its
    ``radiance``, ``reflectance`` or ``transmittance``, else its one other ``(y, x, band)``
    variable (:func:`which_cube`). With :class:`~snapcorr.files.storage._Rows` chunks, the
    variable is cut into blocks of rows from its shape (each block reads its rows only)."""
    ds = _open_dataset(path, fmt, chunks)
    for var in ds.variables.values():
        var.attrs = decode_attrs(var.attrs)
    cubes = [v for v in ds.data_vars if tuple(ds[v].dims) == DIMS and ds[v].dtype.kind != "b"]
    stream = any(tuple(ds[v].dims) == ("frame", *DIMS) for v in ds.data_vars)
    if not cubes and stream:  # the reason first: a stream is not one cube, input or not
        raise ValueError(f"{path} holds a stream of cubes (frame, y, x, band), not one "
                         "cube: snapcorr stream --lens LENS --f-number F corrects a stream "
                         "(in Python, snapcorr.cube.read_dataset opens it)")
    left_out = ds.attrs.get("input_left_out")
    if not cubes and left_out:  # a result without its input: its mask or angles are no cube
        raise ValueError(f"{path} holds no cube: its input was left out when it was written "
                         f"({left_out})")
    if cubes:
        var = _rows(ds[which_cube(path, cubes)], chunks)
    else:
        frames = [v for v in ds.data_vars if tuple(ds[v].dims) == ("y", "x")]
        if not frames:
            raise ValueError(f"{path} holds no (y, x, band) variable")
        # chunked first: expand_dims would read a variable that is not a dask array whole
        var = _rows(ds[which_cube(path, frames, "frames (y, x)")], chunks).expand_dims(
            "band", axis=2)
    refuse_packed_counts(var, path)
    attrs = {**decode_attrs(ds.attrs), **var.attrs}  # the variables' are decoded above
    found = _File(path, fmt, var, name=var.name, attrs=attrs)
    if "mask" in ds.data_vars and tuple(ds["mask"].dims) == DIMS and var.name != "mask":
        found.extras["mask"] = _rows(ds["mask"], chunks)  # a flat-field result's, same file
    if "wavelength" in var.coords:
        found.wavelength = var["wavelength"].values
        found.units = var["wavelength"].attrs.get("units")
    if "fwhm" in var.coords:
        found.fwhm = var["fwhm"].values
        found.fwhm_units = var["fwhm"].attrs.get("units", found.units)  # else as wavelength
    return found


def _rows(var, chunks):
    """``var`` in blocks of rows when ``chunks`` is :class:`~snapcorr.files.storage._Rows`
    (decided from its shape and dtype), else as it is."""
    if not isinstance(chunks, _Rows):
        return var
    return var.chunk(chunks.chunks(var.shape, var.dtype, var.dims))


# -- writing ---------------------------------------------------------------------------------


def _to_dataset(cube):
    name = cube.name or "radiance"
    ds = cube.to_dataset(name=name)
    ds.attrs = dict(cube.attrs)
    ds[name].attrs = {}
    return ds


#: Encoding keys that describe how a file read laid a variable out (chunks, shards, its
#: shape there), dropped before writing: each output is laid out from the data written.
STORAGE_LAYOUT = ("chunks", "preferred_chunks", "chunksizes", "shards", "contiguous",
                  "original_shape", "source")

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
    ds = with_fwhm_table(ds)  # a width table not built yet is built for the file
    derived = [n for n, v in ds.variables.items() if "derived_from" in v.attrs]
    listed = ds.attrs.get("derived_variables", [])
    if isinstance(listed, str):
        listed = listed.replace(",", " ").split()
    attrs = dict(ds.attrs)
    # what the file could not rebuild (a selection that dropped its compact form) is stored
    whole = derived if store_derived else [n for n in derived if not rebuildable(ds, n)]
    # plain variables for readers without snapcorr; data variables rather than coordinates,
    # so that they are written block by block like the cube
    out = ds.reset_coords([n for n in whole if n in ds.coords])
    out = out.drop_vars([n for n in derived if n not in whole]).copy()
    for name in whole:
        var_attrs = dict(out[name].attrs)
        var_attrs[STORED_FROM] = var_attrs.pop("derived_from")
        out[name].attrs = var_attrs
    names = list(dict.fromkeys([*(n for n in listed if n not in whole),
                                *(n for n in derived if n not in whole)]))
    attrs.pop("derived_variables", None)
    if names:
        attrs["derived_variables"] = names
    attrs["written_by"] = _mark()
    out.attrs = encode_attrs(attrs, "the dataset")
    for name, var in out.variables.items():
        var.attrs = encode_attrs(var.attrs, f"variable {name!r}")
        # how the file it was read from laid it out is not how this one will be: a store's
        # chunks kept on a variable rechunked since (a cube read in blocks of rows, its
        # sensor positions with it) would overlap the blocks written
        var.encoding = {k: v for k, v in var.encoding.items() if k not in STORAGE_LAYOUT}
    return out


#: ``compression`` of :func:`write_dataset`.
COMPRESSIONS = ("auto", "all", "none")


# -- the type a result's values are stored as ------------------------------------------------

#: ``dtype`` of :func:`write_dataset`: the type the physical values (the cube and the spectra
#: computed from it) are stored as. None keeps each variable's own.
STORAGE_DTYPES = ("float32", "float16", "uint16")
#: uint16 packing: stored codes ``0 .. PACKED_TOP`` (``valid_range``); ``PACKED_FILL`` is NaN.
PACKED_TOP, PACKED_FILL = 65534, 65535
#: The range uint16 packs ratios (units ``"1"``: reflectance, transmittance) into by default:
#: a step of 6.1e-5, about a quarter of one digital number of a 12-bit camera's white.
RATIO_PACK_RANGE = (-0.5, 3.5)
#: The input's copy a result keeps (raw counts, also any ``*_raw``): never packed.
RAW_NAMES = ("raw",)
#: The largest finite float16.
FLOAT16_MAX = 65504.0
#: Units of a variable that places or describes the data rather than holding its values.
_GEOMETRY_UNITS = ("degree", "degrees", "nm", "um", "mm", "px")


def _holds_values(name, var):
    """Whether ``var`` holds the scene's values (a cube, its resampled, harmonised or virtual
    spectra): floating point on ``y`` and ``x`` and a band dimension last, not a quantity that
    places or describes the data (angles, wavelengths), not a stored derived variable."""
    return (var.dtype.kind == "f" and {"y", "x"} <= set(var.dims)
            and var.dims[-1] in ("band", "virtual_band")
            and str(var.attrs.get("units", "")).strip().lower() not in _GEOMETRY_UNITS
            and STORED_FROM not in var.attrs)


def _in_counts(name, var):
    """Whether ``var`` holds a camera's numbers: its units say so, or it has none."""
    return str(var.attrs.get("units", "")).strip().lower() in COUNT_UNITS


def check_storage(dtype, pack_range=None, fmt=None, what="dtype"):
    """Refuse a storage type the format cannot hold, or a packing range that is no range,
    before any work.

    Parameters
    ----------
    dtype : {None, "float32", "float16", "uint16"}
        The type asked for (:func:`~snapcorr.cube.write_dataset`'s ``dtype``).
    pack_range : (float, float), optional
        ``(lo, hi)`` for uint16.
    fmt : {"netcdf", "zarr", "envi"}, optional
        The output's format.
    what : str
        The option's name in the messages (``--dtype`` from the command line).
    """
    if dtype is None:
        if pack_range is not None:
            raise ValueError(f"a packing range goes with {what} uint16")
        return
    if dtype not in STORAGE_DTYPES:
        raise ValueError(f"{what} must be one of {', '.join(STORAGE_DTYPES)}, got {dtype!r}")
    if pack_range is not None:
        if dtype != "uint16":
            raise ValueError(f"a packing range goes with {what} uint16, not {dtype}")
        lo, hi = (float(v) for v in pack_range)
        if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
            raise ValueError(f"the packing range must be two finite numbers LO < HI, got "
                             f"{lo:g}, {hi:g}")
    if fmt == "envi" and dtype != "float32":
        raise ValueError(f"{what} {dtype}: ENVI has no packing a reader applies (no scale, "
                         "offset or fill value every ENVI reader honours) and no 16-bit "
                         "float, so ENVI readers would see the stored codes, not the values; "
                         f"write .nc or .zarr for {dtype}, or ENVI as float32")
    if fmt == "netcdf" and dtype == "float16":
        raise ValueError(f"{what} float16: netCDF has no 16-bit float type (netCDF tools "
                         "cannot read HDF5's); write .zarr for float16, or .nc as uint16")


def stored_as(ds, dtype, pack_range=None, fmt=None):
    """``ds`` with its values laid out for storage as ``dtype`` (see :func:`write_dataset`):
    cast (float16's finite values clipped to its range as they are written, and counted), or
    given the CF packing (``scale_factor``,
    ``add_offset``, ``_FillValue``, ``valid_range``) a reader applies, the packing error and
    the clipping said in the variable's attributes; the values are clipped to the packing's
    range as they are packed (:func:`_packed`, which counts them), so a uint16 layout is
    written through :func:`_store_dataset` only. A camera's numbers are never packed: the input's
    copy (raw counts) keeps its own type, and a cube of counts is refused."""
    check_storage(dtype, pack_range, fmt)
    if dtype is None:
        return ds
    ds = ds.copy()
    for name in list(ds.data_vars):
        var = ds[name]
        if not _holds_values(name, var) or name in RAW_NAMES or name.endswith("_raw"):
            continue  # the input's copy (raw counts) is kept as it is
        attrs = dict(var.attrs)
        # how the input stored its values (its type, Zarr's fill value, codecs set for that
        # type) is not how these are stored: a float's NaN fill value cast to uint16
        encoding = {k: v for k, v in var.encoding.items()
                    if k not in (*PACKING, *STORED_TYPE, "dtype", "valid_range")}
        if dtype != "float32" and _in_counts(name, var):
            units = attrs.get("units")
            said = f"units {shown(units)}" if units else "no units"
            raise ValueError(f"{name} has {said}, which says it holds a camera's numbers: "
                             f"those are stored as they are, never as {dtype}; {dtype} is for "
                             "physical values (flat-field the counts first, or give the cube "
                             "its units)")
        if dtype == "float32":
            if var.dtype.itemsize <= 4:
                var = var.astype(np.float32)
            # else cast as it is written, where finite values beyond float32's range, which
            # the cast would make infinite, are clipped and counted (:func:`_packed`; ENVI's
            # :func:`~snapcorr.files.envi_result.write_envi_result`)
            encoding["dtype"] = "float32"
        elif dtype == "float16":
            # clipped as it is cast, where the values beyond float16's range are counted
            # (:func:`_packed`, :func:`_say_clipped`); infinities and NaN kept
            encoding["dtype"] = "float16"
            attrs["storage"] = ("float16: relative error at most 2**-11 (4.9e-4) of the value "
                                "(absolute 6e-8 below 6.1e-5); finite values beyond "
                                f"+-{FLOAT16_MAX:g} (float16's range) are stored as "
                                f"+-{FLOAT16_MAX:g} (clipped); infinities and NaN as they are")
            attrs["packing_error"] = "relative 4.9e-4"
        else:
            lo, hi = _pack_range(name, var, pack_range)
            scale = (hi - lo) / PACKED_TOP
            # half a step, and float32's rounding in packing and unpacking
            error = scale / 2 + 4 * float(np.finfo(np.float32).eps) * max(abs(lo), abs(hi))
            # clipped as it is packed, where the values beyond the range are counted
            # (:func:`_packed`, :func:`_say_clipped`)
            encoding.update(dtype="uint16", scale_factor=np.float32(scale),
                            add_offset=np.float32(lo), _FillValue=np.uint16(PACKED_FILL))
            attrs["valid_range"] = np.array([0, PACKED_TOP], np.uint16)
            attrs["packing_error"] = error
            attrs["storage"] = (
                f"uint16 packed: value = code * scale_factor + add_offset (scale_factor "
                f"{scale:.6g}, add_offset {lo:g}), at most {error:.3g} (half a step) from "
                f"the value computed; values below {lo:g} stored as {lo:g}, above {hi:g} as "
                f"{hi:g} (clipped); NaN stored as {PACKED_FILL} (_FillValue)")
        var.attrs = attrs
        var.encoding = encoding
        ds[name] = var
    return ds


def _pack_range(name, var, pack_range):
    """``(lo, hi)`` uint16 packs ``var`` into: the one given, else :data:`RATIO_PACK_RANGE`
    for ratios (units ``"1"``); other units need one given."""
    if pack_range is not None:
        return tuple(float(v) for v in pack_range)
    units = str(var.attrs.get("units", "")).strip()
    if units == "1":
        return RATIO_PACK_RANGE
    raise ValueError(f"{name} is in units {shown(units)}: uint16 packs a range of values, chosen "
                     "for ratios (units '1': -0.5 to 3.5) but not known for these; give the "
                     "range (pack_range=)")


def _store(ds, path, fmt, compression="auto"):
    try:
        return _store_dataset(ds, path, fmt, compression)
    except (OSError, ValueError, TypeError):
        raise
    except Exception as err:  # the libraries' own error types: report them plainly
        text = _one_line(err)
        if damaged_input(text):
            raise _damaged_input_error(err, text, ds.encoding.get("source"), path) from None
        raise ValueError(f"cannot write {path}: {type(err).__name__}: {text}") from None


def _compresses(var):
    """Whether ``var``'s own encoding (from the file it was read from) compresses it."""
    e = var.encoding
    return bool(e.get("zlib")) or bool(e.get("compression")) or bool(e.get("compressors")) \
        or e.get("compressor") is not None


def _compressible(ds, compression="auto"):
    """Numeric variables of two or more dims that ``compression`` decides for: every one for
    ``"all"`` and ``"none"`` (whatever their source's encoding), for ``"auto"`` those whose
    own encoding does not already compress them."""
    return [name for name, v in ds.variables.items()
            if v.dtype.kind in "biuf" and v.ndim >= 2
            and (compression != "auto" or not _compresses(v))]


def _zarr_encoding(ds, compression="auto"):
    """Blosc LZ4 with bit shuffling for numeric variables without an encoding of their own:
    on cubes it writes about 4 x faster than zarr's default Zstandard for files about a tenth
    larger (measured on flat-fielded reflectance, raw counts and masks), and the writing is
    what a file-to-file run spends its time on. Noisy float32 reflectance: 0.70 of its bytes
    (no shuffle: 1.00, byte shuffle 0.76); uint16-packed, level 9 (for types of 2 bytes or
    less): 0.57 of the codes, level 5 0.59 (``benchmarks/output_size.py``).
    ``compression="none"``: no compressor."""
    from zarr.codecs import BloscCodec

    if compression == "none":
        return {name: {**_storage_keys(ds[name]), "compressors": None,
                       **_zarr_row_chunks(ds[name])} for name in _compressible(ds, compression)}
    def codec(var):
        stored = np.dtype(var.encoding.get("dtype", var.dtype))
        return BloscCodec(cname="lz4", clevel=9 if stored.itemsize <= 2 else 5,
                          shuffle="bitshuffle")

    # every chunk written as it is: zarr's check that a chunk holds only the fill value (to
    # leave it out) is a pass over each chunk, 14 % of a stream's time (a mask, often all
    # false, keeps the check: cheap on booleans)
    return {name: {**_storage_keys(ds[name]), "compressors": [codec(ds[name])],
                   **_zarr_row_chunks(ds[name])}
            | ({} if ds[name].dtype == bool else {"write_empty_chunks": True})
            for name in _compressible(ds, compression)}


def _storage_keys(var):
    """How ``var`` is to be stored (its type, CF packing and fill value): an encoding given
    for writing replaces the variable's own, so these are carried into it."""
    return {k: var.encoding[k] for k in ("dtype", *PACKING) if k in var.encoding}


def _netcdf_encoding(ds, compression="auto"):
    """DEFLATE level 1 with byte shuffling (readable by every netCDF-4 reader) for every
    numeric variable of two or more dims (``"auto"``: those whose source does not compress
    them already). On noisy float32 reflectance it stores 0.69 of the bytes, levels 2-6 no
    better than 0.686 for more time; on uint16-packed values about 0.4 (measured:
    ``benchmarks/output_size.py``). ``"none"`` turns a source's own off."""
    if compression == "none":
        return {name: {**_storage_keys(ds[name]), "zlib": False}
                for name in _compressible(ds, compression)}
    return {name: {**_storage_keys(ds[name]), "zlib": True, "complevel": 1, "shuffle": True,
                   **_hdf5_chunks(ds[name])}
            for name in _compressible(ds, compression)}


def _hdf5_chunks(var):
    """``{"chunksizes": ...}``: a compressed lazy variable stored in HDF5 chunks that its
    blocks fill whole. Left to h5py's guess (chunks of a few frames of a stream), every block
    would rewrite, decompressing and compressing again, chunks it shares with the next: a
    100-frame stream took 29 x the plain write.

    Along each dim the chunk is the largest size every block but the last is a multiple of
    (their greatest common divisor), so that uneven blocks (a stream's 5, 10, 10, 3 frames)
    still start on chunk boundaries; where that would cut the blocks into pieces under half
    the first block, the first block is taken instead (some chunks then shared, the data the
    same). HDF5 refuses a chunk of 4 GiB or more, and one block can be the whole variable, so
    the chunk is then halved along its longest dims until it holds at most
    :data:`HDF5_MAX_CHUNK_BYTES`.
    """
    if var.chunks is None:
        return {}
    sizes = []
    for blocks in var.chunks:
        whole = blocks[:-1] if len(blocks) > 1 else blocks
        common = int(np.gcd.reduce(np.asarray(whole, dtype=np.int64)))
        sizes.append(common if 2 * common >= blocks[0] else int(blocks[0]))
    itemsize = np.dtype(var.encoding.get("dtype", var.dtype)).itemsize  # as stored
    while int(np.prod(sizes, dtype=np.int64)) * itemsize > HDF5_MAX_CHUNK_BYTES:
        longest = int(np.argmax(sizes))
        if sizes[longest] == 1:
            break
        sizes[longest] = -(-sizes[longest] // 2)
    return {"chunksizes": tuple(sizes)}


#: The most a chunk of a compressed netCDF variable holds (HDF5's own limit is 4 GiB; a
#: chunk is read and decompressed whole, so a reader of one pixel's spectrum pays for all of
#: it).
HDF5_MAX_CHUNK_BYTES = 256 * 2**20


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


def _zarr_blocks(blocks):
    """Whether dask ``blocks`` along one dim are Zarr chunks: all equal but a smaller last."""
    return all(b == blocks[0] for b in blocks[:-1]) and blocks[-1] <= blocks[0]


def _in_zarr_blocks(ds):
    """``ds`` with every dask variable in blocks a Zarr store can hold, one chunk per block
    (equal along each dim but the last one): a selection or a crop cut from blocks of rows
    leaves them uneven, which zarr refuses. Each uneven dim goes to its largest block."""
    out = ds.copy()
    for name, var in ds.variables.items():
        if var.chunks is None:
            continue
        sizes = {d: max(b) for d, b in zip(var.dims, var.chunks, strict=True)
                 if not _zarr_blocks(b)} | _zarr_row_blocks(var)
        if not sizes:
            continue
        if name in ds.coords:
            out = out.assign_coords({name: var.chunk(sizes)})
        else:
            out[name] = var.chunk(sizes)
    return out


def _packed(ds, clipped):
    """``ds`` with each variable :func:`stored_as` gave the uint16 CF packing replaced by its
    codes, packed in one pass (:func:`~snapcorr.files._packing.pack_uint16`, block by block
    for dask), the packing's ``scale_factor``, ``add_offset`` and ``_FillValue`` moved to its
    attributes: stored as they are, read back by any CF reader as xarray's own encoding of
    the values would be; and each float variable stored as a narrower float (float16,
    float32 from float64) with its finite values beyond that type's range clipped to its ends
    (:func:`_narrowed`; cast, they would become infinities). ``clipped`` (a dict) gets each
    variable's ``(counts, range, advice)``: the packing appends to ``counts`` as its blocks
    are written (:func:`_say_clipped`)."""
    names = [n for n in ds.data_vars
             if ds[n].encoding.get("dtype") == "uint16" and "scale_factor" in ds[n].encoding
             and np.issubdtype(ds[n].dtype, np.floating)]
    narrowed = [n for n in ds.data_vars
                if ds[n].dtype.kind == "f"
                and np.dtype(ds[n].encoding.get("dtype", ds[n].dtype)).kind == "f"
                and np.dtype(ds[n].encoding.get("dtype", ds[n].dtype)).itemsize
                < ds[n].dtype.itemsize]
    if not names and not narrowed:
        return ds
    from ._packing import pack_uint16

    out = ds.copy()
    for name in names:
        var = ds[name]
        enc = dict(var.encoding)
        scale, offset = enc.pop("scale_factor"), enc.pop("add_offset", np.float32(0))
        fill = enc.pop("_FillValue", np.uint16(PACKED_FILL))
        hi = float(offset) + PACKED_TOP * float(scale)
        counts = clipped.setdefault(name, (
            [], f"the uint16 packing's range {float(offset):.6g} to {hi:.6g}",
            "widen the packing range, or store float32"))[0]

        def pack(a, offset=offset, scale=scale, fill=fill, counts=counts):
            return pack_uint16(a, offset, scale, PACKED_TOP, fill, clipped=counts)

        data = var.data
        codes = (data.map_blocks(pack, dtype=np.uint16) if var.chunks is not None
                 else pack(np.asarray(data)))
        packed = xr.Variable(var.dims, codes, {**var.attrs, "scale_factor": scale,
                                               "add_offset": offset, "_FillValue": fill},
                             {**enc, "dtype": "uint16"})
        out[name] = xr.DataArray(packed, coords=var.coords)
    for name in narrowed:
        var = ds[name]
        to = np.dtype(var.encoding["dtype"])
        top = float(np.finfo(to).max)
        counts = clipped.setdefault(name, (
            [], f"{to}'s range -{top:g} to {top:g}",
            "store float32, or uint16 with a packing range that holds them"
            if to == np.float16 else f"keep their {var.dtype} (no dtype)"))[0]

        def clip(a, counts=counts, to=to):
            return _narrowed(a, to, counts)

        data = var.data
        kept = (data.map_blocks(clip, dtype=var.dtype) if var.chunks is not None
                else clip(np.asarray(data)))
        out[name] = var.copy(data=kept)  # its attributes and encoding (the narrower type)
    return out


def _narrowed(values, to, counts):
    """``values`` (floats wider than the float type ``to``) with the finite ones that ``to``
    cannot hold (those its cast makes infinite: for float16 65520 and beyond, the rounding
    takes smaller ones to 65504) set to its largest finite value of their sign, infinities
    and NaN kept; the count of those and of the values in all appended to ``counts`` as a
    pair."""
    values = np.asarray(values)
    top = float(np.finfo(to).max)
    # halfway from the largest finite value to the next power of two: from there on the cast
    # rounds to infinity (65520 for float16), in the values' own type
    info = np.finfo(to)
    edge = values.dtype.type(top + 2.0 ** (info.maxexp - 2 - info.nmant))
    magnitude = np.abs(values)
    beyond = (magnitude >= edge) & (magnitude != np.inf)
    n = int(np.count_nonzero(beyond))
    counts.append((n, int(values.size)))
    if n:
        values = np.where(beyond, np.copysign(values.dtype.type(top), values), values)
    return values


def _store_dataset(ds, path, fmt, compression="auto"):
    # Dask-backed variables are written one at a time: computed together, a block read once
    # for two variables (a cube and its resampled copy) stays in memory until both are done,
    # which can hold the whole cube. Apart, each streams through in bounded memory.
    ds = _in_zarr_blocks(ds) if fmt == "zarr" else _float16_widened(ds)  # netCDF has none
    clipped = {}
    ds = _packed(ds, clipped)
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

        with dask_threads():
            atomic_write(path, write)
        _say_clipped(clipped, path)
        return path

    every_chunk = _every_chunk_written(first)

    def write_zarr(tmp):
        import zarr

        every_chunk.to_zarr(tmp, mode="w", consolidated=False,
                            encoding=_zarr_encoding(first, compression))
        for group in groups:
            # the coordinates went in with the first pass (sensor positions, the corrected
            # wavelengths' compact form): zarr refuses an encoding for a variable that already
            # exists, so later passes give one for their own variables only
            part = _every_chunk_written(ds[group])
            part.to_zarr(tmp, mode="a", consolidated=False,
                         encoding={k: e for k, e in _zarr_encoding(part, compression).items()
                                   if k not in first.variables})
        # Zarr 3 keeps consolidated metadata in zarr.json as an extension that other readers
        # may ignore ("must_understand": false); it lets xr.open_zarr(path) open the store
        # with its default arguments, quickly and without a warning.
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*[Cc]onsolidated metadata")
            zarr.consolidate_metadata(str(tmp))

    with dask_threads():
        atomic_write_dir(path, write_zarr)
    _say_clipped(clipped, path)
    return path


def _every_chunk_written(ds):
    """``ds`` with every variable but the booleans stored whole in Zarr, none of its chunks
    left out for holding only the fill value: a reader cannot tell a chunk left out from one
    lost, and refuses a store that lacks chunks of valid values
    (:func:`_refuse_missing_chunks`). :func:`_zarr_encoding` says so for the variables it
    gives an encoding; this for the others (a source's own compression kept, a scalar, a
    coordinate). A mask's all-false chunks are still left out: missing, a boolean reads
    false, as snapcorr's reader accepts."""
    out = ds.copy()
    for var in out.variables.values():
        if var.dtype != bool:
            var.encoding = {**var.encoding, "write_empty_chunks": True}
    return out


class PackingClipWarning(UserWarning):
    """Values beyond a uint16 packing's range, or finite values beyond float16's, were stored
    at its ends."""


def _say_clipped(clipped, path):
    """One warning per variable whose packing stored values beyond its range at its ends
    (the counts :func:`_packed` collected while the blocks were written)."""
    for name, (counts, beyond, advice) in clipped.items():
        n = sum(c for c, _ in counts)
        total = sum(t for _, t in counts)
        if n:
            warnings.warn(PackingClipWarning(
                f"{path}: {n} of {total} values of {shown(name)} ({100 * n / total:.3g} %) lie "
                f"beyond {beyond} and are stored at its ends: {advice}"),
                stacklevel=outside_stacklevel())


def _read_netcdf(path, data_file, chunks, what, drop_alpha):
    return _read_xarray(path, "netcdf", chunks)


def _read_zarr(path, data_file, chunks, what, drop_alpha):
    return _read_xarray(path, "zarr", chunks)


def _write_netcdf(ds, path, compression="auto"):
    return _store(ds, path, "netcdf", compression)


def _write_zarr(ds, path, compression="auto"):
    return _store(ds, path, "zarr", compression)


#: netCDF 4 through xarray and h5netcdf (its mark: the ``written_by`` attribute).
NETCDF = FileFormat("netcdf", (".nc",), _read_netcdf, _write_netcdf, marked_as=("netcdf",),
                    holds_datasets=True)
#: Zarr through xarray, a folder (its mark: the root group's ``written_by``).
ZARR = FileFormat("zarr", (".zarr",), _read_zarr, _write_zarr, marked_as=("zarr",),
                  directory=True, holds_datasets=True)


#: The earlier name of :func:`stored_as`.
_stored_as = stored_as
