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


def _bundled(kind, name):
    folder = calibration_dir() / kind
    path = folder / f"{name}.toml"
    if not path.exists():
        names = sorted(p.stem for p in folder.glob("*.toml"))
        raise FileNotFoundError(f"no bundled {kind[:-1]} {name!r}; bundled {kind}: {names}")
    return path


def lens_path(name: str = DEFAULT_LENS) -> Path:
    """Path of a bundled lens profile by name (file stem), e.g. ``"edmund_optics_16mm"``."""
    return _bundled("lenses", name)


def sensor_path(name: str) -> Path:
    """Path of a bundled sensor description by name (file stem), e.g. ``"snapscan_vnir"``."""
    return _bundled("sensors", name)
