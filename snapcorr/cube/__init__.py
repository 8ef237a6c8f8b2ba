"""Cubes in and out: the data model, sensor layouts and flat-fielding."""

from .flatfield import flatfield
from .model import DIMS, check_cube, make_cube
from .mosaic import mosaic_to_cube, sensor_positions
from .sensor import LAYOUTS, Sensor

__all__ = [
    "DIMS",
    "LAYOUTS",
    "Sensor",
    "check_cube",
    "flatfield",
    "make_cube",
    "mosaic_to_cube",
    "sensor_positions",
]
