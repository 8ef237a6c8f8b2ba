"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.locate`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.locate import (
    AOI_VALIDITY_DEG,
    CANDIDATE_TARGETS,
    DEFAULT_TOLERANCE_NM,
    EDGE_CRA_DEG,
    HELDOUT_SKIP,
    IN_MEMORY_BYTES,
    LAMP_LINES_NM,
    MAX_REL_STDERR,
    MIN_DELTA_CHI2,
    MIN_HELDOUT_SIGMA,
    N_EFF_P,
    N_EFF_REL_STDERR,
    PUPIL_CHI2_GAIN,
    RARE_EARTH_BANDS,
    FeaturelessTargetError,
    ImpreciseTargetError,
    Lens,
    Precision,
    PupilFit,
    TargetModel,
    TargetPrecision,
    _annuli,
    _check_cubes,
    _index_ladder,
    _max_shift_rel,
    _one_blas_thread,
    _Problem,
    accepts_center_rc,
    check_modelled,
    choose_pupil,
    colour_filter,
    estimate_target_center,
    line_lamp,
    locate_pupil,
    pupil_precision,
    rare_earth_glass,
    scaled_circles,
    target_precision,
    white_tile,
)

_MOVED_TO = "snapcorr.calibrate.pupil.locate"

__all__ = [
    "CANDIDATE_TARGETS",
    "FeaturelessTargetError",
    "ImpreciseTargetError",
    "Precision",
    "PupilFit",
    "estimate_target_center",
    "locate_pupil",
    "pupil_precision",
]
