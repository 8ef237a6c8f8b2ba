"""The bundled lens profiles and sensor descriptions, found by name.

A profile is given as a file or by the name of a bundled one (``edmund_optics_16mm``,
``snapscan_vnir``): :func:`profile_path` says which file a value names, for
:meth:`snapcorr.optics.Lens.load` and :meth:`snapcorr.cube.Sensor.load`.
"""

from __future__ import annotations

import os
from pathlib import Path

#: The folder of ``calibration/`` holding each kind of bundled profile, and what one is called.
BUNDLED_FOLDERS = {"lens": ("lenses", "lens"), "sensor": ("sensors", "sensor")}

#: The suffixes of the files each kind of profile is read from (another value is a name).
PROFILE_SUFFIXES = {"lens": (".toml",), "sensor": (".toml", ".xml")}


def calibration_dir() -> Path:
    """The repository's ``calibration/`` folder (snapcorr installed from a source checkout)."""
    path = Path(__file__).resolve().parents[1] / "calibration"
    if not path.is_dir():
        raise FileNotFoundError(
            f"bundled calibration data not found at {path}; install snapcorr from a source "
            "checkout with `pip install -e .`"
        )
    return path


def bundled_path(kind: str, name) -> Path:
    """``calibration/<folder>/<name>.toml`` of a bundled ``kind`` (``"lens"``, ``"sensor"``);
    ``name`` is a bare name (a path gives its stem)."""
    folder_name, what = BUNDLED_FOLDERS[kind]
    if isinstance(name, os.PathLike):
        name = Path(name).stem
    name = str(name)
    if name.endswith(".toml"):
        name = name[: -len(".toml")]
    folder = calibration_dir() / folder_name
    path = folder / f"{name}.toml"
    bare = name and Path(name).name == name and name not in (".", "..")
    if not (bare and path.is_file()):
        names = sorted(p.stem for p in folder.glob("*.toml"))
        raise FileNotFoundError(f"no bundled {what} named {name!r}; bundled {folder_name}: "
                                f"{names}")
    return path


def profile_path(kind: str, value) -> Path:
    """The file a profile ``value`` names: itself when it has a profile's suffix or exists,
    else the bundled ``kind`` (``"lens"``, ``"sensor"``) of that name."""
    path = Path(value)
    if path.suffix.lower() in PROFILE_SUFFIXES[kind] or path.exists():
        return path
    return bundled_path(kind, str(value))


def input_path(value) -> Path:
    """An input as the file it names: a bundled lens or sensor by name is its profile."""
    path = Path(value)
    if path.exists() or path.suffix:
        return path
    for kind in BUNDLED_FOLDERS:
        try:
            found = bundled_path(kind, str(value))
        except (FileNotFoundError, ValueError):
            continue
        if found.exists():
            return found
    return path


def bundled_folder() -> Path | None:
    """The bundled profiles' folder, links resolved (None when not installed from a
    checkout)."""
    try:
        return Path(os.path.realpath(calibration_dir()))
    except FileNotFoundError:
        return None
