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
