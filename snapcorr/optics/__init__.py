"""Physics of thin-film filters behind a lens: shift law, pupil geometry, kernels, mean shift.

Pure numpy, no file I/O beyond lens profiles; every function broadcasts.
"""

from .bandwidth import FWHM_METHODS, FwhmTable, response_fwhm
from .chief_ray import cra_deg, cra_map, pixel_cra_deg
from .goossens2019 import PupilCutOffError, kernel, kernel_asymptotic
from .lens import Lens
from .mean import (
    CORRECTION_MODELS,
    MEAN_SHIFT_METHODS,
    METHODS,
    MODELS,
    choose_model,
    mean_shift,
    select_method,
)
from .neff import NeffFit, fit_n_eff
from .profiles import (
    FILTER_PROFILES,
    PROFILES,
    Airy,
    Gaussian,
    MultiLorentzian,
    PiShaped,
    Tabulated,
)
from .response import RESPONSE_METHODS, filter_response
from .shift import (
    AOI_VALIDITY_DEG,
    EffectiveIndexWarning,
    aoi_from_shift_deg,
    shift_nm,
    tilted_cwl_nm,
)
from .table import ShiftGrid, ShiftTable

__all__ = [
    "AOI_VALIDITY_DEG",
    "CORRECTION_MODELS",
    "FILTER_PROFILES",
    "FWHM_METHODS",
    "MEAN_SHIFT_METHODS",
    "METHODS",
    "MODELS",
    "PROFILES",
    "RESPONSE_METHODS",
    "Airy",
    "EffectiveIndexWarning",
    "FwhmTable",
    "Gaussian",
    "Lens",
    "MultiLorentzian",
    "NeffFit",
    "PiShaped",
    "PupilCutOffError",
    "ShiftGrid",
    "ShiftTable",
    "Tabulated",
    "aoi_from_shift_deg",
    "choose_model",
    "cra_deg",
    "cra_map",
    "filter_response",
    "fit_n_eff",
    "kernel",
    "kernel_asymptotic",
    "mean_shift",
    "pixel_cra_deg",
    "response_fwhm",
    "select_method",
    "shift_nm",
    "tilted_cwl_nm",
]
