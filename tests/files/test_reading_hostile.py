"""Inputs that are not regular files: a FIFO, a device, a folder named like a cube, a symlink
loop and unreadable ENVI data are each one error line, promptly, with nothing written.

Every input is built as a user would make it, with other libraries than snapcorr's
writers (Spectral Python, tifffile, OpenImageIO, numpy, xarray/h5netcdf, TOML written by
hand); each refusal is the exit status and one error line naming the problem in
command-line terms, with nothing written."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from hostile import (
    assert_refused,
    correct_args,
    save_cubes,
    snapshot,
    write_envi,
)


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


def _two_cubes(path, names=("a", "b"), dims=("y", "x", "band")):
    import xarray as xr

    shape = (4, 5, 3)[:len(dims)]
    rng = np.random.default_rng(0)
    ds = xr.Dataset({n: (dims, rng.random(shape)) for n in names},
                    coords={"wavelength": ("band", [500.0, 600.0, 700.0])} if "band" in dims
                    else {})
    if path.suffix == ".zarr":
        ds.to_zarr(path)
    else:
        ds.to_netcdf(path, engine="h5netcdf")
    return path


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_a_file_of_two_unknown_cubes_is_refused_naming_them(tmp_path, ext):
    from snapcorr.cube import read_cube

    path = _two_cubes(tmp_path / f"two{ext}", ("scene_a", "scene_b"))
    with pytest.raises(ValueError, match=r"two\.\w+ holds 2 cubes .*scene_a, scene_b.*alone"):
        read_cube(path)


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_a_file_of_two_unknown_frames_is_refused_naming_them(tmp_path, ext):
    from snapcorr.cube import read_frame

    path = _two_cubes(tmp_path / f"two{ext}", ("dark_a", "dark_b"), dims=("y", "x"))
    with pytest.raises(ValueError, match=r"holds 2 frames .*dark_a, dark_b"):
        read_frame(path)


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_one_unknown_cube_beside_snapcorrs_own_variables_is_read(tmp_path, ext):
    from snapcorr.cube import read_cube

    path = _two_cubes(tmp_path / f"one{ext}", ("resampled", "scene", "harmonised"))
    assert read_cube(path).name == "scene"


def test_correct_refuses_a_file_of_two_unknown_cubes_in_one_line(tmp_path, cli):
    _two_cubes(tmp_path / "two.nc")
    rc, _, err = cli("correct", tmp_path / "two.nc", "--lens", "edmund_optics_16mm", "--sensor",
                     "snapscan_vnir", "--f-number", "2", "--out", tmp_path / "o.nc")
    assert_refused(rc, err, "two.nc", "a, b")
    assert not (tmp_path / "o.nc").exists()


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_a_stream_written_without_its_input_is_said_to_be_a_stream(tmp_path, ext):
    """A stream's file whose raw input was left out (``--no-input``) was said to hold no cube
    for that reason, naming an option the reading command may not have; the reason is that it
    is a stream."""
    import xarray as xr

    from snapcorr.cube import read_cube

    ds = xr.Dataset({"reflectance": (("frame", "y", "x", "band"), np.ones((2, 3, 4, 5)))},
                    attrs={"input_left_out": "raw (--no-input)"})
    path = tmp_path / f"s{ext}"
    ds.to_netcdf(path) if ext == ".nc" else ds.to_zarr(path)
    with pytest.raises(ValueError, match="holds a stream of cubes"):
        read_cube(path)


@pytest.mark.parametrize("shape", [(4, 4, 0), (4, 0, 16), (0, 4, 16)])
def test_an_empty_npy_cube_read_in_blocks_is_refused_for_what_it_is(tmp_path, shape):
    """Read in blocks of rows (as the commands read), a cube without bands failed with a
    ZeroDivisionError from sizing the blocks."""
    from snapcorr.cube import read_cube

    np.save(tmp_path / "e.npy", np.zeros(shape, np.float32))
    with pytest.raises(ValueError) as err:
        read_cube(tmp_path / "e.npy", wavelength_nm=np.arange(max(shape[2], 1)) + 500.0,
                  chunks="rows")
    assert "ZeroDivision" not in str(err.value) and "e.npy" in str(err.value)


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_a_file_of_a_radiance_and_a_reflectance_cube_is_refused(tmp_path, ext):
    """The radiance was read, silently; a reflectance with its filter's transmittance beside
    it (a flat-field result) is still read as the reflectance."""
    import xarray as xr

    from snapcorr.cube import read_cube

    wl = {"wavelength": ("band", np.arange(5) + 500.0)}
    both = xr.Dataset({n: (("y", "x", "band"), np.ones((3, 4, 5))) for n in
                       ("reflectance", "radiance")}, coords=wl)
    path = tmp_path / f"two{ext}"
    both.to_netcdf(path) if ext == ".nc" else both.to_zarr(path)
    with pytest.raises(ValueError, match="radiance and a reflectance"):
        read_cube(path)
    ff = both.rename({"radiance": "transmittance"})
    path = tmp_path / f"ff{ext}"
    ff.to_netcdf(path) if ext == ".nc" else ff.to_zarr(path)
    assert read_cube(path).name == "reflectance"


def test_a_text_table_larger_than_any_is_refused_unread(tmp_path):
    """A 17 MiB two-column file as a spectrum or a sensor's measured filter shape: read whole
    (a 64 MB one took 830 MB and 24 s) before any check."""
    from snapcorr.cube import Sensor
    from snapcorr.spectra import read_spectrum

    big = tmp_path / "big.csv"
    with open(big, "w") as f:
        f.write("0, 1\n" * (17 * 2**20 // 5 + 1))
    with pytest.raises(ValueError, match=r"the spectrum holds 17\.0 MiB of text, more than 16"):
        read_spectrum(big)
    with pytest.raises(ValueError, match=r"the filter profile holds 17\.0 MiB of text"):
        Sensor("s", "snapscan", 5.5, (500.0, 600.0), 10.0, 1.7, profile=str(big))
