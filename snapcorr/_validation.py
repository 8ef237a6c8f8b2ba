"""Small shared checks."""

from __future__ import annotations

__all__ = ["validate_method"]


def validate_method(method, methods, what="method"):
    """Return ``method`` if it names an entry of ``methods``, else raise a helpful error."""
    if method not in methods:
        names = ", ".join(repr(m) for m in methods)
        raise ValueError(f"unknown {what} {method!r}; choose one of {names}")
    return method
