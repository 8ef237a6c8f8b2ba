"""Hostile and everyday inputs, as a user would make them, against the command line.

Every input here is built with other libraries than snapcorr's writers where a user would
(Spectral Python, tifffile, OpenImageIO, numpy, xarray/h5netcdf, TOML written by hand). Each
test states what ``snapcorr`` must do: the exit status, one error line on stderr that names the
problem in command-line terms, nothing written (no output, no hidden temporary left), inputs
unchanged, or the right result.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
import xarray as xr
from numpy.testing import assert_allclose

REPO = Path(__file__).resolve().parents[1]
LENS = REPO / "calibration" / "lenses" / "edmund_optics_16mm.toml"
MOSAIC = REPO / "calibration" / "sensors" / "mosaic_4x4_vis.toml"
SUBCOMMANDS = ("demo", "shift", "flatfield", "calibrate", "correct", "budget")

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


def mosaic_sensor_text(**override):
    """A 4 x 4 mosaic sensor written by hand; ``override`` replaces whole lines (raw TOML)."""
    lines = {
        "name": '"user-mosaic"',
        "layout": '"mosaic"',
        "pixel_pitch_um": "5.5",
        "cwl_nm": "[" + ", ".join(f"{w:.1f}" for w in MOSAIC_WL) + "]",
        "fwhm_nm": "12.0",
        "n_eff": "1.7",
        "mosaic_shape": "[4, 4]",
        "band_offset": "[" + ", ".join(f"[{r}, {c}]" for r in range(4) for c in range(4)) + "]",
    }
    lines.update(override)
    return "[sensor]\n" + "".join(f"{k} = {v}\n" for k, v in lines.items())


def lens_text(**override):
    lines = {
        "name": '"user lens"',
        "exit_pupil_mm": "21.0",
        "vignetting_radius_mm": "7.4236",
        "vignetting_distance_mm": "16.991",
        "magnification": "0.06",
        "pupil_magnification": "1.3",
    }
    lines.update(override)
    return "[lens]\n" + "".join(f"{k} = {v}\n" for k, v in lines.items())


# -- helpers ---------------------------------------------------------------------------------


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


# -- data safety: demo -----------------------------------------------------------------------


def _forbid_demo_work(monkeypatch):
    """The demo's computations fail the test if started: a refusal must come before them."""
    import snapcorr.demo
    import snapcorr.paper_experiment

    def work(*args, **kwargs):
        raise AssertionError("the refusal must come before any work")

    monkeypatch.setattr(snapcorr.demo, "mean_shift", work)
    monkeypatch.setattr(snapcorr.paper_experiment, "run", work)


@pytest.mark.parametrize("files", [("lens.toml", "summary.txt"), ("notes.txt",)],
                         ids=["demo-like-names", "other-file"])
def test_demo_refuses_a_folder_it_did_not_make(tmp_path, monkeypatch, files, cli):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "results"
    out.mkdir()
    for i, name in enumerate(files):
        (out / name).write_text(f"the user's own {name}, {i}\n")
    before = snapshot(tmp_path)
    _forbid_demo_work(monkeypatch)
    rc, _, err = cli("demo", "--out", "results")
    assert_refused(rc, err, "--overwrite")
    assert snapshot(tmp_path) == before


