"""Values no camera has, in every place a user can give them: integers too large for a float
in lens and sensor files, placement keys of a lens calibration of the wrong type, command-line
numbers that would overflow or exhaust memory, spectrum files that are empty, binary or not
files at all; and outputs that would replace a bundled profile or lie in one another. Each is
one line naming what is wrong, never a traceback."""

from __future__ import annotations

import os

import numpy as np
import pytest

from snapcorr import Lens
from snapcorr.data import lens_path

HUGE = "9" * 400


def _one_line(res):
    assert res.returncode in (1, 2), res.stdout  # 2: argparse's refusal of an option
    assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1, \
        res.stderr
    return res.stderr


@pytest.mark.parametrize("body", [
    f"[lens]\nexit_pupil_mm = {HUGE}\n",
    f"[lens]\nexit_pupil_mm = 21.0\nmagnification = {HUGE}\n",
    f"[lens]\nexit_pupil_mm = 21.0\n[[lens.vignetting]]\nradius_mm = {HUGE}\n"
    "distance_mm = 17.0\n",
])
def test_a_huge_integer_in_a_lens_file_is_one_line(tmp_path, cli, body):
    (tmp_path / "l.toml").write_text(body)
    err = _one_line(cli("shift", "--lens", "l.toml", "--f-number", "2.8", "--cra", "5",
                        cwd=tmp_path))
    assert "finite number" in err and len(err) < 300


@pytest.mark.parametrize("key", ["pixel_pitch_um", "cwl_nm", "size_px", "n_eff", "fwhm_nm"])
def test_a_huge_integer_in_a_sensor_file_is_one_line(tmp_path, cli, key):
    table = {"pixel_pitch_um": "5.5", "cwl_nm": "[500.0, 550.0]", "fwhm_nm": "10.0",
             "n_eff": "1.7", "size_px": "[40, 50]"}
    table[key] = f"[500.0, {HUGE}]" if key == "cwl_nm" else (
        f"[{HUGE}, 50]" if key == "size_px" else HUGE)
    (tmp_path / "s.toml").write_text('[sensor]\nname = "x"\nlayout = "snapscan"\n' + "".join(
        f"{k} = {v}\n" for k, v in table.items()))
    err = _one_line(cli("sensor", "s.toml", cwd=tmp_path))
    assert key in err and len(err) < 300


@pytest.mark.parametrize(("calibration", "match"), [
    ({"pixel_pitch_um": "100"}, "pixel_pitch_um must be a number, got text"),
    ({"pixel_pitch_um": True}, "pixel_pitch_um must be a number, got a boolean"),
    ({"pixel_pitch_um": 10**400}, "pixel_pitch_um must be a finite number"),
    ({"image_size_px": 5}, "image_size_px must be a list of two numbers"),
    ({"image_size_px": [1, 2, 3]}, "image_size_px must be two whole numbers"),
    ({"image_size_px": [640.5, 512]}, "image_size_px must be whole numbers"),
    ({"center_rc": [1.0, "a"]}, "center_rc must be a number, got text"),
    ({"center_px": 3}, "center_px must be a list of two numbers"),
])
def test_the_placement_keys_of_a_calibration_are_checked(calibration, match):
    """These keys place the optical axis on another sensor (correct reads them), so a wrong
    type is refused when the lens is made, not used as 1 um or as garbage later."""
    with pytest.raises(ValueError, match=match):
        Lens(21.0, calibration=calibration)


def test_other_calibration_keys_stay_free_form_and_good_ones_load():
    lens = Lens(21.0, calibration={"center_rc": [250.5, 320.0], "pixel_pitch_um": 5.5,
                                   "image_size_px": [640, 512], "notes": True, "x": "free"})
    assert lens.calibration["notes"] is True


def test_a_lens_file_with_a_pitch_as_text_is_refused(tmp_path, cli):
    (tmp_path / "l.toml").write_text('[lens]\nexit_pupil_mm = 21.0\n[calibration]\n'
                                     'pixel_pitch_um = "100"\n')
    err = _one_line(cli("shift", "--lens", "l.toml", "--f-number", "2.8", "--cra", "5",
                        cwd=tmp_path))
    assert "pixel_pitch_um must be a number, got text" in err


