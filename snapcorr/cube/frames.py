"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.frames`."""


from snapcorr.files.api import read_frame as read_frame
from snapcorr.files.datasets import _open_dataset as _open_dataset
from snapcorr.files.datasets import refuse_packed_counts as refuse_packed_counts
from snapcorr.files.frames import _NUMBER as _NUMBER
from snapcorr.files.frames import _OIIO_TYPES as _OIIO_TYPES
from snapcorr.files.frames import FRAME_ORDER as FRAME_ORDER
from snapcorr.files.frames import FRAME_SUFFIXES as FRAME_SUFFIXES
from snapcorr.files.frames import _npy_stack as _npy_stack
from snapcorr.files.frames import _page as _page
from snapcorr.files.frames import _plain_zarr as _plain_zarr
from snapcorr.files.frames import _tiff_pages as _tiff_pages
from snapcorr.files.frames import _tokens as _tokens
from snapcorr.files.frames import _xarray_stack as _xarray_stack
from snapcorr.files.frames import natural_order as natural_order
from snapcorr.files.frames import read_frames as read_frames
from snapcorr.files.reading import check_input as check_input
from snapcorr.files.reading import open_image as open_image
from snapcorr.files.registry import FORMATS as FORMATS

_MOVED_TO = "snapcorr.files.frames"

__all__ = [
    "natural_order",
    "read_frames",
]
