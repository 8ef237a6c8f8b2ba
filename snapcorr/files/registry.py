"""The file formats snapcorr reads and writes, by name and by the ending of a file's name.

Each format family's module exposes its format object
(:class:`~snapcorr.files.storage.FileFormat`: name, suffixes, reader, writer, the targets it
writes and how they carry snapcorr's mark); :data:`FILE_FORMATS` collects them, and
:func:`format_of` finds a path's (an ENVI data file given instead of its header names the
header), and :func:`input_files` the files that belong to an input (what a write of its format
makes, and what its readers may take for its data).
"""

from __future__ import annotations

import os
from pathlib import Path

from .datasets import NETCDF, ZARR
from .envi import ENVI
from .images import EXR, TIFF
from .npy import NPY
from .storage import _ENVI_DATA, _ENVI_EXTS

__all__ = ["FILE_FORMATS", "FORMATS", "format_by_suffix", "format_of", "input_files"]

#: Format name -> its :class:`~snapcorr.files.storage.FileFormat`.
FILE_FORMATS = {f.name: f for f in (ENVI, TIFF, EXR, NETCDF, ZARR, NPY)}

#: Suffix (lower case) -> format name, every suffix snapcorr reads and writes.
FORMATS = {suffix: f.name for f in FILE_FORMATS.values() for suffix in f.suffixes}


def format_by_suffix(suffix):
    """The :class:`~snapcorr.files.storage.FileFormat` of a name's ending (``".nc"``, any
    case), or None."""
    name = FORMATS.get(str(suffix).lower())
    return None if name is None else FILE_FORMATS[name]


def format_of(path, what="cube"):
    """``(format, main path, data file or None)`` of ``path``; an ENVI data file given
    instead of its header names the header as main path and itself as the data file.

    Parameters
    ----------
    path : str or Path
    what : str
        What the file holds, for the messages ("cube", "frame", ...).

    Returns
    -------
    (FileFormat, Path, Path or None)

    Raises
    ------
    ValueError
        An ending snapcorr does not know, or ENVI data without a header.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in _ENVI_DATA:
        if not os.path.lexists(path.with_suffix(".hdr")):
            raise ValueError(f"{path} looks like ENVI data but has no header "
                             f"{path.with_suffix('.hdr').name} next to it; an ENVI {what} is "
                             "read through its header")
        return FILE_FORMATS["envi"], path.with_suffix(".hdr"), path
    found = format_by_suffix(suffix)
    if found is None:
        known = ", ".join(sorted(FORMATS))
        raise ValueError(f"unknown {what.replace(' ', '-')} format {path.suffix or '(none)'!r} "
                         f"for {path}; snapcorr reads and writes {known}")
    return found, path, None


def _format(path, what="cube"):
    """``(format name, main path, data file or None)``: :func:`format_of` by name."""
    found, path, data_file = format_of(path, what)
    return found.name, path, data_file


def _envi_data_files(hdr):
    """The data files ENVI readers may take for the header ``hdr``: those that exist under
    any name they look for (Spectral Python's, the interleaves', in either case)."""
    names = [*_ENVI_EXTS, ".bsq", ".bil", ".bip"]
    return [c for e in names for c in {hdr.with_suffix(e), hdr.with_suffix(e.upper())}
            if c != hdr and c.is_file()]


#: Format name -> the files its readers may take for an input beyond what a write makes
#: (``format.targets``), for a format whose readers look further.
_READ_ALSO = {"envi": _envi_data_files}


def input_files(path):
    """The files that belong to the input ``path``, itself first: every path its format
    writes (:attr:`~snapcorr.files.storage.FileFormat.targets`: an ENVI header's data file, a
    ``.npy``'s sidecar), the files its readers may take for its data (an ENVI header's data
    under other names), and the header of an ENVI data file given instead of it. An input of
    no registered format (a TOML, a PNG) is its own only file.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    list of Path
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in _ENVI_DATA:  # ENVI data given instead of its header, which may be missing
        found, main = FILE_FORMATS["envi"], path.with_suffix(".hdr")
    else:
        found, main = format_by_suffix(suffix), path
    if found is None:
        return [path]
    out = [path]
    also = _READ_ALSO.get(found.name)
    for p in [*found.targets(main), *(also(main) if also else ())]:
        if p not in out:
            out.append(p)
    return out
