"""The independent flat-field simulator (tests/oracles/flatsim.py) checked against brute force."""

import numpy as np
import pytest
from conftest import PAPER_TRUTH
from flatsim import (
    LensTruth,
    common_area_mm2,
    make_flats,
    mean_shift_nm,
    relative_illumination,
)

PAPER = PAPER_TRUTH


def grid_area(radii, centers, n=2001):
    """Midpoint count of a fine grid over the first disc's bounding square."""
    R, c0 = radii[0], centers[0]
    step = 2 * R / n
    g = (np.arange(n) + 0.5) * step - R
    X, Y = np.meshgrid(g + c0, g, indexing="ij")
    inside = np.ones(X.shape, bool)
    for r, c in zip(radii, centers, strict=True):
        inside &= (X - c) ** 2 + Y**2 <= r * r
    return inside.sum() * step * step, step


def lens_area(R, P, dv):
    """Closed-form area of two discs (Goossens 2019, Eq. 33-35)."""
    if dv <= abs(P - R):
        return np.pi * min(P, R) ** 2
    if dv >= P + R:
        return 0.0
    a = np.arccos((P * P - R * R + dv * dv) / (2 * P * dv))
    b = np.arccos((R * R - P * P + dv * dv) / (2 * R * dv))
    return P * P * (a - np.sin(a) * np.cos(a)) + R * R * (b - np.sin(b) * np.cos(b))


@pytest.mark.parametrize("R, P, dv", [(5.0, 7.4, 3.1), (3.0, 7.4, 6.0), (5.0, 4.0, 0.5),
                                      (5.0, 4.0, 8.5), (2.0, 9.0, 10.9), (4.0, 4.0, 0.0),
                                      (4.0, 5.0, -2.5), (4.0, 5.0, 9.5)])
def test_two_disc_area_matches_closed_form(R, P, dv):
    got = common_area_mm2([R, P], [0.0, dv])
    assert got == pytest.approx(lens_area(R, P, abs(dv)), rel=1e-10, abs=1e-12)


def test_two_disc_area_vectorised_over_the_field():
    dv = np.linspace(0, 14, 301)
    got = common_area_mm2([5.0, 7.4], [np.zeros_like(dv), dv])
    want = [lens_area(5.0, 7.4, v) for v in dv]
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("radii, centers", [
    ([5.0, 7.4], [0.0, 3.5]),
    ([5.0, 7.4, 6.0], [0.0, 3.5, -1.5]),  # front and rear circle both cutting
    ([3.0, 7.4, 3.2], [0.0, 2.0, 2.9]),  # circle plus pixel vignetting (h = x)
    ([5.0, 6.0, 6.5, 5.5], [0.0, 2.0, -2.5, 0.8]),  # pupil and three circles
])
def test_area_matches_grid_count(radii, centers):
    got = common_area_mm2(radii, centers)
    want, step = grid_area(radii, centers)
    # the count's error is about the boundary length times half a cell
    assert got == pytest.approx(want, abs=2 * np.pi * radii[0] * step * 0.05 + 1e-9)


def test_area_is_zero_when_discs_miss_and_full_when_nested():
    assert common_area_mm2([1.0, 1.0], [0.0, 2.5]) == 0.0
    assert common_area_mm2([1.0, 2.0, 5.0], [0.0, 3.5, 0.0]) == 0.0
    assert common_area_mm2([1.0, 3.0, 4.0], [0.0, 0.5, -1.0]) == pytest.approx(np.pi)


def test_relative_illumination_of_the_papers_lens():
    # at f/1.4 the onset is at arctan((P - R) / h) = arctan(0.254 / 16.991) = 0.86 deg
    t = np.tan(np.deg2rad([0.0, 0.8, 0.95, 10.0, 45.0]))
    ri = relative_illumination(PAPER, 1.4, t)
    assert ri[0] == pytest.approx(1.0) and ri[1] == pytest.approx(1.0)
    assert ri[2] < 1.0
    assert ri[3] == pytest.approx(0.766, abs=5e-4)  # the value printed in snapcorr's Lens doc
    assert ri[4] == 0.0


