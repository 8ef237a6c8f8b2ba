"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.flats.onsets`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .flats.onsets import (
    SIGNIFICANCE_CHI2,
    SYSTEMATIC_DEG,
    WINDOW_DEG,
    Onset,
    detect_onset,
)

_MOVED_TO = "snapcorr.calibrate.flats.onsets"

__all__ = [
    "Onset",
    "detect_onset",
]
