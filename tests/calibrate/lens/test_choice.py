"""The rules that choose the vignetting model (snapcorr.calibrate.lens.choice), each shown failing
the model it is there to stop, on flats from the independent simulator tests/oracles/flatsim.py."""

from dataclasses import replace

import numpy as np
import pytest
from conftest import PAPER_CIRCLE, PAPER_LENS
from flatsim import LensTruth, make_flats

from snapcorr import Lens, mean_shift
from snapcorr.calibrate import calibrate_lens
from snapcorr.calibrate.lens.choice import check_circles, choose, shift_difference_nm
from snapcorr.calibrate.lens.joint_fit import fit_model
from snapcorr.calibrate.lens.stages import block_data, clean_flats, ratio_images

X = 21.0
FS = (2.0, 2.8, 4.0, 5.6, 11.0)
SCENE = dict(shape=(256, 320), pitch_um=28.4, center_px=(174.75, 119.75))
H_GT_X = LensTruth(X, ((9.5, 26.0),), 0.06, 1.3)  # the user's case: one circle, h > x


@pytest.fixture(scope="module")
def user_flats():
    return make_flats(H_GT_X, FS, noise=0.005, seed=3, **SCENE)


def _data(flats):
    fl = clean_flats(sorted(flats.items()), None, None)
    base = Lens(X, (), 0.06, 1.3)
    return block_data(fl, ratio_images(fl), base, SCENE["pitch_um"]), base


def test_a_stop_like_second_circle_is_refused(user_flats):
    data, base = _data(user_flats)
    R_fast = float(base.exit_pupil_radius_mm(FS[0]))
    center = SCENE["center_px"][::-1]  # the vector holds it row first
    one = fit_model(data, "one", [[9.5, 26.0, *center]])
    # the spurious solution seen on a user's flats: a stop at the fastest pupil's radius
    stop = fit_model(data, "two", [[9.5, 26.0, *center, R_fast, 0.03]], max_nfev=5)
    problems = check_circles(stop, base, FS, 16.66)
    assert any("circle 2" in p for p in problems), problems
    bic = {"one": 0.0, "two": -1e9}  # even an overwhelming criterion gain does not admit it
    model, verdicts = choose({"one": one, "two": stop}, bic, base, FS, 16.66)
    assert model == "one" and "not identifiable" in verdicts["two"].why


def test_the_rules_are_each_decisive():
    # identifiability: one f-number's onset inside the field does not tell P from h
    lens = Lens(X, [(12.0, 30.0)], 0.06, 1.3)
    on = lens.circle_onsets_cra_deg(np.array(FS))[0]
    assert np.sum(on < 14.0) == 1 and np.sum(on < 16.66) == 2
    # the functional test: identical lenses differ by nothing, a moved circle by nanometres
    a = PAPER_LENS
    b = replace(a, vignetting=[PAPER_CIRCLE, (200.0, 30.0)])  # never cuts in the field
    c = Lens(X, [(7.0, 16.991)], 0.06, 1.3)
    assert np.nanmax(shift_difference_nm(a, b, FS, 16.0)) < 1e-9
    assert np.nanmax(shift_difference_nm(a, c, FS, 16.0)) > 0.1


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_pixel_vignetting_is_kept_only_where_it_matters_to_the_tolerance():
    truth = LensTruth(X, ((7.4236, 16.991), (8.5, X)), 0.06, 1.3)
    flats = make_flats(truth, FS, noise=0.005, seed=1, **SCENE)
    kw = dict(exit_pupil_mm=X, pixel_pitch_um=SCENE["pitch_um"], magnification=0.06,
              pupil_magnification=1.3)
    res = calibrate_lens(flats, **kw)
    assert res.model == "two" and len(res.lens.vignetting) == 2
    coarse = calibrate_lens(flats, tolerance_nm=1.0, **kw)  # 0.2 nm does not matter at 1 nm
    assert coarse.model == "one" and "suffices" in coarse.verdicts["two"].why
    only_one = calibrate_lens(flats, max_circles=1, **kw)
    assert list(only_one.fits) == ["none", "one"]
    table = res.lens.calibration["model_choice"]
    assert table["next_best"] in ("one", "three") and table["models_tried"][0] == "none"
    assert len(table["shift_difference_to_next_best_nm"]) == len(FS)


def test_where_a_circle_starts_to_cut_the_light_the_others_leave():
    # circle 2 touches circle 1 inside it at atan((8 - 7.4236) / (19 - 16.991)) = 16.0 deg at
    # every f-number: against the bare pupil it would start at 8.9 and 13.1 deg
    from snapcorr.calibrate.lens.choice import effective_onsets_deg

    lens = Lens(X, [(7.4236, 16.991), (8.0, 19.0)], 0.06, 1.3)
    bare = lens.circle_onsets_cra_deg(np.array([2.0, 2.8]))[1]
    eff = effective_onsets_deg(lens, [2.0, 2.8], 18.0)[1]
    touch = np.rad2deg(np.arctan((8.0 - 7.4236) / (19.0 - 16.991)))
    assert np.all(bare < touch - 2.0) and np.all(np.abs(eff - touch) < 0.1)
    # a circle wholly hidden behind another cuts no light: never identifiable
    hidden = Lens(X, [(7.4236, 16.991), (9.0, 16.991)], 0.06, 1.3)
    assert np.all(np.isinf(effective_onsets_deg(hidden, [2.0, 2.8], 18.0)[1]))


