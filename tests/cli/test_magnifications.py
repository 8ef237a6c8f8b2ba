"""--magnification and --pupil-magnification outside physics: refused by the option's parser,
naming the option, before any file is looked at."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize("command", ["calibrate", "pupil"])
@pytest.mark.parametrize("option, value", [("--magnification", "1e300"),
                                           ("--magnification", "-0.5"),
                                           ("--magnification", "inf"),
                                           ("--pupil-magnification", "1e300"),
                                           ("--pupil-magnification", "nan")])
def test_the_commands_refuse_them_naming_the_option(command, option, value, cli, tmp_path):
    args = {"calibrate": ["--flat", "2=missing.npy", "--exit-pupil-mm", "21",
                          "--pixel-pitch-um", "5.5"],
            "pupil": ["--cube", "2=missing.nc", "--sensor", "snapscan_vnir"]}[command]
    res = cli(command, *args, f"{option}={value}", "--out", tmp_path / "l.toml")
    assert res.returncode == 2, res.stderr
    assert f"argument {option}: m" in res.stderr and "Traceback" not in res.stderr
    assert "missing" not in res.stderr  # refused before any file is looked at


@pytest.mark.slow
def test_pupil_without_magnifications_widens_says_and_records(cli, tmp_path):
    """`snapcorr pupil` not given m and m_P (cubes of the paper's lens, tests/oracles/
    spectralsim.py): the warning, the note, x's error holding the 4 % the assumption costs,
    and the record in the profile, which a later calibration reads as not given."""
    from calibrate.test_unknown_magnification import (
        CWL,
        FWHM,
        N_EFF,
        PAPER,
        PITCH_UM,
        SHAPE,
        small_data,
    )

    from snapcorr import Lens
    from snapcorr.calibrate.lens.magnification import ratio_range
    from snapcorr.cube import Sensor, write_cube

    _, cubes, _ = small_data(5)
    Sensor("test", "snapscan", PITCH_UM, CWL, FWHM, N_EFF, size_px=SHAPE).save(
        tmp_path / "sensor.toml")
    for f, cube in cubes.items():
        write_cube(cube, tmp_path / f"t{f:g}.nc")
    res = cli("pupil", "--cube", "2=t2.nc", "--cube", "8=t8.nc", "--sensor", "sensor.toml",
              "--fit-n-eff", "--pupil", "paper", "--out", "lx.toml", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "warning: no magnifications given" in res.stderr
    assert "note: no magnifications given" in res.stdout
    lens = Lens.load(tmp_path / "lx.toml")
    cal = lens.calibration
    assert cal["magnification"]["assumed"] is True and ratio_range(lens=lens)[0] == "neither"
    assert 0.3 < abs(lens.exit_pupil_mm - PAPER.exit_pupil_mm) / cal["exit_pupil_stderr_mm"] < 2
