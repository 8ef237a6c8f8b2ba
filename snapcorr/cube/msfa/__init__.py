"""Demosaicking a multispectral filter array (MSFA) frame, one module per published method.

Every method takes a 2-D frame (float, NaN where a value is missing), the first sample row and
column of each band in the frame (``y0``, ``x0``) and the tile's size, and returns the
``(rows, cols, bands)`` cube at full resolution. Each keeps the measured value of a band where
it was measured, leaves a missing (NaN) sample out of every estimate and its own value NaN,
and at the frame's edges uses the samples that exist.
"""

from .brauers2006 import weighted_bilinear
from .mihoubi2017 import ppid, pseudo_panchromatic
from .monno2017 import residual_interpolation
from .nearest import tile_replication

__all__ = ["ppid", "pseudo_panchromatic", "residual_interpolation", "tile_replication",
           "weighted_bilinear"]
