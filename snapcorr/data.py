"""Where the bundled calibration data (lens profiles, sensors) lives."""

from __future__ import annotations

from pathlib import Path

__all__ = ["DEFAULT_LENS", "calibration_dir", "lens_path", "sensor_path"]

#: The lens of Goossens et al. 2019, used by ``snapcorr demo``.
DEFAULT_LENS = "edmund_optics_16mm"


def calibration_dir() -> Path:
    """The repository's ``calibration/`` folder (snapcorr installed from a source checkout)."""
    path = Path(__file__).resolve().parents[1] / "calibration"
    if not path.is_dir():
        raise FileNotFoundError(
            f"bundled calibration data not found at {path}; install snapcorr from a source "
            "checkout with `pip install -e .`"
        )
    return path


def lens_path(name: str = DEFAULT_LENS) -> Path:
    """Path of a bundled lens profile by name (file stem), e.g. ``"edmund_optics_16mm"``."""
    folder = calibration_dir() / "lenses"
    path = folder / f"{name}.toml"
    if not path.exists():
        names = sorted(p.stem for p in folder.glob("*.toml"))
        raise FileNotFoundError(f"no bundled lens {name!r}; bundled lenses: {names}")
    return path


def sensor_path(name: str) -> Path:
    """Path of a bundled sensor description by name (file stem), e.g. ``"snapscan_vnir"``."""
    folder = calibration_dir() / "sensors"
    path = folder / f"{name}.toml"
    if not path.exists():
        names = sorted(p.stem for p in folder.glob("*.toml"))
        raise FileNotFoundError(f"no bundled sensor {name!r}; bundled sensors: {names}")
    return path
