"""Lens characterisation: the least-squares system of Goossens et al. 2019, Eq. 26."""

import numpy as np
import pytest
from conftest import PAPER_LENS
from numpy.testing import assert_allclose

from snapcorr import Lens
from snapcorr.calibrate import solve_vignetting_circle


def test_eq30_gives_eq31():
    fit = solve_vignetting_circle([0.38, 9, 13, 15.4], [7.1715, 5.0201, 3.5858, 2.5100])
    assert abs(fit.P_mm - 7.4236) < 1e-3 and abs(fit.h_mm - 16.991) < 1e-3
    assert fit.residuals_mm.shape == (4,) and np.all(np.isfinite([fit.P_stderr_mm,
                                                                   fit.h_stderr_mm]))


def test_exact_onsets_recover_the_lens():
    # Onsets computed from a known lens (Eq. 46) give back its P and h exactly (f-numbers
    # where P > R, so the onset is not at 0).
    lens = Lens(21.0, [(6.5, 23.0)], 0.05, 1.2, name="t")
    f = np.array([2.0, 2.8, 4.0, 5.6, 8.0])
    fit = solve_vignetting_circle(lens.onset_cra_deg(f), lens.exit_pupil_radius_mm(f))
    assert_allclose([fit.P_mm, fit.h_mm], [6.5, 23.0], rtol=1e-10)
    assert np.max(np.abs(fit.residuals_mm)) < 1e-10


def test_two_equations_solve_exactly_without_uncertainty():
    fit = solve_vignetting_circle([5.0, 12.0], [6.0, 4.0])
    assert np.max(np.abs(fit.residuals_mm)) < 1e-12 and np.isnan(fit.P_stderr_mm)


@pytest.mark.parametrize(
    ("onsets", "radii", "message"),
    [([5.0], [6.0], "two or more"), ([5.0, 5.0], [6.0, 4.0], "same angle"),
     ([5.0, np.nan], [6.0, 4.0], "finite"), ([5.0, 9.0], [6.0, -1.0], "finite")],
)
def test_bad_inputs(onsets, radii, message):
    with pytest.raises(ValueError, match=message):
        solve_vignetting_circle(onsets, radii)


def test_shipped_edmund_profile_is_eq26_of_its_own_onsets():
    from snapcorr.data import lens_path

    lens = Lens.load(lens_path("edmund_optics_16mm"))
    cal = lens.calibration
    fit = solve_vignetting_circle(cal["onset_cra_deg"], cal["exit_pupil_radius_mm"])
    assert abs(fit.P_mm - lens.vignetting[0][0]) < 1e-3
    assert abs(fit.h_mm - lens.vignetting[0][1]) < 1e-3
    assert_allclose(fit.residuals_mm, cal["residuals_mm"], atol=1e-4)
    assert_allclose([fit.P_stderr_mm, fit.h_stderr_mm],
                    [cal["P_stderr_mm"], cal["h_stderr_mm"]], rtol=5e-3)
    assert cal["h_matlab_toolbox_mm"] == 16.911


def test_onset_uncertainties_propagate_into_p_and_h():
    lens = Lens(21.0, [(6.5, 23.0)], 0.05, 1.2, name="t")
    f = np.array([2.0, 4.0])
    on = lens.onset_cra_deg(f)
    exact = solve_vignetting_circle(on, lens.exit_pupil_radius_mm(f), [0.1, 0.1])
    # two equations: no residual error, so the error comes from the onsets alone; compare
    # with a Monte-Carlo of the same solve
    rng = np.random.default_rng(0)
    draws = np.array([
        (lambda r: (r.P_mm, r.h_mm))(solve_vignetting_circle(
            on + rng.normal(0, 0.1, 2), lens.exit_pupil_radius_mm(f)))
        for _ in range(4000)])
    assert_allclose([exact.P_stderr_mm, exact.h_stderr_mm], draws.std(axis=0), rtol=0.06)


