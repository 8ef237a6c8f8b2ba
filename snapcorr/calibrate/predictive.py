"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.lens.predictive`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .lens.predictive import (
    MIN_PREDICTIVE_GAIN,
    REFIT_NFEV,
    BlockData,
    ModelFit,
    Prediction,
    _block_model,
    _profiled,
    compare_estimators,
    fit_model,
    predict_left_out,
    without_flat,
)

_MOVED_TO = "snapcorr.calibrate.lens.predictive"

__all__ = [
    "MIN_PREDICTIVE_GAIN",
    "Prediction",
    "compare_estimators",
    "predict_left_out",
]
