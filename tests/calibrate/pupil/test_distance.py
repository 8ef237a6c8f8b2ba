"""The exit-pupil fit's x stage: the trial range and scan, the search's start, and the
held-out test that a target shows a shift at all.

The scan is checked against the thin-film shift law written out here (a chief ray at
``atan(r / x)`` moves a band to ``sqrt(1 - sin^2 / n^2)`` of its wavelength); the start
against a dense grid; the held-out test on cubes from ``tests/oracles/spectralsim.py``.
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from calibrate.pupil.test_locate import PAPER, PLAIN, as_lens, cubes, sensor
from snapcorr.calibrate import FeaturelessTargetError, locate_pupil
from snapcorr.calibrate.pupil.distance import (
    EDGE_CRA_DEG,
    _half,
    _scan_grid,
    _start,
    _trial_range,
)
from snapcorr.calibrate.pupil.target_model import RadialBins


def _edge_shift(r_mm, x_mm, n):
    """The relative shift of the chief ray at the field's edge, by the shift law."""
    sin = r_mm / math.hypot(r_mm, x_mm)
    return 1.0 - math.sqrt(1.0 - sin**2 / n**2)


def test_the_trial_range_spans_the_edge_angles():
    lo, hi = _trial_range(4.5)
    assert math.degrees(math.atan(4.5 / lo)) == pytest.approx(EDGE_CRA_DEG[1])
    assert math.degrees(math.atan(4.5 / hi)) == pytest.approx(EDGE_CRA_DEG[0])


@pytest.mark.parametrize("step_nm", [1.5, 0.2])
def test_the_scan_steps_evenly_in_the_shift_at_the_edge(step_nm):
    r, n, cwl = 4.5, 1.7, 650.0
    lo, hi = _trial_range(r)
    grid = _scan_grid(r, lo, hi, n, cwl, step_nm)
    assert grid[0] == pytest.approx(hi) and grid[-1] == pytest.approx(lo)
    shifts = np.array([_edge_shift(r, x, n) for x in grid])
    steps = np.diff(shifts)
    np.testing.assert_allclose(steps, steps[0], rtol=1e-6)
    # the step asked, unless the scan's 16-80 trials bound it
    count = (shifts[-1] - shifts[0]) * cwl / step_nm
    if 16 <= count <= 80:
        assert steps[0] * cwl == pytest.approx(step_nm, rel=0.1)
    assert 16 <= grid.size <= 80


def test_the_start_is_the_deepest_minimum_refined():
    """Three minima over the scan: the start is the deepest, refined between its neighbours,
    as a dense grid finds it."""
    def chi2(x):
        return (50 - 30 * np.exp(-((x - 14.2) / 1.1) ** 2) - 38 * np.exp(-((x - 23.7) / 0.9) ** 2)
                - 20 * np.exp(-((x - 40.0) / 3.0) ** 2))

    problem = SimpleNamespace(chi2=chi2)
    grid = np.linspace(60.0, 8.0, 40)
    dense = np.linspace(8.0, 60.0, 200001)
    assert _start(problem, grid) == pytest.approx(dense[np.argmin(chi2(dense))], abs=1e-3)


def test_half_the_annuli_leave_the_other_half_empty():
    mean = np.arange(14.0).reshape(2, 7)
    bins = RadialBins(2.0, np.arange(7.0), mean, mean, mean, mean, mean)
    even, odd = _half(bins, 0), _half(bins, 1)
    assert np.all(np.isnan(even.mean[:, 1::2])) and np.all(np.isnan(odd.mean[:, ::2]))
    np.testing.assert_array_equal(even.mean[:, ::2], mean[:, ::2])
    np.testing.assert_array_equal(odd.mean[:, 1::2], mean[:, 1::2])
    np.testing.assert_array_equal(bins.mean, mean)  # the bins given stay whole


@pytest.mark.slow  # the command line's refusal is in the default run (test_cli_pupil.py)
@pytest.mark.parametrize("fit_n_eff", [False, True])
@pytest.mark.parametrize("noise, seed", [(0.01, 4), (0.005, 0), (0.005, 2)])
def test_a_white_target_is_refused_in_every_mode(fit_n_eff, noise, seed):
    """A white tile carries no information about x, with the index fitted or known, at any
    noise: fitted on every other annulus, its field predicts the annuli in between no better
    than a field without shift (the gain was -41 to -99 against 90-100 needed). In sample
    alone the search over x fitted enough noise to pass: x = 22.6 +- 0.45 mm with n_eff
    fitted, 34.5 +- 1.2 mm with it known, chi-square 1.01-1.02."""
    with pytest.raises(FeaturelessTargetError, match="fitted on every other annulus"):
        locate_pupil(cubes("white", "paper", (2.0, 8.0), noise=noise, seed=seed), sensor(),
                     lens=as_lens(PAPER), fit_n_eff=fit_n_eff)


@pytest.mark.slow
def test_a_weak_real_target_passes_the_held_out_test():
    """Emission lines under 10 % noise: the field's held-out gain (365) is far above the 5
    standard deviations of noise needed (about 50); x comes out within 3 standard errors."""
    got = locate_pupil(cubes("emission_lines", "plain", (2.0, 8.0), noise=0.1, seed=0),
                       sensor(), lens=as_lens(PLAIN, 30.0), fit_n_eff=True)
    assert abs(got.exit_pupil_mm - 16.0) < 3 * got.exit_pupil_stderr_mm, got.summary()

