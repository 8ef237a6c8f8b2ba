"""Sensor files with values no camera has: central wavelengths in micrometres, values of the
wrong type, integers too large for a float. Each is one line naming the key."""

from __future__ import annotations

import pytest
from hostile import (
    HUGE,
    MOSAIC_WL,
    SENSOR4,
    assert_refused,
    correct_args,
    refused_in_one_line,
    save_cubes,
    snapshot,
)


def mosaic_sensor_text(**override):
    """A 4 x 4 mosaic sensor written by hand; ``override`` replaces whole lines (raw TOML)."""
    lines = {
        "name": '"user-mosaic"',
        "layout": '"mosaic"',
        "pixel_pitch_um": "5.5",
        "cwl_nm": "[" + ", ".join(f"{w:.1f}" for w in MOSAIC_WL) + "]",
        "fwhm_nm": "12.0",
        "n_eff": "1.7",
        "mosaic_shape": "[4, 4]",
        "band_offset": "[" + ", ".join(f"[{r}, {c}]" for r in range(4) for c in range(4)) + "]",
    }
    lines.update(override)
    return "[sensor]\n" + "".join(f"{k} = {v}\n" for k, v in lines.items())


@pytest.mark.parametrize("command", ["correct", "budget"])
def test_sensor_with_cwl_in_micrometres_is_refused(tmp_path, monkeypatch, command, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    (tmp_path / "um.toml").write_text(SENSOR4.replace("500.0, 520.0, 540.0, 560.0",
                                                      "0.50, 0.52, 0.54, 0.56"))
    if command == "correct":
        args = correct_args("raw.npy", "o.nc", sensor="um.toml")
    else:
        args = ("budget", "--sensor", "um.toml", "--lens", "edmund_optics_16mm", "--f-number",
                "1.4", "--source", "tungsten:3000", "--cra-max", "5")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "cwl_nm")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("key, value", [
    ("pixel_pitch_um", "true"),
    ("mosaic_shape", "[4.7, 5]"),
    ("band_offset", "[" + ", ".join(f"[{r}, {c}]" for r in range(4) for c in range(4))
     .replace("[3, 3]", "[3, 3.9]") + "]"),
    ("n_eff", "true"),
    ("fwhm_nm", "true"),
    ("cwl_nm", "[" + ", ".join(["true"] * 16) + "]"),
])
def test_sensor_value_of_the_wrong_type_is_refused(tmp_path, monkeypatch, key, value, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text(mosaic_sensor_text(**{key: value}))
    rc, out, err = cli("budget", "--sensor", "s.toml", "--lens", "edmund_optics_16mm",
                       "--f-number", "1.4", "--source", "tungsten:3000", "--cra-max", "5")
    assert_refused(rc, err, key)
    assert "recommended" not in out


@pytest.mark.parametrize("key", ["pixel_pitch_um", "cwl_nm", "size_px", "n_eff", "fwhm_nm"])
def test_a_huge_integer_in_a_sensor_file_is_one_line(tmp_path, cli, key):
    table = {"pixel_pitch_um": "5.5", "cwl_nm": "[500.0, 550.0]", "fwhm_nm": "10.0",
             "n_eff": "1.7", "size_px": "[40, 50]"}
    table[key] = f"[500.0, {HUGE}]" if key == "cwl_nm" else (
        f"[{HUGE}, 50]" if key == "size_px" else HUGE)
    (tmp_path / "s.toml").write_text('[sensor]\nname = "x"\nlayout = "snapscan"\n' + "".join(
        f"{k} = {v}\n" for k, v in table.items()))
    err = refused_in_one_line(cli("sensor", "s.toml", cwd=tmp_path))
    assert key in err and len(err) < 300


BEYOND_INT64 = "100000000000000000000"  # 1e20: a float, but no int64


@pytest.mark.parametrize("key, value", [
    ("size_px", f"[{BEYOND_INT64}, 2]"),
    ("mosaic_shape", f"[{BEYOND_INT64}, 4]"),
    ("band_offset", "[" + ", ".join(f"[{r}, {c}]" for r in range(4) for c in range(4))
     .replace("[3, 3]", f"[3, {BEYOND_INT64}]") + "]"),
    ("filter_area_px", f"[0, 0, {BEYOND_INT64}, 4]"),
    ("bit_depth", BEYOND_INT64),
])
def test_a_whole_number_beyond_int64_is_refused_before_any_cast(tmp_path, cli, key, value):
    """1e20 cast to int64 is no number (numpy warned 'invalid value encountered in cast'
    before the error): it is refused, naming the key, with no warning."""
    (tmp_path / "s.toml").write_text(mosaic_sensor_text(**{key: value}))
    err = refused_in_one_line(cli("sensor", "s.toml", cwd=tmp_path))
    assert key in err and "warning" not in err and "cast" not in err, err


@pytest.mark.parametrize("key, value", [
    ("layout", '"' + "x" * 100_000 + '"'),
    ("profile", '"' + "y" * 100_000 + '"'),
], ids=["layout", "profile"])
def test_text_of_100_kb_in_a_sensor_file_is_quoted_as_an_excerpt(tmp_path, cli, key, value):
    (tmp_path / "s.toml").write_text(mosaic_sensor_text(**{key: value}))
    err = refused_in_one_line(cli("sensor", "s.toml", cwd=tmp_path))
    assert len(err) < 400 and value[1:21] in err, err[:500]


def test_a_tile_larger_than_the_sensor_is_refused():
    """A 1000 x 1000 tile on a 64 x 64 px sensor was described as such, and only a later
    correct refused it."""
    from snapcorr.cube import Sensor

    with pytest.raises(ValueError, match=r"a 1000 x 1000 tile does not fit on a sensor of 64 x "
                                         "64 px"):
        Sensor("m", "mosaic", 5.5, (500.0,), 10.0, 1.7, mosaic_shape=(1000, 1000),
               band_offset=((0, 0),), size_px=(64, 64))
    with pytest.raises(ValueError, match=r"\[sensor\] name must be text"):
        Sensor.from_dict({"name": 5, "layout": "snapscan", "pixel_pitch_um": 5.5,
                          "cwl_nm": [500.0], "fwhm_nm": 10.0, "n_eff": 1.7})
