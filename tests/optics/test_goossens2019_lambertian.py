"""The Lambertian pupil (``Lens(pupil_radiance="lambertian")``): the sine condition and cos^4
weights.

Checked against what snapcorr does not compute itself: the independent quadrature of
``tests/oracles/spectralsim.py`` (its "sine" pupil: marginal ray at sin(theta) = 1 / (2 f_W), each
ray weighted by cos^4(phi) per unit area), and a closed form derived here for the pixel on
the axis.
"""

import numpy as np
import pytest
import spectralsim as sim
from flatsim import LensTruth

from snapcorr import Lens, mean_shift
from snapcorr.optics import ShiftGrid, goossens2019, select_method
from snapcorr.optics.response import kernel_bins

CIRCLES = [(), ((7.4236, 16.991),), ((7.4236, 16.991), (9.0, 30.0))]
N_EFF, CWL = 1.5, 1000.0


def _brute(circles, f, cra):
    """Mean shift and variance (nm, nm^2) from spectralsim's pupil quadrature."""
    truth = LensTruth(21.0, circles, 0.06, 1.3, meta={"pupil": "sine"})
    q, w = sim._sin2_phi(truth, f, 21.0 * np.tan(np.deg2rad(cra)))
    shift = CWL * (np.sqrt(1.0 - q / N_EFF**2) - 1.0)
    mean = np.sum(w * shift) / w.sum()
    return mean, np.sum(w * (shift - mean) ** 2) / w.sum()


@pytest.mark.parametrize("circles", CIRCLES, ids=["none", "one", "two"])
@pytest.mark.parametrize(("f", "cra"), [(1.4, 0.0), (1.4, 8.0), (1.4, 15.0), (2.8, 15.0),
                                        (8.0, 12.0)])
def test_mean_shift_matches_an_independent_quadrature(circles, f, cra):
    lens = Lens(21.0, circles, 0.06, 1.3, pupil_radiance="lambertian")
    want, _ = _brute(circles, f, cra)
    got = float(mean_shift(CWL, N_EFF, f, cra, lens, method="vignetted"))
    assert got == pytest.approx(want, abs=1e-9)
    # and it is another pupil than the paper's: they differ by far more than that
    paper = float(mean_shift(CWL, N_EFF, f, cra, Lens(21.0, circles, 0.06, 1.3),
                             method="vignetted"))
    assert abs(paper - got) > 1e-3


@pytest.mark.parametrize("f", [1.0, 1.4, 2.0, 4.0])
def test_on_axis_closed_form(f):
    """On the axis the rays fill a disc of direction sines of radius NA uniformly; with
    u = sin^2(phi) uniform on [0, NA^2]: mean of sqrt(1 - u / n^2) = (2 n^2 / (3 NA^2))
    (1 - (1 - NA^2 / n^2)^(3/2))."""
    na = 1.0 / (2.0 * f)
    n2 = N_EFF**2
    want = CWL * (2.0 * n2 / (3.0 * na * na) * (1.0 - (1.0 - na * na / n2) ** 1.5) - 1.0)
    lens = Lens(50.0, pupil_radiance="lambertian")
    got = float(mean_shift(CWL, N_EFF, f, 0.0, lens, method="ideal"))
    assert got == pytest.approx(want, abs=1e-9)  # the closed form loses digits at small NA
    # the pupil's radius obeys the sine condition
    lens = Lens(50.0, pupil_radiance="lambertian")
    assert np.sin(np.arctan(lens.exit_pupil_radius_mm(f) / 50.0)) == pytest.approx(na)


@pytest.mark.parametrize("circles", CIRCLES[:2], ids=["none", "one"])
def test_kernel_bins_have_the_weighted_mean_and_spread(circles):
    lens = Lens(21.0, circles, 0.06, 1.3, pupil_radiance="lambertian")
    for f, cra in ((1.4, 0.0), (1.4, 12.0), (2.8, 15.0)):
        mu, w = kernel_bins(CWL, N_EFF, f, cra, lens, step_nm=0.05)
        want_mean, want_var = _brute(circles, f, cra)
        assert w @ mu == pytest.approx(want_mean, abs=1e-9)
        # the bins leave out width^2 / 12 of the spread, 2e-4 nm^2 at 0.05 nm
        assert np.sum(w * (mu - w @ mu) ** 2) == pytest.approx(want_var, abs=5e-4)


def test_the_fast_methods_follow_the_pupil_or_refuse():
    lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, pupil_radiance="lambertian")
    cra = np.linspace(0.0, 20.0, 30_000)  # enough for "auto" to build a table
    exact = mean_shift(CWL, N_EFF, 1.4, cra, lens, method="vignetted")
    for method in ("auto", "table"):
        got = mean_shift(CWL, N_EFF, 1.4, cra, lens, method=method, tolerance_nm=0.001)
        assert np.max(np.abs(got - exact)) < 0.001, method
    for method in ("asymptotic", "riemann"):  # derived for the paper's pupil
        with pytest.raises(ValueError, match="paper's pupil"):
            mean_shift(CWL, N_EFF, 1.4, 1.0, lens, method=method)
    assert "asymptotic" not in set(select_method(N_EFF, 8.0, np.linspace(0, 1, 5), lens))
    with pytest.raises(ValueError, match="paper's pupil only"):
        ShiftGrid.build(N_EFF, lens, f_range=(1.4, 2.8), cra_max_deg=10.0)
    with pytest.raises(ValueError, match="pupil must be"):
        goossens2019.mean_shift_contour(CWL, N_EFF, 21.0, 7.0, 0.0, pupil="sine")


