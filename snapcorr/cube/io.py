"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.api`."""


from snapcorr._validation import check_wavelengths_nm as check_wavelengths_nm
from snapcorr.cube.attrs import JSON_PREFIX as JSON_PREFIX
from snapcorr.cube.attrs import _decode_positions as _decode_positions
from snapcorr.cube.attrs import _json_attrs as _json_attrs
from snapcorr.cube.attrs import _mark as _mark
from snapcorr.cube.attrs import _one_line as _one_line
from snapcorr.cube.attrs import _positions as _positions
from snapcorr.cube.attrs import _version as _version
from snapcorr.cube.attrs import decode_attrs as decode_attrs
from snapcorr.cube.attrs import encode_attrs as encode_attrs
from snapcorr.cube.model import FWHM_LONG_NAME as FWHM_LONG_NAME
from snapcorr.cube.model import POSITION_ATTRS as POSITION_ATTRS
from snapcorr.cube.model import POSITION_DIMS as POSITION_DIMS
from snapcorr.cube.model import check_cube as check_cube
from snapcorr.cube.model import check_dtype as check_dtype
from snapcorr.cube.model import make_cube as make_cube
from snapcorr.files.api import BLOCK_BYTES as BLOCK_BYTES
from snapcorr.files.api import _as_chunks as _as_chunks
from snapcorr.files.api import _cube_meta as _cube_meta
from snapcorr.files.api import _cube_wavelengths as _cube_wavelengths
from snapcorr.files.api import _read_file as _read_file
from snapcorr.files.api import _to_cube as _to_cube
from snapcorr.files.api import read_cube as read_cube
from snapcorr.files.api import read_cube_and_mask as read_cube_and_mask
from snapcorr.files.api import read_dataset as read_dataset
from snapcorr.files.api import read_frame as read_frame
from snapcorr.files.api import row_blocks as row_blocks
from snapcorr.files.api import write_cube as write_cube
from snapcorr.files.api import write_dataset as write_dataset
from snapcorr.files.datasets import COMPRESSIONS as COMPRESSIONS
from snapcorr.files.datasets import COMPUTED_WITH as COMPUTED_WITH
from snapcorr.files.datasets import STORED_FROM as STORED_FROM
from snapcorr.files.datasets import _encoded as _encoded
from snapcorr.files.datasets import _open_dataset as _open_dataset
from snapcorr.files.datasets import _read_xarray as _read_xarray
from snapcorr.files.datasets import _store as _store
from snapcorr.files.datasets import _stored_as as _stored_as
from snapcorr.files.datasets import _to_dataset as _to_dataset
from snapcorr.files.envi import _envi_position_keys as _envi_position_keys
from snapcorr.files.envi import _quiet_spectral as _quiet_spectral
from snapcorr.files.envi import _read_envi as _read_envi
from snapcorr.files.envi import _write_envi as _write_envi
from snapcorr.files.images import _read_oiio as _read_oiio
from snapcorr.files.images import _write_oiio as _write_oiio
from snapcorr.files.npy import _npy_layout as _npy_layout
from snapcorr.files.npy import _read_npy as _read_npy
from snapcorr.files.npy import _write_npy as _write_npy
from snapcorr.files.outputs import _check_targets as _check_targets
from snapcorr.files.outputs import _check_writable as _check_writable
from snapcorr.files.outputs import _targets as _targets
from snapcorr.files.reading import check_input as check_input
from snapcorr.files.reading import open_image as open_image
from snapcorr.files.registry import FILE_FORMATS as _FILE_FORMATS
from snapcorr.files.registry import FORMATS as FORMATS
from snapcorr.files.registry import _format as _format
from snapcorr.files.storage import _ENVI_DATA as _ENVI_DATA
from snapcorr.files.storage import UNITS_TO_NM as UNITS_TO_NM
from snapcorr.files.storage import _from_file as _from_file
from snapcorr.files.storage import _lazy_or_loaded as _lazy_or_loaded
from snapcorr.files.storage import _resolve_chunks as _resolve_chunks
from snapcorr.files.storage import _Rows as _Rows
from snapcorr.files.storage import _rows_per_block as _rows_per_block
from snapcorr.files.storage import _to_nm as _to_nm

#: Format name -> the writer of a cube in it (not netCDF and Zarr).
_WRITERS = {f.name: f.write for f in _FILE_FORMATS.values() if not f.holds_datasets}

_MOVED_TO = "snapcorr.files.api"

__all__ = [
    "BLOCK_BYTES",
    "FORMATS",
    "read_cube",
    "read_cube_and_mask",
    "read_dataset",
    "read_frame",
    "row_blocks",
    "write_cube",
    "write_dataset",
]
