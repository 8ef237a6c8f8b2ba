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
        _check_sidecar(meta, side, path, list(data.shape[:file_ndim]), data.dtype)
        found.wavelength = meta.get("wavelength_nm")
        found.fwhm = meta.get("fwhm_nm")
        found.name = meta.get("name")
        if meta.get("attrs") is not None:
            found.attrs.update(meta["attrs"])
        for key in POSITION_DIMS:
            if meta.get(key) is not None:
                found.positions[key] = meta[key]
    return found


def _check_sidecar(meta, side, path, shape, dtype):
    """Refuse a sidecar that describes another array than the ``.npy`` holds (its ``shape``, a
    list of whole numbers, or its ``dtype``, the type's name; byte order aside: snapcorr
    writes the machine's own) or whose fields are not of their kind (``name`` a string,
    ``attrs`` and the sensor positions objects)."""
    def refuse(what):
        raise ValueError(f"{path}: its sidecar {side.name} {what}; the two files do not "
                         "belong together or the sidecar is damaged (remove or fix it)")

    said = meta.get("shape")
    if said is not None:
        if not (isinstance(said, list)
                and all(isinstance(n, int) and not isinstance(n, bool) for n in said)):
            refuse(f"gives the shape {said!r}, not a list of whole numbers")
        if said != shape:
            refuse(f"describes shape {said} but the array is {shape}")
    said = meta.get("dtype")
    if said is not None:
        try:
            named = np.dtype(said) if isinstance(said, str) else None
        except TypeError:
            named = None
        if named is None:
            refuse(f"names the dtype {said!r}, which is no numpy type")
        if named.newbyteorder("=") != np.dtype(dtype).newbyteorder("="):
            refuse(f"describes {named} values but the array holds {np.dtype(dtype)}")
    if meta.get("name") is not None and not isinstance(meta["name"], str):
        refuse(f"gives the name {meta['name']!r}, not a string")
    for key in ("attrs", *POSITION_DIMS):
        if meta.get(key) is not None and not isinstance(meta[key], dict):
            refuse(f"gives {key} as {type(meta[key]).__name__}, not a JSON object")


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
