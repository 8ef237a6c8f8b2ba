"""The per-pixel spectrum helpers against numpy and scipy: samples sorted and merged as
``np.unique`` would, the straight line as ``np.interp`` draws it, and the line averaged with a
Gaussian as a quadrature on a fine grid computes it; the faster value from the line's kinks
against the segment-by-segment one."""


import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import norm

from snapcorr.correct._spectra import (
    cdf,
    line_slopes,
    line_value,
    pdf,
    smoothed_line_value,
    sort_samples,
    spectrum_value,
)


def test_the_normal_density_and_distribution_are_scipys():
    z = np.linspace(-8.0, 8.0, 161)
    np.testing.assert_allclose([pdf(v) for v in z], norm.pdf(z), rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose([cdf(v) for v in z], norm.cdf(z), rtol=1e-13, atol=1e-16)


def test_samples_are_sorted_and_those_at_one_wavelength_merged_into_their_mean():
    rng = np.random.default_rng(1)
    lam = rng.choice([500.0, 510.0, 520.0, 530.0, 545.0, 560.0], 15)
    d = rng.random(15)
    want_lam, inverse = np.unique(lam, return_inverse=True)
    want_d = np.bincount(inverse, d) / np.bincount(inverse)
    got_lam, got_d = lam.copy(), d.copy()
    k = sort_samples(got_lam, got_d, lam.size)
    assert k == want_lam.size
    np.testing.assert_array_equal(got_lam[:k], want_lam)
    np.testing.assert_allclose(got_d[:k], want_d, rtol=1e-15)


def test_the_line_is_numpys_interp_walked_in_increasing_order():
    rng = np.random.default_rng(2)
    lam = np.sort(rng.uniform(400.0, 900.0, 12))
    d = rng.normal(size=12)
    t = np.sort(rng.uniform(lam[0], lam[-1], 50))
    j = 0
    got = []
    for v in t:
        value, j = line_value(lam, d, v, j)
        got.append(value)
    np.testing.assert_allclose(got, np.interp(t, lam, d), rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("sigma", [0.0, 0.4, 3.0, 25.0])
def test_the_gaussian_average_of_the_line_is_the_quadratures(sigma):
    """``integral line(l) N(l; t, sigma) dl`` with the line held constant beyond its ends,
    by adaptive quadrature (scipy's ``quad``, split at the line's kinks) over twelve standard
    deviations each side; the pass leaves out the mass beyond six (2e-9)."""
    rng = np.random.default_rng(3)
    lam = np.sort(rng.uniform(500.0, 560.0, 9))
    d = rng.normal(size=9) + 2.0
    j = 0
    for t in np.sort(rng.uniform(lam[0], lam[-1], 6)):
        got, j = spectrum_value(lam, d, t, sigma, j)
        if sigma == 0.0:
            want = np.interp(t, lam, d)
        else:
            lo, hi = t - 12 * sigma, t + 12 * sigma
            kinks = lam[(lam > lo) & (lam < hi)]
            want = quad(lambda v, t=t: np.interp(v, lam, d) * norm.pdf(v, t, sigma), lo, hi,
                        points=kinks, limit=200, epsabs=1e-13, epsrel=1e-13)[0]
        assert got == pytest.approx(want, rel=1e-8, abs=1e-12)


def test_the_kinks_give_the_segments_value():
    """:func:`smoothed_line_value` (the direct values of the tabulated pass, finite spectra)
    against :func:`spectrum_value` on random samples, widths from none to many segments:
    1e-9 of the spectrum's range (the Gaussian's mass beyond six standard deviations, which
    the two leave out differently)."""
    rng = np.random.default_rng(9)
    for _ in range(400):
        n = int(rng.integers(2, 14))
        lam = np.unique(rng.uniform(400.0, 460.0, n))
        if lam.size < 2:
            continue
        d = rng.normal(0.0, 3.0, lam.size) + rng.choice([0.0, 50.0])
        sigma = float(rng.choice([0.0, 0.01, 0.3, 2.0, 8.0, 40.0]) * rng.random())
        slope = np.empty(lam.size)
        line_slopes(lam, d, slope)
        j_new = j_old = 0
        for t in np.sort(rng.uniform(lam[0], lam[-1], 5)):
            a, j_new = smoothed_line_value(lam, d, slope, t, sigma, j_new)
            b, j_old = spectrum_value(lam, d, t, sigma, j_old)
            assert abs(a - b) <= 2e-9 * np.abs(d).max() + 1e-12
