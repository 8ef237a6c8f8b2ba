"""Magnifications outside physics are refused where they enter, naming the option, the file
and key or the keyword, before any work; a lens profile that states none does not count as
stating m = 0 and m_P = 1."""

from __future__ import annotations

import numpy as np
import pytest

from snapcorr import Lens
from snapcorr.calibrate import calibrate_lens, calibrate_with_target, locate_pupil
from snapcorr.calibrate.lens import magnification as mag
from snapcorr.cube import Sensor

BAD_M = [1e300, float("inf"), float("nan"), -0.1, 11.0]
BAD_MP = [1e300, float("inf"), float("nan"), 0.0, -1.0, 1e-5, 50.0]


@pytest.mark.parametrize("m", BAD_M)
def test_a_lens_refuses_a_magnification_outside_physics(m):
    with pytest.raises(ValueError, match="magnification"):
        Lens(21.0, (), m, 1.3)


@pytest.mark.parametrize("mp", BAD_MP)
def test_a_lens_refuses_a_pupil_magnification_outside_physics(mp):
    with pytest.raises(ValueError, match="pupil_magnification"):
        Lens(21.0, (), 0.06, mp)


def test_the_bounds_keep_real_lenses():
    for m, mp in [(0.0, 1.0), (0.06, 1.3), (1.0, 0.3), (5.0, 4.0), (10.0, 10.0), (0.0, 0.1)]:
        Lens(21.0, (), m, mp)


def test_a_profile_out_of_bounds_is_refused_naming_the_file_and_key(tmp_path):
    path = tmp_path / "far.toml"
    path.write_text('[lens]\nexit_pupil_mm = 21.0\nmagnification = 1e300\n')
    with pytest.raises(ValueError, match=r"far\.toml: magnification must be between 0"):
        Lens.load(path)


# not a flat, a cube or a sensor: a refusal of anything but the magnification would say so
NOT_DATA = {2.0: "not an image"}


@pytest.mark.parametrize("key, value", [("magnification", 1e300),
                                        ("pupil_magnification", float("inf")),
                                        ("magnification", -1.0)])
def test_the_library_refuses_them_before_any_work(key, value):
    with pytest.raises(ValueError, match=f"^{key} "):
        calibrate_lens(NOT_DATA, exit_pupil_mm=21.0, pixel_pitch_um=5.5, **{key: value})
    with pytest.raises(ValueError, match=f"^{key} "):
        calibrate_with_target(NOT_DATA, NOT_DATA, None, pixel_pitch_um=5.5, **{key: value})
    sensor = Sensor("test", "snapscan", 44.0, np.arange(500.0, 600.0, 12.0), 12.0, 1.7)
    with pytest.raises(ValueError, match=f"^{key} "):
        locate_pupil(NOT_DATA, sensor, **{key: value})


@pytest.mark.parametrize("stated, want", [
    ("", ("neither", 0.0, (0.0, 0.1))),
    ("magnification = 0.06\n", ("m only", 0.06, (0.03, 0.12))),
    ("pupil_magnification = 1.3\n", ("m_P only", 0.0, (0.0, 0.1))),
    ("magnification = 0.0\n", ("m = 0", 0.0, (0.0, 0.0))),
    ("magnification = 0.06\npupil_magnification = 1.3\n",
     ("both", 0.06 / 1.3, (0.06 / 1.3,) * 2)),
])
def test_a_profile_that_states_no_magnifications_does_not_give_them(stated, want, tmp_path):
    """m and m_P a profile leaves out are the defaults assumed, not the lens's: a calibration
    given the profile judges them over the plausible range (and so widens its errors)."""
    path = tmp_path / "lens.toml"
    path.write_text(f"[lens]\nexit_pupil_mm = 21.0\n{stated}")
    lens = Lens.load(path)
    given, r, rng = mag.ratio_range(lens=lens)
    assert given == want[0] and r == pytest.approx(want[1]) and rng == pytest.approx(want[2])
    # the record survives a save and a load (the saved [lens] table states both)
    lens.save(tmp_path / "again.toml")
    assert mag.ratio_range(lens=Lens.load(tmp_path / "again.toml"))[0] == want[0]
    # values given to the calibration still count as given
    assert mag.ratio_range(0.06, 1.3, lens)[0] == "both"


def test_a_bundled_profile_states_its_magnifications():
    assert mag.ratio_range(lens=Lens.load("edmund_optics_16mm"))[0] == "both"
