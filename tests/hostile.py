"""Inputs a user makes by hand and the checks of a refusal, shared by the hostile-input tests.

Sensor and lens TOML text written by hand, cubes saved with numpy or Spectral Python, the one
error line a refusal prints, and snapshots of a folder to show that nothing was written."""

from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from snapcorr import _io
from snapcorr.cube import make_cube

REPO = Path(__file__).resolve().parents[1]

LENS = REPO / "calibration" / "lenses" / "edmund_optics_16mm.toml"

WL4 = [500.0, 520.0, 540.0, 560.0]

SENSOR4 = """\
# a user's own 4-band line-scan camera, no size given
[sensor]
name = "plain-4"
layout = "snapscan"
pixel_pitch_um = 5.5
cwl_nm = [500.0, 520.0, 540.0, 560.0]
fwhm_nm = 10.0
n_eff = 1.7
"""

MOSAIC_WL = [470.0 + 10.0 * i for i in range(16)]


def error_line(err):
    """The one error line on stderr (warnings and argparse's usage line may precede it)."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if "error:" in ln or ln.startswith("error")]
    assert len(lines) == 1, f"expected one error line, got:\n{err}"
    assert lines[0].startswith("snapcorr"), f"the error shares its line: {lines[0]!r}"
    return lines[0]


def assert_refused(rc, err, *words):
    """Non-zero exit, one error line naming every one of ``words`` (case-insensitive)."""
    assert rc != 0, f"accepted; stderr:\n{err}"
    line = error_line(err)
    for w in words:
        assert w.lower() in line.lower(), f"{w!r} not in the error: {line}"
    return line


def snapshot(root):
    """Every entry under ``root`` (hidden ones too): files by content hash."""
    root = Path(root)
    found = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = p.relative_to(root).as_posix()
            if p.is_symlink():
                found[rel] = "link:" + os.readlink(p)
            elif p.is_fifo():
                found[rel] = "fifo"
            elif p.is_file():
                found[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
            elif p.is_dir():
                found[rel] = "dir"
    return found


def hidden(root):
    return sorted(p.name for p in Path(root).iterdir() if p.name.startswith("."))


def save_cubes(folder, shape=(12, 10, 4), dtype=np.float32, seed=0, dark=10.0, white=400.0):
    """raw.npy, dark.npy, white.npy as a user saves them with numpy."""
    folder = Path(folder)
    rng = np.random.default_rng(seed)
    raw = rng.uniform(100, 200, shape).astype(dtype)
    np.save(folder / "raw.npy", raw)
    np.save(folder / "dark.npy", np.full(shape, dark, dtype))
    np.save(folder / "white.npy", np.full(shape, white, dtype))
    (folder / "sensor.toml").write_text(SENSOR4)
    return raw

FF = ("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy",
      "--sensor", "sensor.toml")


def correct_args(cube, out, *extra, sensor="sensor.toml", lens=LENS):
    return ("correct", cube, "--lens", lens, "--sensor", sensor, "--f-number", "1.4",
            "--out", out, *extra)


def cra_of(ds):
    """The chief-ray-angle map of a result (named ``cra_deg``, or ``cra``)."""
    return ds["cra_deg"] if "cra_deg" in ds.variables else ds["cra"]


def read_result(path):
    """A written result, through snapcorr's reader of Datasets where there is one."""
    import snapcorr.cube

    reader = getattr(snapcorr.cube, "read_dataset", None)
    if reader is not None:
        return reader(path)
    path = Path(path)
    if path.suffix == ".zarr":
        return xr.open_zarr(path)
    return xr.open_dataset(path, engine="h5netcdf")


def write_envi(stem, data, *, wavelength=WL4, data_type=4, fields=None, units="Nanometers"):
    """A hand-written ENVI header (BSQ) and its data file ``stem.raw``."""
    stem = Path(stem)
    data = np.asarray(data)
    ny, nx, nb = data.shape
    data.transpose(2, 0, 1).tofile(stem.with_suffix(".raw"))
    head = {"samples": nx, "lines": ny, "bands": nb, "header offset": 0,
            "file type": "ENVI Standard", "data type": data_type, "interleave": "bsq",
            "byte order": 0}
    if wavelength is not None:
        head["wavelength"] = "{" + ", ".join(f"{w:g}" for w in wavelength) + "}"
        if units is not None:
            head["wavelength units"] = units
    head.update(fields or {})
    text = "ENVI\n" + "".join(f"{k} = {v}\n" for k, v in head.items())
    stem.with_suffix(".hdr").write_text(text)
    return stem.with_suffix(".hdr")

WL_OUT = [500.0, 550.0, 600.0, 650.0]


def output_cube(scale=1):
    data = np.random.default_rng(3).integers(0, 1000, (5, 6, 4)).astype(np.uint16) * scale
    return make_cube(data, WL_OUT, attrs={"f_number": 2.0})


def snapshot_bounded(root):
    """Every entry under ``root``: files by content hash, links by target, others by kind."""
    found = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = p.relative_to(root).as_posix()
            mode = os.lstat(p).st_mode
            if stat.S_ISLNK(mode):
                found[rel] = "link:" + os.readlink(p)
            elif stat.S_ISREG(mode):  # a huge (sparse) file by its size and first MiB
                with open(p, "rb") as fh:
                    head = fh.read(1 << 20)
                found[rel] = (os.path.getsize(p), hashlib.sha256(head).hexdigest())
            else:
                found[rel] = stat.filemode(mode)[0]
    return found


def only_line(text):
    lines = str(text).strip().splitlines()
    assert len(lines) == 1, text
    return lines[0]


def snapcorr_png(path):
    fig = Figure(figsize=(1, 1))
    fig.subplots().plot([0, 1])
    return _io.save_png(fig, path, dpi=30)


def snapcorr_toml(path, overwrite=False):
    return _io.write_toml(path, {"lens": {"name": "x", "exit_pupil_mm": 21.0}},
                          overwrite=overwrite)

HUGE = "9" * 400


def refused_in_one_line(res):
    assert res.returncode in (1, 2), res.stdout  # 2: argparse's refusal of an option
    assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1, \
        res.stderr
    return res.stderr


def read_only(monkeypatch, folder):
    """Make ``folder`` refuse new entries as a read-only folder does for a user who is not
    root (tests may run as root, who may write anywhere): creating a file or a folder directly
    in it raises ``PermissionError``, as the kernel would. Everything that creates a file
    (``tempfile``, and with it every writer and the output probe) goes through ``os.open`` or
    ``os.mkdir``."""
    import errno

    folder = os.path.realpath(folder)
    real_open, real_mkdir = os.open, os.mkdir

    def refused(path):
        return os.path.dirname(os.path.realpath(os.fspath(path))) == folder

    def fake_open(path, flags, *args, **kwargs):
        if flags & os.O_CREAT and refused(path):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fspath(path))
        return real_open(path, flags, *args, **kwargs)

    def fake_mkdir(path, *args, **kwargs):
        if refused(path):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fspath(path))
        return real_mkdir(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", fake_open)
    monkeypatch.setattr(os, "mkdir", fake_mkdir)
