"""The precomputed mean-shift tables (over CRA, and over f-number and CRA) against the exact
vignetted mean (Goossens 2019 Eq. 22)."""

from dataclasses import replace

import numpy as np
import pytest
from conftest import PAPER_LENS, load_reference_csv

from snapcorr import Lens, ShiftTable, mean_shift
from snapcorr.optics import ShiftGrid

X = 21.0


def test_table_is_used_for_large_groups_and_meets_tolerance(edmund):
    rng = np.random.default_rng(3)
    cra = rng.uniform(0, 25, 30_000)
    got = mean_shift(700.0, 1.7, 1.4, cra, edmund)
    exact = mean_shift(700.0, 1.7, 1.4, cra, edmund, method="vignetted")
    assert np.max(np.abs(got - exact)) <= 0.001
    table = ShiftTable.build(1.7, 1.4, edmund, cra_max_deg=25, tolerance_nm=0.001, cwl_max_nm=700)
    onset = float(edmund.onset_cra_deg(1.4))
    assert np.any(np.isclose(table.cra_deg, onset))  # the kink is a node
    with pytest.raises(ValueError, match="beyond this table"):
        table(700, 26)


@pytest.mark.filterwarnings("ignore::snapcorr.EffectiveIndexWarning")
@pytest.mark.parametrize(
    "lens",
    [replace(PAPER_LENS, name="h<x"),
     Lens(X, [(6.5, 27.0)], 0.06, 1.3, name="h>=x"),
     Lens(X, magnification=0.06, pupil_magnification=1.3, name="ideal")],
    ids=lambda lens: lens.name,
)
@pytest.mark.parametrize("cra_max", [30.0, 12.0])
def test_grid_meets_tolerance_on_scattered_pairs(lens, cra_max):
    # Both regimes, P = R inside the f-range (h<x at f/1.37, h>=x at f/1.56) and the full
    # cut-off inside the CRA range for the slow f-numbers.
    # cra_max 12 deg: the onset crosses cra_max inside the f-range (another kink in f).
    rng = np.random.default_rng(11)
    f = np.exp(rng.uniform(np.log(1.2), np.log(16), 60_000))
    cra = rng.uniform(0, cra_max, 60_000)
    keep = cra < lens.cutoff_cra_deg(f) - 0.01
    f, cra = f[keep], cra[keep]
    grid = ShiftGrid.build(1.7, lens, f_range=(1.2, 16), cra_max_deg=cra_max,
                           tolerance_nm=0.001, cwl_max_nm=700)
    exact = mean_shift(700.0, 1.7, f, cra, lens, method="vignetted")
    assert np.max(np.abs(grid(700.0, f, cra) - exact)) <= 0.001
    assert grid.cell_ok.mean() > 0.99  # the exact fallback stays rare
    with pytest.raises(ValueError, match="range"):
        grid(700.0, 20.0, 5.0)
    with pytest.raises(ValueError, match="f_range"):
        ShiftGrid.build(1.7, lens, f_range=(2.0, 2.0))


def test_table_and_grid_build_arguments_are_checked(edmund):
    for kw in (dict(tolerance_nm=0.0), dict(tolerance_nm=1e-15), dict(cwl_max_nm=0.0),
               dict(cwl_max_nm=np.nan), dict(cra_max_deg=np.nan)):
        with pytest.raises(ValueError):
            ShiftTable.build(1.7, 2.0, edmund, **({"cra_max_deg": 10.0} | kw))
        with pytest.raises(ValueError):
            ShiftGrid.build(1.7, edmund, f_range=(2.0, 4.0), **kw)
    table = ShiftTable.build(1.7, 2.0, edmund, cra_max_deg=10.0)
    with pytest.raises(ValueError, match="finite"):
        table(700.0, np.nan)


def test_table_and_grid_give_the_reference_mean_shift_of_the_papers_lens(edmund):
    # mean_shift_edmund16mm.csv: brute-force pupil sampling and Goossens' MATLAB toolbox
    f, cra, _ideal, vign, _rel = load_reference_csv().T
    grid = ShiftGrid.build(1.7, edmund, f_range=(float(f.min()), float(f.max())),
                           cra_max_deg=float(cra.max()), tolerance_nm=0.001, cwl_max_nm=700)
    np.testing.assert_allclose(grid(700.0, f, cra), vign, atol=1.5e-3)
    for fn in np.unique(f):
        sel = f == fn
        table = ShiftTable.build(1.7, float(fn), edmund, cra_max_deg=float(cra.max()),
                                 tolerance_nm=0.001, cwl_max_nm=700)
        np.testing.assert_allclose(table(700.0, cra[sel]), vign[sel], atol=1.5e-3)
        # the shift scales with the wavelength (Eq. 3): one table serves every band
        np.testing.assert_allclose(table(350.0, cra[sel]), vign[sel] / 2, atol=1e-3)