def test_demo_refuses_a_file_as_its_folder(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").write_text("not a folder\n")
    before = snapshot(tmp_path)
    _forbid_demo_work(monkeypatch)
    rc, _, err = cli("demo", "--out", "results")
    assert_refused(rc, err, "results")
    assert snapshot(tmp_path) == before


@pytest.mark.slow
def test_demo_runs_in_a_new_folder(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    rc, _, err = cli("demo", "--out", "fresh")
    assert rc == 0, err
    names = {p.name for p in (tmp_path / "fresh").iterdir()}
    assert {"summary.txt", "lens.toml", "spectra.png"} <= names
    # no temporary left; a marker saying the folder is the demo's own is fine
    assert not [n for n in names if n.startswith(".") and not n.startswith(".snapcorr")]


# -- data safety: --overwrite ----------------------------------------------------------------


def _inputs_inside_out(tmp_path, command):
    """A folder out.zarr holding the inputs themselves; the arguments that point into it."""
    box = tmp_path / "out.zarr"
    box.mkdir()
    save_cubes(box)
    (tmp_path / "sensor.toml").write_text(SENSOR4)
    if command == "flatfield":
        return ("flatfield", "out.zarr/raw.npy", "--dark", "out.zarr/dark.npy", "--white",
                "out.zarr/white.npy", "--sensor", "sensor.toml", "--out", "out.zarr",
                "--overwrite")
    return correct_args("out.zarr/raw.npy", "out.zarr", "--overwrite")


@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_overwrite_never_deletes_a_folder_holding_the_inputs(tmp_path, monkeypatch, command, cli):
    monkeypatch.chdir(tmp_path)
    args = _inputs_inside_out(tmp_path, command)
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "out.zarr")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_overwrite_never_deletes_a_users_folder(tmp_path, monkeypatch, command, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    box = tmp_path / "out.zarr"
    (box / "holiday").mkdir(parents=True)
    (box / "thesis.tex").write_text("\\chapter{Two years of work}\n")
    (box / "holiday" / "photo.jpg").write_bytes(os.urandom(2048))
    args = (*FF, "--out", "out.zarr", "--overwrite") if command == "flatfield" else \
        correct_args("raw.npy", "out.zarr", "--overwrite")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "out.zarr")
    assert snapshot(tmp_path) == before


def _foreign_nc(path, kind):
    if kind == "text":
        path.write_text("lab notes, saved with the wrong extension\n")
    else:  # a user's own netCDF, written with xarray
        xr.Dataset({"temperature": (("t",), np.arange(5.0))},
                   attrs={"title": "greenhouse log"}).to_netcdf(path, engine="h5netcdf")


@pytest.mark.parametrize("kind", ["text", "users-netcdf"])
@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_overwrite_never_replaces_a_file_snapcorr_did_not_write(tmp_path, monkeypatch, command,
                                                                kind, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    _foreign_nc(tmp_path / "out.nc", kind)
    args = (*FF, "--out", "out.nc", "--overwrite") if command == "flatfield" else \
        correct_args("raw.npy", "out.nc", "--overwrite")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "out.nc")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_overwrite_replaces_a_previous_result(tmp_path, monkeypatch, ext, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    rc, _, err = cli(*FF, "--out", f"out{ext}")
    assert rc == 0, err
    raw = save_cubes(tmp_path, seed=7)  # a new scene
    rc, _, err = cli(*FF, "--out", f"out{ext}", "--overwrite")
    assert rc == 0, err
    got = read_result(tmp_path / f"out{ext}")["reflectance"].values
    np.testing.assert_allclose(got, (raw - 10.0) / 390.0, rtol=1e-6)
    assert not hidden(tmp_path)


def test_existing_result_is_kept_without_overwrite(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    assert cli(*FF, "--out", "out.nc")[0] == 0
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "out.nc")
    assert_refused(rc, err, "--overwrite")
    assert snapshot(tmp_path) == before


def test_result_written_over_its_own_input_is_refused(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    assert cli(*FF, "--out", "ff.nc")[0] == 0
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("ff.nc", "ff.nc", "--overwrite"))
    assert_refused(rc, err, "ff.nc")
    assert snapshot(tmp_path) == before


def test_overwrite_through_a_link_to_the_input_is_refused(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    assert cli(*FF, "--out", "ff.nc")[0] == 0
    os.symlink("ff.nc", tmp_path / "latest.nc")
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("ff.nc", "latest.nc", "--overwrite"))
    assert_refused(rc, err, "latest.nc")
    assert snapshot(tmp_path) == before


def test_overwrite_through_a_hard_link_leaves_the_input_intact(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    assert cli(*FF, "--out", "ff.nc")[0] == 0
    os.link(tmp_path / "ff.nc", tmp_path / "latest.nc")
    before = snapshot(tmp_path)["ff.nc"]
    rc, _, err = cli(*correct_args("ff.nc", "latest.nc", "--overwrite"))
    if rc != 0:  # refusing is fine too, in one line
        error_line(err)
    assert snapshot(tmp_path)["ff.nc"] == before
    assert not hidden(tmp_path)


@pytest.mark.parametrize("how", ["input-inside", "input-linked-inside", "lens-inside",
                                 "users-file-inside"])
def test_overwrite_never_deletes_a_previous_result_holding_an_input(tmp_path, monkeypatch, how,
                                                                    cli):
    """A previous snapcorr result that now holds (or backs) an input is not replaced."""
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    assert cli(*FF, "--out", "out.zarr")[0] == 0
    if how == "input-inside":
        os.replace(tmp_path / "raw.npy", tmp_path / "out.zarr" / "raw.npy")
        args = ("flatfield", "out.zarr/raw.npy", "--dark", "dark.npy", "--white", "white.npy",
                "--sensor", "sensor.toml", "--out", "out.zarr", "--overwrite")
    elif how == "input-linked-inside":
        os.replace(tmp_path / "raw.npy", tmp_path / "out.zarr" / "kept.npy")
        os.symlink("out.zarr/kept.npy", tmp_path / "raw.npy")
        args = (*FF, "--out", "out.zarr", "--overwrite")
    elif how == "lens-inside":
        (tmp_path / "out.zarr" / "lens.toml").write_text(LENS.read_text())
        args = correct_args("raw.npy", "out.zarr", "--overwrite", lens="out.zarr/lens.toml")
    else:  # the user kept notes in the result's folder: not snapcorr's to delete
        (tmp_path / "out.zarr" / "notes.txt").write_text("exposure 12 ms, sphere at 3 A\n")
        args = (*FF, "--out", "out.zarr", "--overwrite")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "out.zarr")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("target", ["folder", "folder-overwrite", "existing-png"])
@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_plot_never_replaces_what_is_there(tmp_path, monkeypatch, command, target, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    if target.startswith("folder"):
        (tmp_path / "look.png").mkdir()
        (tmp_path / "look.png" / "keep.txt").write_text("my figures\n")
    else:
        (tmp_path / "look.png").write_bytes(b"\x89PNG\r\n\x1a\n my own figure")
    extra = ("--plot", "look.png") + (("--overwrite",) if target == "folder-overwrite" else ())
    args = (*FF, "--out", "o.nc", *extra) if command == "flatfield" else \
        correct_args("raw.npy", "o.nc", *extra)
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "look.png")
    assert snapshot(tmp_path) == before


# -- data safety: signals, FIFOs, links, permissions, empty cubes -----------------------------


@pytest.fixture(scope="module")
def big_inputs(tmp_path_factory):
    """A 160 MB float32 cube (and one-row dark and white strips): its result takes a moment
    to write."""
    d = tmp_path_factory.mktemp("big")
    ny, nx, nb = 1000, 1250, 32
    raw = np.lib.format.open_memmap(d / "raw.npy", mode="w+", dtype=np.float32,
                                    shape=(ny, nx, nb))
    raw[:] = np.linspace(100, 300, nx, dtype=np.float32)[None, :, None]
    raw.flush()
    del raw
    np.save(d / "dark.npy", np.full((1, nx, nb), 10.0, np.float32))
    np.save(d / "white.npy", np.full((1, nx, nb), 900.0, np.float32))
    cwl = ", ".join(f"{500.0 + 10 * i:.1f}" for i in range(nb))
    (d / "sensor.toml").write_text(
        f'[sensor]\nname = "big"\nlayout = "snapscan"\npixel_pitch_um = 5.5\n'
        f"cwl_nm = [{cwl}]\nfwhm_nm = 10.0\nn_eff = 1.7\n")
    return d


def _sigint_default():
    """In the child: Ctrl-C as a terminal sends it. A shell starts background jobs with
    SIGINT ignored, and Python then installs no KeyboardInterrupt handler."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupt(args, folder, out, signals, *, after=0.0, attempts=3):
    """Run ``snapcorr ARGS`` in ``folder``; once a hidden temporary appears (the write has
    begun), wait ``after`` s and send ``signals`` (10 ms apart). Returns (status, stderr).

    An attempt where the result was written before the first signal arrived proves nothing
    and is repeated."""
    for _ in range(attempts):
        proc = subprocess.Popen([sys.executable, "-m", "snapcorr", *map(str, args)], cwd=folder,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=_sigint_default)
        try:
            deadline = time.monotonic() + 90
            while not hidden(folder):
                if proc.poll() is not None:
                    pytest.fail(f"finished (status {proc.returncode}) before a temporary "
                                f"appeared: {proc.stderr.read()}")
                if time.monotonic() > deadline:
                    pytest.fail("no temporary appeared within 90 s")
                time.sleep(0.01)
            time.sleep(after)
            for i, sig in enumerate(signals):
                if proc.poll() is None:
                    proc.send_signal(sig)
                if i + 1 < len(signals):
                    time.sleep(0.01)
            stdout, stderr = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        if "wrote" not in stdout:
            return proc.returncode, stderr
        # the write won the race: start again
        if out.is_dir():
            import shutil

            shutil.rmtree(out)
        elif out.exists():
            out.unlink()
    pytest.fail(f"the write finished before the signal in {attempts} attempts")


def _assert_interrupted_cleanly(status, err, folder, out):
    assert status != 0
    assert "Traceback" not in err, err
    assert not hidden(folder), f"left behind: {hidden(folder)}"
    if out.exists():  # renamed just before the signal: it must then be whole
        read_result(out).load()


def _flatfield_big(d, out):
    return ("flatfield", d / "raw.npy", "--dark", d / "dark.npy", "--white", d / "white.npy",
            "--sensor", d / "sensor.toml", "--out", out)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_signal_during_write_leaves_no_temporary(tmp_path, big_inputs, sig, ext):
    out = tmp_path / f"result{ext}"
    status, err = _interrupt(_flatfield_big(big_inputs, out), tmp_path, out, [sig], after=0.1)
    _assert_interrupted_cleanly(status, err, tmp_path, out)


@pytest.mark.slow
@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_sigterm_during_correct_leaves_no_temporary(tmp_path, big_inputs, ext):
    d = big_inputs
    out = tmp_path / f"corrected{ext}"
    args = ("correct", d / "raw.npy", "--lens", LENS, "--sensor", d / "sensor.toml",
            "--f-number", "1.4", "--resample", "--out", out)
    status, err = _interrupt(args, tmp_path, out, [signal.SIGTERM])
    _assert_interrupted_cleanly(status, err, tmp_path, out)


@pytest.mark.slow
@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_ctrl_c_twice_during_write_leaves_no_temporary(tmp_path, big_inputs, ext):
    """An impatient user presses Ctrl-C again while snapcorr cleans up."""
    out = tmp_path / f"result{ext}"
    status, err = _interrupt(_flatfield_big(big_inputs, out), tmp_path, out,
                             [signal.SIGINT] * 6, after=0.1)
    _assert_interrupted_cleanly(status, err, tmp_path, out)


def _run_with_timeout(args, cwd, timeout=120):
    """``python -m snapcorr ARGS`` in a process of its own, which a read blocked on a FIFO or
    a device cannot hang; the timeout only guards against that (generous: the machine may be
    busy), no duration is asserted."""
    try:
        return subprocess.run([sys.executable, "-m", "snapcorr", *map(str, args)], cwd=cwd,
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"still running after {timeout} s (blocked on the FIFO or device)")


@pytest.mark.parametrize("where", ["flatfield-raw-npy", "correct-cube-nc", "calibrate-flat",
                                   "correct-sensor-toml"])
def test_fifo_input_returns_promptly_with_an_error(tmp_path, where):
    save_cubes(tmp_path)
    if where == "flatfield-raw-npy":
        os.mkfifo(tmp_path / "scene.npy")
        args = ("flatfield", "scene.npy", "--dark", "dark.npy", "--white", "white.npy",
                "--sensor", "sensor.toml", "--out", "o.nc")
    elif where == "correct-cube-nc":
        os.mkfifo(tmp_path / "scene.nc")
        args = correct_args("scene.nc", "o.nc")
    elif where == "correct-sensor-toml":
        os.mkfifo(tmp_path / "camera.toml")
        args = correct_args("raw.npy", "o.nc", sensor="camera.toml")
    else:
        os.mkfifo(tmp_path / "f14.npy")
        np.save(tmp_path / "f2.npy", np.full((64, 64), 1000.0))
        args = ("calibrate", "--flat", "1.4=f14.npy", "--flat", "2=f2.npy", "--exit-pupil-mm",
                "21", "--pixel-pitch-um", "5.5", "--out", "lens.toml")
    before = snapshot(tmp_path)
    res = _run_with_timeout(args, tmp_path)
    assert_refused(res.returncode, res.stderr)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_a_device_as_the_cube_returns_promptly_with_an_error(tmp_path, device):
    if not os.path.exists(device):
        pytest.skip(f"no {device} here")
    save_cubes(tmp_path)
    os.symlink(device, tmp_path / "scene.npy")
    before = snapshot(tmp_path)
    res = _run_with_timeout(correct_args("scene.npy", "o.nc"), tmp_path)
    assert_refused(res.returncode, res.stderr, "scene.npy")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("name", ["scene.npy", "scene.nc", "scene.hdr", "scene.tif"])
def test_a_folder_named_like_a_cube_is_one_error_line(tmp_path, monkeypatch, name, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    (tmp_path / name).mkdir()
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args(name, "o.nc"))
    assert_refused(rc, err, name)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_symlink_loop_is_one_error_line(tmp_path, monkeypatch, command, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    os.symlink("loop_b.npy", tmp_path / "loop_a.npy")
    os.symlink("loop_a.npy", tmp_path / "loop_b.npy")
    args = ("flatfield", "loop_a.npy", "--dark", "dark.npy", "--white", "white.npy",
            "--sensor", "sensor.toml", "--out", "o.nc") if command == "flatfield" else \
        correct_args("loop_a.npy", "o.nc")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "loop_a.npy")
    assert snapshot(tmp_path) == before


def test_unreadable_envi_data_is_one_error_line(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    write_envi(tmp_path / "scene", np.ones((12, 10, 4), np.float32))
    os.chmod(tmp_path / "scene.raw", 0)
    try:
        if os.access(tmp_path / "scene.raw", os.R_OK):
            pytest.skip("running as a user who reads any file (root): chmod 000 has no effect")
        before = snapshot(tmp_path)
        rc, _, err = cli("flatfield", "scene.hdr", "--dark", "dark.npy", "--white", "white.npy",
                         "--sensor", "sensor.toml", "--out", "o.nc")
        assert_refused(rc, err, "scene")
        assert snapshot(tmp_path) == before
    finally:
        os.chmod(tmp_path / "scene.raw", 0o644)


@pytest.mark.parametrize("shape", [(0, 10, 4), (12, 0, 4), (12, 10, 0)],
                         ids=["no-rows", "no-columns", "no-bands"])
def test_empty_cube_is_refused_and_nothing_written(tmp_path, monkeypatch, shape, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=shape)
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert_refused(rc, err)
    assert snapshot(tmp_path) == before


def test_correct_refuses_a_zero_row_cube(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=(0, 10, 4))
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("raw.npy", "o.nc"))
    assert_refused(rc, err)
    assert snapshot(tmp_path) == before


# -- silently wrong results: a mosaic's sensor positions --------------------------------------


@pytest.fixture
def mosaic_cube():
    from snapcorr.cube import Sensor, mosaic_to_cube

    sensor = Sensor.load(MOSAIC)
    frame = np.random.default_rng(3).uniform(100, 200, (64, 64)).astype(np.float32)
    return mosaic_to_cube(frame, sensor, origin_px=(400, 800)), sensor


@pytest.mark.parametrize("ext", [".hdr", ".tif", ".exr", ".npy", ".nc", ".zarr"])
def test_mosaic_cube_keeps_its_sensor_positions_through_a_file(tmp_path, monkeypatch,
                                                               mosaic_cube, ext, cli):
    """Written and read back, the cube corrects to the same CRA as in memory.

    A format that cannot hold the positions must refuse to write them away (the README:
    every format refuses what it cannot hold).
    """
    from snapcorr import Lens
    from snapcorr.correct import correct_cube
    from snapcorr.cube import write_cube

    monkeypatch.chdir(tmp_path)
    cube, sensor = mosaic_cube
    expected = cra_of(correct_cube(cube, sensor, 1.4, Lens.load(LENS),
                                  center_px=(1024.0, 544.0), method="none"))
    assert expected.ndim == 3  # a mosaic: every band at its own place
    try:
        write_cube(cube, tmp_path / f"mosaic{ext}")
    except ValueError as err:
        assert ext == ".npy", f"{ext} refused the cube: {err}"
        assert "position" in str(err).lower(), err
        return
    rc, _, err = cli(*correct_args(f"mosaic{ext}", "out.nc", "--center-px", "1024,544",
                                   "--method", "none", sensor=MOSAIC))
    assert rc == 0, err
    got = cra_of(read_result(tmp_path / "out.nc"))
    assert got.shape == expected.shape
    np.testing.assert_allclose(got.values, expected.values, rtol=0, atol=1e-9)


def test_mosaic_npy_replaced_by_another_array_is_not_given_stale_positions(tmp_path,
                                                                          monkeypatch,
                                                                          mosaic_cube, cli):
    """The cube file is replaced by the user (np.save) with a smaller cube; whatever snapcorr
    kept next to the old one must not be applied to it."""
    from snapcorr.cube import write_cube

    monkeypatch.chdir(tmp_path)
    cube, _ = mosaic_cube
    write_cube(cube, tmp_path / "m.npy")
    np.save(tmp_path / "m.npy", np.ones((8, 8, 16), np.float32))
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("m.npy", "out.nc", "--center-px", "1024,544",
                                   sensor=MOSAIC))
    assert_refused(rc, err, "m.npy")
    assert snapshot(tmp_path) == before


def _mosaic_without_positions(path, cube):
    data = np.asarray(cube.values)
    if path.suffix == ".npy":
        np.save(path, data)
    elif path.suffix == ".tif":
        import tifffile

        tifffile.imwrite(path, data, photometric="minisblack", planarconfig="contig")
    else:
        from spectral.io import envi

        envi.save_image(str(path), data, dtype=np.float32, interleave="bsq", ext=".raw",
                        metadata={"wavelength": MOSAIC_WL, "wavelength units": "nm"})


@pytest.mark.parametrize("ext", [".npy", ".tif", ".hdr"])
def test_mosaic_cube_without_positions_is_refused(tmp_path, monkeypatch, mosaic_cube, ext, cli):
    monkeypatch.chdir(tmp_path)
    cube, _ = mosaic_cube
    _mosaic_without_positions(tmp_path / f"cube{ext}", cube)
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args(f"cube{ext}", "out.nc", "--center-px", "1024,544",
                                   sensor=MOSAIC))
    line = assert_refused(rc, err, "position")
    assert any(w in line for w in ("--sensor-origin-px", "frame", "mosaic_to_cube")), line
    assert snapshot(tmp_path) == before


# -- silently wrong results: units ------------------------------------------------------------


def _envi_triplet(folder, wavelength, units):
    rng = np.random.default_rng(1)
    write_envi(folder / "scene", rng.uniform(100, 200, (6, 5, 4)).astype(np.float32),
               wavelength=wavelength, units=units)
    write_envi(folder / "dark", np.full((6, 5, 4), 10, np.float32), wavelength=wavelength,
               units=units)
    write_envi(folder / "white", np.full((6, 5, 4), 400, np.float32), wavelength=wavelength,
               units=units)
    return ("flatfield", "scene.hdr", "--dark", "dark.hdr", "--white", "white.hdr")


@pytest.mark.parametrize("units", [None, "Unknown", "Nanometers"],
                         ids=["no-units", "units-unknown", "labelled-nanometers"])
def test_envi_wavelengths_in_micrometres_without_units_are_refused(tmp_path, monkeypatch,
                                                                   units, cli):
    monkeypatch.chdir(tmp_path)
    args = _envi_triplet(tmp_path, [0.50, 0.52, 0.54, 0.56], units)
    before = snapshot(tmp_path)
    rc, _, err = cli(*args, "--out", "o.nc")
    assert_refused(rc, err, "wavelength")
    assert snapshot(tmp_path) == before


def test_envi_nm_values_labelled_micrometers_are_refused(tmp_path, monkeypatch, cli):
    """500 micrometres is not a filter of a VNIR camera: the header's units are wrong."""
    monkeypatch.chdir(tmp_path)
    args = _envi_triplet(tmp_path, WL4, "Micrometers")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args, "--out", "o.nc")
    assert_refused(rc, err, "wavelength")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("units", ["micrometers", "Micrometers"])
def test_envi_wavelength_units_micrometers_read_as_nm(tmp_path, monkeypatch, units, cli):
    monkeypatch.chdir(tmp_path)
    args = _envi_triplet(tmp_path, [0.50, 0.52, 0.54, 0.56], units)
    rc, _, err = cli(*args, "--out", "o.nc")
    assert rc == 0, err
    wl = read_result(tmp_path / "o.nc")["wavelength"].values
    np.testing.assert_allclose(wl, WL4, rtol=1e-9)


@pytest.mark.parametrize("units", ["um", "micrometre", "m"])
def test_netcdf_wavelength_in_um_reads_as_nm(tmp_path, monkeypatch, units, cli):
    monkeypatch.chdir(tmp_path)
    factor = 1e-9 if units == "m" else 1e-3
    rng = np.random.default_rng(2)
    for name, data in (("scene", rng.uniform(100, 200, (6, 5, 4))),
                       ("dark", np.full((6, 5, 4), 10.0)), ("white", np.full((6, 5, 4), 400.0))):
        xr.Dataset({"radiance": (("y", "x", "band"), data.astype(np.float32))},
                   coords={"wavelength": ("band", np.array(WL4) * factor,
                                          {"units": units})},
                   attrs={"instrument": "lab camera"}).to_netcdf(tmp_path / f"{name}.nc",
                                                                 engine="h5netcdf")
    rc, _, err = cli("flatfield", "scene.nc", "--dark", "dark.nc", "--white", "white.nc",
                     "--out", "o.nc")
    assert rc == 0, err
    wl = read_result(tmp_path / "o.nc")["wavelength"]
    np.testing.assert_allclose(wl.values, WL4, rtol=1e-9)
    assert wl.attrs.get("units") == "nm"


def test_netcdf_wavelength_in_um_without_units_is_refused(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    for name, value in (("scene", 150.0), ("dark", 10.0), ("white", 400.0)):
        xr.Dataset({"radiance": (("y", "x", "band"), np.full((6, 5, 4), value, np.float32))},
                   coords={"wavelength": ("band", [0.50, 0.52, 0.54, 0.56])}).to_netcdf(
                       tmp_path / f"{name}.nc", engine="h5netcdf")
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.nc", "--dark", "dark.nc", "--white", "white.nc",
                     "--out", "o.nc")
    assert_refused(rc, err, "wavelength")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["correct", "budget"])
