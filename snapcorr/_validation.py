"""Small shared checks."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["check_curve", "check_positive", "validate_method"]


def check_positive(name, value):
    """``value`` as a float, raising a clear ``ValueError`` unless it is a finite number > 0."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return v


def validate_method(method, methods, what="method"):
    """Return ``method`` if it names an entry of ``methods``, else raise a helpful error."""
    if method not in methods:
        names = ", ".join(repr(m) for m in methods)
        raise ValueError(f"unknown {what} {method!r}; choose one of {names}")
    return method


def check_curve(wavelength_nm, transmission):
    """Return a sampled curve as float arrays, raising unless it is 1-D, of equal lengths
    (>= 2), finite, with strictly increasing wavelengths."""
    w = np.asarray(wavelength_nm, float)
    t = np.asarray(transmission, float)
    if (w.ndim != 1 or w.shape != t.shape or w.size < 2 or np.any(np.diff(w) <= 0)
            or not (np.all(np.isfinite(w)) and np.all(np.isfinite(t)))):
        raise ValueError("a transmission curve needs finite 1-D wavelength and transmission "
                         "arrays of equal length (>= 2), wavelengths strictly increasing")
    return w, t
