"""Whole-filter response: kernel convolution (Goossens Eq. 13) and Rienstra's transform."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from snapcorr import Lens, mean_shift
from snapcorr.optics import kernel, kernel_asymptotic
from snapcorr.optics.mean import _geometry
from snapcorr.optics.profiles import MultiLorentzian
from snapcorr.optics.response import filter_response, kernel_bins

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
