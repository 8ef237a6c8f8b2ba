"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.measured_target`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.measured_target import (
    GRID_STEP_FWHM,
    PROFILE_CUT,
    MeasuredTargetModel,
    TargetModel,
    target_model,
)

_MOVED_TO = "snapcorr.calibrate.pupil.measured_target"

__all__ = [
    "MeasuredTargetModel",
    "target_model",
]
