"""The budget over band and chief-ray angle against Mishev & Bakalova, exact invariants and a
brute-force pupil integration."""

import numpy as np
import pytest
from conftest import PAPER_LENS

from snapcorr import budget, spectra
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, make_cube
from snapcorr.optics.profiles import MultiLorentzian

PAPER = PAPER_LENS
FLAT = spectra.Spectrum(np.array([200.0, 2000.0]), np.array([3.7, 3.7]), "flat")


@pytest.fixture(scope="module")
def sun():
    return spectra.solar()


# --- exact invariants ---------------------------------------------------------------------

def test_a_flat_spectrum_leaves_exactly_zero_residual_for_every_model_and_pixel():
    sensor = Sensor("s", "snapscan", 5.5, np.linspace(470, 900, 7), 10.0, 1.7)
    b = budget.scene_budget(FLAT, sensor, 1.4, PAPER, cra_max_deg=20.0, n_cra=9)
    assert np.all(b.data["residual"].values == 0.0)
    assert b.recommend(0.01)[0] == "none"


# --- Mishev & Bakalova ----------------------------------------------------------------------

def test_mishev_smooth_scene_negligible_step_scene_large_and_growing_with_radius():
    # MKF-6 channel 2 (540 nm, 40 nm) as a one-band sensor behind the paper's lens at f/4
    sensor = Sensor("mkf6-2", "snapscan", 5.5, [540.0], 40.0, 1.5)
    smooth = spectra.blackbody(5800.0)
    lc = 555.0  # the edge inside the band
    step = spectra.Spectrum(np.array([300.0, lc, lc + 1e-6, 1100.0]), np.array([1, 1, 0, 0.0]),
                           "step")
    kw = dict(cra_max_deg=20.0, n_cra=11, profile="pi")
    b_smooth = budget.scene_budget(smooth, sensor, 4.0, PAPER, **kw)
    b_step = budget.scene_budget(step, sensor, 4.0, PAPER, **kw)
    e_smooth = np.abs(b_smooth.data["residual"].sel(model="none").values[0])
    e_step = np.abs(b_step.data["residual"].sel(model="none").values[0])
    assert e_smooth.max() < 0.01           # < 1 % at 20 deg (a 13 nm shift of a 40 nm band)
    assert e_step.max() > 10 * e_smooth.max() and e_step.max() > 0.05
    assert np.all(np.diff(e_step) > -1e-12) and e_step[-1] > 5 * e_step[0]  # grows with r
    assert b_smooth.recommend(1.0)[0] == "none"
    # Mishev's radius: inside it the uncorrected step scene stays within 5 %
    r = b_step.radius_mm(5.0)
    inside = b_step.data["radius_mm"].values <= r
    assert 0 < r < float(b_step.data["radius_mm"].max())
    assert np.all(e_step[inside] <= 0.05) and np.all(e_step[~inside] > 0.05)
    assert b_smooth.radius_mm(1.0) == np.inf  # within 1 % over the whole field
    # normalised to the frame's centre, as Mishev & Bakalova's d(r): the step scene still
    # leaves its circle, at a larger radius than against the nominal band
    rc = b_step.radius_mm(5.0, relative_to="center")
    assert r < rc < float(b_step.data["radius_mm"].max())


# --- the pixel's signal: brute force over the pupil -----------------------------------------

def _line_spectrum():
    lam = np.arange(300.0, 1100.0, 0.05)
    v = 1.0 - 0.6 * np.exp(-0.5 * ((lam - 696.0) / 1.5) ** 2)  # an absorption line in band
    return spectra.Spectrum(lam, v, "line")


