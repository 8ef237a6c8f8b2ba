"""The cos^4-weighted overlap of discs against a quadrature over the pupil plane."""

import numpy as np
import pytest

from snapcorr.optics.aperture import (
    overlap_area_mm2,
    overlap_irradiance_mm2,
    relative_irradiance,
)


def brute_irradiance(radii, centers, foot, x, n=1601):
    """Midpoint rule on a square grid over the first disc: every point's cos^4 summed."""
    R = radii[0]
    g = (np.arange(n) + 0.5) / n * 2 * R - R + centers[0]
    u, v = np.meshgrid(g, g - centers[0], indexing="ij")
    inside = np.ones(u.shape, bool)
    for r, c in zip(radii, centers, strict=True):
        inside &= (u - c) ** 2 + v**2 < r * r
    cos2 = x * x / (x * x + (u - foot) ** 2 + v**2)
    return float(np.sum(cos2**2 * inside)) * (2 * R / n) ** 2


CASES = [
    # (radii, centres, foot, x): f/1.4 on axis; a pixel at tan(CRA) 0.4 through one circle;
    # three circles; the foot outside the pupil (CRA steeper than the cone)
    ([7.5], [0.0], 0.0, 21.0),
    ([7.5, 10.0], [0.0, 17.0 * 0.4], 21.0 * 0.4, 21.0),
    ([5.25, 8.0, 9.0, 12.0], [0.0, 3.0, -2.0, -6.0], 7.0, 21.0),
    ([2.0, 6.0], [0.0, 5.0], 12.0, 21.0),
]


@pytest.mark.parametrize("radii, centers, foot, x", CASES)
def test_matches_a_quadrature_over_the_plane(radii, centers, foot, x):
    exact = float(overlap_irradiance_mm2(radii, centers, foot, x))
    brute = brute_irradiance(radii, centers, foot, x)
    # the midpoint rule's error is its boundary's: ~ perimeter * step^2 / ... , about 1e-4 here
    assert exact == pytest.approx(brute, rel=3e-4)
    area = float(overlap_area_mm2(radii, centers))
    assert exact < area  # every weight is below 1 off the foot
    # the naive model, the area times cos^4 of the chief ray, is far from both
    naive = area * (1.0 + (foot / x) ** 2) ** -2
    assert abs(naive - brute) > 10 * 3e-4 * brute


def test_the_closed_form_on_axis():
    """A disc of radius R about the foot: pi x^2 R^2 / (x^2 + R^2) exactly."""
    for R in (0.1, 3.0, 7.5, 21.0, 40.0):
        x = 21.0
        got = float(overlap_irradiance_mm2([R], [0.0], 0.0, x))
        assert got == pytest.approx(np.pi * x * x * R * R / (x * x + R * R), rel=1e-12)


def test_empty_and_broadcast():
    assert float(overlap_irradiance_mm2([1.0, 1.0], [0.0, 5.0], 0.0, 10.0)) == 0.0
    t = np.linspace(0.0, 0.5, 7)
    got = overlap_irradiance_mm2([np.full(7, 7.5), 10.0], [0.0, 17.0 * t], 21.0 * t, 21.0)
    one = [float(overlap_irradiance_mm2([7.5, 10.0], [0.0, 17.0 * v], 21.0 * v, 21.0))
           for v in t]
    np.testing.assert_allclose(got, one, rtol=1e-14)
    assert np.all(np.diff(got) < 0)  # more cut and steeper rays away from the axis


def test_tends_to_the_area_far_away():
    radii, centers = [7.5, 10.0], [0.0, 3.0]
    got = float(overlap_irradiance_mm2(radii, centers, 1.0, 1e6))
    assert got == pytest.approx(float(overlap_area_mm2(radii, centers)), rel=1e-9)


