"""snapcorr: wavelength correction for spectral cameras with thin-film Fabry-Perot filters."""

from importlib.metadata import PackageNotFoundError, version

from .optics import EffectiveIndexWarning, Lens, PupilCutOffError, ShiftTable, mean_shift

try:
    __version__ = version("snapcorr")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0+unknown"

__all__ = [
    "EffectiveIndexWarning",
    "Lens",
    "PupilCutOffError",
    "ShiftTable",
    "__version__",
    "mean_shift",
]
