"""The target model's annuli and its numerical pieces, each against a direct computation.

The annulus means are checked against every pixel's distance from the centre worked out one
pixel at a time, and the standard error against ``numpy.polyfit``'s straight line in ``d^2``
inside each annulus; the merged annuli against the annuli binned coarsely from the start; the
derivative matrices against the exact derivatives of a parabola.
"""

import warnings

import numpy as np
import pytest

from snapcorr.calibrate.pupil.target_model import (
    _derivatives,
    _lerp,
    radial_bins,
    rebin,
    scaled_circles,
)

SHAPE = (40, 52)
PITCH_MM = 0.044
CENTER_RC = (17.3, 29.6)  # (row, column)


def _images(seed=0, n_bands=3, nan_fraction=0.1):
    """Random band images, a tenth of their pixels masked."""
    rng = np.random.default_rng(seed)
    imgs = rng.normal(1.0, 0.2, (n_bands, *SHAPE))
    imgs[rng.random(imgs.shape) < nan_fraction] = np.nan
    return imgs


def _positions():
    return np.arange(SHAPE[0], dtype=float)[:, None], np.arange(SHAPE[1], dtype=float)[:, None]


def _bins(imgs, n_bins, min_count=1):
    rows, cols = _positions()
    return radial_bins(lambda b: imgs[b], imgs.shape[0], rows, cols, None, PITCH_MM,
                       center_rc=CENTER_RC, f_number=2.0, n_bins=n_bins, min_count=min_count)


def _by_pixel(imgs, n_bins):
    """Each band's pixels by annulus, every pixel's d^2 worked out on its own."""
    cy, cx = CENTER_RC
    d2 = np.empty(SHAPE)
    for r in range(SHAPE[0]):
        for c in range(SHAPE[1]):
            d2[r, c] = ((r - cy) * PITCH_MM) ** 2 + ((c - cx) * PITCH_MM) ** 2
    width = (d2.max() - d2.min()) / n_bins
    which = np.minimum(((d2 - d2.min()) / width).astype(int), n_bins - 1)
    out = []
    for img in imgs:
        ok = np.isfinite(img)
        out.append([(d2[ok & (which == i)], img[ok & (which == i)]) for i in range(n_bins)])
    return out


def test_annulus_means_and_counts_are_those_of_each_pixels_own_distance():
    imgs = _images()
    got = _bins(imgs, 12)
    for b, annuli in enumerate(_by_pixel(imgs, 12)):
        for i, (d2, v) in enumerate(annuli):
            assert got.count[b, i] == v.size
            assert got.mean[b, i] == pytest.approx(v.mean(), rel=1e-12)
            assert got.rho_band[b, i] == pytest.approx(d2.mean(), rel=1e-12)
            assert got.var_rho[b, i] == pytest.approx(d2.var(), rel=1e-6, abs=1e-15)


