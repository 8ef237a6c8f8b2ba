"""The exit-pupil fit: the exit pupil distance ``x`` and the filters' effective index from
cubes of a spectral target (:func:`~snapcorr.calibrate.pupil.locate.locate_pupil`), its
stages, the target models and the precision a target can give."""

from .locate import (
    CANDIDATE_TARGETS,
    FeaturelessTargetError,
    ImpreciseTargetError,
    Precision,
    PupilFit,
    estimate_target_center,
    estimate_target_center_rc,
    locate_pupil,
    pupil_precision,
)
from .precision import OutsideChartError, colour_chart_precision

__all__ = [
    "CANDIDATE_TARGETS",
    "FeaturelessTargetError",
    "ImpreciseTargetError",
    "OutsideChartError",
    "Precision",
    "PupilFit",
    "colour_chart_precision",
    "estimate_target_center",
    "estimate_target_center_rc",
    "locate_pupil",
    "pupil_precision",
]
