"""Whole-filter response: kernel convolution (Goossens Eq. 13) and Rienstra's transform."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from snapcorr import Lens, mean_shift
from snapcorr.optics import kernel, kernel_asymptotic
from snapcorr.optics.aperture import eta
from snapcorr.optics.mean import _geometry
from snapcorr.optics.profiles import MultiLorentzian, Tabulated
from snapcorr.optics.response import filter_response, kernel_bins
from snapcorr.optics.rienstra1998 import arc_half_angle, ray_bundle_weights, shift_factors

P_GRID = np.arange(600.0, 760.0, 0.02)
CASES = [(1.4, 0.0), (1.4, 12.0), (1.4, 20.0), (2.8, 15.0), (4.0, 10.0), (8.0, 22.0)]


def centroid(w, t):
    return np.trapezoid(w * t, w) / np.trapezoid(t, w)


@pytest.mark.parametrize(("f", "cra"), CASES)
def test_kernel_integrates_to_one_and_its_mean_is_mean_shift(edmund, f, cra):
    x, R, d, P, dv = _geometry(f, cra, edmund)
    lam = np.linspace(-60, 0, 600001)
    K = kernel(lam, 700.0, 1.7, x, R, d, P, dv)
    assert_allclose(np.trapezoid(K, lam), 1.0, atol=2e-3)  # sqrt kinks limit the sum
    mu, w = kernel_bins(700.0, 1.7, f, cra, edmund)
    # The bins are placed so their mean is the exact kernel mean; their spread must match the
    # kernel's own second moment (independent of that placement) to the bin width.
    exact = mean_shift(700.0, 1.7, f, cra, edmund, method="vignetted")
    assert_allclose(mu @ w, exact, atol=1e-9)
    m1 = np.trapezoid(lam * K, lam) / np.trapezoid(K, lam)
    var_k = np.trapezoid(lam**2 * K, lam) / np.trapezoid(K, lam) - m1**2
    assert_allclose(w @ (mu - exact) ** 2, var_k, rtol=0.02, atol=1e-3)


@pytest.mark.parametrize(("f", "cra"), CASES)
def test_convolution_centroid_is_kernel_mean(edmund, f, cra):
    T = MultiLorentzian(700.0, 10.0)(P_GRID)
    out = filter_response(P_GRID, T, cwl_nm=700.0, n_eff=1.7, f_number=f, cra_deg=cra, lens=edmund)
    # Convolution adds means: centroid(K * T) = centroid(T) + mean(K).
    assert_allclose(
        centroid(P_GRID, out) - centroid(P_GRID, T),
        mean_shift(700.0, 1.7, f, cra, edmund, method="vignetted"),
        atol=2e-5,
    )
    assert_allclose(np.trapezoid(out, P_GRID), np.trapezoid(T, P_GRID), rtol=1e-6)


@pytest.mark.parametrize(("f", "cra"), CASES)
def test_rienstra_and_kernel_give_the_same_centroid(edmund, f, cra):
    T = MultiLorentzian(700.0, 10.0)(P_GRID)
    kw = dict(cwl_nm=700.0, n_eff=1.7, f_number=f, cra_deg=cra, lens=edmund)
    ck = centroid(P_GRID, filter_response(P_GRID, T, **kw))
    cr = centroid(P_GRID, filter_response(P_GRID, T, method="rienstra", step_deg=0.1, **kw))
    # They differ at second order: Rienstra scales each ring's curve by S_j (stretching it by
    # S_j too), Goossens shifts it by Delta_j; the centroids differ by ~cwl Var(S) plus the
    # ring discretisation, <= 0.05 nm here (shifts up to 13 nm at 700 nm).
    assert abs(ck - cr) <= 0.05


def test_rienstra_arc_angle_is_goossens_eta():
    # Two papers, two derivations of the same arc: Rienstra A-6..A-8 and Goossens Eq. 15.
    rng = np.random.default_rng(7)
    R_j, A, D = rng.uniform(0, 1, 5000), rng.uniform(0.02, 0.5, 5000), rng.uniform(0, 0.6, 5000)
    assert_allclose(arc_half_angle(R_j, A, D), eta(R_j, A, D), atol=1e-9)


@pytest.mark.parametrize("step", [0.25, 0.5])
@pytest.mark.parametrize(("f", "cra"), [(3.0, 5.0), (3.0, 10.0), (2.0, 15.0), (1.4, 20.0)])
def test_rienstra_weights_sum_to_one(step, f, cra):
    # Rienstra: steps of 1/4 to 1/2 degree give weights summing "very close to unity".
    _, W = ray_bundle_weights(f, cra, step_deg=step)
    assert abs(W.sum() - 1) < 0.01


def test_rienstra_weights_on_axis_are_quantised():
    # On axis every ring is a full circle or nothing, so the pupil edge is resolved to one
    # ring: the sum misses up to ~2 Delta R / A. Finer steps fix it.
    s = [ray_bundle_weights(3.0, 0.0, step_deg=st)[1].sum() for st in (0.5, 0.25, 0.05)]
    assert 0.94 < s[0] < s[1] < s[2] and abs(s[2] - 1) < 0.005


def test_rienstra_temperature_factor_scales_wavelengths():
    # Nearly collimated, on axis: only the temperature factor (0.992, Rienstra's MWIR filter)
    # acts; the curve's centroid scales by it.
    prof = Tabulated(P_GRID * 5, MultiLorentzian(3500.0, 60.0)(P_GRID * 5), n_eff=2.037)
    w, t = prof.wavelength_nm, prof.transmission
    lens = Lens(100.0, name="cold shield")
    out = filter_response(
        w,
        t,
        cwl_nm=3500.0,
        n_eff=2.037,
        f_number=500.0,
        cra_deg=0.0,
        lens=lens,
        method="rienstra",
        temperature_factor=0.992,
        step_deg=0.001,
    )
    assert_allclose(centroid(w, out), 0.992 * centroid(w, t), rtol=2e-5)
    assert_allclose(shift_factors([0.0, 30.0], 1.775)[1], np.cos(np.arcsin(0.5 / 1.775)))


def test_asymptotic_kernel_close_for_small_shifts(edmund):
    x, R, d, P, dv = _geometry(8.0, 2.0, edmund)
    lam = np.linspace(-0.6, -0.01, 200)
    assert_allclose(
        kernel_asymptotic(lam, 700, 1.7, x, R, d, P, dv),
        kernel(lam, 700, 1.7, x, R, d, P, dv),
        rtol=0.02,
    )


def test_no_light_and_dirac_kernels(edmund):
    T = MultiLorentzian(700.0, 10.0)(P_GRID)
    kw = dict(cwl_nm=700.0, n_eff=1.7, f_number=8.0, lens=edmund)
    cut = float(edmund.cutoff_cra_deg(8.0))
    for method in ("kernel", "rienstra"):
        with pytest.raises(ValueError, match="cut"):
            filter_response(P_GRID, T, cra_deg=cut + 1, method=method, **kw)
    # A nearly collimated beam: the response is the curve shifted by Eq. 3, not zeros.
    lens = Lens(21.0, name="ideal")
    out = filter_response(P_GRID, T, cwl_nm=700.0, n_eff=1.7, f_number=1e6, cra_deg=10.0,
                          lens=lens)
    assert_allclose(centroid(P_GRID, out) - centroid(P_GRID, T),
                    mean_shift(700.0, 1.7, 1e6, 10.0, lens, method="vignetted"), atol=1e-4)
    for step in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match="step"):
            filter_response(P_GRID, T, cra_deg=5.0, step_nm=step, **kw)
    with pytest.raises(ValueError, match="cra_deg"):
        filter_response(P_GRID, T, cra_deg=np.nan, method="rienstra", **kw)


def test_bad_curves_and_methods(edmund):
    kw = dict(cwl_nm=700.0, n_eff=1.7, f_number=2.0, cra_deg=5.0, lens=edmund)
    with pytest.raises(ValueError, match="increasing"):
        filter_response(P_GRID[::-1], P_GRID, **kw)
    with pytest.raises(ValueError, match="choose one of"):
        filter_response(P_GRID, P_GRID, method="fft", **kw)
    with pytest.raises(ValueError, match="rienstra"):
        filter_response(P_GRID, P_GRID, temperature_factor=0.99, **kw)
