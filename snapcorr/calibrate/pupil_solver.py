"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.solver`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.solver import (
    DENSE_FILL,
    DENSE_MAX,
    _pinv_solve,
    _Problem,
    _project_off,
    _solve,
    _whiten,
)

_MOVED_TO = "snapcorr.calibrate.pupil.solver"
