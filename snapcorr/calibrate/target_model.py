"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.target_model`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.target_model import (
    KERNEL_STEP_FWHM,
    N_REF,
    ONSET_NODES,
    PRIOR_SD,
    PROFILE_CUT,
    PROFILE_REACH,
    PROFILES,
    TRANSFORMS,
    EffectiveIndexWarning,
    Lens,
    PupilCutOffError,
    RadialBins,
    TargetModel,
    accepts_center_rc,
    kernel_bins,
    kernel_bins_batch,
    radial_bins,
    rebin,
    scaled_circles,
)

_MOVED_TO = "snapcorr.calibrate.pupil.target_model"

__all__ = [
    "RadialBins",
    "TargetModel",
    "radial_bins",
    "rebin",
]
