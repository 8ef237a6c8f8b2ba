"""What every format shares: its description, what a reader found, lazy rows.

- :class:`FileFormat`, what the registry (:data:`snapcorr.files.registry.FILE_FORMATS`)
  knows of a format, and ENVI's data-file names (a ``.npy``'s JSON sidecar is
  :func:`~snapcorr.files.reading._sidecar`);
- :class:`_File`, what a reader found (the data and the metadata as the file has them);
- lazy data: raw files (ENVI, ``.npy``) read in blocks of rows (:func:`_from_file`), memory
  maps read block by block (:func:`_lazy_or_loaded`), and ``chunks="rows"`` resolved once a
  reader knows the shape and dtype (:class:`_Rows`);
- wavelength units (:data:`UNITS_TO_NM`, :func:`_to_nm`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._validation import shown
from ..cube.model import DIMS
from .blockfile import RowBlockFile, lazy_file_array

__all__ = ["UNITS_TO_NM", "FileFormat"]


#: Data-file names Spectral Python looks for next to a header, in its order (then the
#: interleave's name, then all of them in upper case).
_ENVI_EXTS = ("", ".img", ".dat", ".sli", ".hyspex", ".raw", ".bin")
#: Data files given instead of their header.
_ENVI_DATA = (".raw", ".img", ".dat", ".bsq", ".bil", ".bip", ".bin", ".sli", ".hyspex")

#: Length units of wavelengths and their factor to nanometres ("unknown" or none: nm).
UNITS_TO_NM = {
    **dict.fromkeys(("nanometers", "nanometer", "nanometres", "nanometre", "nm"), 1.0),
    **dict.fromkeys(("micrometers", "micrometer", "micrometres", "micrometre", "microns",
                     "micron", "um", "\u00b5m", "\u03bcm"), 1e3),
    **dict.fromkeys(("millimeters", "millimeter", "millimetres", "millimetre", "mm"), 1e6),
    **dict.fromkeys(("meters", "meter", "metres", "metre", "m"), 1e9),
}


def _only(path):
    """The one file a format writes at ``path``."""
    return [Path(path)]


@dataclass(frozen=True)
class FileFormat:
    """One file format, as the registry knows it (after xarray's ``BackendEntrypoint``).

    Attributes
    ----------
    name : str
        Its name in messages and in :data:`snapcorr.files.registry.FORMATS` (``"envi"``).
    suffixes : tuple of str
        The names' endings it is known by, lower case (``(".tif", ".tiff")``).
    read : callable
        ``read(path, data_file, chunks, what, drop_alpha)``: what the file holds, a
        :class:`_File` (``data_file``: an ENVI data file given instead of its header).
    write : callable
        Cubes: ``write(cube, path, meta, interleave=...)``; datasets
        (``holds_datasets``): ``write(ds, path, compression)``.
    targets : callable
        ``targets(path)``: every path a write makes (an ENVI header and its data, a
        ``.npy`` and its sidecar), the main one first.
    marked_as : tuple of str
        How each target carries snapcorr's mark, a role of
        :func:`snapcorr.files.marks._written_by_snapcorr` (the last one repeats).
    check_writable : callable or None
        ``check_writable(cube, path, interleave)``: the format's limits, before anything is
        written.
    directory : bool
        Stored as a folder (Zarr).
    holds_datasets : bool
        Stores an ``xarray.Dataset`` with every variable (netCDF, Zarr), not one cube.
    native_byte_order : bool
        Written whole from values in the machine's byte order (OpenImageIO's formats).
    """

    name: str
    suffixes: tuple
    read: Callable
    write: Callable
    targets: Callable = _only
    marked_as: tuple = ()
    check_writable: Callable | None = None
    directory: bool = False
    holds_datasets: bool = False
    native_byte_order: bool = False

    def role(self, index):
        """How the ``index``-th target carries the mark."""
        return self.marked_as[min(index, len(self.marked_as) - 1)]


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
    extras: dict = field(default_factory=dict)  # e.g. a flat-field result's mask


def _rows_per_block(nx, nb, dtype, target_bytes):
    """Rows of ``nx`` pixels of ``nb`` bands of ``dtype`` in a block of about ``target_bytes``,
    at least one; a value counts as at least 4 bytes (computations widen smaller types to
    float32); an empty row (no pixel or no band: refused once read) is one block."""
    row_bytes = nx * nb * max(np.dtype(dtype).itemsize, 4)
    return max(1, target_bytes // row_bytes) if row_bytes > 0 else 1


@dataclass(frozen=True)
class _Rows:
    """``chunks="rows"`` as the readers get it: blocks of whole rows (every x and band) of
    about ``target_bytes``, decided by the reader from the shape and dtype it finds in the
    file's header, so that the file is opened once and the blocks are read as computed."""

    target_bytes: int

    def chunks(self, shape, dtype, dims=DIMS):
        """Dask chunks (a dict by dim) for data of ``shape`` ``(y, x[, band])`` and ``dtype``."""
        nb = shape[2] if len(shape) > 2 else 1
        return {dims[0]: _rows_per_block(shape[1], nb, dtype, self.target_bytes),
                **dict.fromkeys(dims[1:], -1)}


