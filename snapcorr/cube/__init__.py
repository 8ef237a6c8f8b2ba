"""Cubes in and out: the data model, sensor layouts and flat-fielding."""

from .demosaicking import DEMOSAIC_METHODS, demosaic, demosaicking_error
from .flatfield import flatfield
from .frames import read_frames
from .io import (
    FORMATS,
    read_cube,
    read_dataset,
    read_frame,
    row_blocks,
    write_cube,
    write_dataset,
)
from .model import DIMS, check_cube, make_cube
from .mosaic import mosaic_to_cube, sensor_positions
from .sensor import LAYOUTS, Sensor

__all__ = [
    "DEMOSAIC_METHODS",
    "DIMS",
    "FORMATS",
    "LAYOUTS",
    "Sensor",
    "check_cube",
    "demosaic",
    "demosaicking_error",
    "flatfield",
    "make_cube",
    "mosaic_to_cube",
    "read_cube",
    "read_dataset",
    "read_frame",
    "read_frames",
    "row_blocks",
    "sensor_positions",
    "write_cube",
    "write_dataset",
]
