"""Flats of a crop beside the optical axis (the axis outside them, a corner away), from
``tests/oracles/flatsim.py``: the joint fit finds the centre outside the crop; the circle's
onsets are counted over the field about that centre, not about the crop's own middle."""

import warnings

import pytest
from flatsim import LensTruth, make_flats

from snapcorr.calibrate import calibrate_lens

TRUTH = LensTruth(21.0, ((10.0, 17.0),), 0.0, 1.0)
CENTRE_PX = (-39.3, -38.7)  # (column, row) of the axis in the crop's pixels


def _flats(f_numbers, seed=1):
    return make_flats(TRUTH, f_numbers, shape=(120, 100), pitch_um=44.0, center_px=CENTRE_PX,
                      noise=0.003, seed=seed)


def _calibrate(flats):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return calibrate_lens(flats, exit_pupil_mm=21.0, pixel_pitch_um=44.0, magnification=0,
                              pupil_magnification=1)


def test_a_crop_beside_the_axis_is_calibrated():
    """Five f-numbers, four onsets inside the field about the true centre (tan 0.12-0.44);
    about the crop's middle the field reached 9 deg and held one, and the flats were refused
    as "vignetting they cannot pin"."""
    res = _calibrate(_flats((1.4, 2.0, 2.8, 4.0, 8.0)))
    fit = res.fits[res.model]
    assert res.model == "one" and res.center_source == "joint fit"
    assert res.max_cra_deg > 20
    for name, truth in (("P_mm", 10.0), ("h_mm", 17.0), ("center_row_px", CENTRE_PX[1]),
                        ("center_col_px", CENTRE_PX[0])):
        assert abs(fit.params[name] - truth) < 4 * fit.stderr[name], name


def test_too_few_onsets_about_a_found_centre_asks_for_the_centre():
    """f/1.4 and f/8 only: one onset inside even about the true centre. The refusal names the
    centre it found and the keyword that gives one, besides more f-numbers."""
    with pytest.raises(ValueError, match="cannot pin") as err:
        _calibrate(_flats((1.4, 8.0)))
    text = str(err.value)
    assert "take flats at more f-numbers" in text
    assert "the optical centre was found from these flats" in text and "center_rc=" in text


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_a_crop_far_beside_the_axis_names_the_centre_and_keeps_a_given_one():
    """60 x 60 px with the axis 150 px off in both directions: found from the flats the
    centre landed on the wrong side, two circles were written at a reduced chi-square of
    361 and the misfit blamed on the pupil; given, it was doubted because the flats'
    contours (which cannot reach it) placed it elsewhere."""
    flats = make_flats(TRUTH, (1.4, 2.0, 2.8, 4.0, 8.0), shape=(60, 60), pitch_um=44.0,
                       center_px=(-150.0, -150.0), noise=0.003, seed=1)
    with pytest.raises(ValueError, match="the optical centre could not be placed") as err:
        _calibrate(flats)
    assert "outside them" in str(err.value) and "center_rc=" in str(err.value)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        given = calibrate_lens(flats, exit_pupil_mm=21.0, pixel_pitch_um=44.0, magnification=0,
                               pupil_magnification=1, center_rc=(-150.0, -150.0))
    (P, h), = given.lens.vignetting
    assert P == pytest.approx(10.0, rel=1e-3) and h == pytest.approx(17.0, rel=1e-3)
    assert not any("contours place the optical centre" in n for n in given.notes)
    assert not any("misfit" in n for n in given.notes)


def test_a_centre_the_joint_fit_found_is_not_said_to_be_the_image_centre():
    """The axis above a 60 x 60 crop: the contours found no fall-off and noted that the
    image centre is used; the joint fit then found the centre (row -149, col 30) and the
    note stayed in the profile beside it."""
    flats = make_flats(TRUTH, (1.4, 2.0, 2.8, 4.0, 8.0), shape=(60, 60), pitch_um=44.0,
                       center_px=(30.0, -150.0), noise=0.003, seed=1)
    res = _calibrate(flats)
    assert res.center_source == "joint fit"
    assert abs(res.center_rc[0] + 150.0) < 3 and abs(res.center_rc[1] - 30.0) < 3
    assert not any("the image centre is used" in n for n in res.notes)
    assert not any("the image centre is used" in n for n in res.lens.calibration["notes"])