KW = dict(exit_pupil_mm=X, pixel_pitch_um=SCENE["pitch_um"], magnification=0.06,
          pupil_magnification=1.3)


def test_without_vignetting_the_center_is_not_taken_from_a_refused_fit():
    truth = LensTruth(X, (), 0.06, 1.3)
    res = calibrate_lens(make_flats(truth, FS, noise=0.005, seed=4, **SCENE), **KW)
    assert res.model == "none" and res.center_source == "contours"
    assert np.hypot(res.center_rc[1] - SCENE["center_px"][0],
                    res.center_rc[0] - SCENE["center_px"][1]) < 1.0


def test_max_circles_zero_tries_no_circle_and_says_so(user_flats):
    res = calibrate_lens(user_flats, max_circles=0, **KW)
    assert list(res.fits) == ["none"] and not res.lens.has_vignetting
    assert "no vignetting circle tried" in res.reason


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_two_circles_predict_left_out_flats_better_than_the_onsets():
    # the paper's onsets see one circle: they predict a flat they did not see worse than the
    # two-circle joint fit, so auto keeps the joint fit and says by how much
    truth = LensTruth(X, ((6.2, 12.0), (10.0, 30.0)), 0.0, 1.0)
    flats = make_flats(truth, FS, noise=0.005, seed=2, **SCENE)
    steps = []
    res = calibrate_lens(flats, **{**KW, "magnification": 0.0, "pupil_magnification": 1.0},
                         progress=steps.append)
    assert res.method == "joint" and len(res.lens.vignetting) == 2
    # every long step is announced, for a progress bar
    assert steps[:2] == ["joint fit, one circle", "joint fit, 2 circles"]
    assert [s for s in steps if s.startswith("predicting")] == [
        f"predicting f/{f:g} left out" for f in FS[:-1]]
    joint, onsets = res.predictive["joint"], res.predictive["onset-ratio"]
    assert list(joint.chi2) == list(onsets.chi2) and len(joint.chi2) >= 2
    assert joint.total < onsets.total
    assert "predicts the flats left out" in res.reason
    table = res.lens.calibration["estimator_choice"]
    assert table["joint"]["total_chi2"] == pytest.approx(joint.total, abs=0.01)


def test_an_onset_method_leaves_no_joint_model_marked_chosen(user_flats):
    res = calibrate_lens(user_flats, method="onset-model", **KW)
    assert res.method == "onset-model" and len(res.lens.vignetting) == 1
    table = res.lens.calibration["joint_fit"]
    assert not any(entry["chosen"] for entry in table.values())
    assert "not used (onset-model)" in table["one"]["why"]


@pytest.mark.slow
def test_the_reported_shift_uncertainty_is_honest_over_seeds():
    # |error| / reported standard error of the mean shift, worst f-number, over seeds
    from flatsim import mean_shift_nm

    ratios = []
    for seed in range(8):
        res = calibrate_lens(make_flats(H_GT_X, FS, noise=0.05, seed=100 + seed, **SCENE), **KW)
        assert res.model == "one"
        j = int(np.nanargmax(res.shift_stderr_nm))
        f = FS[j]
        cra = np.linspace(0.0, res.max_cra_deg, 25)
        got = mean_shift(1000.0, 1.5, f, cra, res.lens, method="vignetted")
        want = np.ravel(mean_shift_nm(H_GT_X, 1000.0, 1.5, f, cra))
        ratios.append(np.max(np.abs(got - want)) / res.shift_stderr_nm[j])
    ratios = np.array(ratios)
    assert np.all(ratios < 4.0), ratios
    assert 0.3 < np.sqrt(np.mean(ratios ** 2)) < 2.0, ratios


def test_a_wrong_x_fits_as_well_and_moves_p_and_h_as_the_profile_says(user_flats):
    # the flats fix P / x and h / x^2: a 10 % wrong x is invisible in them, P moves by 10 %
    # and h by 21 %, and the profile states how (dP/dx, dh/dx) and says x was not checked
    kw = {**KW, "max_circles": 1}
    right = calibrate_lens(user_flats, **kw)
    wrong = calibrate_lens(user_flats, **{**kw, "exit_pupil_mm": 1.1 * X})
    assert wrong.fits["one"].reduced_chi2 == pytest.approx(right.fits["one"].reduced_chi2,
                                                           rel=1e-3)
    (P0, h0), (P1, h1) = right.lens.vignetting[0], wrong.lens.vignetting[0]
    assert P1 / P0 == pytest.approx(1.1, rel=2e-4) and h1 / h0 == pytest.approx(1.21, rel=2e-4)
    scaling = right.lens.calibration["exit_pupil_scaling"]
    # the finite difference between the two calibrations against the stated derivatives
    assert (P1 - P0) / (0.1 * X) == pytest.approx(scaling["dP_dx"][0], rel=1e-3)
    assert (h1 - h0) / (0.1 * X) == pytest.approx(scaling["dh_dx"][0], rel=0.06)  # h ~ x^2
    assert scaling["exit_pupil_stderr_mm"] == "not given"
    assert any("without an error" in n and "cannot check it" in n for n in right.notes)
    # with x's error, P's and h's errors carry it
    known = calibrate_lens(user_flats, **{**kw, "exit_pupil_stderr_mm": 0.2})
    sc = known.lens.calibration["exit_pupil_scaling"]
    P, h = known.lens.vignetting[0]
    assert sc["P_stderr_with_x_mm"][0] >= P / X * 0.2
    assert sc["h_stderr_with_x_mm"][0] >= 2 * h / X * 0.2
