"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.npy`."""


from snapcorr.cube.attrs import _one_line as _one_line
from snapcorr.cube.model import DIMS as DIMS
from snapcorr.cube.model import POSITION_DIMS as POSITION_DIMS
from snapcorr.files.npy import _npy_found as _npy_found
from snapcorr.files.npy import _npy_layout as _npy_layout
from snapcorr.files.npy import _read_npy as _read_npy
from snapcorr.files.npy import _read_sidecar as _read_sidecar
from snapcorr.files.npy import _write_npy as _write_npy
from snapcorr.files.reading import _sidecar as _sidecar
from snapcorr.files.reading import check_input as check_input
from snapcorr.files.safety import atomic_write_files as atomic_write_files
from snapcorr.files.storage import _File as _File
from snapcorr.files.storage import _from_file as _from_file
from snapcorr.files.storage import _lazy_or_loaded as _lazy_or_loaded
from snapcorr.files.storage import _resolve_chunks as _resolve_chunks

_MOVED_TO = "snapcorr.files.npy"

