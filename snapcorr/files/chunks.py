"""Whether a stored file holds every chunk it declares: Zarr stores (a chunk left out reads as
the array's fill value) and netCDF-4 files (HDF5 reads an unwritten chunk as its fill value,
0 by default). Where that value is a datum, not a mark of missing data, the file is refused
before anything is read (a copied-in-part store read as zeros, silently). Also: an input chunk
that cannot be decoded, said of the input, and the stored types a format has not got (float16
in netCDF, stored as float32)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._validation import parse_json


def _zarr_consolidated(path):
    """Whether the store has consolidated metadata (Zarr 3 inline, or Zarr 2 .zmetadata)."""
    meta = Path(path) / "zarr.json"
    if meta.is_file():
        try:
            return parse_json(meta.read_text(encoding="utf-8")).get(
                "consolidated_metadata") is not None
        except (OSError, ValueError, AttributeError):
            return False
    return (Path(path) / ".zmetadata").is_file()


def _fill_is_missing(arr, cf=True):
    """Whether a Zarr array's fill value reads as missing rather than as a value: booleans
    (snapcorr leaves out a mask's all-false chunks), floats whose fill value is NaN and,
    with ``cf`` (read through xarray, which masks it), a fill value that is the CF
    ``_FillValue`` (Zarr 2's fill value is; Zarr 3's when the attributes say so)."""
    fill = arr.fill_value
    if arr.dtype == bool:
        return True
    if fill is None:
        return False
    if arr.dtype.kind == "f" and np.isnan(fill):
        return True
    if not cf:
        return False
    if arr.metadata.zarr_format == 2:
        return True
    said = arr.attrs.get("_FillValue", arr.attrs.get("missing_value"))
    try:
        return said is not None and bool(np.all(np.asarray(said, arr.dtype) == fill))
    except (TypeError, ValueError, OverflowError):
        return False


#: Grids of more chunks (or shards) than this many times the files in the array's folder, plus
#: this many, are not walked key by key: they lack most of their chunks (a store declaring 4e10
#: chunks of which a few exist kept the walk busy for minutes).
_WALK_FACTOR = 4


def _missing_chunks(arr, folder):
    """``(missing, all)``: how many of a Zarr array's chunks are not stored in its ``folder``,
    from a listing of its files and, where it is sharded, each shard's index (no data read;
    zarr's own ``nchunks_initialized`` compares each key with a list of them, quadratic: 7.9 s
    for 20 000 chunks, against 2.7 s here, nearly all of it listing their folders). Only the
    files named as chunks (or shards) of the grid count; the array's metadata (``zarr.json``,
    ``.zarray``, ``.zattrs``) and anything else in the folder do not. ``all`` counts the
    chunks overlapping the array. A grid far larger than the files listed is not walked:
    only the listed files are looked up (and each listed shard's index read)."""
    import itertools
    import math
    import os

    grid = [math.ceil(n / c) for n, c in zip(arr.shape, arr.shards or arr.chunks,
                                               strict=True)]
    stored = set()
    for top, _, files in os.walk(folder):
        rel = os.path.relpath(top, folder)
        prefix = "" if rel == "." else rel.replace(os.sep, "/") + "/"
        stored.update(prefix + f for f in files)
    every = math.prod(grid)
    per = ([s // c for s, c in zip(arr.shards, arr.chunks, strict=True)] if arr.shards
           else [1] * arr.ndim)
    total = math.prod(math.ceil(n / c) for n, c in zip(arr.shape, arr.chunks, strict=True))
    if every > _WALK_FACTOR * len(stored) + 1000:  # most are missing: no walk needed
        held = 0
        for key in stored:
            c = _chunk_coords(arr, key, grid)
            if c is not None:  # a chunk, or a shard less the inner chunks its index lacks
                held += _inside(arr, c, per) - (
                    _unwritten_in_shard(arr, Path(folder) / key, c, per) if arr.shards else 0)
        return total - held, total
    missing = 0
    for c in itertools.product(*map(range, grid)):
        key = arr.metadata.encode_chunk_key(c)
        if key not in stored:
            missing += _inside(arr, c, per)
        elif arr.shards:
            missing += _unwritten_in_shard(arr, Path(folder) / key, c, per)
    return missing, total


def _chunk_coords(arr, key, grid):
    """The grid position of the chunk (or shard) a file's ``key`` (its path in the array's
    folder) names, or None where it names none of the grid (metadata, another file)."""
    import re

    coords = tuple(int(d) for d in re.findall(r"\d+", key))
    if len(coords) != len(grid) or any(i >= n for i, n in zip(coords, grid, strict=True)):
        return None
    return coords if arr.metadata.encode_chunk_key(coords) == key else None


def _inside(arr, shard, per):
    """How many of a shard's ``per`` inner chunks (1 if not sharded) overlap the array."""
    import math

    return math.prod(min(p, -(-(n - s * p * c) // c)) for n, s, p, c in
                     zip(arr.shape, shard, per, arr.chunks, strict=True))


def _unwritten_in_shard(arr, path, shard, per):
    """How many inner chunks overlapping the array the shard file at ``path`` lacks, from its
    index (a few bytes at its end or start); 0 where its index cannot be read (zarr's reader
    then says what is wrong)."""
    try:
        from zarr.core.buffer import default_buffer_prototype
        from zarr.core.sync import sync

        codec = arr.metadata.codecs[0]
        size = codec._shard_index_size(tuple(per))
        with open(path, "rb") as fh:
            if codec.index_location.value == "end":
                fh.seek(-size, os.SEEK_END)
            raw = fh.read(size)
        index = sync(codec._decode_shard_index(
            default_buffer_prototype().buffer.from_bytes(raw), tuple(per)))
        have = np.asarray(index.get_full_chunk_map(), bool)
    except Exception:  # an index zarr's own reader will judge
        return 0
    lim = tuple(slice(0, min(p, -(-(n - s * p * c) // c))) for n, s, p, c in
                zip(arr.shape, shard, per, arr.chunks, strict=True))
    return int((~have[lim]).sum())


def _fill_said(arr):
    """The value a missing chunk of ``arr`` reads as, as said: its fill value, or 0 where it
    states none (a Zarr 2 fill value of null)."""
    if arr.fill_value is None:
        return "0 (it states no fill value)"
    return f"its fill value {np.asarray(arr.fill_value).tolist()!r}"


class _IncompleteStore(ValueError):
    """A Zarr store or netCDF-4 file lacks chunks that would read as valid values
    (:func:`_refuse_missing_chunks`, :func:`_refuse_unwritten_hdf5_chunks`)."""


def _refuse_missing_chunks(path, arrays, cf=True, whole=False):
    """Refuse a Zarr store whose arrays lack chunks that would read as valid values.

    Zarr reads a chunk missing from the store as the array's fill value. Where that is a
    valid datum (integers, floats with a fill value other than NaN) a deleted or never
    written chunk would read as a block of, say, zeros, with nothing to tell it from data.
    Arrays of two or more dims are checked (an image's values, a stream's frames, the
    sensor positions); scalars and coordinates, whose all-fill chunks writers leave out (a
    count of zero masked values), are not. Arrays whose fill value reads as missing
    (:func:`_fill_is_missing`) are not refused either.

    Parameters
    ----------
    path : str or Path
        The store, for the message.
    arrays : iterable of (str, path, zarr.Array)
        Its arrays: the name, the folder holding the array's files, the array.
    cf : bool
        They are read through xarray, which masks a CF ``_FillValue`` (NaN, missing).
    whole : bool
        The store is snapcorr's (its ``written_by`` mark), which writes every chunk but a
        mask's all-false ones: a float array's missing chunk, NaN on reading, is refused too.

    Raises
    ------
    ValueError
        Naming the store, the variable and how many chunks it lacks.
    """
    for name, folder, arr in arrays:
        # a store snapcorr wrote (``whole``) has every chunk but a mask's all-false ones:
        # one missing read as NaN, silently (a chunk deleted, its keys renamed)
        exempt = arr.dtype == bool if whole else _fill_is_missing(arr, cf)
        if arr.ndim < 2 or exempt:
            continue
        missing, every = _missing_chunks(arr, Path(folder))
        if missing > 0:
            raise _IncompleteStore(
                f"{path}: variable {name!r} lacks {missing} of its {every} "
                f"chunks in the store; Zarr would read them as {_fill_said(arr)}, "
                + ("missing values where snapcorr, which wrote the store, wrote data"
                   if _fill_is_missing(arr, cf) else f"a valid {arr.dtype} value")
                + ", so the data read could be wrong: restore the "
                "missing chunks, or, where they were left out for holding only that value (as "
                "Zarr's writers do by default, and snapcorr's did before it wrote every "
                "chunk), copy the store with them written: xarray.open_zarr(store).to_zarr("
                "copy, write_empty_chunks=True)")


def _refuse_unwritten_hdf5_chunks(path):
    """Refuse a netCDF-4 (HDF5) file whose variables of two or more dims lack chunks (or, not
    chunked, their storage) that would read as valid values: HDF5 reads a chunk never
    written (a writer stopped part way, a variable created and not filled) as the fill
    value, 0 unless one is set. The count comes from the chunk index (no data read). As for
    Zarr (:func:`_refuse_missing_chunks`), a fill value that reads as missing (NaN, the CF
    ``_FillValue`` xarray masks) is accepted; snapcorr writes every chunk."""
    import math

    import h5py

    try:
        f = h5py.File(path, "r")
    except Exception:  # not HDF5 after all: xarray's open says what it is
        return
    with f:
        for name, d in f.items():
            if not isinstance(d, h5py.Dataset) or d.ndim < 2 or d.size == 0:
                continue
            fill = d.fillvalue
            if d.dtype.kind not in "iuf" or (d.dtype.kind == "f" and np.isnan(fill)):
                continue
            said = d.attrs.get("_FillValue", d.attrs.get("missing_value"))
            if said is not None and bool(np.all(np.asarray(said) == fill)):
                continue
            if d.chunks is None:
                every = 1
                missing = int(d.id.get_storage_size() == 0)
            else:
                every = math.prod(math.ceil(n / c) for n, c in zip(d.shape, d.chunks,
                                                                    strict=True))
                missing = every - d.id.get_num_chunks()
            if missing > 0:
                raise _IncompleteStore(
                    f"{path}: variable {name!r} lacks {missing} of its {every} chunks, never "
                    f"written; HDF5 would read them as its fill value "
                    f"{np.asarray(fill).tolist()!r}, a valid {d.dtype} value, so the data "
                    "read would be wrong: the file is incomplete (its writer stopped part "
                    "way?); write it again")


def _refuse_incomplete_zarr(path):
    """:func:`_refuse_missing_chunks` for the arrays of the Zarr store at ``path`` (the root
    group's, those xarray reads)."""
    import zarr

    try:
        group = zarr.open_group(str(path), mode="r", use_consolidated=False)
    except Exception:  # not a group: xarray's open says what it is
        return
    arrays = list(group.arrays())
    ours = str(group.attrs.get("written_by", "")).startswith("snapcorr ")
    _refuse_missing_chunks(path, ((name, Path(path) / name, arr) for name, arr in arrays),
                           whole=ours)
    for name, arr in arrays:
        _refuse_a_chunk_of_another_type(path, name, arr)


def _refuse_a_chunk_of_another_type(path, name, arr):
    """Decode the first chunk of ``arr``: a store whose metadata states another type than its
    chunks hold (``data_type`` edited) fails there with numpy's reshape text, met later where
    the values are first computed. Only the first chunk is read: one copied in from another
    array elsewhere is said where it is read (the command line's ``_message``)."""
    if arr.size == 0 or arr.ndim == 0:
        return
    first = tuple(slice(0, min(c, s)) for c, s in zip(arr.chunks, arr.shape, strict=True))
    try:
        arr[first]
    except ValueError as err:
        if "reshape" not in str(err):
            raise
        raise ValueError(
            f"{path}: variable {name!r}: its first chunk does not hold {arr.dtype} values of "
            f"the chunk's shape {tuple(s.stop for s in first)} ({err}): the store's "
            "metadata does not match its chunks (its type changed?); copy the store again "
            "from its source") from None


#: Words of the codecs' errors on bytes they cannot decode (Blosc, Zstandard, zlib, LZ4):
#: an input's damaged chunk, met while the output is computed.
_DAMAGED = ("decompression", "decompress", "dictionary is corrupted", "corrupt", "invalid "
            "stored block", "incorrect header check", "checksum")


def damaged_input(text):
    """Whether a codec's error ``text`` says it met bytes it cannot decode."""
    return any(w in text.lower() for w in _DAMAGED)


def damaged_input_said(err, text, source=None):
    """What to say of an input chunk that cannot be decoded (``text``: ``err``'s, on one line;
    ``source``: the input store, where it is known)."""
    return (f"a chunk of {'the input ' + str(source) if source else 'an input'} cannot be "
            f"decoded ({type(err).__name__}: {text}): the store is damaged or truncated; copy "
            "it again from its source")


def _damaged_input_error(err, text, source, path):
    """The error of an input chunk that cannot be decoded, met while ``path`` was computed
    (``source``: the input store, where the dataset knows it)."""
    return ValueError(f"{damaged_input_said(err, text, source)}. Nothing was written to {path}")


#: Encoding keys a file read sets for the type it stored a variable as (Zarr's fill value,
#: codecs and their element size, HDF5 filters): dropped where another type is stored.
STORED_TYPE = ("fill_value", "compressors", "compressor", "filters", "serializer", "zlib",
               "complevel", "shuffle", "compression", "compression_opts", "fletcher32")


def _float16_widened(ds):
    """Every float16 variable (data or coordinate, an input's raw copy included) as float32,
    which holds each of its values exactly: netCDF has no 16-bit float, and HDF5's half float
    written into a netCDF-4 file is one netCDF tools cannot read (netCDF4-python crashed on
    it). A float16 asked for as storage is refused before any work (:func:`check_storage`)."""
    names = [n for n, v in ds.variables.items()
             if v.dtype == np.float16 or np.dtype(v.encoding.get("dtype", v.dtype)) == np.float16]
    if not names:
        return ds
    ds = ds.copy()
    for name in names:
        var = ds[name].astype(np.float32) if ds[name].dtype == np.float16 else ds[name]
        var.attrs = {**ds[name].attrs, "stored_as": "float32: every float16 value exactly "
                     "(netCDF has no 16-bit float)"}
        var.encoding = {k: v for k, v in ds[name].encoding.items()
                        if k not in (*STORED_TYPE, "dtype")}
        ds[name] = var
    return ds
