"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.lens.stages`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .lens.joint_fit import (
    MODELS,
)
from .lens.stages import (
    BIN_DEG,
    CIRCLE_MODELS,
    FIT_GRID,
    LIT_FRACTION,
    N_CIRCLES,
    PROFILE_SIZE,
    TILE_SPREAD,
    BlockData,
    Flats,
    Lens,
    ModelFit,
    Onset,
    OnsetFit,
    Ratios,
    _band_labels,
    _tile_period,
    accepts_center_rc,
    block_average,
    block_centroids,
    block_data,
    check_center,
    clean_flat,
    clean_flats,
    cra_map,
    detect_onset,
    estimate_center,
    fit_model,
    floor_chi2,
    joint_fits,
    optical_center,
    pixel_rival,
    profiles_and_onsets,
    radial_profile,
    ratio_images,
    remove_band_gains,
    solve_onsets,
    solve_vignetting_circle,
    without_band_gains,
)

_MOVED_TO = "snapcorr.calibrate.lens.stages"

__all__ = [
    "Flats",
    "Ratios",
    "block_data",
    "clean_flats",
    "joint_fits",
    "optical_center",
    "pixel_rival",
    "profiles_and_onsets",
    "ratio_images",
    "solve_onsets",
    "without_band_gains",
]