def test_profiles_keep_the_pupil_and_old_ones_stay_the_papers(tmp_path):
    lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, pupil_radiance="lambertian", name="fast")
    lens.save(tmp_path / "l.toml")
    assert 'pupil = "lambertian"' in (tmp_path / "l.toml").read_text()
    assert Lens.load(tmp_path / "l.toml") == lens
    Lens(21.0).save(tmp_path / "p.toml")
    assert "pupil =" not in (tmp_path / "p.toml").read_text()
    assert Lens.load(tmp_path / "p.toml").pupil_radiance == "paper"
    with pytest.raises(ValueError, match="pupil_radiance must be one of"):
        Lens(21.0, pupil_radiance="gaussian")


def test_the_correction_uses_the_profiles_pupil():
    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor, make_cube

    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 5), 10.0, N_EFF)
    cube = make_cube(np.ones((30, 40, 5), np.float32), sensor.cwl_nm)
    for pupil in ("paper", "lambertian"):
        lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, pupil_radiance=pupil)
        ds = correct_cube(cube, sensor, 1.4, lens, tolerance_nm=0.001)
        cra = ds["cra_deg"].values
        want = sensor.cwl_nm + mean_shift(np.asarray(sensor.cwl_nm), N_EFF, 1.4,
                                          cra[..., None], lens, method="vignetted")
        np.testing.assert_allclose(ds["wavelength_corrected"].values, want, atol=2e-3)
        assert ds.attrs["method"] != "asymptotic"


@pytest.mark.slow
@pytest.mark.parametrize("truth", ["paper", "sine"])
def test_auto_chooses_the_pupil_the_target_shows(truth):
    """Cubes of an independent simulator, a fast and a slow f-number, n_eff fitted: "auto"
    takes the right pupil, and x and n_eff come right with errors that cover."""
    from snapcorr.calibrate import locate_pupil
    from snapcorr.cube import Sensor, make_cube

    shape, pitch = (128, 160), 44.0
    center = (shape[0] * 0.481, shape[1] * 0.514)
    cwl = np.arange(500.0, 849.0, 12.0)
    lens_truth = LensTruth(16.0, (), 0.0, 1.0, meta={"pupil": truth})
    sensor = Sensor("test", "snapscan", pitch, cwl, 12.0, 1.7)
    for seed in (0, 1):
        rng = np.random.default_rng(seed)
        cubes = {f: make_cube(sim.target_cube(
            sim.rare_earth_glass, cwl_nm=cwl, fwhm_nm=12.0, n_eff=1.7, f_number=f,
            lens=lens_truth, shape=shape, pixel_pitch_um=pitch, center_px=center[::-1])
            + rng.normal(0.0, 0.0005, (*shape, cwl.size)), cwl) for f in (2.0, 8.0)}
        got = locate_pupil(cubes, sensor, lens=Lens(30.0), fit_n_eff=True, center_rc=center,
                           pupil_radiance="auto")
        assert got.lens.pupil_radiance == ("lambertian" if truth == "sine" else "paper")
        assert abs(got.exit_pupil_mm / 16.0 - 1) < 0.005
        assert abs(got.exit_pupil_mm - 16.0) < 3 * got.exit_pupil_stderr_mm
        assert abs(got.n_eff[0] - 1.7) < 3 * got.n_eff_stderr[0]


@pytest.mark.parametrize(("f", "cra_max"), [(1.4, 0.5), (1.4, 3.0), (1.0, 3.0)])
def test_measured_responses_reach_over_the_lambertian_cone(f, cra_max):
    """The measured-response table's window covers the Lambertian cone (arcsin NA, wider
    than the paper's arctan), and its centres move by the Lambertian kernel's mean."""
    from snapcorr.cube.responses import FilterResponses, Peak
    from snapcorr.optics.measured import MeasuredTable

    grid = np.arange(400.0, 1000.01, 0.1)
    cwl, fwhm = np.array([500.0, 800.0]), np.array([8.0, 12.0])
    curves = np.exp(-4 * np.log(2) * ((grid[None] - cwl[:, None]) / fwhm[:, None]) ** 2)
    r = FilterResponses(grid, curves, np.ones(grid.size),
                        [[Peak(c, w, 1.0)] for c, w in zip(cwl, fwhm, strict=True)])
    lens = Lens(21.0, pupil_radiance="lambertian")
    table = MeasuredTable.build(r, 1.7, f, lens, cra_max_deg=cra_max)  # raised before
    assert np.all(np.isfinite(table.centre_nm))


def test_the_pupil_chooser_keeps_the_paper_unless_the_gain_is_clear():
    from types import SimpleNamespace

    from snapcorr.calibrate.pupil.locate import PUPIL_CHI2_GAIN, choose_pupil

    def results():
        return {k: SimpleNamespace(notes=[], lens=Lens(21.0, pupil_radiance=k))
                for k in ("paper", "lambertian")}

    near = choose_pupil(results(), {"paper": 100.0, "lambertian": 100.0 - PUPIL_CHI2_GAIN},
                        "chi-square")
    assert near.lens.pupil_radiance == "paper"
    assert near.lens.calibration["pupil_choice"]["chosen"] == "paper"
    clear = choose_pupil(results(), {"paper": 100.0, "lambertian": 89.0}, "chi-square")
    assert clear.lens.pupil_radiance == "lambertian" and "pupil: lambertian" in clear.notes[0]
    only = choose_pupil({"lambertian": results()["lambertian"]}, {"lambertian": 5.0}, "x")
    assert only.lens.pupil_radiance == "lambertian"
