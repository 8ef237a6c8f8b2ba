"""Compatibility re-exports: this module moved to :mod:`snapcorr.calibrate.pupil.index`.

Import from there; this path will be removed in snapcorr 0.3.
"""

# ruff: noqa: F401

from .pupil.index import (
    N_EFF_P,
    N_EFF_REL_STDERR,
    _index_ladder,
    _per_band_jacobian,
    _project_off,
    _solve,
    _whiten,
)

_MOVED_TO = "snapcorr.calibrate.pupil.index"
