"""snapcorr: wavelength correction for spectral cameras with thin-film Fabry-Perot filters.

The public names below are imported at their first use (PEP 562), so ``import snapcorr`` and
the command line's ``--help`` stay quick: the physics (scipy) loads only when it is needed.
"""

from importlib import import_module

#: Each public name and the module that defines it.
_LAZY = {
    "EffectiveIndexWarning": "snapcorr.optics",
    "Lens": "snapcorr.optics",
    "PupilCutOffError": "snapcorr.optics",
    "ShiftTable": "snapcorr.optics",
    "mean_shift": "snapcorr.optics",
}

__all__ = [
    "EffectiveIndexWarning",
    "Lens",
    "PupilCutOffError",
    "ShiftTable",
    "__version__",
    "mean_shift",
]


def _version():
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("snapcorr")
    except PackageNotFoundError:  # running from a source tree without installation
        return "0+unknown"


def _is_module(name):
    from importlib.util import find_spec

    return find_spec(f"snapcorr.{name}") is not None


def __getattr__(name):
    if name == "__version__":
        value = _version()
    elif name in _LAZY:
        value = getattr(import_module(_LAZY[name]), name)
    elif not name.startswith("_") and _is_module(name):  # ``snapcorr.cube`` after ``import
        value = import_module(f"snapcorr.{name}")      # snapcorr``, as before
    else:
        raise AttributeError(f"module 'snapcorr' has no attribute {name!r}")
    globals()[name] = value  # imported once
    return value


def __dir__():
    return sorted({*globals(), *__all__})
