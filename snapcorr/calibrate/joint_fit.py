"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.lens.joint_fit`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .lens.joint_fit import (
    BLOCK_NODES,
    CIRCLE_MODELS,
    GRID_POINTS,
    MODELS,
    N_CIRCLES,
    POLISH_NFEV,
    SCREEN_BLOCKS,
    BlockData,
    ModelFit,
    _block_model,
    _profiled,
    _tan,
    block_average,
    block_centroids,
    circles_of,
    fit_model,
    floor_chi2,
    model_ratio,
    overlap_area_mm2,
    param_names,
)

_MOVED_TO = "snapcorr.calibrate.lens.joint_fit"

__all__ = [
    "BlockData",
    "ModelFit",
    "block_average",
    "block_centroids",
    "fit_model",
]
