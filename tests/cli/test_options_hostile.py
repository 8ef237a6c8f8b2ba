"""Refusals that name the option to give: missing wavelengths name ``--sensor``, a budget
source without a cube names ``--source-cube``, an unknown bundled lens lists the bundled ones."""

from __future__ import annotations

import numpy as np
import pytest
from hostile import (
    assert_refused,
    correct_args,
    save_cubes,
    snapshot,
)


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


@pytest.mark.parametrize("value", ["2,1", "1,1", "0,nan", "-inf,1"])
def test_a_pack_range_not_finite_lo_below_hi_is_one_usage_line(value, capsys):
    """The range is checked where the library checks it (check_pack_range); the command
    line says it as a usage error naming the option, before any file is opened."""
    from snapcorr.cli import main

    rc = main(["flatfield", "missing.hdr", "--dark", "d.hdr", "--white", "w.hdr",
               "--dtype", "uint16", f"--pack-range={value}", "--out", "o.nc"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1, err
    assert "argument --pack-range" in err and "expected finite LO < HI" in err, err
    assert "Traceback" not in err and "missing.hdr" not in err


def test_phase_from_on_a_sensor_without_a_mosaic_is_refused_by_its_option(tmp_path, cli):
    np.save(tmp_path / "w.npy", np.ones((64, 64)))
    rc, _, err = cli("sensor", "snapscan_vnir", "--phase-from", tmp_path / "w.npy")
    assert_refused(rc, err, "--phase-from", "not a mosaic")  # was 'NoneType' ... subscriptable


def test_a_budget_centre_without_a_cube_sets_the_field_about_it(cli):
    """``--center`` without ``--cube`` was ignored (the same budget as without it); the field
    is now the sensor's about that centre, its farthest corner worked out here."""
    import math

    from snapcorr import Lens, data
    from snapcorr.cube import Sensor

    base = ("budget", "--sensor", "mosaic_4x4_vis", "--lens", "edmund_optics_16mm",
            "--f-number", "2", "--source", "solar")
    plain, off = cli(*base), cli(*base, "--center=-5,5")
    assert plain.returncode == off.returncode == 0, off.stderr
    assert "about --center -5,5" in off.stdout and off.stdout != plain.stdout
    sensor = Sensor.load(data.sensor_path("mosaic_4x4_vis"))
    lens = Lens.load(data.lens_path("edmund_optics_16mm"))
    rows, cols = sensor.size_px
    far = math.hypot(rows - 0.5 + 5, cols - 0.5 - 5) * sensor.pixel_pitch_um * 1e-3
    assert f"CRA up to {math.degrees(math.atan(far / lens.exit_pupil_mm)):.2f} deg" in off.stdout


def test_a_budget_of_a_sensor_without_n_eff_says_how_to_measure_it(tmp_path, cli):
    from snapcorr import data

    toml = tmp_path / "v.toml"
    vendor = data.sensor_path("imec_5x5_nir").parent / "CMV2K-SSM5x5-600_875-5.5.9.2.xml"
    assert cli("sensor", vendor, "--toml", toml).returncode == 0
    rc, _, err = cli("budget", "--sensor", toml, "--lens", "edmund_optics_16mm", "--f-number",
                     "2", "--source", "solar")
    line = assert_refused(rc, err, "n_eff")
    assert "nan" not in line, line  # was: n_eff must be a finite ... (got [nan])


#: For each command with options taking a pair of numbers: what it needs besides them.
PAIR_COMMANDS = {
    "correct": ["scene.nc", "--lens", "edmund_optics_16mm", "--sensor", "snapscan_vnir",
                "--f-number", "2", "--out", "o.nc"],
    "budget": ["--sensor", "snapscan_vnir", "--lens", "edmund_optics_16mm", "--f-number", "2",
               "--source", "flat"],
    "calibrate": ["--flat", "2=f2.npy", "--flat", "8=f8.npy", "--exit-pupil-mm", "21",
                  "--out", "l.toml"],
}


def _parsed(monkeypatch, command, argv):
    """The options ``snapcorr COMMAND ARGV`` reaches its command with (it is not run)."""
    import importlib

    from snapcorr.cli import main

    seen = {}
    monkeypatch.setattr(importlib.import_module(f"snapcorr.cli.{command}"), "run",
                        lambda args: seen.setdefault("args", args) and 0)
    rc = main([command, *argv])
    return rc, seen.get("args")


@pytest.mark.parametrize("command", sorted(PAIR_COMMANDS))
@pytest.mark.parametrize(("typed", "dest", "expected"), [
    (["--center", "-5,5"], "center", (-5.0, 5.0)),
    (["--center-px", "-5.5,2"], "center_px", (-5.5, 2.0)),
    (["--center-p", "-1e1,3"], "center_px", (-10.0, 3.0)),  # shortened, as argparse allows
])
def test_a_pair_starting_with_a_minus_is_the_options_value(monkeypatch, capsys, command, typed,
                                                           dest, expected):
    """``--center -5,5`` (a centre outside the crop) was taken for an option of its own and
    refused as '--center: expected one argument'."""
    rc, args = _parsed(monkeypatch, command, [*PAIR_COMMANDS[command], *typed])
    assert rc == 0, capsys.readouterr().err
    assert getattr(args, dest) == expected


@pytest.mark.parametrize("command", ["correct", "sensor"])
def test_a_negative_origin_is_refused_by_its_own_check(monkeypatch, capsys, command):
    """A negative crop origin reaches the origin's own check, which says what it may be."""
    argv = PAIR_COMMANDS.get(command, ["snapscan_vnir"])
    rc, args = _parsed(monkeypatch, command, [*argv, "--sensor-origin-px", "-1,2"])
    err = capsys.readouterr().err
    assert rc == 2 and args is None
    assert "--sensor-origin-px" in err and "whole pixels >= 0" in err, err
    assert "expected one argument" not in err


def test_a_value_after_the_end_of_options_is_left_alone():
    from snapcorr.cli import _negative_pairs, build_parser

    given = ["correct", "--center", "-5,5", "--", "--center", "-1,1"]
    assert _negative_pairs(build_parser(), given) == ["correct", "--center=-5,5", "--",
                                                      "--center", "-1,1"]


@pytest.mark.parametrize("args, said", [
    (("shift", "--f-number", "2", "--f-number", "1e5", "--cwl-nm", "500", "--n-eff", "1.7",
      "--cra", "10"), "--f-number is given twice"),
    (("shift", "--f-number=2", "--cwl-nm", "500", "--n-eff", "1.7", "--cra", "10",
      "--f-number=4"), "--f-number is given twice"),
    (("pupil", "--predict", "--pupil-radiance", "paper", "--pupil", "lambertian"),
     "--pupil-radiance and --pupil are one option, given twice"),
])
def test_an_option_of_one_value_given_twice_is_refused(tmp_path, monkeypatch, args, said, cli):
    """argparse keeps the last of a repeated option without a word: --out a.toml --out
    b.toml wrote only b.toml, --f-number 2 --f-number 1e5 took 1e5, and an alias given
    after its option won."""
    monkeypatch.chdir(tmp_path)
    rc, out, err = cli(*args)
    assert rc == 2 and said in err and "give it once" in err and not out, (out, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_options_that_gather_values_still_take_many(tmp_path, monkeypatch, cli):
    """--dark and --white are lists: given twice, both frames are averaged."""
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    rc, out, err = cli("flatfield", "raw.npy", "--dark", "dark.npy", "--dark", "dark.npy",
                     "--white", "white.npy", "--white", "white.npy", "--sensor", "sensor.toml",
                     "--out", "o.nc")
    assert rc == 0 and "2 dark and 2 white frame(s) averaged" in out, err


@pytest.mark.parametrize("argv", [
    ["stream", "", "--dark", "d.npy", "--white", "w.npy", "--sensor", "mosaic_4x4_vis",
     "--out", "o.zarr"],
    ["flatfield", " ", "--dark", "d.npy", "--white", "w.npy", "--out", "o.nc"],
    ["correct", "c.nc", "--lens", "edmund_optics_16mm", "--f-number", "2", "--out", ""],
])
def test_an_empty_path_is_refused_not_read_as_the_current_folder(tmp_path, monkeypatch, argv,
                                                                 cli):
    """stream "" (an unset shell variable) streamed every frame file of the current folder."""
    monkeypatch.chdir(tmp_path)
    np.save(tmp_path / "f1.npy", np.zeros((8, 8), np.uint16))
    before = snapshot(tmp_path)
    rc, _, err = cli(*argv)
    assert_refused(rc, err, "an empty path")
    assert snapshot(tmp_path) == before
