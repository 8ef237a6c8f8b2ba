"""A lens profile from flat fields: the joint fit of the vignetting circles, the choice of the
model and of the estimator, the stages of a calibration and its record."""

from .calibration import LensCalibration, calibrate_lens
from .choice import ModelVerdict
from .joint_fit import CIRCLE_MODELS, ModelFit

__all__ = ["CIRCLE_MODELS", "LensCalibration", "ModelFit", "ModelVerdict", "calibrate_lens"]
