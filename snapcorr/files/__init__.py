"""Files: reading and writing cubes, frames and results, safely.

Each format family has its module (:mod:`~snapcorr.files.envi`, :mod:`~snapcorr.files.images`
for TIFF and OpenEXR, :mod:`~snapcorr.files.npy`, :mod:`~snapcorr.files.datasets` for netCDF
and Zarr, :mod:`~snapcorr.files.envi_result`), each with one format object in the registry
:data:`~snapcorr.files.registry.FILE_FORMATS`; the public readers and writers are in
:mod:`~snapcorr.files.api`. Beneath them, format-blind: :mod:`~snapcorr.files.reading` (inputs
checked before they are opened), :mod:`~snapcorr.files.safety` (atomic writes, temporaries,
signals), :mod:`~snapcorr.files.marks` (the writer's mark), :mod:`~snapcorr.files.outputs`
(what is checked before anything is written), :mod:`~snapcorr.files.png` and
:mod:`~snapcorr.files.toml`.
"""

from .api import (
    read_cube,
    read_cube_and_mask,
    read_dataset,
    read_frame,
    row_blocks,
    write_cube,
    write_dataset,
)
from .envi_result import write_envi_result
from .frames import read_frames
from .outputs import check_outputs

__all__ = [
    "check_outputs",
    "read_cube",
    "read_cube_and_mask",
    "read_dataset",
    "read_frame",
    "read_frames",
    "row_blocks",
    "write_cube",
    "write_dataset",
    "write_envi_result",
]
