"""The stages of a lens calibration: a mosaic's tile of gains told from a sensor's own pattern;
the optical centre and the profiles about it, row first."""

import warnings

import numpy as np
import pytest
from conftest import PAPER_LENS

from snapcorr import Lens
from snapcorr.calibrate.lens.stages import (
    clean_flats,
    optical_center,
    optical_center_rc,
    profiles_and_onsets,
    ratio_images,
)
from snapcorr.simulate import Detector, flat_frame


def test_a_tile_of_gains_is_told_from_a_sensors_own_fixed_pattern():
    """A smooth fall-off with 1 % pixel gains (PRNU), 1 % even/odd column gains and shot noise
    is no mosaic; the same light through a 5 x 5 tile of gains 0.3-1.0 is, with its period
    (not 10 x 10, where it shows as much)."""
    from snapcorr.calibrate.lens.stages import _tile_period

    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[:300, :400]
    light = 3000.0 * (1 - 0.4 * (((yy - 140) / 300.0) ** 2 + ((xx - 210) / 400.0) ** 2))
    own = (1 + 0.01 * rng.standard_normal(light.shape)) * np.where(xx % 2, 1.01, 1.0)
    flat = rng.poisson(light * own).astype(float)
    ok = np.ones(flat.shape, bool)
    assert _tile_period(flat, ok) is None
    tile = rng.uniform(0.3, 1.0, (5, 5))
    mosaic = rng.poisson(light * own * np.tile(tile, (60, 80))).astype(float)
    k, spread = _tile_period(mosaic, ok)
    assert k == 5 and spread > 0.1


SMALL = dict(shape=(96, 160), pitch_um=88.0)
ROW, COL = 30.6, 101.3  # the optical axis, off the middle of a wide image


def _stages_of(lens, fs=(1.4, 2.8, 8.0), center_rc=(ROW, COL)):
    rng = np.random.default_rng(5)
    cam = Detector(signal_electrons=1e4)
    items = [(f, flat_frame(SMALL["shape"], SMALL["pitch_um"], f, lens, center_rc=center_rc,
                            detector=cam, rng=rng)) for f in fs]
    fl = clean_flats(items, None, None)
    return fl, ratio_images(fl)


def test_the_optical_centre_is_row_first_and_its_x_first_form_warns():
    fl, ratios = _stages_of(PAPER_LENS)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)
        (row, col), source, note = optical_center_rc(fl, ratios)
    assert source == "contours" and note is None
    assert abs(row - ROW) < 1.0 and abs(col - COL) < 1.0
    with pytest.warns(FutureWarning, match="optical_center gives the optical centre x first"):
        assert optical_center(fl, ratios) == ((col, row), source, note)
    assert optical_center_rc(fl, ratios, (3.0, 4.0)) == ((3.0, 4.0), "given", None)
    with pytest.warns(FutureWarning, match="x first"):
        assert optical_center(fl, ratios, center_px=(4.0, 3.0))[0] == (4.0, 3.0)
    with pytest.warns(FutureWarning, match="x first"):
        assert optical_center(fl, ratios, center_rc=(3.0, 4.0))[0] == (4.0, 3.0)


def test_without_a_fall_off_the_centre_is_the_image_centre_row_first():
    fl, ratios = _stages_of(Lens(1e6))  # an exit pupil so far that nothing falls off
    center, source, note = optical_center_rc(fl, ratios)
    assert center == (47.5, 79.5) and source == "image centre" and "image centre" in note


def test_the_profiles_take_the_centre_row_first_and_the_x_first_keyword_warns():
    fl, ratios = _stages_of(PAPER_LENS, fs=(2.8, 8.0))
    new = profiles_and_onsets(fl, ratios, (ROW, COL), PAPER_LENS, SMALL["pitch_um"])
    with pytest.warns(FutureWarning, match=r"center is the old x-first form .* "
                                           r"center_rc=\(30\.6, 101\.3\)"):
        old = profiles_and_onsets(fl, ratios, center=(COL, ROW), base=PAPER_LENS,
                                  pixel_pitch_um=SMALL["pitch_um"])
    for f in new[0]:
        np.testing.assert_array_equal(new[0][f].value, old[0][f].value)
    assert new[3] == old[3]
    # the field's largest angle, Eq. 8 by hand: the far corner from (ROW, COL) is (95, 0)
    d_mm = np.hypot(95 - ROW, 0 - COL) * SMALL["pitch_um"] * 1e-3
    assert new[3] == pytest.approx(np.degrees(np.arctan(d_mm / PAPER_LENS.exit_pupil_mm)),
                                   rel=1e-12)


def test_a_flat_without_light_is_refused_as_such_not_as_a_mosaic():
    """A negated flat (every value below 0, smooth) was refused for '0 % usable pixels' with
    the advice to give a mosaic sensor; it says there is no light, and checks to make."""
    from snapcorr.calibrate import calibrate_lens

    yy, xx = np.mgrid[:64, :80]
    smooth = 3000.0 * (1 - 1e-4 * ((yy - 32) ** 2 + (xx - 40) ** 2))
    flats = {2.0: -smooth, 4.0: -0.5 * smooth}
    with pytest.raises(ValueError, match=r"f/2 has no signal") as err:
        calibrate_lens(flats, exit_pupil_mm=21.0, pixel_pitch_um=44.0, magnification=0,
                       pupil_magnification=1)
    assert "sign" in str(err.value) and "mosaic" not in str(err.value)
