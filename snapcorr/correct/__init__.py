"""Per-pixel wavelength correction of cubes (Goossens et al. 2019, Eq. 8 and 23)."""

from ..cube.derived import with_fwhm_table
from .core import correct_cube, relative_shift
from .geometry import (
    CubeCRA,
    PlacementError,
    cube_cra,
    cube_cra_deg,
    cube_positions,
    optical_center,
    optical_center_rc,
)
from .resample import resample_cube, resample_to_nominal
from .virtual import VIRTUAL_METHODS, virtual_bands

__all__ = [
    "VIRTUAL_METHODS",
    "CubeCRA",
    "PlacementError",
    "correct_cube",
    "cube_cra",
    "cube_cra_deg",
    "cube_positions",
    "optical_center",
    "optical_center_rc",
    "relative_shift",
    "resample_cube",
    "resample_to_nominal",
    "virtual_bands",
    "with_fwhm_table",
]
