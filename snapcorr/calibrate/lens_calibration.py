"""Compatibility re-exports: this module moved to the lens calibration
(:mod:`~snapcorr.calibrate.lens.calibration`), its estimator
(:mod:`~snapcorr.calibrate.lens.estimator`) and its record
(:mod:`~snapcorr.calibrate.lens.table`).

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .lens.calibration import (
    CALIBRATION_METHODS,
    METHODS,
    EffectiveIndexWarning,
    Lens,
    LensCalibration,
    accepts_center_rc,
    calibrate_lens,
    check_center,
    check_mosaic_sensor,
    check_pixel_pitch_um,
    check_positive,
    cra_map,
)
from .lens.estimator import (
    MISFIT_CHI2,
    N_CIRCLES,
    ModelFit,
    _what_sets_it,
    param_names,
)
from .lens.table import (
    _circle_stderrs,
)

_MOVED_TO = "snapcorr.calibrate.lens.calibration"

__all__ = [
    "METHODS",
    "LensCalibration",
    "calibrate_lens",
]