def test_sensor_with_cwl_in_micrometres_is_refused(tmp_path, monkeypatch, command, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    (tmp_path / "um.toml").write_text(SENSOR4.replace("500.0, 520.0, 540.0, 560.0",
                                                      "0.50, 0.52, 0.54, 0.56"))
    if command == "correct":
        args = correct_args("raw.npy", "o.nc", sensor="um.toml")
    else:
        args = ("budget", "--sensor", "um.toml", "--lens", "edmund_optics_16mm", "--f-number",
                "1.4", "--source", "tungsten:3000", "--cra-max", "5")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "cwl_nm")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("value", ["0.7", "7e-7"], ids=["micrometres", "metres"])
def test_shift_refuses_a_wavelength_not_in_nm(value, cli):
    rc, out, err = cli("shift", "--f-number", "1.4", "--cra", "5", "--cwl-nm", value)
    assert_refused(rc, err, "--cwl-nm")
    assert "cra_deg" not in out


# -- silently wrong results: types in TOML ----------------------------------------------------


@pytest.mark.parametrize("key, value", [
    ("exit_pupil_mm", "true"), ("exit_pupil_mm", '"twenty"'), ("vignetting_radius_mm", "true"),
    ("magnification", "true"), ("pupil_magnification", "false"),
])
def test_lens_value_of_the_wrong_type_is_refused(tmp_path, monkeypatch, key, value, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "lens.toml").write_text(lens_text(**{key: value}))
    rc, out, err = cli("shift", "--lens", "lens.toml", "--f-number", "2", "--cra", "5")
    assert_refused(rc, err, key)
    assert out == ""


