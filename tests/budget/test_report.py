"""The budget's result: the choice of model, the residual at each pixel and the plot."""

import numpy as np
import pytest
from conftest import PAPER_LENS

from snapcorr import budget, spectra
from snapcorr.cube import Sensor

PAPER = PAPER_LENS


@pytest.fixture(scope="module")
def sun():
    return spectra.solar()


def test_recommend_takes_the_cheapest_model_within_tolerance(sun):
    sensor = Sensor("s", "snapscan", 5.5, np.linspace(470, 900, 12), 10.0, 1.7)
    b = budget.scene_budget(sun, sensor, 8.0, PAPER, cra_max_deg=15.0, n_cra=7)
    res = np.abs(b.data["residual"].values).max(axis=(1, 2)) * 100  # worst per model
    none, asym, ideal, vig, _har = res
    assert vig < none  # the sun at f/8: correcting helps
    assert b.recommend(none * 1.001)[0] == "none"
    assert b.recommend(min(asym, ideal, vig) * 1.001)[0] == budget.CORRECTION_MODELS[
        1 + int(np.argmax(np.array([asym, ideal, vig]) <= min(asym, ideal, vig) * 1.001))]
    model, reason = b.recommend(min(res) * 0.5)
    assert model == budget.CORRECTION_MODELS[int(np.argmin(res))] and "no model is within" in reason
    # models given out of order are still tried cheapest first
    b2 = budget.scene_budget(sun, sensor, 8.0, PAPER, cra_max_deg=15.0, n_cra=7,
                             models=("vignetted", "ideal"))
    assert b2.models == ("none", "ideal", "vignetted")  # "none" always: the reference
    assert b2.recommend(none * 1.001)[0] == "none"
    np.testing.assert_array_equal(b2.data["residual"].sel(model="vignetted"),
                                  b.data["residual"].sel(model="vignetted"))


def test_pixel_residual_interpolates_the_table(sun):
    sensor = Sensor("s", "snapscan", 5.5, [500.0, 600.0], 10.0, 1.7)
    b = budget.scene_budget(sun, sensor, 2.0, PAPER, cra_max_deg=10.0, n_cra=11)
    grid = b.data["cra"].values
    cra = np.stack([grid[:4], grid[4:8]])
    got = b.pixel_residual(cra, "none")
    assert got.dims == ("y", "x", "band")
    np.testing.assert_array_equal(got.values[1, 2], b.data["residual"].sel(model="none")
                                  .values[:, 6])
    with pytest.raises(ValueError, match="leave the budget"):
        b.pixel_residual(np.full((2, 2), 11.0))
    # between the nodes: linear in CRA; a (y, x, 1) map as correct_cube's geometry gives it
    mid = 0.5 * (grid[2] + grid[3])
    got = b.pixel_residual(np.full((1, 1, 1), mid), "vignetted").values[0, 0]
    table = b.data["residual"].sel(model="vignetted").values
    np.testing.assert_allclose(got, 0.5 * (table[:, 2] + table[:, 3]), rtol=1e-12)


def test_plot_writes_a_png_and_refuses_to_overwrite(sun, tmp_path):
    sensor = Sensor("s", "snapscan", 5.5, [500.0, 600.0], 10.0, 1.7)
    b = budget.scene_budget(sun, sensor, 2.0, PAPER, cra_max_deg=10.0, n_cra=5,
                            models=("vignetted",))
    out = tmp_path / "b.png"
    b.plot(out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="exists"):
        b.plot(out)
    b.plot(out, overwrite=True)
