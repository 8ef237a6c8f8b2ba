"""`snapcorr shift`: a wavelength not in nm is refused by its option's name; an angle past the
cut-off says so and gives the cut-off angle."""

from __future__ import annotations

import re

import pytest
from hostile import LENS, assert_refused


@pytest.mark.parametrize("value", ["0.7", "7e-7"], ids=["micrometres", "metres"])
def test_shift_refuses_a_wavelength_not_in_nm(value, cli):
    rc, out, err = cli("shift", "--f-number", "1.4", "--cra", "5", "--cwl-nm", value)
    assert_refused(rc, err, "--cwl-nm")
    assert "cra_deg" not in out


def test_shift_past_the_cutoff_says_so_and_gives_the_angle(cli):
    from snapcorr import Lens

    cutoff = float(Lens.load(LENS).cutoff_cra_deg(1.4))
    rc, _, err = cli("shift", "--cra", "45", "--f-number", "1.4")
    line = assert_refused(rc, err, "cut")
    numbers = [float(v) for v in re.findall(r"\d+\.\d+", line)]
    assert any(abs(v - cutoff) < 0.051 for v in numbers), f"no {cutoff:.2f} in: {line}"



@pytest.mark.parametrize("cra", [["-89.9"], ["10", "-50", "40"]])
def test_shift_past_the_cutoff_names_the_angle_as_given(cli, cra):
    """``--cra=-89.9`` was told ``CRA 89.9 deg is past ...``: the sign was dropped."""
    rc, _, err = cli("shift", "--f-number", "2", "--cra", *cra)
    assert_refused(rc, err, f"--cra {min(cra, key=float)} deg is past the full cut-off at "
                            "36.21 deg (of either sign)")


OVERFLOW = ["1e200", "1e308", "inf", "nan"]


@pytest.mark.parametrize("value", OVERFLOW)
@pytest.mark.parametrize("option", ["--f-number", "--cra", "--cwl-nm", "--n-eff"])
def test_shift_refuses_an_overflow_sized_value_by_its_option(option, value, cli):
    args = {"--f-number": "2", "--cra": "5"}
    args[option] = value
    rc, out, err = cli("shift", *[a for kv in args.items() for a in kv])
    line = assert_refused(rc, err, option)
    assert "(f_number)" not in line and "Lens." not in line, line
    assert "cra_deg" not in out


@pytest.mark.parametrize("value", ["1e200", "1.1e6"])
@pytest.mark.parametrize("command", ["shift", "budget", "correct", "stream", "pupil"])
def test_an_f_number_past_any_lens_gives_the_range(command, value, cli):
    args = {"shift": ("shift", "--cra", "5"),
            "budget": ("budget", "--sensor", "snapscan_vnir", "--lens", LENS, "--source",
                       "solar"),
            "correct": ("correct", "c.nc", "--lens", LENS, "--sensor", "snapscan_vnir",
                        "--out", "o.nc"),
            "stream": ("stream", "f.npy", "--dark", "d.npy", "--white", "w.npy", "--sensor",
                       "mosaic_4x4_vis", "--lens", LENS, "--out", "o.zarr"),
            "pupil": ("pupil", "--predict", "--sensor", "snapscan_vnir")}[command]
    rc, _, err = cli(*args, "--f-number", value)
    assert_refused(rc, err, "--f-number", "1e+06")


@pytest.mark.parametrize("option", ["--flat", "--target-cube"])
def test_calibrate_refuses_an_f_number_past_any_lens_in_a_pair(option, cli):
    rc, _, err = cli("calibrate", option, "1e200=f.npy", "--out", "l.toml")
    assert_refused(rc, err, option, "1e+06")


def test_the_library_refuses_an_f_number_past_any_lens():
    from snapcorr import Lens
    from snapcorr.optics import mean_shift

    with pytest.raises(ValueError, match=r"f_number must be at most 1e\+06"):
        mean_shift(700.0, 1.7, 1e200, 5.0, Lens.load(LENS))


@pytest.mark.parametrize("key", ["exit_pupil_mm", "magnification", "pupil_magnification",
                                 "vignetting"])
def test_a_lens_with_an_overflow_sized_value_is_refused_by_its_name(key):
    from snapcorr import Lens

    kwargs = {"exit_pupil_mm": 21.0, "vignetting": [(7.4, 17.0)], "magnification": 0.06,
              "pupil_magnification": 1.3}
    kwargs[key] = [(7.4, 1e200)] if key == "vignetting" else 1e200
    with pytest.raises(ValueError, match=r"must be at most|must be between") as err:
        Lens(**kwargs)
    assert (key if key != "vignetting" else "distance_mm") in str(err.value)


@pytest.mark.parametrize("value", OVERFLOW)
@pytest.mark.parametrize("command", ["budget", "correct"])
def test_a_blackbody_source_of_overflow_temperature_names_the_option(command, value, cli,
                                                                     tmp_path):
    args = {"budget": ("budget", "--sensor", "snapscan_vnir", "--cra-max", "5"),
            "correct": ("correct", tmp_path / "no_cube.nc", "--sensor", "snapscan_vnir",
                        "--out", tmp_path / "o.nc")}[command]
    rc, _, err = cli(*args, "--lens", LENS, "--f-number", "2", "--source", f"tungsten:{value}")
    assert_refused(rc, err, "--source", "1e+06 K")


@pytest.mark.parametrize(("key", "value", "words"), [
    ("magnification", '"0.06"', "text"), ("pupil_magnification", '"1.3"', "text"),
    ("exit_pupil_mm", '"21"', "text"), ("exit_pupil_mm", "1e-310", "at least"),
])
def test_a_lens_file_number_given_as_text_or_next_to_nothing_is_refused(tmp_path, key, value,
                                                                        words):
    """Text was read as the number it spells for the magnifications (and counted as given),
    and a 1e-310 mm exit pupil was accepted, to overflow later."""
    from snapcorr import Lens

    keys = {"exit_pupil_mm": "21.0", "magnification": "0.06", "pupil_magnification": "1.3"}
    keys[key] = value
    path = tmp_path / "l.toml"
    path.write_text("[lens]\nname = 'l'\n" + "".join(f"{k} = {v}\n" for k, v in keys.items()))
    with pytest.raises((TypeError, ValueError), match=words) as err:
        Lens.load(path)
    assert key in str(err.value)
