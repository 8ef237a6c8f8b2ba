"""Do the exit pupil's error bars cover? Checked on target cubes from physical rays.

Cubes from ``tests/oracles/spectralsim.py`` (every pupil ray scales the whole Gaussian filter curve,
``T(lambda) = T0(lambda / s)``, point by point over the vignetted pupil; no code shared with
snapcorr) and, for measured responses, ``tests/calibrate/pupil/test_measured_target.py``'s
forward model of the real imec 4 x 4 curves behind their band-pass; the paper lens at f/1.4 and f/8.

Behind the paper lens at f/1.4 the vignetting circle starts to cut the pupil 0.31 mm from the
axis, inside the first annulus: the model's Taylor step across that onset moved x by half a
standard error at 1 % noise (z of x -7, of n_eff +5 at lower noise, with a reduced chi-square
of 1.000). The default test measures what the model's own error does to x and n_eff, on
noise-free cubes, in units of their standard errors; the over-seeds check runs with -m slow.
"""

from __future__ import annotations

import dataclasses
import functools
import sys
from pathlib import Path

import numpy as np
import pytest
import spectralsim as sim
from conftest import PAPER_LENS, PAPER_TRUTH

from snapcorr.calibrate.pupil.measured_target import target_model
from snapcorr.calibrate.pupil.solver import _Problem
from snapcorr.calibrate.pupil.target import _annuli
from snapcorr.cube import Sensor, make_cube

# the field of the 128 x 160 sensor of 44 um in tests/calibrate/pupil/test_locate.py, in
# 64 x 80 pixels: 10 bands
PITCH_UM = 88.0
SHAPE = (64, 80)
CWL = np.arange(500.0, 849.0, 36.0)
FWHM = 12.0
N_EFF = 1.7
CENTER = (41.15, 30.8)  # (column, row)
X_MM = PAPER_TRUTH.exit_pupil_mm


@functools.cache
def clean(f_number, target="rare_earth_glass"):
    return sim.target_cube(getattr(sim, target), cwl_nm=CWL, fwhm_nm=FWHM, n_eff=N_EFF,
                           f_number=f_number, lens=PAPER_TRUTH, shape=SHAPE,
                           pixel_pitch_um=PITCH_UM, center_px=CENTER, n_radii=96)


def model_bias(f_numbers, noise, n_bins=48):
    """What the model's error at the truth does to x and n_eff: the Gauss-Newton step from
    the truth on noise-free cubes, in standard errors at per-pixel ``noise``."""
    sensor = Sensor("test", "snapscan", PITCH_UM, CWL, FWHM, N_EFF)
    cubes = {f: make_cube(clean(f), CWL) for f in f_numbers}
    bins, *_ = _annuli(cubes, sensor, PAPER_LENS, None, CENTER[::-1], n_bins)  # (row, col)
    bins = [dataclasses.replace(b, stderr=np.where(np.isfinite(b.mean),
                                                   noise / np.sqrt(b.count), np.nan))
            for b in bins]
    n = np.full(CWL.size, N_EFF)
    problem = _Problem(target_model(bins, sensor, PAPER_LENS, n_eff_design=n,
                                    max_shift_rel=0.15), n)
    r0 = problem.residuals(X_MM)[0]
    e = 1e-5
    J = np.column_stack([
        (problem.residuals(X_MM * (1 + e))[0] - problem.residuals(X_MM * (1 - e))[0]) / (2 * e),
        (problem.residuals(X_MM, 1 + e)[0] - problem.residuals(X_MM, 1 - e)[0]) / (2 * e)])
    cov = np.linalg.inv(J.T @ J)
    return -(cov @ J.T @ r0) / np.sqrt(np.diag(cov))


def test_the_models_error_at_the_truth_is_a_fraction_of_the_error_bars():
    # before the onset's annulus was averaged over nodes: -2.0 and +0.21 standard errors
    z = model_bias((1.4, 8.0), noise=0.001)
    assert np.all(np.abs(z) < 0.3), z


@pytest.mark.slow  # 8 seeds of two full fits: tens of minutes
@pytest.mark.parametrize("case", ["modelled", "measured"])
def test_errors_over_seeds_cover(case):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks import pupil_coverage

    rows = pupil_coverage.run((case,), seeds=8, first=200, write=False)
    z = np.array([[r["z_x"], r["z_n_eff"]] for r in rows])
    rms = np.sqrt(np.mean(z**2, axis=0))
    assert np.all((0.5 <= rms) & (rms <= 2.0)), (rms, z)
    assert np.all(np.abs(z) < 4), z