@pytest.mark.parametrize("bad", [dict(x_mm=0.0), dict(x_mm=-1.0), dict(x_mm=np.nan),
                                 dict(radii_mm=[-1.0]), dict(radii_mm=[0.0]),
                                 dict(radii_mm=[np.nan]), dict(foot_mm=np.inf),
                                 dict(centers_mm=[np.nan])])
def test_a_geometry_outside_physics_is_refused(bad):
    """x = 0 gave 0.0 with warnings, a radius of -1 or NaN gave 0.0 silently."""
    args = dict(radii_mm=[1.0], centers_mm=[0.0], foot_mm=0.0, x_mm=1.0) | bad
    with pytest.raises(ValueError, match=next(iter(bad))):
        overlap_irradiance_mm2(**args)


@pytest.mark.parametrize("weight, natural", [("area", True), ("area", False),
                                             ("cos4", True), ("cos4", False)])
@pytest.mark.parametrize("bad", [dict(x_mm=0.0), dict(x_mm=-1.0), dict(radii_mm=[-1.0]),
                                 dict(radii_mm=[np.nan]), dict(foot_mm=np.nan)])
def test_every_weight_of_the_relative_irradiance_refuses_such_a_geometry(bad, weight,
                                                                         natural):
    """Only the cos^4 weight checked: the area's gave inf at x = 0, 0.64 at x = -1, 0.0
    for a radius of -1 and NaN for one of NaN, all silently."""
    args = dict(radii_mm=[1.0], centers_mm=[0.0], foot_mm=0.0, x_mm=1.0) | bad
    with pytest.raises(ValueError, match=next(iter(bad))):
        relative_irradiance(**args, weight=weight, natural=natural)


@pytest.mark.parametrize("radii, centers", [([], []), ([1.0], []), ([1.0, 2.0], [0.0])])
def test_discs_of_no_number_or_unmatched_centres_are_refused(radii, centers):
    """No disc at all gave an IndexError."""
    for fn in (overlap_irradiance_mm2, relative_irradiance):
        with pytest.raises(ValueError, match="same number of discs, at least one"):
            fn(radii, centers, 0.0, 1.0)


def test_far_feet_stay_accurate():
    """A disc seen from far off its axis: the weight nearly uniform over it, ~ pi / F^4."""
    for F in (30.0, 100.0, 1000.0):
        got = float(overlap_irradiance_mm2([1.0], [0.0], F, 1.0))
        assert got == pytest.approx(np.pi / (1 + F * F) ** 2, rel=3 / F**2 + 1e-7)


@pytest.mark.parametrize("nodes", [0, -1, 3.7, "12", True, 10**6])
def test_nodes_outside_a_rule_are_refused(nodes):
    """nodes=3.7 was truncated to 3, 0 gave numpy's 'deg must be a positive integer' and
    10**6 asked for 7 TiB."""
    with pytest.raises(ValueError, match="nodes must be a whole number from 1 to 256"):
        overlap_irradiance_mm2([1.0], [0.0], 0.0, 1.0, nodes=nodes)


def test_any_distance_of_the_pupil_plane_or_a_refusal():
    """x = 1e200 gave 0.0 (the area underflowed in units of x), x = 1e-9 a value 162 x too
    large, a foot 1e6 x away 15 x too large: far planes tend to the area, and a pupil or a
    foot beyond 1000 x is refused."""
    for x in (1e10, 1e100, 1e200, 1e300):
        assert float(overlap_irradiance_mm2([1.0], [0.0], 0.0, x)) == pytest.approx(np.pi,
                                                                                     rel=1e-12)
    for R in (3.0, 300.0):
        got = float(overlap_irradiance_mm2([R], [0.0], 0.0, 1.0))
        assert got == pytest.approx(np.pi * R * R / (1 + R * R), rel=1e-10)
    for args in (([1.0], [0.0], 0.0, 1e-9), ([1.0], [0.0], 1e6, 1.0)):
        with pytest.raises(ValueError, match="within 1000 x"):
            overlap_irradiance_mm2(*args)
