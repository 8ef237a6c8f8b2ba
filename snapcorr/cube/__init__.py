"""Cubes in and out: the data model, sensor layouts and flat-fielding.

The names are loaded when first used: the file formats (:mod:`snapcorr.files`) build on the
data model here (:mod:`snapcorr.cube.model`, :mod:`snapcorr.files.attrs`), and importing
that must not load every reader and writer first. Reading and writing files is
:mod:`snapcorr.files`' (re-exported here).
"""

from .._lazy import lazy_names

# ``flatfield`` is also the name of its module: imported here, the function is the attribute
from .flatfield import flatfield as flatfield
from .model import DIMS as DIMS
from .model import check_cube as check_cube
from .model import make_cube as make_cube

#: Public name -> the module that defines it.
_HOMES = {
    "DEMOSAIC_METHODS": "snapcorr.cube.demosaicking",
    "demosaic": "snapcorr.cube.demosaicking",
    "demosaicking_error": "snapcorr.cube.demosaicking",
    "read_frames": "snapcorr.files.frames",
    "FORMATS": "snapcorr.files.registry",
    "read_cube": "snapcorr.files.api",
    "read_dataset": "snapcorr.files.api",
    "read_frame": "snapcorr.files.api",
    "row_blocks": "snapcorr.files.api",
    "write_cube": "snapcorr.files.api",
    "write_dataset": "snapcorr.files.api",
    "mosaic_to_cube": "snapcorr.cube.mosaic",
    "sensor_positions": "snapcorr.cube.mosaic",
    "LAYOUTS": "snapcorr.cube.sensor",
    "Sensor": "snapcorr.cube.sensor",
}

__all__ = sorted([*_HOMES, "DIMS", "check_cube", "flatfield", "make_cube"])


__getattr__, __dir__ = lazy_names(__name__, _HOMES)
