"""netCDF and Zarr through xarray: opening a file, finding its cube, storing a Dataset.

- reading: :func:`_open_dataset` (netCDF with h5netcdf, Zarr in its own chunks) and
  :func:`_read_xarray` (the cube, or a frame, among a file's variables);
- writing: :func:`_encoded` (a Dataset ready to store: derived variables left out and listed,
  attributes encoded by :func:`snapcorr.cube.attrs.encode_attrs`, the writer's mark) and
  :func:`_store` (lazy variables one pass at a time, :data:`COMPUTED_WITH` grouping those
  computed together; the compression of :data:`COMPRESSIONS`).
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import xarray as xr

from .._io import atomic_write, atomic_write_dir
from .attrs import _mark, _one_line, decode_attrs, encode_attrs
from .derived import rebuildable, with_fwhm_table
from .formats import _File, _Rows
from .model import DIMS

__all__ = ["COMPRESSIONS", "COMPUTED_WITH", "STORED_FROM", "refuse_packed_counts"]


# -- reading ---------------------------------------------------------------------------------


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


def _netcdf_engine(path):
    """h5netcdf for netCDF-4 (HDF5), SciPy's reader for netCDF-3 (classic, 64-bit offset
    and CDF-5 files begin with ``CDF``), which h5netcdf cannot open."""
    with open(path, "rb") as f:
        return "scipy" if f.read(3) == b"CDF" else "h5netcdf"


def _open_dataset(path, fmt, chunks):
    """The file's Dataset, lazily. ``chunks``: None (each variable read whole when used), a
    dict by dim (dask: netCDF in those chunks, Zarr in its own chunks then rechunked), or
    :class:`~snapcorr.cube.formats._Rows`: opened without dask and without caching, for the
    caller to chunk the variable it reads once it knows its shape (opened with ``chunks={}``
    instead, a contiguous netCDF variable would be one dask chunk, read whole by every block
    cut from it)."""
    if isinstance(chunks, _Rows):
        if fmt == "netcdf":
            return xr.open_dataset(path, engine=_netcdf_engine(path), chunks=None, cache=False)
        return xr.open_dataset(path, engine="zarr", consolidated=_zarr_consolidated(path),
                               chunks=None, cache=False)
    if fmt == "netcdf":
        with warnings.catch_warnings():
            # blocks that split the file's own chunks read some of them twice: a cost, not an
            # error (opened in the file's chunks instead, a contiguous variable would be one
            # block, read whole by every block cut from it)
            warnings.filterwarnings("ignore", message="The specified chunks separate")
            return xr.open_dataset(path, engine=_netcdf_engine(path), chunks=chunks)
    # Zarr: opened in the store's own chunks, then rechunked lazily as asked (asked for
    # directly, chunks that split the stored ones make xarray warn).
    ds = xr.open_zarr(path, consolidated=_zarr_consolidated(path),
                      chunks=None if chunks is None else {})
    if chunks:
        ds = ds.chunk({d: c for d, c in chunks.items() if d in ds.dims})
    return ds


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
    said = ", ".join(f"{k} {np.asarray(v).tolist()!r}" for k, v in packing.items())
    raise ValueError(f"{path}: {var.name} is stored as {stored} with {said}, which a reader "
                     "applies (scaled, or fill values made NaN), so the camera's numbers would "
                     "not be read as they are; store the counts without them, or give the "
                     "variable the units of the physical values it holds")


def _read_xarray(path, fmt, chunks):
    """The cube of a netCDF file or Zarr store (a ``(y, x)`` frame as one band): its
    ``radiance``, ``reflectance`` or ``transmittance``, else its first ``(y, x, band)``
    variable. With :class:`~snapcorr.cube.formats._Rows` chunks, the variable is cut into
    blocks of rows from its shape (each block reads its rows only)."""
    ds = _open_dataset(path, fmt, chunks)
    for var in ds.variables.values():
        var.attrs = decode_attrs(var.attrs)
    cubes = [v for v in ds.data_vars if tuple(ds[v].dims) == DIMS]
    if cubes:
        preferred = [n for n in ("radiance", "reflectance", "transmittance") if n in cubes]
        var = _rows(ds[(preferred or cubes)[0]], chunks)
    else:
        frames = [v for v in ds.data_vars if tuple(ds[v].dims) == ("y", "x")]
        if any(tuple(ds[v].dims) == ("frame", *DIMS) for v in ds.data_vars):
            raise ValueError(f"{path} holds a stream of cubes (frame, y, x, band): open it with "
                             "read_dataset; snapcorr stream --lens LENS --f-number F corrects "
                             "a stream")
        if not frames:
            raise ValueError(f"{path} holds no (y, x, band) variable")
        # chunked first: expand_dims would read a variable that is not a dask array whole
        var = _rows(ds[frames[0]], chunks).expand_dims("band", axis=2)
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
    """``var`` in blocks of rows when ``chunks`` is :class:`~snapcorr.cube.formats._Rows`
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


def _store(ds, path, fmt, compression="auto"):
    try:
        return _store_dataset(ds, path, fmt, compression)
    except (OSError, ValueError, TypeError):
        raise
    except Exception as err:  # the libraries' own error types: report them plainly
        raise ValueError(f"cannot write {path}: {type(err).__name__}: {_one_line(err)}") \
            from None


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
    what a file-to-file run spends its time on. ``compression="none"``: no compressor."""
    from zarr.codecs import BloscCodec

    if compression == "none":
        return {name: {"compressors": None} for name in _compressible(ds, compression)}
    codec = BloscCodec(cname="lz4", clevel=5, shuffle="bitshuffle")
    return {name: {"compressors": [codec]} for name in _compressible(ds, compression)}


def _netcdf_encoding(ds, compression="auto"):
    """DEFLATE level 1 with byte shuffling (readable by every netCDF-4 reader) where it pays:
    integer and boolean variables and stored derived ones for ``"auto"``, every numeric one
    for ``"all"`` (see :func:`write_dataset`); ``"none"`` turns a source's own off."""
    if compression == "none":
        return {name: {"zlib": False} for name in _compressible(ds, compression)}
    return {name: {"zlib": True, "complevel": 1, "shuffle": True}
            for name in _compressible(ds, compression)
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
