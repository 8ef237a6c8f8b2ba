"""One f-number: the index pinned by the field where it can be, and x * n_eff that covers where not.

Cubes from physical rays (``tests/oracles/spectralsim.py``: every pupil ray scales the whole
filter curve, ``T(lambda) = T0(lambda / s)``; no code shared with snapcorr) behind the paper
lens (x = 21 mm), a rare-earth glass, 128 x 160 pixels of 44 um with the axis on the sensor
(15 degrees at the far corner), the filters' true index 1.75 where the sensor says 1.7.

Holding the index at the sensor's 1.7 gave x * n_eff = 36.19 +- 0.018 mm against the true
36.75 at f/2 (30 of its errors off): over a 15 degree field the field does not fix the product
alone (sin^2 against tan^2 of the chief-ray angle, the cone's tilt off axis), and those same
terms pin the index.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import spectralsim as sim
from conftest import PAPER_LENS, PAPER_TRUTH

from snapcorr.calibrate import locate_pupil
from snapcorr.cube import Sensor, make_cube

CWL = np.arange(500.0, 849.0, 12.0)
N_TRUE, N_SENSOR, X_MM = 1.75, 1.7, 21.0


@functools.cache
def clean(f_number):
    return sim.target_cube(sim.rare_earth_glass, cwl_nm=CWL, fwhm_nm=12.0, n_eff=N_TRUE,
                           f_number=f_number, lens=PAPER_TRUTH, shape=(128, 160),
                           pixel_pitch_um=44.0, center_px=(82.3, 61.6))


def fit(f_number, seed, n_eff=N_SENSOR):
    rng = np.random.default_rng(seed)
    cube = clean(f_number) + rng.normal(0.0, 0.002, clean(f_number).shape)
    sensor = Sensor("modelled", "snapscan", 44.0, CWL, 12.0, n_eff)
    return locate_pupil({f_number: make_cube(cube, CWL)}, sensor, lens=PAPER_LENS,
                        fit_n_eff=True)


def test_a_fast_cone_over_a_wide_field_pins_the_index_at_one_f_number():
    got = fit(2.0, 0)
    assert got.n_eff_fitted == "one", got.notes
    assert got.n_eff_stderr[0] < 0.01 * N_TRUE
    for value, err, truth in ((got.exit_pupil_mm, got.exit_pupil_stderr_mm, X_MM),
                              (got.n_eff[0], got.n_eff_stderr[0], N_TRUE),
                              (got.x_n_eff_mm, got.x_n_eff_stderr_mm, X_MM * N_TRUE)):
        assert abs(value - truth) < 3 * err, (value, err, truth)
    assert any("one f-number: the field alone" in note for note in got.notes)
    assert got.lens.calibration["n_eff_fitted"] == "one"


def test_a_slow_cone_gives_a_product_whose_error_includes_the_index():
    """At f/8 the field alone knows the index to 5 % only: x is fitted at the sensor's index
    (and says so), x * n_eff with the index free; its error covers the 3 % wrong index."""
    got = fit(8.0, 1)
    assert got.n_eff_fitted == "product", got.notes
    assert got.n_eff_stderr is None
    truth = X_MM * N_TRUE
    assert abs(got.x_n_eff_mm - truth) < 3 * got.x_n_eff_stderr_mm
    # x assumes the sensor's index: near the product over it, not the truth
    assert got.exit_pupil_mm == pytest.approx(got.x_n_eff_mm / N_SENSOR, rel=0.01)
    assert any("x assumes the sensor's n_eff" in note and "index free" in note
               for note in got.notes)
    assert got.lens.calibration["x_times_n_eff_stderr_mm"] == pytest.approx(
        got.x_n_eff_stderr_mm, rel=1e-2)


def test_a_sensor_without_an_index_is_refused_where_one_f_number_cannot_pin_it():
    clean_cube = clean(8.0)
    sensor = Sensor("no index", "snapscan", 44.0, CWL, 12.0, None)
    with pytest.raises(ValueError, match=r"one f-number \(f/8\) does not pin the effective "
                       r"index.*gives none.*second f-number.*n_eff in a sensor TOML"):
        locate_pupil({8.0: make_cube(clean_cube + np.random.default_rng(2).normal(
            0.0, 0.002, clean_cube.shape), CWL)}, sensor, lens=PAPER_LENS, fit_n_eff=True)