@pytest.mark.parametrize("key, value", [
    ("pixel_pitch_um", "true"),
    ("mosaic_shape", "[4.7, 5]"),
    ("band_offset", "[" + ", ".join(f"[{r}, {c}]" for r in range(4) for c in range(4))
     .replace("[3, 3]", "[3, 3.9]") + "]"),
    ("n_eff", "true"),
    ("fwhm_nm", "true"),
    ("cwl_nm", "[" + ", ".join(["true"] * 16) + "]"),
])
def test_sensor_value_of_the_wrong_type_is_refused(tmp_path, monkeypatch, key, value, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text(mosaic_sensor_text(**{key: value}))
    rc, out, err = cli("budget", "--sensor", "s.toml", "--lens", "edmund_optics_16mm",
                       "--f-number", "1.4", "--source", "tungsten:3000", "--cra-max", "5")
    assert_refused(rc, err, key)
    assert "recommended" not in out


# -- silently wrong results: ENVI headers -----------------------------------------------------


@pytest.mark.parametrize("field, value, dtype", [
    ("byte order", "7", np.float32),
    ("data type", "99", np.float32),
    ("data type", "6", np.complex64),
    ("interleave", "xyz", np.float32),
    ("samples", "4.5", np.float32),
    ("header offset", "-8", np.float32),
], ids=["byte-order-7", "data-type-99", "data-type-6-complex", "interleave-xyz",
        "samples-4.5", "header-offset-negative"])
def test_envi_header_field_out_of_range_is_refused(tmp_path, monkeypatch, field, value, dtype, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=(6, 5, 4))
    data = np.ones((6, 5, 4), dtype)
    stem = tmp_path / "scene"
    write_envi(stem, data, data_type=4 if field != "data type" else value,
               fields={field: value})
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.hdr", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "sensor.toml", "--out", "o.nc")
    assert_refused(rc, err, field)
    assert snapshot(tmp_path) == before


def test_envi_header_with_fewer_wavelengths_than_bands_is_refused(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=(6, 5, 4))
    write_envi(tmp_path / "scene", np.ones((6, 5, 4), np.float32), wavelength=WL4[:3])
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.hdr", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "sensor.toml", "--out", "o.nc")
    assert_refused(rc, err, "wavelength")
    assert snapshot(tmp_path) == before


# -- silently wrong results: EXR with a wavelength twice --------------------------------------


def test_exr_with_a_repeated_wavelength_is_refused_on_read(tmp_path, monkeypatch, cli):
    import OpenImageIO as oiio

    monkeypatch.chdir(tmp_path)
    for name, value in (("scene", 0.5), ("dark", 0.0), ("white", 1.0)):
        spec = oiio.ImageSpec(5, 6, 4, "float")
        spec.channelnames = ("T.500nm", "T.500,0nm", "T.520nm", "T.540nm")
        spec.attribute("spectralLayoutVersion", "1.0")
        out = oiio.ImageOutput.create(str(tmp_path / f"{name}.exr"))
        assert out.open(str(tmp_path / f"{name}.exr"), spec)
        out.write_image(np.full((6, 5, 4), value, np.float32))
        out.close()
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.exr", "--dark", "dark.exr", "--white", "white.exr",
                     "--out", "o.nc")
    assert_refused(rc, err, "500")
    assert snapshot(tmp_path) == before