def test_a_circle_that_cuts_no_ray_has_no_standard_error():
    # noise-free ratio images of one vignetting circle, fitted with two: a second circle far
    # outside every ray changes nothing when it moves, so its P2 and h2 have no error bar
    from snapcorr.calibrate.lens.joint_fit import BlockData, _tan, fit_model, model_ratio

    lens = PAPER_LENS
    y, x = np.mgrid[0:2048:64, 0:2048:64]
    xpix, ypix = x.ravel() + 32.0, y.ravel() + 32.0
    fs = np.array([1.4, 2.0, 2.8])
    data = BlockData(q=np.zeros((3, xpix.size)), sigma=np.full((3, xpix.size), 1e-3),
                     xpix=xpix, ypix=ypix, R_mm=lens.exit_pupil_radius_mm(fs),
                     R_ref_mm=float(lens.exit_pupil_radius_mm(8.0)), pitch_mm=5.5e-3,
                     x_mm=21.0)
    center = (1030.0, 1000.0)  # (row, col)
    data.q[:] = model_ratio(data, "one", [7.4236, 16.991, *center], _tan(data, center))
    fit = fit_model(data, "two", [[7.4, 17.0, *center, 200.0, 21.0]], center_rc=center)
    assert fit.params["P_mm"] == pytest.approx(7.4236, rel=1e-3)
    assert np.isfinite(fit.stderr["P_mm"]) and np.isfinite(fit.stderr["h_mm"])
    assert fit.stderr["P2_mm"] == np.inf and fit.stderr["h2_mm"] == np.inf


def test_a_second_circle_the_flats_hardly_see_gets_a_wide_error_bar():
    # 256 x 256 flats of the paper's lens: the two-circle fit parks its second circle where it
    # barely touches the field; moving it by 0.5 mm changes the model by (almost) nothing, so
    # its error bar must not be a small one
    from snapcorr.calibrate import calibrate_lens
    from snapcorr.simulate import flat_frame

    lens = PAPER_LENS
    rng = np.random.default_rng(2019)
    flats = {f: flat_frame((256, 256), 44.0, f, lens, center_px=(140.3, 118.6), rng=rng)
             for f in (1.4, 2.0, 2.8, 4.0, 8.0)}
    res = calibrate_lens(flats, exit_pupil_mm=21, pixel_pitch_um=44.0, magnification=0.06,
                         pupil_magnification=1.3)
    # the free second circle (the two-circle model, or its rival where the second circle
    # held at h = x had the lower BIC)
    two = res.rivals["free"][0] if "free" in res.rivals else res.fits["two"]
    assert "held" not in two.extra
    assert two.stderr["P_mm"] < 0.01 and two.stderr["h_mm"] < 0.05
    # loose, or not pinned at all
    assert two.stderr["P2_mm"] > 0.05 * two.params["P2_mm"]
    assert two.stderr["h2_mm"] > 0.05 * abs(two.params["h2_mm"])
    assert res.model == "one" and not res.verdicts["two"].chosen
    why = res.verdicts["two"].why
    assert any(s in why for s in ("not identifiable", "cannot tell them apart",
                                  "no better than one")), why


def test_gains_and_exposures_solved_for_match_a_brute_force_joint_fit():
    # q = e_F G A per block: the closed-form gains with Gauss-Newton exposures against every
    # gain and exposure as explicit parameters of one scipy least-squares fit; some values
    # unused (sigma inf), from a cold start and from a warm one
    from scipy.optimize import least_squares

    from snapcorr.calibrate.lens.joint_fit import _profiled

    rng = np.random.default_rng(1)
    k, n = 4, 300
    A = rng.uniform(0.2, 1.0, (k, n))
    G = rng.uniform(1.0, 2.0, n)
    e = np.array([3.0, 1.5, 0.7, 1.0])
    sigma = 0.01 * rng.uniform(0.5, 2.0, (k, n))
    sigma[1, :50] = np.inf
    q = e[:, None] * G * A + np.where(np.isfinite(sigma), sigma, 0) * rng.standard_normal((k, n))
    q[~np.isfinite(sigma)] = 0.0

    def residuals(x):
        ee = np.r_[np.exp(x[: k - 1]), 1.0]
        return np.where(np.isfinite(sigma), (q - ee[:, None] * x[k - 1:] * A) / sigma,
                        0.0).ravel()

    ref = least_squares(residuals, np.r_[np.zeros(k - 1), np.ones(n)], xtol=1e-15,
                        ftol=1e-15, gtol=1e-15)
    r, got = _profiled(q, sigma, A)
    assert r @ r == pytest.approx(2 * ref.cost, rel=1e-10)
    np.testing.assert_allclose(got[:-1], np.exp(ref.x[: k - 1]), rtol=1e-8)
    _, warm = _profiled(q, sigma, A, start=np.log(got) + 0.05)
    np.testing.assert_allclose(warm, got, rtol=1e-10)
