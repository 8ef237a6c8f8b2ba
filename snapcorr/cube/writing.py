"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.outputs`."""


from snapcorr.files.images import _EXR_EXACT as _EXR_EXACT
from snapcorr.files.images import _TIFF_TYPES as _TIFF_TYPES
from snapcorr.files.marks import _ENVI_MARK as _ENVI_MARK
from snapcorr.files.marks import _META_LIMIT as _META_LIMIT
from snapcorr.files.marks import _ZARR_META as _ZARR_META
from snapcorr.files.marks import _envi_description as _envi_description
from snapcorr.files.marks import _inode as _inode
from snapcorr.files.marks import _is_mark as _is_mark
from snapcorr.files.marks import _is_mark_line as _is_mark_line
from snapcorr.files.marks import _mark_matches as _mark_matches
from snapcorr.files.marks import _netcdf_description as _netcdf_description
from snapcorr.files.marks import _npy_of as _npy_of
from snapcorr.files.marks import _open_regular as _open_regular
from snapcorr.files.marks import _plain as _plain
from snapcorr.files.marks import _read_json as _read_json
from snapcorr.files.marks import _sidecar_description as _sidecar_description
from snapcorr.files.marks import _tie_mark as _tie_mark
from snapcorr.files.marks import _tied_mark as _tied_mark
from snapcorr.files.marks import _written_by_snapcorr as _written_by_snapcorr
from snapcorr.files.marks import _zarr_description as _zarr_description
from snapcorr.files.marks import _zarr_is_ours as _zarr_is_ours
from snapcorr.files.marks import _zarr_root as _zarr_root
from snapcorr.files.outputs import _check_targets as _check_targets
from snapcorr.files.outputs import _check_writable as _check_writable
from snapcorr.files.outputs import _input_family as _input_family
from snapcorr.files.outputs import _targets as _targets
from snapcorr.files.reading import NotRegularFileError as NotRegularFileError
from snapcorr.files.reading import _sidecar as _sidecar
from snapcorr.files.reading import file_kind as file_kind
from snapcorr.files.reading import open_image as open_image
from snapcorr.files.reading import read_regular as read_regular
from snapcorr.files.registry import FILE_FORMATS as _FILE_FORMATS
from snapcorr.files.safety import note_checked as note_checked
from snapcorr.files.safety import refuse_inputs as refuse_inputs
from snapcorr.files.storage import _ENVI_DATA as _ENVI_DATA
from snapcorr.files.storage import _ENVI_EXTS as _ENVI_EXTS

#: Format name -> how its main target carries snapcorr's mark.
_ROLES = {f.name: f.marked_as[0] for f in _FILE_FORMATS.values()}

_MOVED_TO = "snapcorr.files.outputs"

