"""Lens characterisation from flat fields (Goossens et al. 2019, Sec. 2.7 and 3.2)."""

# The earlier module of this name, loaded first: a later import of it would otherwise bind the
# module over the function pupil_precision below.
from . import pupil_precision as _pupil_precision_module  # noqa: F401
from .flats.cleaning import clean_flat, noise_model, read_flat, remove_band_gains
from .flats.onset_fit import OnsetFit, solve_vignetting_circle
from .flats.onsets import Onset, detect_onset
from .flats.radial import RadialProfile, estimate_center, estimate_center_rc, radial_profile
from .lens.calibration import METHODS, LensCalibration, calibrate_lens
from .lens.choice import ModelVerdict
from .lens.joint_fit import ModelFit
from .pupil.locate import (
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
from .pupil.precision import OutsideChartError, colour_chart_precision
from .unknown_lens import LensAndPupil, calibrate_with_target

__all__ = [
    "CANDIDATE_TARGETS",
    "METHODS",
    "FeaturelessTargetError",
    "ImpreciseTargetError",
    "LensAndPupil",
    "LensCalibration",
    "ModelFit",
    "ModelVerdict",
    "Onset",
    "OnsetFit",
    "OutsideChartError",
    "Precision",
    "PupilFit",
    "RadialProfile",
    "calibrate_lens",
    "calibrate_with_target",
    "clean_flat",
    "colour_chart_precision",
    "detect_onset",
    "estimate_center",
    "estimate_center_rc",
    "estimate_target_center",
    "estimate_target_center_rc",
    "locate_pupil",
    "noise_model",
    "pupil_precision",
    "radial_profile",
    "read_flat",
    "remove_band_gains",
    "solve_vignetting_circle",
]
