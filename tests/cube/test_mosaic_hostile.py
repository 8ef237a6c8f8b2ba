"""Mosaic cubes and raw mosaic frames on the command line: the sensor positions kept through
every file format, frames and crops through flat-fielding and correction, a crop placed on
the sensor by its origin (and refused without one, past the sensor's edge, or where the
origin contradicts the positions a file records).

Every input is built as a user would make it, with other libraries than snapcorr's
writers (Spectral Python, tifffile, OpenImageIO, numpy, xarray/h5netcdf, TOML written by
hand); each refusal is the exit status and one error line naming the problem in
command-line terms, with nothing written."""

from __future__ import annotations

import numpy as np
import pytest
from hostile import (
    LENS,
    MOSAIC_WL,
    REPO,
    assert_refused,
    correct_args,
    cra_of,
    read_result,
    refused_in_one_line,
    snapshot,
)
from numpy.testing import assert_allclose

from snapcorr import Lens

MOSAIC = REPO / "calibration" / "sensors" / "mosaic_4x4_vis.toml"


@pytest.fixture
def mosaic_cube():
    from snapcorr.cube import Sensor, mosaic_to_cube

    sensor = Sensor.load(MOSAIC)
    frame = np.random.default_rng(3).uniform(100, 200, (64, 64)).astype(np.float32)
    return mosaic_to_cube(frame, sensor, sensor_origin_px=(400, 800)), sensor


@pytest.mark.parametrize("ext", [".hdr", ".tif", ".exr", ".npy", ".nc", ".zarr"])
def test_mosaic_cube_keeps_its_sensor_positions_through_a_file(tmp_path, monkeypatch,
                                                               mosaic_cube, ext, cli):
    """Written and read back, the cube corrects to the same CRA as in memory.

    A format that cannot hold the positions must refuse to write them away (the README:
    every format refuses what it cannot hold).
    """
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
    expected = cra_of(correct_cube(mosaic_to_cube(frame, sensor, sensor_origin_px=(400, 800)),
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


def test_an_origin_that_contradicts_the_files_positions_is_refused(tmp_path, cli):
    """A file's recorded positions are used; an option that says otherwise is refused rather
    than silently ignored."""
    from snapcorr.cube import Sensor, make_cube, sensor_positions, write_cube
    from snapcorr.cube.model import with_positions

    sensor = Sensor("p", "snapscan", 5.5, [500.0, 550.0], 10.0, 1.7)
    rng = np.random.default_rng(3)
    for name, level in (("raw", 200.0), ("dark", 10.0), ("white", 400.0)):
        c = make_cube((level + rng.random((6, 7, 2))).astype(np.float32), [500.0, 550.0])
        write_cube(with_positions(c, *sensor_positions(sensor, 6, 7, (10, 20))),
                   tmp_path / f"{name}.nc")
    sensor.save(tmp_path / "s.toml")
    args = ("flatfield", "raw.nc", "--dark", "dark.nc", "--white", "white.nc", "--sensor",
            "s.toml", "--sensor-origin-px")
    assert cli(*args, "10,20", "--out", "a.nc", cwd=tmp_path).returncode == 0
    err = refused_in_one_line(cli(*args, "10,21", "--out", "b.nc", cwd=tmp_path))
    assert "disagrees with the sensor positions raw.nc records" in err