#: A variable held in memory (not dask) of more than this many bytes is stored in Zarr chunks
#: of whole rows of about :data:`ZARR_ROWS_BYTES`: left to zarr, a flat field of a whole
#: 2048 x 1088 x 16 frame was one chunk of 142 MB, decoded whole by every block a reader
#: took (``correct`` zarr to zarr peaked at 783 MiB on it).
ZARR_WHOLE_BYTES = 32 * 2**20
ZARR_ROWS_BYTES = 16 * 2**20


def _zarr_row_chunks(var):
    """``{"chunks": ...}`` for an in-memory ``var`` of two or more dims larger than
    :data:`ZARR_WHOLE_BYTES` (blocks of its first dim), else ``{}`` (a dask variable is
    stored in its blocks, :func:`_zarr_row_blocks`)."""
    if var.chunks is not None or var.ndim < 2 or var.nbytes <= ZARR_WHOLE_BYTES:
        return {}
    row = max(var.nbytes // var.shape[0], 1)
    return {"chunks": (max(1, min(var.shape[0], ZARR_ROWS_BYTES // row)), *var.shape[1:])}


def _zarr_row_blocks(var):
    """``{first dim: rows}`` for a dask ``var`` of two or more dims with a block larger than
    :data:`ZARR_WHOLE_BYTES` (a whole frame computed as one block), to be stored in blocks
    of whole rows of about :data:`ZARR_ROWS_BYTES`; else ``{}``."""
    if var.chunks is None or var.ndim < 2:
        return {}
    block = var.dtype.itemsize * int(np.prod([max(b) for b in var.chunks]))
    if block <= ZARR_WHOLE_BYTES:
        return {}
    row = max(var.nbytes // var.shape[0], 1)
    return {var.dims[0]: max(1, min(var.shape[0], ZARR_ROWS_BYTES // row))}


def _resolve_chunks(chunks, shape, dtype, dims=DIMS):
    """``chunks`` as a dict by dim (or None): :class:`_Rows` decided for ``shape`` and
    ``dtype``, anything else as it is."""
    return chunks.chunks(shape, dtype, dims) if isinstance(chunks, _Rows) else chunks


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
    the memory map reads (it names the dask graph without reading the data). ``chunks``: a
    dict by dim, or :class:`_Rows`."""
    native = array.dtype.newbyteorder("=") if array.dtype.byteorder not in ("=", "|") \
        else array.dtype
    chunks = _resolve_chunks(chunks, array.shape, native, dims)
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
        raise ValueError(f"{where}: units {shown(units)} are not a length (nm, um, mm or m and "
                         "their spellings); pass wavelength_nm or fix the file's units")
    try:
        v = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{where}: values must be numbers, got {values!r:.80}") from None
    return v if scale == 1.0 else np.round(v * scale, 9)


def _from_file(path, dtype, shape, offset, interleave, chunks):
    """The values of a raw file, ``(y, x, band)`` in the machine's byte order: all of them
    (``chunks`` None), or a dask array reading blocks of whole rows as they are computed
    (``chunks`` a dict by dim, or :class:`_Rows`)."""
    source = RowBlockFile(path, dtype, shape, offset, interleave)
    chunks = _resolve_chunks(chunks, shape, source.dtype)
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
