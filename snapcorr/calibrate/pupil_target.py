"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.target`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.target import (
    IN_MEMORY_BYTES,
    N_EFF_START,
    FeaturelessTargetError,
    ImpreciseTargetError,
    _annuli,
    _check_cubes,
    check_center,
    check_modelled,
    check_positive,
    estimate_target_center,
    radial_bins,
)

_MOVED_TO = "snapcorr.calibrate.pupil.target"

__all__ = [
    "FeaturelessTargetError",
    "check_modelled",
    "estimate_target_center",
]
