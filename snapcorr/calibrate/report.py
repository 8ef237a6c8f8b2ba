"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.lens.report`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .lens.joint_fit import (
    MODELS,
)
from .lens.report import (
    CIRCLE_MODELS,
    CIRCLES,
    REFERENCE_CWL_NM,
    REFERENCE_N_EFF,
    BlockData,
    model_ratio,
    plot,
    save_plot,
    summary,
)

_MOVED_TO = "snapcorr.calibrate.lens.report"

__all__ = [
    "CIRCLES",
    "plot",
    "save_plot",
    "summary",
]
