"""Flat fields in: reading and cleaning them, the optical centre and radial profiles, the
onsets of vignetting and the vignetting circle of Eq. (26) they give.

The names of the earlier module ``snapcorr.calibrate.flats`` (now
:mod:`~snapcorr.calibrate.flats.cleaning` and :mod:`~snapcorr.calibrate.flats.radial`) stay
importable from here.
"""

from .cleaning import GAIN_LIT_FRACTION as GAIN_LIT_FRACTION
from .cleaning import OUTLIER_SIGMA as OUTLIER_SIGMA
from .cleaning import check_mosaic_sensor as check_mosaic_sensor
from .cleaning import clean_flat, noise_model, read_flat, remove_band_gains
from .onset_fit import OnsetFit, solve_vignetting_circle
from .onsets import Onset, detect_onset
from .radial import RadialProfile, estimate_center, estimate_center_rc, radial_profile

__all__ = [
    "Onset",
    "OnsetFit",
    "RadialProfile",
    "clean_flat",
    "detect_onset",
    "estimate_center",
    "estimate_center_rc",
    "noise_model",
    "radial_profile",
    "read_flat",
    "remove_band_gains",
    "solve_vignetting_circle",
]