def test_mean_shift_matches_brute_force_grid():
    truth = LensTruth(21.0, ((7.4236, 16.991), (6.0, 30.0)), 0.06, 1.3)
    x, cwl, n = 21.0, 1000.0, 1.5
    for f, cra in [(2.0, 0.0), (2.0, 9.0), (2.8, 14.0), (4.0, 3.0)]:
        R = float(truth.pupil_radius_mm(f))
        t = np.tan(np.deg2rad(cra))
        N = 1500
        step = 2 * R / N
        g = (np.arange(N) + 0.5) * step - R
        X, Y = np.meshgrid(g, g, indexing="ij")
        inside = X**2 + Y**2 <= R * R
        for P, h in truth.circles:
            inside &= (X - h * t) ** 2 + Y**2 <= P * P
        r2 = (X[inside] - x * t) ** 2 + Y[inside] ** 2
        sin2 = r2 / (r2 + x * x)
        brute = float(np.mean(-cwl * (1 - np.sqrt(1 - sin2 / n**2))))
        got = mean_shift_nm(truth, cwl, n, f, cra)
        assert got == pytest.approx(brute, abs=2e-3), (f, cra)


def test_mean_shift_converged_in_its_nodes():
    truth = LensTruth(21.0, ((7.0, 12.0), (9.5, 30.0)), 0.0, 1.0)
    cra = np.linspace(0, 16, 9)
    a = mean_shift_nm(truth, 1000.0, 1.5, 2.0, cra)
    b = mean_shift_nm(truth, 1000.0, 1.5, 2.0, cra, nodes=64)
    np.testing.assert_allclose(a, b, atol=1e-7)


def test_noise_level_and_brightness():
    truth = LensTruth(21.0, ((9.5, 26.0),), 0.0, 1.0)
    fs = (2.0, 4.0)
    flats, clean, exp = make_flats(truth, fs, shape=(128, 160), pitch_um=30.0,
                                   center_px=(90.0, 60.0), noise=0.02, seed=3,
                                   integer=False, return_truth_maps=True)
    for f in fs:
        ok = clean[f] > 0.2 * clean[f].max()
        rel = (flats[f] - clean[f])[ok] / clean[f][ok]
        assert rel.std() == pytest.approx(0.02, rel=0.05)
        assert abs(rel.mean()) < 0.002
    # on axis the f/2 flat is (4/2)^2 times brighter, up to the exposure scales
    ratio = clean[2.0][60, 90] / clean[4.0][60, 90]
    assert ratio == pytest.approx(4.0 * exp[2.0] / exp[4.0], rel=1e-6)
    assert all(0.8 <= e <= 1.2 for e in exp.values())


def test_deterministic_by_seed_and_integer_output():
    truth = PAPER_TRUTH
    kw = dict(shape=(64, 80), pitch_um=60.0, center_px=(45.0, 30.0), noise=0.01,
              source_amplitude=0.05, dark_dn=100.0, poisson_gain=1.0)
    a = make_flats(truth, seed=7, **kw)
    b = make_flats(truth, seed=7, **kw)
    c = make_flats(truth, seed=8, **kw)
    assert set(a) == {2.0, 2.8, 4.0, 5.6, 11.0}
    for f in a:
        np.testing.assert_array_equal(a[f], b[f])
        assert not np.array_equal(a[f], c[f])
        assert np.array_equal(a[f], np.rint(a[f]))
        assert a[f].min() >= 0 and a[f].max() <= 65535


def test_saturation_and_default_scene_shape():
    truth = LensTruth(21.0, (), 0.0, 1.0)
    flats = make_flats(truth, (2.0,), shape=(32, 40), pitch_um=100.0, center_px=(20, 16),
                       noise=0.0, level_dn=70000.0, exposure_spread=0.0)
    assert flats[2.0].max() == 65535.0
    assert flats[2.0].shape == (32, 40)