@pytest.mark.parametrize("cra", [0.0, 12.0, 22.0])
def test_pixel_signal_matches_brute_force_pupil_sampling(cra):
    # two bands, so the kernel built at the largest centre is scaled to the other one
    src = _line_spectrum()
    cwls, fwhm, n, f = np.array([450.0, 700.0]), 10.0, 1.7, 1.4
    sensor = Sensor("two", "snapscan", 5.5, cwls, fwhm, n)
    b = budget.scene_budget(src, sensor, f, PAPER, cra_max_deg=cra, n_cra=2,
                            profile="multi_lorentzian")
    # every ray through the (vignetted) pupil shifts the whole filter by Eq. 3 at its angle
    x, R = PAPER.exit_pupil_mm, float(PAPER.exit_pupil_radius_mm(f))
    t = np.tan(np.deg2rad(cra))
    d, P, dv = x * t, PAPER.vignetting[0][0], PAPER.vignetting[0][1] * t
    N = 600
    c = (np.arange(N) + 0.5) * (2 * R / N) - R
    X, Y = np.meshgrid(c, c, indexing="ij")
    inside = (X**2 + Y**2 <= R * R) & ((X - dv) ** 2 + Y**2 <= P * P)
    r2 = (X[inside] - d) ** 2 + Y[inside] ** 2
    factor = np.sqrt(1 - r2 / (r2 + x * x) / n**2) - 1  # shift / cwl of each ray
    lam = np.arange(300.0, 1099.9, 0.002)
    S = src(lam)
    for k, cwl in enumerate(cwls):
        prof = MultiLorentzian(cwl, fwhm, n)
        counts, edges = np.histogram(cwl * factor, bins=max(8, int(np.ptp(cwl * factor) / 0.02)))
        mids = 0.5 * (edges[1:] + edges[:-1])

        near = np.abs(lam - cwl) < 6 * fwhm + 25.0
        lb, Sb = lam[near], S[near]

        def P_at(shift, prof=prof, lb=lb, Sb=Sb):  # direct integration, nothing from the module
            return np.trapezoid(prof(lb - shift) * Sb, lb)

        brute = sum(w * P_at(m) for w, m in zip(counts, mids, strict=True)) / counts.sum()
        got = 1.0 + float(b.data["residual"].sel(model="none").values[k, -1])
        assert got == pytest.approx(brute / P_at(0.0), abs=3e-5), cwl
        assert abs(got - 1) > 1e-3 or cwl == 450.0  # the line is in the 700 nm band


def test_the_exact_mean_is_exact_for_a_linear_spectrum_but_not_across_a_line():
    # For a spectrum linear within the band, P is linear in the shift, so the kernel's mean
    # carries all of it: the vignetted model leaves nothing. Across an absorption line the
    # kernel's width (Goossens Sec. 3.4) leaves a residual that no mean correction undoes.
    sensor = Sensor("one", "snapscan", 5.5, [700.0], 10.0, 1.7)
    lam = np.arange(300.0, 1100.0, 0.1)
    ramp = spectra.Spectrum(lam, 1.0 + (lam - 300.0) / 400.0, "ramp")
    kw = dict(cra_max_deg=20.0, n_cra=9)
    b = budget.scene_budget(ramp, sensor, 1.4, PAPER, **kw)
    res = np.abs(b.data["residual"])
    assert float(res.sel(model="none").max()) > 3e-3
    assert float(res.sel(model="vignetted").max()) < 1e-7
    assert float(res.sel(model="ideal").max()) > 1e-4  # wrong mean past the onset
    b = budget.scene_budget(_line_spectrum(), sensor, 1.4, PAPER, **kw,
                            models=("asymptotic", "ideal", "vignetted"))
    vig = float(np.abs(b.data["residual"].sel(model="vignetted")).max())
    assert vig > 1e-3
    _model, reason = b.recommend(vig * 100 * 0.5)
    assert "no model is within" in reason
    # bringing every pixel to one response per band undoes most of what the width leaves
    h = budget.scene_budget(_line_spectrum(), sensor, 1.4, PAPER, **kw)
    har = float(np.abs(h.data["residual"].sel(model="harmonised")).max())
    assert har < 0.5 * vig
    assert h.recommend(vig * 100 * 0.5)[0] == "harmonised"


def test_budget_arguments_are_checked(sun):
    sensor = Sensor("s", "snapscan", 5.5, [500.0], 10.0, 1.7)
    with pytest.raises(ValueError, match="cut-off"):
        budget.scene_budget(sun, sensor, 1.4, PAPER, cra_max_deg=60.0)
    with pytest.raises(ValueError, match="profile"):
        budget.scene_budget(sun, sensor, 1.4, PAPER, cra_max_deg=5.0, profile="box")
    with pytest.raises(ValueError, match="n_cra"):
        budget.scene_budget(sun, sensor, 1.4, PAPER, cra_max_deg=5.0, n_cra=1)
    with pytest.raises(ValueError, match="tolerance_pct must be a finite number > 0, got -1"):
        budget.scene_budget(sun, sensor, 1.4, PAPER, cra_max_deg=5.0, tolerance_pct=-1)
    b = budget.scene_budget(sun, sensor, 1.4, PAPER, cra_max_deg=5.0, n_cra=3)
    with pytest.raises(ValueError, match="tolerance_pct must be a finite number > 0, got -1"):
        b.recommend(-1)


# --- the model correct_cube takes -------------------------------------------------------

