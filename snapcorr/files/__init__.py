"""Files: reading and writing cubes, frames and results, safely.

Each format family has its module (:mod:`~snapcorr.files.envi`, :mod:`~snapcorr.files.images`
for TIFF and OpenEXR, :mod:`~snapcorr.files.npy`, :mod:`~snapcorr.files.datasets` for netCDF
and Zarr, :mod:`~snapcorr.files.envi_result`), each with one format object in the registry
:data:`~snapcorr.files.registry.FILE_FORMATS`; the public readers and writers are in
:mod:`~snapcorr.files.api`. Beneath them, format-blind: :mod:`~snapcorr.files.reading` (inputs
checked before they are opened), :mod:`~snapcorr.files.chunks` (a stored file lacking chunks
refused), :mod:`~snapcorr.files.safety` (atomic writes, temporaries,
signals), :mod:`~snapcorr.files.marks` (the writer's mark), :mod:`~snapcorr.files.outputs`
(what is checked before anything is written), :mod:`~snapcorr.files.png` and
:mod:`~snapcorr.files.toml`.
"""

from .._lazy import lazy_names

#: Public name -> the module that defines it. Loaded at first use: the format-blind modules
#: (safety, reading, marks) import no reader, so the command line starts without them.
_HOMES = {
    "PackingClipWarning": "snapcorr.files.datasets",
    "check_outputs": "snapcorr.files.outputs",
    "read_array": "snapcorr.files.api",
    "read_cube": "snapcorr.files.api",
    "read_cube_and_mask": "snapcorr.files.api",
    "read_dataset": "snapcorr.files.api",
    "read_frame": "snapcorr.files.api",
    "read_frames": "snapcorr.files.frames",
    "row_blocks": "snapcorr.files.api",
    "write_cube": "snapcorr.files.api",
    "write_dataset": "snapcorr.files.api",
    "write_envi_result": "snapcorr.files.envi_result",
}

__all__ = sorted(_HOMES)


__getattr__, __dir__ = lazy_names(__name__, _HOMES)
