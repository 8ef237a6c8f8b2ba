"""Rienstra (1998)'s ray-bundle transform: its weights (App. A-9), the arc it shares with
Goossens' eta, and its shift and temperature factors (Eq. 4)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from snapcorr import Lens
from snapcorr.optics.aperture import eta
from snapcorr.optics.profiles import MultiLorentzian, Tabulated
from snapcorr.optics.response import filter_response
from snapcorr.optics.rienstra1998 import arc_half_angle, ray_bundle_weights, shift_factors

P_GRID = np.arange(600.0, 760.0, 0.02)


def centroid(w, t):
    return np.trapezoid(w * t, w) / np.trapezoid(t, w)


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


def _bundle_angles_deg(f_number, cra_deg, n=2000):
    """Incidence angle of every ray of the bundle: a grid over the disc of radius 1 / (2 f#)
    about tan(CRA), in units of the filter height (Rienstra's App. A, sampled, not summed)."""
    A, D = 1.0 / (2.0 * f_number), np.tan(np.deg2rad(cra_deg))
    c = (np.arange(n) + 0.5) / n * 2 * A - A
    U, V = np.meshgrid(D + c, c, indexing="ij")
    inside = (U - D) ** 2 + V**2 <= A * A
    return np.rad2deg(np.arctan(np.hypot(U[inside], V[inside])))


@pytest.mark.parametrize(("f", "cra", "step"), [(3.0, 10.0, 0.25), (2.0, 15.0, 0.5),
                                                 (1.4, 20.0, 0.25)])
def test_rienstra_weights_are_the_rings_share_of_the_sampled_bundle(f, cra, step):
    theta, W = ray_bundle_weights(f, cra, step_deg=step)
    ang = _bundle_angles_deg(f, cra)
    counts, _ = np.histogram(ang, np.concatenate([[0.0], theta + step / 2]))
    brute = counts / ang.size
    assert counts.sum() == ang.size  # the rings reach past the bundle's edge
    assert np.abs(W - brute).sum() < 0.005
    assert (W * theta).sum() / W.sum() == pytest.approx(ang.mean(), abs=0.01)


def test_rienstra_transform_is_the_bundles_average_of_the_scaled_curve():
    # Eq. 5-7 against the rays one by one: each ray sees the curve at lambda / S(theta_ray),
    # S = cos(asin(sin(theta) / n)) (Eq. 4)
    from snapcorr.optics.rienstra1998 import transform

    n, f, cra = 1.775, 3.0, 10.0
    t = MultiLorentzian(700.0, 10.0)(P_GRID)
    got = transform(P_GRID, t, n, f, cra, step_deg=0.05, normalize=True)
    ang = np.deg2rad(_bundle_angles_deg(f, cra, n=600))
    S = np.sqrt(1.0 - (np.sin(ang) / n) ** 2)
    lam_s, idx = np.unique(np.round(S, 6), return_counts=True)  # equal factors grouped
    brute = sum(c * np.interp(P_GRID / s, P_GRID, t, left=0.0, right=0.0)
                for s, c in zip(lam_s, idx, strict=True)) / ang.size
    assert_allclose(got, brute, atol=2e-3 * t.max())
    assert centroid(P_GRID, got) == pytest.approx(centroid(P_GRID, brute), abs=0.02)
    # a curve scaled by S has its centroid at S * 700 nm and its area times S
    assert centroid(P_GRID, got) == pytest.approx(700.0 * (S**2).sum() / S.sum(), abs=0.02)
    assert centroid(P_GRID, got) < 700.0 - 4.0  # the band moved to the blue


@pytest.mark.parametrize("pupil", ["lambertian", "paper-lambertian"])
@pytest.mark.parametrize("circles", [[], [(7.4236, 16.991)]])
def test_the_ray_bundle_refuses_a_pupil_that_is_not_the_papers(pupil, circles):
    """Rienstra's weights are the paper's pupil's: a Lambertian lens had been given the same
    weights (their sum 1.00055, the curve's centroid the same to 0.001 nm) silently."""
    lens = Lens(21.0, circles, 0.06, 1.3, pupil_radiance=pupil)
    with pytest.raises(ValueError, match=rf"pupil is '{pupil}': use .*method='kernel'"):
        ray_bundle_weights(2.0, 10.0, lens=lens)
    ray_bundle_weights(2.0, 10.0, lens=Lens(21.0, circles, 0.06, 1.3))
