"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.distance`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.distance import (
    EDGE_CRA_DEG,
    HELDOUT_SKIP,
    MAX_REL_STDERR,
    MAX_STEP_REL,
    MAX_STEPS,
    MIN_DELTA_CHI2,
    MIN_HELDOUT_SIGMA,
    STEP_TOL,
    EffectiveIndexWarning,
    FeaturelessTargetError,
    _max_shift_rel,
    _one_blas_thread,
    _Problem,
    _solve,
    rebin,
    target_model,
)

_MOVED_TO = "snapcorr.calibrate.pupil.distance"
