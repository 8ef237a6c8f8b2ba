"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.envi`."""


from snapcorr.cube.attrs import JSON_PREFIX as JSON_PREFIX
from snapcorr.cube.attrs import _one_line as _one_line
from snapcorr.cube.attrs import _version as _version
from snapcorr.cube.model import POSITION_DIMS as POSITION_DIMS
from snapcorr.files.envi import _ENVI_COMPLEX as _ENVI_COMPLEX
from snapcorr.files.envi import _ENVI_DTYPES as _ENVI_DTYPES
from snapcorr.files.envi import _apply_envi_values as _apply_envi_values
from snapcorr.files.envi import _envi_data_file as _envi_data_file
from snapcorr.files.envi import _envi_header as _envi_header
from snapcorr.files.envi import _envi_int as _envi_int
from snapcorr.files.envi import _envi_list as _envi_list
from snapcorr.files.envi import _envi_numbers as _envi_numbers
from snapcorr.files.envi import _envi_position_keys as _envi_position_keys
from snapcorr.files.envi import _envi_repeated_keys as _envi_repeated_keys
from snapcorr.files.envi import _envi_values as _envi_values
from snapcorr.files.envi import _quiet_spectral as _quiet_spectral
from snapcorr.files.envi import _read_envi as _read_envi
from snapcorr.files.envi import _same_file as _same_file
from snapcorr.files.envi import _write_envi as _write_envi
from snapcorr.files.reading import check_input as check_input
from snapcorr.files.safety import atomic_write_files as atomic_write_files
from snapcorr.files.storage import _ENVI_EXTS as _ENVI_EXTS
from snapcorr.files.storage import _File as _File
from snapcorr.files.storage import _from_file as _from_file
from snapcorr.files.storage import _resolve_chunks as _resolve_chunks

_MOVED_TO = "snapcorr.files.envi"

