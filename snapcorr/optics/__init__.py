"""Physics of thin-film filters behind a lens: shift law, pupil geometry, kernels, mean shift.

Pure numpy, no file I/O beyond lens profiles; every function broadcasts.
"""

from .goossens2019 import PupilCutOffError, kernel, kernel_asymptotic
from .lens import Lens
from .mean import METHODS, mean_shift, select_method
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
    "METHODS",
    "EffectiveIndexWarning",
    "Lens",
    "PupilCutOffError",
    "ShiftGrid",
    "ShiftTable",
    "aoi_from_shift_deg",
    "kernel",
    "kernel_asymptotic",
    "mean_shift",
    "select_method",
    "shift_nm",
    "tilted_cwl_nm",
]
