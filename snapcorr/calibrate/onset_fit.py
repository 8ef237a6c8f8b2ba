"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.flats.onset_fit`.

Import from there; this path will be removed in snapcorr 0.3.
"""


from .flats.onset_fit import (
    OnsetFit,
    solve_vignetting_circle,
)

_MOVED_TO = "snapcorr.calibrate.flats.onset_fit"

__all__ = [
    "OnsetFit",
    "solve_vignetting_circle",
]
