"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.datasets`."""


from snapcorr.cube.attrs import _mark as _mark
from snapcorr.cube.attrs import _one_line as _one_line
from snapcorr.cube.attrs import decode_attrs as decode_attrs
from snapcorr.cube.attrs import encode_attrs as encode_attrs
from snapcorr.cube.derived import rebuildable as rebuildable
from snapcorr.cube.derived import with_fwhm_table as with_fwhm_table
from snapcorr.cube.model import DIMS as DIMS
from snapcorr.files.chunks import _zarr_consolidated as _zarr_consolidated
from snapcorr.files.datasets import _GEOMETRY_UNITS as _GEOMETRY_UNITS
from snapcorr.files.datasets import COMPRESSIONS as COMPRESSIONS
from snapcorr.files.datasets import COMPUTED_WITH as COMPUTED_WITH
from snapcorr.files.datasets import COUNT_UNITS as COUNT_UNITS
from snapcorr.files.datasets import FLOAT16_MAX as FLOAT16_MAX
from snapcorr.files.datasets import PACKED_FILL as PACKED_FILL
from snapcorr.files.datasets import PACKED_TOP as PACKED_TOP
from snapcorr.files.datasets import PACKING as PACKING
from snapcorr.files.datasets import RATIO_PACK_RANGE as RATIO_PACK_RANGE
from snapcorr.files.datasets import RAW_NAMES as RAW_NAMES
from snapcorr.files.datasets import STORAGE_DTYPES as STORAGE_DTYPES
from snapcorr.files.datasets import STORAGE_LAYOUT as STORAGE_LAYOUT
from snapcorr.files.datasets import STORED_FROM as STORED_FROM
from snapcorr.files.datasets import STORED_TYPE as STORED_TYPE
from snapcorr.files.datasets import _compresses as _compresses
from snapcorr.files.datasets import _compressible as _compressible
from snapcorr.files.datasets import _encoded as _encoded
from snapcorr.files.datasets import _hdf5_chunks as _hdf5_chunks
from snapcorr.files.datasets import _holds_values as _holds_values
from snapcorr.files.datasets import _in_counts as _in_counts
from snapcorr.files.datasets import _in_zarr_blocks as _in_zarr_blocks
from snapcorr.files.datasets import _netcdf_encoding as _netcdf_encoding
from snapcorr.files.datasets import _netcdf_engine as _netcdf_engine
from snapcorr.files.datasets import _open_dataset as _open_dataset
from snapcorr.files.datasets import _pack_range as _pack_range
from snapcorr.files.datasets import _read_xarray as _read_xarray
from snapcorr.files.datasets import _rows as _rows
from snapcorr.files.datasets import _storage_keys as _storage_keys
from snapcorr.files.datasets import _store as _store
from snapcorr.files.datasets import _store_dataset as _store_dataset
from snapcorr.files.datasets import _stored_as as _stored_as
from snapcorr.files.datasets import _to_dataset as _to_dataset
from snapcorr.files.datasets import _write_groups as _write_groups
from snapcorr.files.datasets import _zarr_blocks as _zarr_blocks
from snapcorr.files.datasets import _zarr_encoding as _zarr_encoding
from snapcorr.files.datasets import check_storage as check_storage
from snapcorr.files.datasets import refuse_packed_counts as refuse_packed_counts
from snapcorr.files.safety import atomic_write as atomic_write
from snapcorr.files.safety import atomic_write_dir as atomic_write_dir
from snapcorr.files.storage import _File as _File
from snapcorr.files.storage import _Rows as _Rows

_MOVED_TO = "snapcorr.files.datasets"

__all__ = [
    "COMPRESSIONS",
    "COMPUTED_WITH",
    "STORAGE_DTYPES",
    "STORED_FROM",
    "check_storage",
    "refuse_packed_counts",
]
