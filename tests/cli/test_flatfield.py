"""`snapcorr flatfield`: the result, and every foreseeable mistake as one line, no output."""

import io
import re
import sys

import numpy as np
import pytest
import xarray as xr
from numpy.testing import assert_allclose

from snapcorr.cube import Sensor, make_cube, write_cube

WL = np.linspace(500.0, 800.0, 4)


@pytest.fixture
def files(tmp_path):
    rng = np.random.default_rng(0)
    scene = rng.integers(100, 3000, (6, 5, 4)).astype(np.uint16)
    write_cube(make_cube(scene, WL), tmp_path / "scene.hdr")
    write_cube(make_cube(np.full((6, 5, 4), 50, np.uint16), WL), tmp_path / "dark.hdr")
    write_cube(make_cube(np.full((1, 5, 4), 3050, np.uint16), WL), tmp_path / "white.tif")
    write_cube(make_cube(np.full((6, 5, 4), 1550, np.uint16), WL), tmp_path / "fw.nc")
    return tmp_path, scene


def test_flatfield_writes_result_mask_raw_and_provenance(files, cli):
    d, scene = files
    res = cli("flatfield", "scene.hdr", "--dark", "dark.hdr", "--dark", "dark.hdr", "--white",
              "white.tif", "--filter-white", "fw.nc", "--out", "out.nc", cwd=d)
    assert res.returncode == 0, res.stderr
    assert "0 of 120 values masked" in res.stdout
    ds = xr.open_dataset(d / "out.nc")
    assert_allclose(ds.reflectance.values, (scene - 50.0) / 3000.0)
    assert_allclose(ds.transmittance.values, 0.5)
    assert (ds.raw.values == scene).all() and not ds.mask.values.any()
    assert ds.attrs["raw_file"] == "scene.hdr" and ds.attrs["dark_frames"] == 2
    assert "snapcorr_version" in ds.attrs and "created" in ds.attrs


def _assert_clean_failure(res, d, message, before):
    assert res.returncode != 0
    assert "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], res.stderr
    assert sorted(p.name for p in d.iterdir()) == before  # nothing written, nothing left


def test_truncated_data_file(files, cli):
    d, _ = files
    raw = d / "scene.raw"
    raw.write_bytes(raw.read_bytes()[:-7])
    before = sorted(p.name for p in d.iterdir())
    res = cli("flatfield", "scene.hdr", "--dark", "dark.hdr", "--white", "white.tif", "--out",
              "o.nc", cwd=d)
    _assert_clean_failure(res, d, "truncated", before)


def test_header_band_count_differs_from_data(files, cli):
    d, _ = files
    hdr = d / "scene.hdr"
    hdr.write_text(hdr.read_text().replace("bands = 4", "bands = 3"))
    before = sorted(p.name for p in d.iterdir())
    res = cli("flatfield", "scene.hdr", "--dark", "dark.hdr", "--white", "white.tif", "--out",
              "o.nc", cwd=d)
    _assert_clean_failure(res, d, "bytes", before)


def test_wavelength_list_length_mismatch(files, cli):
    d, _ = files
    hdr = d / "scene.hdr"
    text = hdr.read_text()
    start = text.index("wavelength = {")
    hdr.write_text(text[:start] + "wavelength = {500, 600, 700}" +
                   text[text.index("}", start) + 1:])
    before = sorted(p.name for p in d.iterdir())
    res = cli("flatfield", "scene.hdr", "--dark", "dark.hdr", "--white", "white.tif", "--out",
              "o.nc", cwd=d)
    _assert_clean_failure(res, d, "4 bands but 3 wavelengths", before)