def test_exr_with_a_repeated_wavelength_is_refused_on_write(tmp_path):
    from snapcorr.cube import write_cube

    cube = xr.DataArray(np.ones((6, 5, 3), np.float32), dims=("y", "x", "band"),
                        coords={"wavelength": ("band", [500.0, 500.0, 520.0], {"units": "nm"})},
                        name="reflectance")
    with pytest.raises(ValueError, match="500"):
        write_cube(cube, tmp_path / "twice.exr")
    assert list(tmp_path.iterdir()) == []


# -- silently wrong results: everything (or most) masked --------------------------------------


@pytest.mark.parametrize("white", [10.0, 5.0], ids=["white-equals-dark", "white-below-dark"])
def test_white_not_above_dark_anywhere_is_refused(tmp_path, monkeypatch, white, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, dark=10.0, white=white)
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert_refused(rc, err)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("which", ["raw", "dark", "white"])
def test_all_nan_input_is_refused(tmp_path, monkeypatch, which, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    np.save(tmp_path / f"{which}.npy", np.full((12, 10, 4), np.nan, np.float32))
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert_refused(rc, err)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("value", ["nan", "-1"])
def test_saturation_that_masks_everything_is_refused(tmp_path, monkeypatch, value, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc", f"--saturation={value}")
    assert_refused(rc, err, "saturation")
    assert snapshot(tmp_path) == before


def test_more_than_half_masked_is_a_loud_warning(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    white = np.full((12, 10, 4), 400.0, np.float32)
    white[:7] = 10.0  # 7 of 12 rows: white == dark
    np.save(tmp_path / "white.npy", white)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert rc == 0, err
    warned = [ln for ln in err.splitlines() if "warning" in ln.lower() and "mask" in ln.lower()]
    assert warned, f"no warning about the masked values:\n{err}"
    assert read_result(tmp_path / "o.nc")["mask"].values.mean() == pytest.approx(7 / 12)


@pytest.mark.parametrize("which, value", [("dark", 10.0), ("white", 400.0)])
def test_reference_with_more_rows_than_the_cube_is_refused(tmp_path, monkeypatch, which,
                                                          value, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    np.save(tmp_path / f"{which}.npy", np.full((20, 10, 4), value, np.float32))
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert_refused(rc, err, which)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("dtype", [np.complex64, np.bool_], ids=["complex", "bool"])
@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_complex_or_bool_cube_is_refused(tmp_path, monkeypatch, command, dtype, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    np.save(tmp_path / "raw.npy", np.ones((12, 10, 4), dtype))
    args = (*FF, "--out", "o.nc") if command == "flatfield" else correct_args("raw.npy", "o.nc")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "complex" if dtype is np.complex64 else "bool")
    assert snapshot(tmp_path) == before


# -- inputs real users have: raw mosaic frames ------------------------------------------------


def _save_frame(path, frame):
    if path.suffix == ".npy":
        np.save(path, frame)
    elif path.suffix == ".tif":
        import tifffile

        tifffile.imwrite(path, frame)
    else:
        from spectral.io import envi

        envi.save_image(str(path), frame[:, :, None], dtype=frame.dtype, interleave="bsq",
                        ext=".raw")


@pytest.mark.parametrize("ext", [".npy", ".tif", ".hdr"])
def test_raw_mosaic_frame_goes_through_flatfield_and_correct(tmp_path, monkeypatch, ext, cli):
    """A full 1088 x 2048 frame of the bundled 4 x 4 mosaic, as the camera gives it."""
    monkeypatch.chdir(tmp_path)
    rows, cols = 1088, 2048
    rng = np.random.default_rng(4)
    raw = rng.integers(100, 200, (rows, cols)).astype(np.uint16)  # as the camera gives it
    _save_frame(tmp_path / f"raw{ext}", raw)
    _save_frame(tmp_path / f"dark{ext}", np.full((rows, cols), 10, np.uint16))
    _save_frame(tmp_path / f"white{ext}", np.full((rows, cols), 400, np.uint16))
    rc, _, err = cli("flatfield", f"raw{ext}", "--dark", f"dark{ext}", "--white",
                     f"white{ext}", "--sensor", MOSAIC, "--out", "ff.nc")
    assert rc == 0, err
    ff = read_result(tmp_path / "ff.nc")
    assert ff["reflectance"].shape == (rows // 4, cols // 4, 16)
    from snapcorr.cube import Sensor, mosaic_to_cube

    expected = mosaic_to_cube((raw.astype(float) - 10.0) / 390.0, Sensor.load(MOSAIC))
    np.testing.assert_allclose(ff["reflectance"].values, expected.values, rtol=1e-5)
    rc, _, err = cli(*correct_args("ff.nc", "c.nc", "--method", "none", sensor=MOSAIC))
    assert rc == 0, err
    res = read_result(tmp_path / "c.nc")
    assert res["wavelength_corrected"].shape == (rows // 4, cols // 4, 16)
    cra = cra_of(res)
    assert "band" in cra.dims and not np.allclose(cra.isel(band=0), cra.isel(band=15)), \
        "every band of a mosaic sits at its own place on the sensor"


def test_raw_mosaic_crop_with_origin_goes_through_flatfield(tmp_path, monkeypatch, cli):
    """A 64 x 64 crop of the raw frame at row 400, column 800: positions as mosaic_to_cube's."""
    from snapcorr import Lens
    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor, mosaic_to_cube

    monkeypatch.chdir(tmp_path)
    frame = np.random.default_rng(6).uniform(100, 200, (64, 64)).astype(np.float32)
    np.save(tmp_path / "raw.npy", frame)
    np.save(tmp_path / "dark.npy", np.full((64, 64), 10.0, np.float32))
    np.save(tmp_path / "white.npy", np.full((64, 64), 400.0, np.float32))
    rc, _, err = cli("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", MOSAIC, "--sensor-origin-px", "400,800", "--out", "ff.nc")
    assert rc == 0, err
    rc, _, err = cli(*correct_args("ff.nc", "c.nc", "--center-px", "1024,544", "--method",
                                   "none", sensor=MOSAIC))
    assert rc == 0, err
    sensor = Sensor.load(MOSAIC)
    expected = cra_of(correct_cube(mosaic_to_cube(frame, sensor, origin_px=(400, 800)),
                                   sensor, 1.4, Lens.load(LENS), center_px=(1024.0, 544.0),
                                   method="none"))
    np.testing.assert_allclose(cra_of(read_result(tmp_path / "c.nc")).values, expected.values,
                               rtol=0, atol=1e-9)


def test_raw_mosaic_crop_off_the_tile_grid_follows_the_layout(tmp_path, monkeypatch, cli):
    """A camera's region of interest may start at any row: the bands are found where the
    tile grid puts them (they were once refused)."""
    monkeypatch.chdir(tmp_path)
    rng = np.random.default_rng(2)
    frames = {"raw": rng.uniform(100, 200, (64, 64)), "dark": np.full((64, 64), 10.0),
              "white": rng.uniform(300, 400, (64, 64))}
    for name, value in frames.items():
        np.save(tmp_path / f"{name}.npy", value.astype(np.float32))
    rc, _, err = cli("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", MOSAIC, "--sensor-origin-px", "401,802", "--out", "ff.nc")
    assert rc == 0, err
    from snapcorr.cube import read_dataset

    ds = read_dataset(tmp_path / "ff.nc")
    rows, cols = ds.sensor_row.values, ds.sensor_col.values
    ff = (frames["raw"] - 10.0) / (frames["white"] - 10.0)
    for b in range(16):  # the 4 x 4 sensor's band b sits at tile row b // 4, column b % 4
        assert np.all(rows[:, b] % 4 == b // 4) and np.all(cols[:, b] % 4 == b % 4)
        assert_allclose(ds["reflectance"].values[:, :, b],
                        ff[rows[:, b][:, None] - 401, cols[:, b][None, :] - 802], rtol=1e-6)


# -- inputs real users have: multi-page TIFF --------------------------------------------------


def _multipage(path, cube):
    import tifffile

    with tifffile.TiffWriter(path) as tw:
        for b in range(cube.shape[2]):
            tw.write(np.ascontiguousarray(cube[:, :, b]), photometric="minisblack")


def test_multipage_tiff_is_a_cube_in_flatfield(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sensor.toml").write_text(SENSOR4)
    raw = np.random.default_rng(5).uniform(100, 200, (12, 10, 4)).astype(np.float32)
    raw[:, :, 2] += 1000  # bands differ, so a page mix-up shows
    _multipage(tmp_path / "raw.tif", raw)
    _multipage(tmp_path / "dark.tif", np.full((12, 10, 4), 10.0, np.float32))
    _multipage(tmp_path / "white.tif", np.full((12, 10, 4), 2000.0, np.float32))
    rc, _, err = cli("flatfield", "raw.tif", "--dark", "dark.tif", "--white", "white.tif",
                     "--sensor", "sensor.toml", "--out", "ff.nc")
    assert rc == 0, err
    got = read_result(tmp_path / "ff.nc")["reflectance"]
    assert got.shape == (12, 10, 4)
    np.testing.assert_allclose(got.values, (raw - 10.0) / 1990.0, rtol=1e-5)


def test_multipage_tiff_with_pages_of_different_sizes_is_refused(tmp_path, monkeypatch, cli):
    import tifffile

    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    with tifffile.TiffWriter(tmp_path / "scene.tif") as tw:
        for b in range(4):
            tw.write(np.ones((12, 10) if b != 2 else (12, 9), np.float32),
                     photometric="minisblack")
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.tif", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "sensor.toml", "--out", "o.nc")
    assert_refused(rc, err, "scene.tif")
    assert snapshot(tmp_path) == before


def test_multipage_tiff_flat_with_pages_of_different_sizes_is_refused(tmp_path, monkeypatch, cli):
    import tifffile

    monkeypatch.chdir(tmp_path)
    with tifffile.TiffWriter(tmp_path / "f14.tif") as tw:
        for shape in ((64, 64), (64, 64), (32, 64)):
            tw.write(np.full(shape, 1000.0, np.float32), photometric="minisblack")
    np.save(tmp_path / "f2.npy", np.full((64, 64), 1000.0))
    before = snapshot(tmp_path)
    rc, _, err = cli("calibrate", "--flat", "1.4=f14.tif", "--flat", "2=f2.npy",
                     "--exit-pupil-mm", "21", "--pixel-pitch-um", "5.5", "--out", "lens.toml")
    assert_refused(rc, err, "f14.tif")
    assert snapshot(tmp_path) == before


def test_multipage_tiff_is_a_cube_in_correct(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sensor.toml").write_text(SENSOR4)
    _multipage(tmp_path / "scene.tif", np.ones((12, 10, 4), np.float32))
    rc, _, err = cli(*correct_args("scene.tif", "c.nc"))
    assert rc == 0, err
    assert read_result(tmp_path / "c.nc")["wavelength_corrected"].shape == (12, 10, 4)


def test_multipage_tiff_flats_are_averaged_in_calibrate(tmp_path, monkeypatch, cli):
    from snapcorr import Lens
    from snapcorr.simulate import flat_frame

    monkeypatch.chdir(tmp_path)
    lens = Lens.load(LENS)
    rng = np.random.default_rng(0)
    args = []
    for f in (1.4, 2, 2.8, 4, 8):
        flat = flat_frame((256, 256), 44.0, f, lens, center_px=(130, 120), rng=rng)
        _multipage(tmp_path / f"f{f}.tif", np.stack([flat] * 3, axis=-1))
        args += ["--flat", f"{f}=f{f}.tif"]
    rc, _, err = cli("calibrate", *args, "--exit-pupil-mm", "21", "--pixel-pitch-um", "44",
                     "--magnification", "0.06", "--pupil-magnification", "1.3",
                     "--out", "lens.toml")
    assert rc == 0, err
    assert err.count("mean of 3 bands") == 5, err
    got = Lens.load(tmp_path / "lens.toml")
    assert got.vignetting[0][0] == pytest.approx(7.4236, rel=0.02)
    assert got.vignetting[0][1] == pytest.approx(16.991, rel=0.03)


# -- inputs real users have: a crop of the sensor ---------------------------------------------

SENSOR_2048 = """\
[sensor]
name = "full-2048"
layout = "snapscan"
pixel_pitch_um = 5.5
size_px = [2048, 2048]
cwl_nm = [550.0, 650.0]
fwhm_nm = 10.0
n_eff = 1.7
"""


@pytest.fixture(scope="module")
def full_frame_cra():
    """The CRA map of the whole 2048 x 2048 sensor, as snapcorr computes it for a full frame."""
    from snapcorr import Lens
    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor, make_cube

    doc = __import__("tomllib").loads(SENSOR_2048)["sensor"]
    sensor = Sensor.from_dict(doc)
    cube = make_cube(np.zeros((2048, 2048, 2), np.float32), [550.0, 650.0])
    return np.asarray(cra_of(correct_cube(cube, sensor, 1.4, Lens.load(LENS), method="none")))


def _crop(tmp_path, row=896, col=640):
    (tmp_path / "s2048.toml").write_text(SENSOR_2048)
    np.save(tmp_path / "crop.npy", np.ones((256, 256, 2), np.float32))
    return row, col


def test_crop_without_origin_is_refused(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    _crop(tmp_path)
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("crop.npy", "c.nc", sensor="s2048.toml"))
    assert_refused(rc, err, "--sensor-origin-px")
    assert snapshot(tmp_path) == before


def test_crop_with_origin_has_the_full_frames_cra(tmp_path, monkeypatch, full_frame_cra, cli):
    monkeypatch.chdir(tmp_path)
    r, c = _crop(tmp_path)
    rc, _, err = cli(*correct_args("crop.npy", "c.nc", "--sensor-origin-px", f"{r},{c}",
                                   "--method", "none", sensor="s2048.toml"))
    assert rc == 0, err
    cra = cra_of(read_result(tmp_path / "c.nc")).values
    np.testing.assert_allclose(cra, full_frame_cra[r:r + 256, c:c + 256], rtol=0, atol=1e-9)


def test_crop_origin_survives_the_written_result(tmp_path, monkeypatch, full_frame_cra, cli):
    monkeypatch.chdir(tmp_path)
    r, c = _crop(tmp_path)
    rc, _, err = cli(*correct_args("crop.npy", "c.nc", "--sensor-origin-px", f"{r},{c}",
                                   "--method", "none", sensor="s2048.toml"))
    assert rc == 0, err
    # the written result, corrected again, needs no origin: it carries it
    rc, _, err = cli(*correct_args("c.nc", "again.nc", "--method", "none", sensor="s2048.toml"))
    assert rc == 0, err
    cra = cra_of(read_result(tmp_path / "again.nc")).values
    np.testing.assert_allclose(cra, full_frame_cra[r:r + 256, c:c + 256], rtol=0, atol=1e-9)


def test_crop_origin_survives_flatfielding(tmp_path, monkeypatch, mosaic_cube, cli):
    """A mosaic crop (origin 400, 800 on the sensor) flat-fielded, then corrected."""
    from snapcorr import Lens
    from snapcorr.correct import correct_cube
    from snapcorr.cube import write_cube

    monkeypatch.chdir(tmp_path)
    cube, sensor = mosaic_cube
    write_cube(cube, tmp_path / "crop.nc")
    np.save(tmp_path / "dark.npy", np.full(cube.shape, 10.0, np.float32))
    np.save(tmp_path / "white.npy", np.full(cube.shape, 400.0, np.float32))
    rc, _, err = cli("flatfield", "crop.nc", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", MOSAIC, "--out", "ff.nc")
    assert rc == 0, err
    rc, _, err = cli(*correct_args("ff.nc", "c.nc", "--center-px", "1024,544", "--method",
                                   "none", sensor=MOSAIC))
    assert rc == 0, err
    expected = cra_of(correct_cube(cube, sensor, 1.4, Lens.load(LENS),
                                  center_px=(1024.0, 544.0), method="none")).values
    np.testing.assert_allclose(cra_of(read_result(tmp_path / "c.nc")).values, expected,
                               rtol=0, atol=1e-9)


@pytest.mark.parametrize("origin", ["1900,1900", "-4,0"])
def test_crop_reaching_past_the_sensor_is_refused(tmp_path, monkeypatch, origin, cli):
    monkeypatch.chdir(tmp_path)
    _crop(tmp_path)
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("crop.npy", "c.nc", f"--sensor-origin-px={origin}",
                                   sensor="s2048.toml"))
    assert_refused(rc, err, "--sensor-origin-px")
    assert snapshot(tmp_path) == before


# -- inputs real users have: the optical centre of a lens calibrated on another binning -------


def _calibrated_lens(folder):
    text = LENS.read_text().split("[calibration]")[0]
    text += ("[calibration]\ncenter_px = [1100.0, 950.0]\npixel_pitch_um = 5.5\n"
             "image_size_px = [2048, 2048]\n")
    (folder / "lens.toml").write_text(text)


def _sensor(pitch, size):
    return (f'[sensor]\nname = "binned"\nlayout = "snapscan"\npixel_pitch_um = {pitch}\n'
            f"size_px = [{size}, {size}]\ncwl_nm = [550.0, 650.0]\nfwhm_nm = 10.0\n"
            "n_eff = 1.7\n")


def test_lens_center_follows_binning(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    _calibrated_lens(tmp_path)
    (tmp_path / "binned.toml").write_text(_sensor(11.0, 1024))
    np.save(tmp_path / "binned.npy", np.ones((1024, 1024, 2), np.float32))
    rc, _, err = cli(*correct_args("binned.npy", "c.nc", "--method", "none",
                                   sensor="binned.toml", lens="lens.toml"))
    assert rc == 0, err
    res = read_result(tmp_path / "c.nc")
    cx, cy = ((1100 + 0.5) * 5.5 / 11 - 0.5, (950 + 0.5) * 5.5 / 11 - 0.5)
    np.testing.assert_allclose(res.attrs["optical_center_px"], [cx, cy], rtol=0, atol=1e-9)
    y, x = np.mgrid[0:1024, 0:1024]
    expected = np.degrees(np.arctan(np.hypot(x - cx, y - cy) * 0.011 / 21.0))
    np.testing.assert_allclose(cra_of(res).values, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize("pitch, size", [(11.0, 512), (5.5, 1024)],
                         ids=["binned-half-size", "same-pitch-smaller-sensor"])
def test_lens_center_on_a_sensor_of_another_size_is_refused(tmp_path, monkeypatch, pitch, size,
                                                            cli):
    monkeypatch.chdir(tmp_path)
    _calibrated_lens(tmp_path)
    (tmp_path / "other.toml").write_text(_sensor(pitch, size))
    np.save(tmp_path / "cube.npy", np.ones((size, size, 2), np.float32))
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("cube.npy", "c.nc", "--method", "none",
                                   sensor="other.toml", lens="lens.toml"))
    assert_refused(rc, err, "--center ROW,COL")
    assert snapshot(tmp_path) == before


# -- error messages in command-line terms -----------------------------------------------------


@pytest.mark.parametrize("ext", [".npy", ".tif"])
def test_missing_wavelengths_name_the_sensor_option(tmp_path, monkeypatch, ext, cli):
    import tifffile

    monkeypatch.chdir(tmp_path)
    for name, value in (("raw", 150.0), ("dark", 10.0), ("white", 400.0)):
        data = np.full((12, 10, 4), value, np.float32)
        if ext == ".npy":
            np.save(tmp_path / f"{name}.npy", data)
        else:
            tifffile.imwrite(tmp_path / f"{name}.tif", data, photometric="minisblack",
                             planarconfig="contig")
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", f"raw{ext}", "--dark", f"dark{ext}", "--white",
                     f"white{ext}", "--out", "o.nc")
    line = assert_refused(rc, err, "--sensor")
    assert "wavelength_nm" not in line
    assert snapshot(tmp_path) == before


def test_budget_source_cube_without_cube_names_the_option(cli):
    rc, _, err = cli("budget", "--sensor", "snapscan_vnir", "--lens", "edmund_optics_16mm",
                     "--f-number", "1.4", "--source", "cube")
    assert_refused(rc, err, "--cube")


def test_shift_past_the_cutoff_says_so_and_gives_the_angle(cli):
    from snapcorr import Lens

    cutoff = float(Lens.load(LENS).cutoff_cra_deg(1.4))
    rc, _, err = cli("shift", "--cra", "45", "--f-number", "1.4")
    line = assert_refused(rc, err, "cut")
    numbers = [float(v) for v in re.findall(r"\d+\.\d+", line)]
    assert any(abs(v - cutoff) < 0.051 for v in numbers), f"no {cutoff:.2f} in: {line}"


@pytest.mark.parametrize("command", ["shift", "budget", "correct"])
def test_unknown_bundled_lens_lists_the_bundled_ones(tmp_path, monkeypatch, command, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    args = {
        "shift": ("shift", "--lens", "no_such_lens", "--f-number", "1.4", "--cra", "5"),
        "budget": ("budget", "--sensor", "snapscan_vnir", "--lens", "no_such_lens",
                   "--f-number", "1.4", "--source", "tungsten:3000", "--cra-max", "5"),
        "correct": correct_args("raw.npy", "o.nc", lens="no_such_lens"),
    }[command]
    rc, _, err = cli(*args)
    assert_refused(rc, err, "no bundled lens named 'no_such_lens'", "edmund_optics_16mm")


# -- outputs ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def pipeline(tmp_path_factory, cli):
    """raw -> flatfield (.nc, .zarr) -> correct --resample (.nc, .zarr), one masked pixel."""
    d = tmp_path_factory.mktemp("pipeline")
    save_cubes(d)
    white = np.full((12, 10, 4), 400.0, np.float32)
    white[3, 4, :] = 10.0  # white == dark here: masked
    np.save(d / "white.npy", white)
    runs = {}
    for ext in (".nc", ".zarr"):
        runs[f"ff{ext}"] = cli(*FF, "--out", f"ff{ext}", cwd=d)
        runs[f"c{ext}"] = cli(*correct_args(f"ff{ext}", f"c{ext}", "--resample",
                                            "--source", "tungsten:3000"), cwd=d)
    return d, runs


def _ok(pipeline, name):
    d, runs = pipeline
    rc, _, err = runs[name]
    assert rc == 0, err
    return d / name


def _correct_as_the_cli_does(cube, sensor):
    """``correct --resample --source tungsten:3000`` at f/1.4, in memory."""
    from snapcorr import Lens
    from snapcorr.budget import recommend_model
    from snapcorr.correct import correct_cube

    lens = Lens.load(LENS)
    model, _, attrs = recommend_model(cube, sensor, 1.4, lens, "tungsten:3000")
    ds = correct_cube(cube, sensor, 1.4, lens, method=model, resample=True)
    ds.attrs.update(attrs)
    return ds


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_every_attribute_of_correct_is_written(pipeline, ext):
    from snapcorr.cube import Sensor, read_cube

    path = _ok(pipeline, f"c{ext}")
    d = pipeline[0]
    sensor = Sensor.load(d / "sensor.toml")
    cube = read_cube(d / f"ff{ext}", wavelength_nm=sensor.cwl_nm)
    mem = _correct_as_the_cli_does(cube, sensor).attrs
    written = read_result(path).attrs
    assert "optical_center_px" in mem
    _compare_attrs(mem, written)


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_every_attribute_of_flatfield_is_written(pipeline, ext):
    from snapcorr.cube import Sensor, flatfield, read_cube

    path = _ok(pipeline, f"ff{ext}")
    d = pipeline[0]
    wl = Sensor.load(d / "sensor.toml").cwl_nm
    mem = flatfield(*(read_cube(d / f"{n}.npy", wavelength_nm=wl)
                      for n in ("raw", "dark", "white"))).attrs
    written = read_result(path).attrs
    _compare_attrs(mem, written, skip_values=("created", "source"))


def _compare_attrs(mem, written, skip_values=()):
    missing = sorted(set(mem) - set(written))
    assert not missing, f"not in the file: {missing}"
    for k, v in mem.items():
        if k in skip_values:
            continue
        w = written[k]
        if isinstance(v, str):
            assert w == v, (k, v, w)
        elif isinstance(v, (list, tuple, np.ndarray)):
            assert isinstance(w, (list, tuple, np.ndarray)), (k, v, w)
            assert np.shape(w) == np.shape(v), (k, v, w)
            if len(v) and isinstance(np.asarray(v).flat[0], str):
                assert list(w) == list(v), (k, v, w)
            else:
                np.testing.assert_allclose(np.asarray(w, float), np.asarray(v, float),
                                           rtol=1e-12, err_msg=k)
        elif isinstance(v, (bool, np.bool_)):
            assert bool(w) == bool(v), (k, v, w)
        else:
            assert float(w) == pytest.approx(float(v), rel=1e-12), (k, v, w)


@pytest.mark.parametrize("name, var", [
    ("ff.nc", "reflectance"), ("ff.nc", "mask"), ("c.nc", "cra"),
    ("c.nc", "wavelength_corrected"), ("c.nc", "resampled"), ("c.nc", "reflectance"),
])
def test_cf_units_and_long_name(pipeline, name, var):
    ds = read_result(_ok(pipeline, name))
    if var == "cra":
        var = cra_of(ds).name
    assert var in ds.variables, f"{var} not in {name}"
    attrs = ds[var].attrs
    assert str(attrs.get("units", "")).strip(), f"{var} has no units: {attrs}"
    assert str(attrs.get("long_name", "")).strip(), f"{var} has no long_name: {attrs}"


def test_cf_units_and_long_name_in_zarr(pipeline):
    ds = read_result(_ok(pipeline, "c.zarr"))
    for var in ("reflectance", "mask", cra_of(ds).name, "wavelength_corrected", "resampled"):
        assert var in ds.variables, var
        assert str(ds[var].attrs.get("units", "")).strip(), var
        assert str(ds[var].attrs.get("long_name", "")).strip(), var


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_written_result_reads_back_as_computed(pipeline, ext):
    from snapcorr.cube import Sensor, read_cube

    path = _ok(pipeline, f"c{ext}")
    d = pipeline[0]
    sensor = Sensor.load(d / "sensor.toml")
    cube = read_cube(d / f"ff{ext}", wavelength_nm=sensor.cwl_nm)
    mem = _correct_as_the_cli_does(cube, sensor)
    got = read_result(path)
    for var in ("wavelength_corrected", "resampled", "reflectance"):
        np.testing.assert_allclose(np.asarray(got[var].values, float),
                                   np.asarray(mem[var].values, float), rtol=1e-6,
                                   equal_nan=True, err_msg=var)
    np.testing.assert_allclose(cra_of(got).values, cra_of(mem).values, rtol=1e-12)


def test_wavelength_corrected_is_a_coordinate_to_plot_against(pipeline):
    import matplotlib.pyplot as plt

    ds = read_result(_ok(pipeline, "c.nc"))
    assert "wavelength_corrected" in ds.coords
    fig = plt.figure()
    try:
        ds["reflectance"].isel(y=0, x=0).plot(x="wavelength_corrected")
    finally:
        plt.close(fig)


def test_flatfield_mask_is_carried_into_correct(pipeline):
    ff = read_result(_ok(pipeline, "ff.nc"))
    res = read_result(_ok(pipeline, "c.nc"))
    assert "mask" in res.variables
    np.testing.assert_array_equal(res["mask"].values, ff["mask"].values)
    assert bool(res["mask"].values[3, 4].all()) and int(res["mask"].values.sum()) == 4


@pytest.mark.parametrize("name", ["ff.zarr", "c.zarr"])
def test_zarr_result_opens_with_consolidated_metadata_without_warnings(pipeline, name):
    path = _ok(pipeline, name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds = xr.open_zarr(path)
        assert "reflectance" in ds
    assert not caught, [str(w.message) for w in caught]


@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_plot_writes_a_png(tmp_path, monkeypatch, command, cli):
    import matplotlib.image

    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    if command == "flatfield":
        args = (*FF, "--out", "o.nc", "--plot", "look.png")
    else:
        args = correct_args("raw.npy", "o.nc", "--plot", "look.png")
    rc, _, err = cli(*args)
    assert rc == 0, err
    img = matplotlib.image.imread(tmp_path / "look.png")
    assert img.ndim == 3 and min(img.shape[:2]) > 50


# -- help -------------------------------------------------------------------------------------


@pytest.mark.parametrize("sub", SUBCOMMANDS)
def test_help_shows_this_subcommands_examples_only(sub, cli):
    rc, out, _ = cli(sub, "--help")
    assert rc == 0
    assert "examples:" in out
    examples = out.split("examples:", 1)[1]
    assert re.search(rf"\bsnapcorr {sub}\b", examples), examples
    others = [o for o in SUBCOMMANDS if o != sub and re.search(rf"\bsnapcorr {o}\b", out)]
    assert not others, f"'snapcorr {sub} --help' shows examples of {others}"


@pytest.mark.parametrize("sub", SUBCOMMANDS)
def test_every_option_has_help_text(sub):
    from snapcorr.cli import build_parser

    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    missing = [a.dest for a in subs.choices[sub]._actions
               if not isinstance(a, argparse._HelpAction)
               and (not a.help or a.help == argparse.SUPPRESS or not a.help.strip())]
    assert not missing, f"snapcorr {sub}: options without help: {missing}"
