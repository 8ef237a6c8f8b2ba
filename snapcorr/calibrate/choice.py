"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.lens.choice`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .lens.choice import (
    FLOOR_REL,
    MAX_REL_ERROR,
    MIN_BIC_GAIN,
    MIN_H_SIGMAS,
    MIN_MODEL_WEIGHT,
    MIN_SHIFT_SIGMAS,
    N_CIRCLES,
    REFERENCE_CWL_NM,
    REFERENCE_N_EFF,
    TOLERANCE_NM,
    EffectiveIndexWarning,
    Lens,
    ModelFit,
    ModelVerdict,
    PupilCutOffError,
    _choice_weight,
    check_circles,
    choose,
    circles_of,
    effective_onsets_deg,
    lens_of,
    mean_shift,
    model_choice_stderr,
    shift_difference_nm,
    shift_stderr_nm,
)

_MOVED_TO = "snapcorr.calibrate.lens.choice"

__all__ = [
    "FLOOR_REL",
    "MAX_REL_ERROR",
    "MIN_BIC_GAIN",
    "MIN_H_SIGMAS",
    "MIN_MODEL_WEIGHT",
    "MIN_SHIFT_SIGMAS",
    "ModelVerdict",
    "check_circles",
    "choose",
    "effective_onsets_deg",
    "model_choice_stderr",
    "shift_difference_nm",
    "shift_stderr_nm",
]
