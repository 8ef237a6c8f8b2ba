"""Whether a stored file holds every chunk it declares: Zarr stores (a chunk left out reads as
the array's fill value) and netCDF-4 files (HDF5 reads an unwritten chunk as its fill value,
0 by default). Where that value is a datum, not a mark of missing data, the file is refused
before anything is read (a copied-in-part store read as zeros, silently)."""

from __future__ import annotations

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


def _missing_chunks(arr, folder):
    """``(missing, all)``: how many of a Zarr array's stored objects (chunks, or shards when
    it is sharded) are not in its ``folder``, from a listing of its files (no data read;
    zarr's own ``nchunks_initialized`` compares each key with a list of them, quadratic: 7.9 s
    for 20 000 chunks, against 2.7 s here, nearly all of it listing their folders)."""
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
    found = sum(arr.metadata.encode_chunk_key(c) in stored
                for c in itertools.product(*map(range, grid)))
    return every - found, every


class _IncompleteStore(ValueError):
    """A Zarr store or netCDF-4 file lacks chunks that would read as valid values
    (:func:`_refuse_missing_chunks`, :func:`_refuse_unwritten_hdf5_chunks`)."""


def _refuse_missing_chunks(path, arrays, cf=True):
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

    Raises
    ------
    ValueError
        Naming the store, the variable and how many chunks it lacks.
    """
    for name, folder, arr in arrays:
        if arr.ndim < 2 or _fill_is_missing(arr, cf):
            continue
        missing, every = _missing_chunks(arr, Path(folder))
        if missing > 0:
            raise _IncompleteStore(
                f"{path}: variable {name!r} lacks {missing} of its {every} "
                f"{'shards' if arr.shards else 'chunks'} in the store; "
                f"Zarr would read them as its fill value {np.asarray(arr.fill_value).tolist()!r}"
                f", a valid {arr.dtype} value, so the data read could be wrong: restore the "
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
        group = zarr.open_group(str(path), mode="r")
    except Exception:  # not a group: xarray's open says what it is
        return
    _refuse_missing_chunks(path, ((name, Path(path) / name, arr)
                                  for name, arr in group.arrays()))
