"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.images`."""


from snapcorr.cube.attrs import _one_line as _one_line
from snapcorr.cube.model import POSITION_DIMS as POSITION_DIMS
from snapcorr.files.images import _CHANNEL as _CHANNEL
from snapcorr.files.images import _CONVERTED_PHOTOMETRIC as _CONVERTED_PHOTOMETRIC
from snapcorr.files.images import _EXR_EXACT as _EXR_EXACT
from snapcorr.files.images import _NUMBERED as _NUMBERED
from snapcorr.files.images import _PLAIN_CHANNEL as _PLAIN_CHANNEL
from snapcorr.files.images import _REFLECTIVE as _REFLECTIVE
from snapcorr.files.images import _TIFF_TYPES as _TIFF_TYPES
from snapcorr.files.images import _channel_name as _channel_name
from snapcorr.files.images import _check_stored as _check_stored
from snapcorr.files.images import _check_tifffile_shape as _check_tifffile_shape
from snapcorr.files.images import _described_dtype as _described_dtype
from snapcorr.files.images import _description as _description
from snapcorr.files.images import _exr_channel_order as _exr_channel_order
from snapcorr.files.images import _oiio_pages as _oiio_pages
from snapcorr.files.images import _pixels as _pixels
from snapcorr.files.images import _read_oiio as _read_oiio
from snapcorr.files.images import _write_oiio as _write_oiio
from snapcorr.files.reading import open_image as open_image
from snapcorr.files.safety import atomic_write as atomic_write
from snapcorr.files.storage import _File as _File

_MOVED_TO = "snapcorr.files.images"

__all__ = [
    "open_image",
]