def test_the_budget_recommends_the_model_correct_cube_takes():
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 21), 10.0, 1.7)
    lam = np.asarray(sensor.cwl_nm)
    step = np.where(lam < 700, 1.0, 0.05).astype(np.float32)  # a red edge in the scene
    cube = make_cube(np.broadcast_to(step, (20, 30, 21)).copy(), sensor.cwl_nm)
    model, reason, attrs = budget.recommend_model(cube, sensor, 1.4, PAPER, "cube",
                                                  tolerance_pct=0.1)
    # the edge inside the 700 nm band (200 % uncorrected): only harmonising (the vignetted
    # shift and one response per band) brings it within 0.1 %
    worst = dict(zip(attrs["budget_models"], attrs["budget_worst_pct"], strict=True))
    assert attrs["budget_source"] == "cube mean" and worst["none"] > 100
    assert min(worst, key=worst.get) == "harmonised" and worst["harmonised"] < 0.1
    assert all(worst[m] > 0.1 for m in worst if m != "harmonised")
    assert model == "harmonised" and "harmonised leaves at most" in reason
    # asked for less than any model leaves: the one that leaves the least, and says so
    assert "no model is within" in budget.recommend_model(cube, sensor, 1.4, PAPER, "cube",
                                                          tolerance_pct=0.01)[1]
    ds = correct_cube(cube, sensor, 1.4, PAPER, method=model)
    assert ds.attrs["method"] == "harmonised" and "harmonised" in ds
    # the shift is the vignetted model's
    exact = correct_cube(cube, sensor, 1.4, PAPER, method="vignetted")
    np.testing.assert_array_equal(ds["wavelength_scale"], exact["wavelength_scale"])
    assert "harmonised" not in exact
    # within 0.5 % harmonising is enough, and is what is chosen
    model, reason, _ = budget.recommend_model(cube, sensor, 1.4, PAPER, "cube",
                                              tolerance_pct=0.5)
    assert model == "harmonised" and "harmonised leaves at most" in reason
    flat = make_cube(np.ones((20, 30, 21), np.float32), sensor.cwl_nm)
    assert budget.recommend_model(flat, sensor, 1.4, PAPER, "cube")[0] == "none"
    # a cube of another sensor: refused before any budget is worked out for it
    other = Sensor("other", "snapscan", 40.0, np.linspace(500, 900, 20), 10.0, 1.7)
    with pytest.raises(ValueError, match="has 21 bands, the sensor 'other' 20"):
        budget.recommend_model(cube, other, 1.4, PAPER, "cube")


@pytest.mark.parametrize("scale", [1e306, 1e-300])
def test_the_budget_is_the_same_for_a_spectrum_in_any_unit(scale):
    """The errors are ratios of signals: a spectrum scaled to 1e306 overflowed in their
    products and was said to have 'no signal in the band at 470 nm'; Flittner & Slater's
    ranges and the signal ratio alike."""
    from snapcorr.optics.profiles import Gaussian

    sun = spectra.solar()
    big = spectra.Spectrum(sun.wavelength_nm, sun.values / sun.values.max() * scale, "big")
    sensor = Sensor("s", "snapscan", 5.5, np.linspace(470, 900, 6), 10.0, 1.7)
    a = budget.scene_budget(sun, sensor, 8.0, PAPER_LENS, cra_max_deg=15.0, n_cra=5)
    b = budget.scene_budget(big, sensor, 8.0, PAPER_LENS, cra_max_deg=15.0, n_cra=5)
    np.testing.assert_allclose(b.data["residual"].values, a.data["residual"].values,
                               rtol=1e-6, atol=1e-12)
    assert budget.tolerance_ranges(big, [600.0], [10.0]) == budget.tolerance_ranges(
        sun, [600.0], [10.0])
    g = Gaussian(600.0, 10.0)
    assert budget.relative_signal(big, g, [1.0]) == pytest.approx(
        budget.relative_signal(sun, g, [1.0]), rel=1e-12)


@pytest.mark.parametrize("pupil", ["lambertian", "paper-lambertian"])
def test_a_lambertian_pupils_budget_leaves_out_eq_6_and_says_so(sun, pupil):
    """A budget of a lens with a Lambertian pupil was refused whole: Eq. 6 (asymptotic) is
    the paper's pupil's. It is left out, the other models evaluated, and the reason said."""
    import dataclasses

    sensor = Sensor("s", "snapscan", 5.5, np.linspace(470, 900, 7), 10.0, 1.7)
    lens = dataclasses.replace(PAPER, pupil_radiance=pupil)
    b = budget.scene_budget(sun, sensor, 1.4, lens, cra_max_deg=15.0, n_cra=5)
    assert "asymptotic" not in b.models and "vignetted" in b.models
    assert "Eq. 6 holds for the paper's pupil" in b.recommend(0.5)[1]
    paper = budget.scene_budget(sun, sensor, 1.4, PAPER, cra_max_deg=15.0, n_cra=5)
    assert "asymptotic" in paper.models and "left out" not in paper.recommend(0.5)[1]
