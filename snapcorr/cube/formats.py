"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.storage`."""


from snapcorr.cube.model import DIMS as DIMS
from snapcorr.files.blockfile import RowBlockFile as RowBlockFile
from snapcorr.files.blockfile import lazy_file_array as lazy_file_array
from snapcorr.files.reading import _sidecar as _sidecar
from snapcorr.files.registry import FORMATS as FORMATS
from snapcorr.files.registry import _format as _format
from snapcorr.files.storage import _ENVI_DATA as _ENVI_DATA
from snapcorr.files.storage import _ENVI_EXTS as _ENVI_EXTS
from snapcorr.files.storage import UNITS_TO_NM as UNITS_TO_NM
from snapcorr.files.storage import _Blocks as _Blocks
from snapcorr.files.storage import _File as _File
from snapcorr.files.storage import _file_token as _file_token
from snapcorr.files.storage import _from_file as _from_file
from snapcorr.files.storage import _lazy_or_loaded as _lazy_or_loaded
from snapcorr.files.storage import _resolve_chunks as _resolve_chunks
from snapcorr.files.storage import _Rows as _Rows
from snapcorr.files.storage import _rows_per_block as _rows_per_block
from snapcorr.files.storage import _to_nm as _to_nm

_MOVED_TO = "snapcorr.files.storage"

__all__ = [
    "FORMATS",
    "UNITS_TO_NM",
]
