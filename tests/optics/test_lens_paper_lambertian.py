"""The paper's disc radiating as a Lambertian surface (``pupil_radiance="paper-lambertian"``).

Checked against what snapcorr does not compute itself: the pupil quadrature of
``tests/oracles/spectralsim.py`` (its ``"disc-cos4"`` pupil), and flats counted ray by ray
here, each ray weighted by its own cos^4.
"""

import numpy as np
import pytest
import spectralsim as sim
from flatsim import LensTruth

from snapcorr import Lens, mean_shift
from snapcorr.optics import ShiftGrid
from snapcorr.simulate import relative_illumination_map

N_EFF, CWL = 1.5, 1000.0
CIRCLES = [(), ((7.4236, 16.991),), ((7.4236, 16.991), (9.0, 30.0))]


def test_radius_is_the_papers_and_the_weight_lambertian():
    paper = Lens(21.0, (), pupil_radiance="paper")
    disc = Lens(21.0, (), pupil_radiance="paper-lambertian")
    sine = Lens(21.0, (), pupil_radiance="lambertian")
    assert float(disc.exit_pupil_radius_mm(1.4)) == float(paper.exit_pupil_radius_mm(1.4))
    assert float(sine.exit_pupil_radius_mm(1.4)) > float(paper.exit_pupil_radius_mm(1.4))
    assert (paper.ray_weight, disc.ray_weight, sine.ray_weight) == ("area", "cos4", "cos4")


@pytest.mark.parametrize("circles", CIRCLES, ids=["none", "one", "two"])
@pytest.mark.parametrize(("f", "cra"), [(1.4, 0.0), (1.4, 15.0), (2.8, 15.0), (8.0, 12.0)])
def test_mean_shift_matches_an_independent_quadrature(circles, f, cra):
    truth = LensTruth(21.0, circles, 0.06, 1.3, meta={"pupil": "disc-cos4"})
    q, w = sim._sin2_phi(truth, f, 21.0 * np.tan(np.deg2rad(cra)))
    want = np.sum(w * CWL * (np.sqrt(1.0 - q / N_EFF**2) - 1.0)) / w.sum()
    lens = Lens(21.0, circles, 0.06, 1.3, pupil_radiance="paper-lambertian")
    got = float(mean_shift(CWL, N_EFF, f, cra, lens, method="vignetted"))
    assert got == pytest.approx(want, abs=1e-9)
    paper = float(mean_shift(CWL, N_EFF, f, cra, Lens(21.0, circles, 0.06, 1.3),
                             method="vignetted"))
    sine = float(mean_shift(CWL, N_EFF, f, cra, Lens(21.0, circles, 0.06, 1.3,
                                                     pupil_radiance="lambertian"),
                            method="vignetted"))
    if f < 2:  # three pupils, three answers: the cos^4 lowers the mean, the wider disc raises it
        assert abs(got - paper) > 0.05 and abs(got - sine) > 0.05


def test_the_papers_own_formulas_refuse_it():
    lens = Lens(21.0, ((7.4236, 16.991),), pupil_radiance="paper-lambertian")
    for method in ("asymptotic", "riemann"):
        with pytest.raises(ValueError, match="paper's pupil"):
            mean_shift(CWL, N_EFF, 2.0, 5.0, lens, method=method)
    with pytest.raises(ValueError, match="paper's pupil") as err:
        mean_shift(CWL, N_EFF, 2.0, 5.0, lens, method="asymptotic")
    assert "'table'" not in str(err.value)  # correct has no such method: advice for both
    with pytest.raises(ValueError, match="paper's pupil only"):
        ShiftGrid.build(N_EFF, lens, f_range=(2.0, 8.0), cra_max_deg=10.0)
    assert float(mean_shift(CWL, N_EFF, 2.0, 5.0, lens, method="auto")) == pytest.approx(
        float(mean_shift(CWL, N_EFF, 2.0, 5.0, lens, method="vignetted")), abs=1e-3)


def test_profile_keeps_it(tmp_path):
    lens = Lens(21.0, ((7.4236, 16.991),), 0.06, 1.3, pupil_radiance="paper-lambertian")
    back = Lens.load(lens.save(tmp_path / "lens.toml"))
    assert back.pupil_radiance == "paper-lambertian"


def _counted_flat(r_mm, f, circles, x=21.0, n=1200):
    """Every ray of a square grid over the disc, each weighted by its own cos^4."""
    R = x / (2 * f)
    g = (np.arange(n) + 0.5) / n * 2 * R - R
    u, v = np.meshgrid(g, g, indexing="ij")
    keep = u * u + v * v < R * R
    out = []
    for r in r_mm:
        k = keep.copy()
        for P, h in circles:
            k &= (u - h * r / x) ** 2 + v * v < P * P
        cos2 = x * x / ((u - r) ** 2 + v * v + x * x)
        out.append(np.sum(cos2**2 * k))
    out = np.asarray(out)
    return out / out[0]


@pytest.mark.parametrize("f", [1.4, 4.0])
def test_flats_fall_off_with_every_rays_cos4(f):
    circles = ((10.0, 17.0),)
    lens = Lens(21.0, circles, pupil_radiance="paper-lambertian")
    cols = np.arange(0, 300, 25)
    v = relative_illumination_map((1, 300), 44.0, f, lens, center_rc=(0, 0))[0, cols]
    want = _counted_flat(cols * 0.044, f, circles)
    np.testing.assert_allclose(v, want, rtol=2e-4)
    # the paper's pupil (the chief ray's cos^4) is off by percents at f/1.4
    paper = relative_illumination_map((1, 300), 44.0, f, Lens(21.0, circles),
                                      center_rc=(0, 0))[0, cols]
    assert np.max(np.abs(paper / want - 1)) > (0.02 if f < 2 else 0.002)


def test_a_pupil_given_as_an_array_is_refused():
    """np.array(['paper-lambertian']) passed the membership test; ray_weight then raised
    'unhashable type'."""
    with pytest.raises(ValueError, match="pupil_radiance must be one of"):
        Lens(21.0, pupil_radiance=np.array(["paper-lambertian"]))