def test_shape_mismatch_between_inputs(files, cli):
    d, _ = files
    write_cube(make_cube(np.zeros((6, 4, 4), np.uint16), WL), d / "small_dark.hdr")
    before = sorted(p.name for p in d.iterdir())
    res = cli("flatfield", "scene.hdr", "--dark", "small_dark.hdr", "--white", "white.tif", "--out",
              "o.nc", cwd=d)
    _assert_clean_failure(res, d, "x and band must match", before)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["scene.xyz", "--dark", "dark.hdr", "--white", "white.tif", "--out", "o.nc"],
         "unknown cube format"),
        (["scene.hdr", "--dark", "dark.hdr", "--white", "white.tif", "--out", "o.txt"],
         ".nc or .zarr"),
        (["scene.hdr", "--dark", "dark.hdr", "--white", "white.tif", "--out", "scene.hdr"],
         "also an input"),
        (["scene.hdr", "--dark", "missing.hdr", "--white", "white.tif", "--out", "o.nc"],
         "no such file"),
        (["junk.tif", "--dark", "dark.hdr", "--white", "white.tif", "--out", "o.nc"],
         "cannot read"),
        (["notenvi.hdr", "--dark", "dark.hdr", "--white", "white.tif", "--out", "o.nc"],
         "cannot read"),
    ],
)
def test_bad_arguments(files, args, message, cli):
    d, _ = files
    (d / "junk.tif").write_bytes(b"this is no tiff")
    (d / "scene.xyz").write_bytes(b"?")
    (d / "notenvi.hdr").write_text("this is no ENVI header\n")
    before = sorted(p.name for p in d.iterdir())
    _assert_clean_failure(cli("flatfield", *args, cwd=d), d, message, before)


def test_unreadable_file(files, cli):
    import os

    d, _ = files
    if os.geteuid() == 0:
        # root reads anything: simulate an unreadable file with a directory in its place
        (d / "locked.nc").mkdir()
    else:
        (d / "locked.nc").write_bytes(b"x")
        (d / "locked.nc").chmod(0)
    before = sorted(p.name for p in d.iterdir())
    res = cli("flatfield", "locked.nc", "--dark", "dark.hdr", "--white", "white.tif", "--out",
              "o.nc", cwd=d)
    _assert_clean_failure(res, d, "locked.nc", before)


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_each_stage_shows_one_labelled_progress_bar(tmp_path, monkeypatch):
    from snapcorr import cli
    from snapcorr.cli import _progress

    monkeypatch.chdir(tmp_path)
    wl = [500.0, 600.0, 700.0, 800.0]
    Sensor("s", "snapscan", 5.5, wl, 10.0, 1.7).save(tmp_path / "s.toml")
    for name, value in (("raw", 1500.0), ("dark", 100.0), ("white", 3100.0)):
        np.save(tmp_path / f"{name}.npy", np.full((40, 30, 4), value, np.float32))
    monkeypatch.setattr(_progress._StageBar, "DELAY_S", 0)  # show at once, on a terminal
    err = _Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    assert cli.main(["flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "s.toml", "--out", "o.zarr"]) == 0
    bars = [part.strip() for part in re.split(r"[\r\n]", err.getvalue()) if "block" in part]
    labels = ("flat-fielding (checking the mask)", "writing o.zarr")
    assert bars and all(b.startswith(labels) for b in bars), bars  # none unlabelled
    assert {next(lab for lab in labels if b.startswith(lab)) for b in bars} == set(labels)
    err.truncate(0)
    monkeypatch.setattr(sys, "stderr", io.StringIO())  # a log file or a pipe: no bar at all
    assert cli.main(["flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "s.toml", "--out", "p.zarr"]) == 0
    assert "block" not in sys.stderr.getvalue()


def test_a_filter_white_of_another_size_is_one_line(cli, tmp_path):
    """It gave xarray's alignment error."""
    from snapcorr.cube import make_cube, write_cube

    wl = [500.0, 600.0, 700.0]
    for name, rows, value in (("raw", 6, 500.0), ("dark", 6, 0.0), ("white", 6, 1000.0),
                              ("fw", 5, 400.0)):
        write_cube(make_cube(np.full((rows, 4, 3), value, np.float32), wl),
                   tmp_path / f"{name}.nc")
    res = cli("flatfield", tmp_path / "raw.nc", "--dark", tmp_path / "dark.nc", "--white",
              tmp_path / "white.nc", "--filter-white", tmp_path / "fw.nc", "--out",
              tmp_path / "out.nc")
    assert res.returncode == 1 and "--filter-white" in res.stderr and "5 x 4 x 3" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and not (tmp_path / "out.nc").exists()
