"""Public names of a package loaded at their first use (PEP 562), so that importing one light
module of it does not import every heavy one first."""

from __future__ import annotations

import importlib


def lazy_names(package, homes):
    """``__getattr__`` and ``__dir__`` for the package named ``package``: each name of
    ``homes`` (public name -> the module that defines it) is imported when first asked for,
    then kept in the package's namespace."""
    namespace = importlib.import_module(package).__dict__

    def __getattr__(name):
        if name in homes:
            value = getattr(importlib.import_module(homes[name]), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted({*namespace, *homes})

    return __getattr__, __dir__
