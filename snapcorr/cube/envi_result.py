"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.envi_result`."""


from snapcorr.cube.attrs import JSON_PREFIX as JSON_PREFIX
from snapcorr.cube.attrs import _json_attrs as _json_attrs
from snapcorr.cube.attrs import _positions as _positions
from snapcorr.cube.attrs import _version as _version
from snapcorr.files.envi import _envi_position_keys as _envi_position_keys
from snapcorr.files.envi import _quiet_spectral as _quiet_spectral
from snapcorr.files.envi_result import _ONE_PER_BAND as _ONE_PER_BAND
from snapcorr.files.envi_result import IMAGES as IMAGES
from snapcorr.files.envi_result import _as_image as _as_image
from snapcorr.files.envi_result import _header as _header
from snapcorr.files.envi_result import _write_image as _write_image
from snapcorr.files.envi_result import write_envi_result as write_envi_result
from snapcorr.files.outputs import _check_targets as _check_targets
from snapcorr.files.outputs import _check_writable as _check_writable
from snapcorr.files.safety import atomic_write_files as atomic_write_files

_MOVED_TO = "snapcorr.files.envi_result"

__all__ = [
    "write_envi_result",
]
