"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.report`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.report import (
    _Problem,
    plot_pupil_fit,
)

_MOVED_TO = "snapcorr.calibrate.pupil.report"

__all__ = [
    "plot_pupil_fit",
]
