"""Messages that say what happened: a saturation level beyond the data's type, a wavelength
range beyond those accepted, and an interruption after an output was complete."""

from __future__ import annotations

import numpy as np
import pytest

from snapcorr.cube import make_cube, read_dataset, write_cube

WL = np.linspace(500.0, 800.0, 4)


@pytest.fixture
def cubes(tmp_path):
    rng = np.random.default_rng(0)
    write_cube(make_cube(rng.integers(100, 3000, (6, 5, 4)).astype(np.uint16), WL),
               tmp_path / "scene.hdr")
    write_cube(make_cube(np.full((6, 5, 4), 50, np.uint16), WL), tmp_path / "dark.hdr")
    write_cube(make_cube(np.full((1, 5, 4), 3050, np.uint16), WL), tmp_path / "white.tif")
    return tmp_path


@pytest.fixture
def frames(tmp_path):
    np.save(tmp_path / "frames.npy", np.full((3, 8, 8), 500, np.uint16))
    np.save(tmp_path / "d.npy", np.full((8, 8), 100, np.uint16))
    np.save(tmp_path / "w.npy", np.full((8, 8), 900, np.uint16))
    return tmp_path


STREAM = ("stream", "frames.npy", "--dark", "d.npy", "--white", "w.npy", "--sensor",
          "mosaic_4x4_vis", "--sensor-origin-px", "0,0")


def test_a_saturation_beyond_the_data_type_saturates_nothing_without_a_warning(cubes, cli):
    """1e308 is beyond float32's largest number: numpy's cast of it warned 'overflow
    encountered in cast'. No value can reach it, so nothing is masked for it."""
    args = ("flatfield", "scene.hdr", "--dark", "dark.hdr", "--white", "white.tif")
    res = cli(*args, "--saturation", "1e308", "--out", "high.nc", cwd=cubes)
    assert res.returncode == 0, res.stderr
    assert "warning" not in res.stderr and "overflow" not in res.stderr, res.stderr
    assert "0 of 120 values masked" in res.stdout
    plain = cli(*args, "--out", "plain.nc", cwd=cubes)
    assert plain.returncode == 0, plain.stderr
    np.testing.assert_array_equal(read_dataset(cubes / "high.nc")["reflectance"].values,
                                  read_dataset(cubes / "plain.nc")["reflectance"].values)


def test_a_stream_saturation_beyond_the_data_type_warns_of_nothing(frames, cli):
    res = cli(*STREAM, "--saturation", "1e308", "--out", "s.zarr", cwd=frames)
    assert res.returncode == 0, res.stderr
    assert "overflow" not in res.stderr and "0 of 3072 values masked" in res.stdout, res


@pytest.mark.parametrize(("value", "words"), [
    ("1e308:1e308:1", "START 1e+308 nm is beyond the longest wavelength snapcorr accepts, "
                      "100000 nm"),
    ("500:1e308:1e300", "STOP 1e+308 nm is beyond the longest wavelength"),
    ("1e308", "wavelength 1e+308 nm is beyond the longest wavelength"),
    ("500,2e5", "wavelength 200000 nm is beyond the longest wavelength"),
    ("0.5:1:0.1", "START 0.5 nm is below the shortest wavelength snapcorr accepts, 100 nm"),
    ("500:400:1", "STOP 400 nm is below START 500 nm"),
    ("500:600:0", "STEP must be a finite number > 0 nm"),
    ("inf:1e308:1", "START must be a finite number of nm"),
])
def test_a_wavelength_range_refused_says_why(tmp_path, cli, value, words):
    res = cli("correct", "ff.nc", "--lens", "edmund_optics_16mm", "--sensor", "snapscan_vnir",
              "--f-number", "2", "--virtual-bands", "fitted", "--virtual-wavelengths", value,
              "--out", "o.nc", cwd=tmp_path)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert "argument --virtual-wavelengths: " + words in lines[0], lines[0]
    assert "must be finite" not in lines[0]


def test_a_range_of_no_width_is_its_one_wavelength():
    from snapcorr.cli._types import _wavelength_list

    np.testing.assert_array_equal(_wavelength_list("1e5:1e5:1e-20"), [1e5])
    np.testing.assert_array_equal(_wavelength_list("600:700:50"), [600.0, 650.0, 700.0])


def test_an_output_complete_when_the_interrupt_came_is_said_kept(frames, cli, monkeypatch):
    """The interrupt comes the instant after the output was moved in under its name: it is
    complete, and kept; the message said every output was removed."""
    from snapcorr.files import safety

    def interrupted(target):
        raise KeyboardInterrupt

    monkeypatch.setattr(safety, "_note_written", interrupted)
    res = cli(*STREAM, "--out", "s.zarr", cwd=frames)
    assert res.returncode == 130, res.stderr
    assert (frames / "s.zarr").is_dir()
    assert read_dataset(frames / "s.zarr")["reflectance"].shape[0] == 3
    assert res.stderr.strip() == ("snapcorr stream: interrupted; only unfinished outputs were "
                                  "removed: s.zarr was complete and was kept"), res.stderr


def test_an_output_interrupted_before_it_was_moved_in_is_said_removed(frames, cli,
                                                                      monkeypatch):
    from snapcorr.files import safety

    def interrupted(new, target):
        raise KeyboardInterrupt

    monkeypatch.setattr(safety, "_move_in_new", interrupted)
    res = cli(*STREAM, "--out", "s.zarr", cwd=frames)
    assert res.returncode == 130, res.stderr
    assert not (frames / "s.zarr").exists()
    assert sorted(p.name for p in frames.iterdir()) == ["d.npy", "frames.npy", "w.npy"]
    assert res.stderr.strip() == ("snapcorr stream: interrupted; unfinished outputs were "
                                  "removed"), res.stderr


def test_the_grid_refused_for_a_lambertian_pupil_names_the_options(tmp_path, cli):
    """`shift --method grid` of a Lambertian pupil's lens advised "a ShiftTable per
    f-number", a Python class; the command line names its own choices."""
    from snapcorr import Lens

    Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, pupil_radiance="paper-lambertian").save(
        tmp_path / "lens.toml")
    res = cli("shift", "--lens", "lens.toml", "--f-number", "2", "--cra", "10", "--method",
              "grid", cwd=tmp_path)
    assert res.returncode == 1
    assert "(--method table, or --method auto)" in res.stderr.strip().splitlines()[-1]


@pytest.mark.parametrize("command", ["calibrate", "pupil"])
def test_the_help_of_auto_names_the_criterion_of_each_input(cli, command):
    """The help said "a chi-square gain above 10" where flats alone are judged by their BIC
    (and recorded so)."""
    res = cli(command, "--help")
    text = " ".join(res.stdout.split())
    assert "the chi-square of target cubes, the BIC of flats, their sum for both" in text
    assert "chi-square gain above 10" not in text
