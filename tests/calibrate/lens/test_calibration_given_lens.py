"""A lens whose exit pupil is known, given to the calibration instead of x: its x, m, m_P,
pupil and the standard error of x are used unless given, and the profile records where x
came from (as ``snapcorr calibrate --lens`` writes it)."""

import numpy as np
import pytest
from flatsim import LensTruth, make_flats

from snapcorr import Lens
from snapcorr.calibrate import calibrate_lens
from snapcorr.calibrate.lens.calibration import LENS_RECORD_KEYS

TRUTH = LensTruth(21.0, ((7.4236, 16.991),), 0.05, 1.2, name="paper lens")
PITCH_UM = 44.0
CENTER_RC = (61.6, 82.3)
KNOWN = Lens(21.0, [], 0.05, 1.2, name="from the pupil fit", pupil_radiance="lambertian",
             calibration={"exit_pupil_stderr_mm": 0.2, "n_eff": 1.83, "n_eff_stderr": 0.01,
                          "n_eff_fitted": "one", "method": "exit-pupil fit"})


@pytest.fixture(scope="module")
def flats():
    return make_flats(TRUTH, (1.4, 2.0, 2.8, 4.0, 8.0), shape=(128, 160), pitch_um=PITCH_UM,
                      center_px=CENTER_RC[::-1], noise=0.005, seed=3)


def _calibrate(flats, **kw):
    return calibrate_lens(flats, pixel_pitch_um=PITCH_UM, method="joint", max_circles=1,
                          center_rc=CENTER_RC, **kw)


def _without_record(cal):
    return {k: v for k, v in cal.items() if k not in ("date", "exit_pupil_from",
                                                      *LENS_RECORD_KEYS.values())}


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_the_lens_gives_x_m_mp_the_pupil_and_the_error_of_x(flats):
    got = _calibrate(flats, lens=KNOWN, exit_pupil_from="pupil.toml")
    same = _calibrate(flats, exit_pupil_mm=21.0, magnification=0.05, pupil_magnification=1.2,
                      pupil_radiance="lambertian", exit_pupil_stderr_mm=0.2)
    assert got.lens.vignetting == same.lens.vignetting and got.lens.vignetting
    assert (got.lens.exit_pupil_mm, got.lens.magnification, got.lens.pupil_magnification,
            got.lens.pupil_radiance) == (21.0, 0.05, 1.2, "lambertian")
    assert got.exit_pupil_stderr_mm == 0.2
    np.testing.assert_array_equal(got.shift_stderr_nm, same.shift_stderr_nm)
    assert _without_record(got.lens.calibration) == _without_record(same.lens.calibration)
    cal = got.lens.calibration
    assert cal["exit_pupil_from"] == "pupil.toml"
    assert (cal["exit_pupil_stderr_mm"], cal["exit_pupil_n_eff"], cal["exit_pupil_n_eff_stderr"],
            cal["exit_pupil_n_eff_fitted"]) == (0.2, 1.83, 0.01, "one")
    assert "exit_pupil_from" not in same.lens.calibration
    assert cal["method"] == "joint"  # the calibration's own record, not the lens's


def test_what_is_given_wins_over_the_lens_and_its_name_is_the_default_source(flats):
    bare = Lens(21.0, [], 0.05, 1.2, name="bare", calibration={"exit_pupil_stderr_mm": True})
    got = _calibrate(flats, lens=bare, magnification=0.0, pupil_magnification=1.0)
    assert (got.lens.magnification, got.lens.pupil_magnification) == (0.0, 1.0)
    assert got.lens.pupil_radiance == "paper"
    assert got.exit_pupil_stderr_mm is None  # a flag is no standard error
    assert got.lens.calibration["exit_pupil_from"] == "bare"
    assert "exit_pupil_n_eff" not in got.lens.calibration


@pytest.mark.parametrize(("kw", "error", "words"), [
    ({}, ValueError, "give the exit pupil distance"),
    ({"lens": KNOWN, "exit_pupil_mm": 21.0}, ValueError, "not both"),
    ({"lens": "pupil.toml"}, TypeError, "must be a Lens"),
])
def test_x_comes_from_exactly_one_place(flats, kw, error, words):
    with pytest.raises(error, match=words):
        _calibrate(flats, **kw)


def test_pupil_is_the_earlier_name_of_pupil_radiance(flats):
    """``pupil=`` still works, warns, and gives the lens ``pupil_radiance=`` gives; the
    Lambertian pupil's radius moves the circle's onsets, so the value is seen to arrive."""
    two = {f: flats[f] for f in (1.4, 2.0, 8.0)}
    with pytest.warns(FutureWarning, match="pupil is the earlier name of pupil_radiance"):
        old = _calibrate(two, exit_pupil_mm=21.0, pupil="lambertian")
    new = _calibrate(two, exit_pupil_mm=21.0, pupil_radiance="lambertian")
    assert old.lens.pupil_radiance == new.lens.pupil_radiance == "lambertian"
    assert old.lens.vignetting == new.lens.vignetting and new.lens.vignetting
    with pytest.raises(TypeError, match="give pupil_radiance once"):
        _calibrate(two, exit_pupil_mm=21.0, pupil="paper", pupil_radiance="paper")
