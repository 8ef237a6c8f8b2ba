"""Command-line values no camera has: numbers that would overflow or exhaust memory, spectrum
files that are empty, binary or not files at all, an output that would replace a bundled
profile, two outputs of one command in one another. Each is one line naming what is wrong."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hostile import assert_refused, refused_in_one_line

from snapcorr.data import lens_path


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
    err = refused_in_one_line(cli("correct", "ff.nc", "--lens", str(lens_path()), "--sensor",
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
    err = refused_in_one_line(cli("budget", "--sensor", "sensor.toml", "--lens", str(lens_path()),
                        "--f-number", "2.8", "--source", name, cwd=small))
    assert match in err and name in err


def test_an_output_never_replaces_a_bundled_profile(tmp_path, cli):
    """A bundled lens given by name is an input like any other, and the bundled profiles are
    never replaced, whatever --overwrite says."""
    from snapcorr.cli._output import _check_outputs

    target = lens_path()
    before = target.read_bytes()
    with pytest.raises(ValueError, match=r"also an input|bundled"):
        _check_outputs({"--out": target}, ["edmund_optics_16mm"], True, [(".toml",)])
    with pytest.raises(ValueError, match="bundled files"):
        _check_outputs({"--out": target}, [], True, [(".toml",)])
    assert target.read_bytes() == before


def test_two_outputs_of_one_command_may_not_meet(small, cli):
    from snapcorr.cube import make_cube, write_cube

    for name, level in (("raw", 2000), ("dark", 100), ("white", 3000)):
        write_cube(make_cube(np.full((4, 5, 5), level, np.uint16),
                             [500.0, 550.0, 600.0, 650.0, 700.0]), small / f"{name}.nc")
    err = refused_in_one_line(cli("flatfield", "raw.nc", "--dark", "dark.nc", "--white", "white.nc",
                        "--out", "o.zarr", "--plot", "o.zarr/q.png", cwd=small))
    assert "one lies in the other" in err
    assert not (small / "o.zarr").exists()


LENS_OPTIONS = {"calibrate": ["--exit-pupil-mm", "--magnification", "--pupil-magnification",
                              "--vignetting-distance-mm"],
                "pupil": ["--magnification", "--pupil-magnification"]}


@pytest.mark.parametrize("value", ["1e-310", "5e-324", "0.0009"])
@pytest.mark.parametrize("option", ["--exit-pupil-mm", "--vignetting-distance-mm"])
def test_a_length_below_a_micron_is_refused_by_its_option_before_any_read(tmp_path, option,
                                                                          value, cli):
    """--vignetting-distance-mm 1e-310 flooded overflow warnings and wrote NaN onsets."""
    rest = [] if option == "--exit-pupil-mm" else ["--exit-pupil-mm", "21"]
    rc, _, err = cli("calibrate", "--flat", "2=f2.npy", "--flat", "4=f4.npy", *rest, option,
                     value, "--out", "l.toml", cwd=tmp_path)
    line = assert_refused(rc, err, option, ">= 0.001")
    assert rc == 2 and "overflow" not in err, line


@pytest.mark.parametrize("value", ["1e200", "1e308", "inf", "nan"])
@pytest.mark.parametrize(("command", "option"),
                         [(c, o) for c, options in LENS_OPTIONS.items() for o in options])
def test_a_lens_number_of_overflow_size_is_refused_by_its_option_before_any_read(
        tmp_path, command, option, value, cli):
    """Refused as the options are read, with the range: 1e200 was refused only after the
    flats were read and fitted, and --vignetting-distance-mm by the circle's name."""
    first = {"calibrate": ("calibrate", "--flat", "2=f2.npy", "--flat", "4=f4.npy"),
             "pupil": ("pupil", "--cube", "2=c2.nc", "--sensor", "snapscan_vnir")}[command]
    rest = [] if option == "--exit-pupil-mm" or command == "pupil" else ["--exit-pupil-mm",
                                                                          "21"]
    rc, _, err = cli(*first, *rest, option, value, "--out", "l.toml", cwd=tmp_path)
    line = assert_refused(rc, err, option)
    # with the range the option allows (a magnification's from the lens's own check)
    assert any(w in line for w in ("at most", "between", "finite")), line
    assert rc == 2  # a usage error: nothing was read