@pytest.fixture
def small(tmp_path):
    from snapcorr.cube import make_cube, write_cube

    (tmp_path / "sensor.toml").write_text(
        '[sensor]\nname = "s"\nlayout = "snapscan"\npixel_pitch_um = 100.0\n'
        "size_px = [40, 50]\ncwl_nm = [500.0, 550.0, 600.0, 650.0, 700.0]\nfwhm_nm = 10.0\n"
        "n_eff = 1.7\n")
    rng = np.random.default_rng(0)
    write_cube(make_cube(rng.uniform(0.2, 0.8, (40, 50, 5)).astype(np.float32),
                         [500.0, 550.0, 600.0, 650.0, 700.0]), tmp_path / "ff.nc")
    return tmp_path


@pytest.mark.parametrize(("extra", "match"), [
    (["--harmonise", "--target-fwhm-nm", "1e300"], "at most 1000 nm"),
    (["--virtual-bands", "fitted", "--virtual-wavelengths", "600:900:1e-9"],
     "at most 1,000,000"),
    (["--sensor-origin-px", "99999999999999999999,0"], "no sensor is wider"),
    (["--center", "1e300,5"], "no sensor is wider"),
])
def test_command_line_numbers_that_would_overflow_are_one_line(small, cli, extra, match):
    err = _one_line(cli("correct", "ff.nc", "--lens", str(lens_path()), "--sensor",
                        "sensor.toml", "--f-number", "2.8", "--out", "o.nc", *extra, cwd=small))
    assert match in err
    assert not (small / "o.nc").exists()


@pytest.mark.parametrize(("make", "match"), [
    (lambda p: p.with_suffix(".npy").write_bytes(b""), "not a NumPy array"),
    (lambda p: p.with_suffix(".csv").write_bytes(os.urandom(400) + b"\xff\xfe"),
     "not a text file"),
    (lambda p: os.mkfifo(p.with_suffix(".csv")), "FIFO"),
])
def test_spectrum_files_that_are_not_spectra_are_one_line(small, cli, make, match):
    make(small / "sp")
    name = next(p.name for p in small.iterdir() if p.stem == "sp")
    err = _one_line(cli("budget", "--sensor", "sensor.toml", "--lens", str(lens_path()),
                        "--f-number", "2.8", "--source", name, cwd=small))
    assert match in err and name in err


def test_an_output_never_replaces_a_bundled_profile(tmp_path, cli):
    """A bundled lens given by name is an input like any other, and the bundled profiles are
    never replaced, whatever --overwrite says."""
    from snapcorr.cli import _check_outputs

    target = lens_path()
    before = target.read_bytes()
    with pytest.raises(ValueError, match=r"also an input|bundled"):
        _check_outputs([target], ["edmund_optics_16mm"], True, [(".toml",)])
    with pytest.raises(ValueError, match="bundled files"):
        _check_outputs([target], [], True, [(".toml",)])
    assert target.read_bytes() == before


def test_two_outputs_of_one_command_may_not_meet(small, cli):
    from snapcorr.cube import make_cube, write_cube

    for name, level in (("raw", 2000), ("dark", 100), ("white", 3000)):
        write_cube(make_cube(np.full((4, 5, 5), level, np.uint16),
                             [500.0, 550.0, 600.0, 650.0, 700.0]), small / f"{name}.nc")
    err = _one_line(cli("flatfield", "raw.nc", "--dark", "dark.nc", "--white", "white.nc",
                        "--out", "o.zarr", "--plot", "o.zarr/q.png", cwd=small))
    assert "one lies in the other" in err
    assert not (small / "o.zarr").exists()


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
    err = _one_line(cli(*args, "10,21", "--out", "b.nc", cwd=tmp_path))
    assert "disagrees with the sensor positions raw.nc records" in err
