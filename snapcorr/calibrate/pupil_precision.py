"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.precision`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.precision import (
    CANDIDATE_TARGETS,
    DEFAULT_TOLERANCE_NM,
    LAMP_LINES_NM,
    MAX_REL_STDERR,
    N_EFF_REL_STDERR,
    PRIOR_SD,
    RARE_EARTH_BANDS,
    Lens,
    Precision,
    RadialBins,
    TargetPrecision,
    _max_shift_rel,
    _one_blas_thread,
    _pinv_solve,
    _project_off,
    _whiten,
    check_modelled,
    colour_filter,
    line_lamp,
    pupil_precision,
    rare_earth_glass,
    target_model,
    target_precision,
    white_tile,
)

_MOVED_TO = "snapcorr.calibrate.pupil.precision"

__all__ = [
    "CANDIDATE_TARGETS",
    "Precision",
    "pupil_precision",
]
