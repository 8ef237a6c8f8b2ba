"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.blockfile`."""


from snapcorr.files.blockfile import INTERLEAVES as INTERLEAVES
from snapcorr.files.blockfile import RowBlockFile as RowBlockFile
from snapcorr.files.blockfile import lazy_file_array as lazy_file_array

_MOVED_TO = "snapcorr.files.blockfile"

__all__ = [
    "INTERLEAVES",
    "RowBlockFile",
    "lazy_file_array",
]
