"""``.npy`` cubes and frames, with snapcorr's JSON sidecar (``cube.npy.json``).

A C-ordered numeric array is read in blocks of rows with plain file reads (its layout from the
header, :func:`_npy_layout`); any other ``.npy`` through numpy's memory map. The sidecar holds
wavelengths, fwhm, name, attrs and sensor positions; a bare ``.npy`` has none.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from .._validation import parse_json
from ..cube.model import DIMS, POSITION_DIMS
from .attrs import _one_line
from .reading import _sidecar, check_input
from .safety import atomic_write_files
from .storage import (
    FileFormat,
    _File,
    _from_file,
    _lazy_or_loaded,
    _resolve_chunks,
)

# -- reading ---------------------------------------------------------------------------------


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
    if any(n < 0 for n in shape):  # numpy's header reader takes them; nothing else does
        raise ValueError(f"{path}: its header gives the shape {shape}, with a negative size; "
                         "the file is damaged or not written by numpy")
    if fortran or dtype.kind not in "iuf" or len(shape) not in (2, 3) or 0 in shape:
        return None
    if os.path.getsize(path) < offset + int(np.prod(shape)) * dtype.itemsize:
        raise ValueError(f"{path}: the file is shorter than its header's {shape} "
                         f"{dtype.name} array; it is truncated")
    return shape, dtype, offset


def _read_npy(path, chunks):
    """The cube (or frame) of a ``.npy`` and its sidecar; ``chunks`` None (read whole), a dict
    by dim or :class:`~snapcorr.files.storage._Rows`."""
    layout = _npy_layout(path)
    if layout is not None:  # read in row blocks, not through a memory map
        shape, dtype, offset = layout
        file_ndim = len(shape)
        shape = shape if file_ndim == 3 else (*shape, 1)
        chunks = _resolve_chunks(chunks, shape, dtype)
        data = _from_file(path, dtype, shape, offset, "bip",
                          None if chunks is None else {**chunks, "band": -1})
        return _npy_found(path, data, file_ndim)
    try:
        data = np.load(path, mmap_mode="r", allow_pickle=False)
    except Exception as err:  # numpy raises several types for a bad or empty file
        if "pickle" in str(err) or "Python objects" in str(err):  # (never unpickled)
            raise ValueError(f"{path}: holds pickled Python objects, or is not a .npy file "
                             "at all; snapcorr never loads pickles") from None
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
        meta = parse_json(side.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise ValueError(f"{path}: its sidecar {side.name} is not readable JSON "
                         f"({_one_line(err)}); fix or remove it") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: its sidecar {side.name} is not a JSON object; fix or "
                         "remove it")
    return meta


# -- writing ---------------------------------------------------------------------------------


def _write_npy(cube, path, meta, *, interleave):
    data = np.asarray(cube.values)
    text = json.dumps(meta, indent=1)

    def write(folder):
        # through an open file: given a name, numpy.save appends ".npy" to one ending ".NPY"
        with open(folder / path.name, "wb") as f:
            np.save(f, data, allow_pickle=False)
        (folder / _sidecar(path).name).write_text(text, encoding="utf-8")

    atomic_write_files([path, _sidecar(path)], write)


def _npy_targets(path):
    """A ``.npy`` file and its sidecar, ``cube.npy.json``."""
    return [Path(path), _sidecar(path)]


def _read(path, data_file, chunks, what, drop_alpha):
    return _read_npy(path, chunks)


#: NumPy's ``.npy`` with a JSON sidecar (its mark: the sidecar's ``written_by``).
NPY = FileFormat("npy", (".npy",), _read, _write_npy, targets=_npy_targets,
                 marked_as=("npy", "sidecar"))
