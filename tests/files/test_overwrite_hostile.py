"""Overwriting a result: ``--overwrite`` replaces only a previous result snapcorr wrote, never
a folder or file of the user's, never an input (through links too), never a bundled profile,
and two outputs of one command may not lie in one another.

Every input is built as a user would make it, with other libraries than snapcorr's
writers (Spectral Python, tifffile, OpenImageIO, numpy, xarray/h5netcdf, TOML written by
hand); each refusal is the exit status and one error line naming the problem in
command-line terms, with nothing written."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
import xarray as xr
from hostile import (
    FF,
    LENS,
    SENSOR4,
    assert_refused,
    correct_args,
    error_line,
    hidden,
    read_result,
    save_cubes,
    snapshot,
)


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