def test_the_centre_is_row_first_and_its_x_first_form_warns_with_the_same_annuli():
    """center_rc=(row, col), off both middles of a frame wider than tall: the annuli hold each
    pixel's own distance from that row and column; center_px=(cx, cy) in its old place, the
    x-first form of 0.1, gives the same annuli and warns."""
    shape, row, col = (48, 100), 37.25, 81.5
    imgs = np.random.default_rng(6).normal(1.0, 0.2, (2, *shape))
    rows = np.arange(shape[0], dtype=float)[:, None]
    cols = np.arange(shape[1], dtype=float)[:, None]
    kw = dict(f_number=2.0, n_bins=8, min_count=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        new = radial_bins(lambda b: imgs[b], 2, rows, cols, None, PITCH_MM,
                          center_rc=(row, col), **kw)
    r, c = np.mgrid[:shape[0], :shape[1]]
    d2 = ((r - row) * PITCH_MM) ** 2 + ((c - col) * PITCH_MM) ** 2
    for b in range(2):  # every pixel counted once, at its own distance
        assert new.count[b].sum() == d2.size
        assert np.sum(new.rho_band[b] * new.count[b]) / d2.size == pytest.approx(d2.mean(),
                                                                                 rel=1e-12)
    first = d2 < d2.min() + (d2.max() - d2.min()) / 8  # the annulus about the centre itself
    assert new.count[0, 0] == first.sum()
    assert new.rho_band[0, 0] == pytest.approx(d2[first].mean(), rel=1e-12)
    with pytest.warns(FutureWarning, match=r"center_px is the old x-first form .* "
                                           r"center_rc=\(37\.25, 81\.5\)"):
        old = radial_bins(lambda b: imgs[b], 2, rows, cols, (col, row), PITCH_MM, **kw)
    for name in ("rho", "rho_band", "var_rho", "mean", "stderr", "count"):
        np.testing.assert_array_equal(getattr(old, name), getattr(new, name), err_msg=name)
    with pytest.raises(TypeError, match="give the optical centre once"):
        radial_bins(lambda b: imgs[b], 2, rows, cols, (col, row), PITCH_MM,
                    center_rc=(row, col), **kw)


def test_the_standard_error_is_the_scatter_about_a_straight_line_in_d2():
    imgs = _images(seed=1, n_bands=1)
    got = _bins(imgs, 6)
    for i, (d2, v) in enumerate(_by_pixel(imgs, 6)[0]):
        _, ssr, *_ = np.polyfit(d2, v, 1, full=True)
        assert got.stderr[0, i] == pytest.approx(np.sqrt(ssr[0] / (v.size - 2) / v.size),
                                                 rel=1e-6)


def test_annuli_with_too_few_pixels_are_empty():
    imgs = _images(seed=2, n_bands=1)
    counts = _bins(imgs, 40).count[0]
    least = int(np.median(counts))
    got = _bins(imgs, 40, min_count=least)
    few = counts < least
    assert few.any() and not few.all()
    assert np.all(np.isnan(got.mean[0, few])) and np.all(np.isfinite(got.mean[0, ~few]))


def test_merged_annuli_are_the_annuli_binned_coarsely():
    """Equal-width annuli in d^2: merging neighbours in pairs gives the binning at half as
    many (counts, means and the spread of d^2 alike)."""
    imgs = _images(seed=3)
    merged, coarse = rebin(_bins(imgs, 24), 2), _bins(imgs, 12)
    np.testing.assert_array_equal(merged.count, coarse.count)
    for name in ("mean", "rho_band", "var_rho"):
        np.testing.assert_allclose(getattr(merged, name), getattr(coarse, name), rtol=1e-9,
                                   atol=1e-15, err_msg=name)
    np.testing.assert_allclose(merged.rho, coarse.rho, rtol=1e-12)


def test_the_derivative_matrices_are_exact_for_a_parabola_on_an_uneven_grid():
    x = np.sort(np.random.default_rng(4).uniform(0.0, 5.0, 11))
    f = 0.7 - 1.3 * x + 0.45 * x**2
    D1, D2 = _derivatives(x)
    np.testing.assert_allclose(D1 @ f, -1.3 + 0.9 * x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(D2 @ f, np.full(x.size, 0.9), rtol=1e-9)


def test_linear_interpolation_in_the_table_and_zero_beyond_it():
    table = np.random.default_rng(5).normal(size=9)
    inside = np.linspace(0.0, 8.0, 37)
    np.testing.assert_allclose(_lerp(table, inside), np.interp(inside, np.arange(9), table),
                               rtol=1e-12)
    np.testing.assert_array_equal(_lerp(table, np.array([-1.5, 9.5, 20.0])), 0.0)


def test_circles_scale_as_the_flats_fix_them_and_back():
    """P / x and h / x^2 stay as the flats fixed them, and scaling back returns the circles."""
    circles = [(7.4236, 16.991), (9.1, 25.3)]
    there = scaled_circles(circles, 21.0, 24.5)
    for (P, h), (P2, h2) in zip(circles, there, strict=True):
        assert P2 / 24.5 == pytest.approx(P / 21.0, rel=1e-12)
        assert h2 / 24.5**2 == pytest.approx(h / 21.0**2, rel=1e-12)
    np.testing.assert_allclose(scaled_circles(there, 24.5, 21.0), circles, rtol=1e-11)
