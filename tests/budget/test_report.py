"""The budget's result: the choice of model, the residual at each pixel and the plot."""

import numpy as np
import pytest
import xarray as xr
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


def _handmade(residual_pct, radius_mm, models=("none", "ideal", "vignetted")):
    """A budget whose residuals are given, in percent: (model, band, cra)."""
    res = np.asarray(residual_pct, float) / 100
    _, nb, nc = res.shape
    ds = xr.Dataset(
        {"residual": (("model", "band", "cra"), res),
         "mean_shift": (("model", "band", "cra"), np.zeros(res.shape)),
         "radius_mm": (("cra",), np.asarray(radius_mm, float))},
        coords={"model": list(models), "cra": np.linspace(0.0, 20.0, nc),
                "wavelength": ("band", np.linspace(500.0, 600.0, nb))},
        attrs={"source": "handmade"})
    return budget.Budget(ds, tolerance_pct=0.5)


def test_the_radius_is_where_the_worst_band_crosses_the_tolerance():
    # worst band of "none": 0, 0.2, 0.4, 0.8, 1.6 % at 0, 1, 2, 3, 4 mm; 0.5 % is crossed a
    # quarter of the way from 2 to 3 mm (linear), 1 % a quarter of the way from 3 to 4 mm
    none = [[0.0, 0.2, 0.4, 0.8, 1.6], [0.0, -0.1, -0.2, -0.3, -0.4]]
    b = _handmade([none, np.full((2, 5), 0.1), np.zeros((2, 5))], [0.0, 1.0, 2.0, 3.0, 4.0])
    assert b.radius_mm() == pytest.approx(2.25, rel=1e-12)
    assert b.radius_mm(1.0) == pytest.approx(3.25, rel=1e-12)
    assert b.radius_mm(2.0) == np.inf
    assert b.radius_mm(0.5, "ideal") == np.inf
    # against the axis: a pixel already off by 1 % on the axis
    off = _handmade([[[1.0, 1.0, 2.0]], [[1.0, 1.0, 1.0]], [[0.0, 0.0, 0.0]]], [0.0, 1.0, 2.0])
    assert off.radius_mm(0.5) == 0.0
    crossed = (1.02 / 1.01 - 1) * 100  # the last pixel, relative to the axis
    assert off.radius_mm(crossed * 0.5, relative_to="center") == pytest.approx(
        1.0 + 0.5, rel=1e-6)
    with pytest.raises(ValueError, match="relative_to"):
        off.radius_mm(relative_to="edge")


def test_the_choice_table_and_worst_errors_of_a_handmade_budget():
    b = _handmade([np.full((2, 3), 2.0), [[0.3, -0.45, 0.1], [0.0, 0.2, 0.4]],
                   np.full((2, 3), 0.01)], [0.0, 1.0, 2.0])
    assert b.worst_pct("none") == pytest.approx(2.0) and b.worst_pct("ideal") == pytest.approx(0.45)
    model, reason = b.recommend()
    assert model == "ideal" and "cheaper: none 2 %" in reason
    assert b.recommend(5.0)[0] == "none" and b.recommend(0.1)[0] == "vignetted"
    assert b.recommend(0.001)[0] == "vignetted" and "no model is within" in b.recommend(0.001)[1]
    lines = b.table().splitlines()
    assert lines[0].split() == ["band", "cwl", "nm", "none", "ideal", "vignetted"]
    assert lines[1].split() == ["0", "500.00", "2%", "0.45%", "0.01%"]
    assert lines[-1].split() == ["all", "2%", "0.45%", "0.01%"]
    # a model that could not be evaluated somewhere is never the one within tolerance
    b.data["residual"].loc[{"model": "vignetted"}] = np.nan
    assert b.worst_pct("vignetted") == np.inf and b.recommend(0.001)[0] == "ideal"
