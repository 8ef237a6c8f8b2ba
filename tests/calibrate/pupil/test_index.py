"""The exit-pupil fit's index stage: an effective index linear in wavelength, or one per
band, where the data ask for it (cubes as in ``test_locate.py``)."""

from __future__ import annotations

import numpy as np
import pytest
import spectralsim as sim

from calibrate.pupil.test_locate import (
    CENTER,
    CWL,
    FWHM,
    PITCH_UM,
    PLAIN,
    SHAPE,
    as_lens,
    cubes,
    sensor,
)
from snapcorr.calibrate import locate_pupil
from snapcorr.cube import make_cube


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_an_index_linear_in_wavelength_is_found_and_nothing_richer():
    """Filters whose index rises from 1.6 to 2.1 across the bands (the sensor file says 1.8
    everywhere): one value misfits, a factor linear in wavelength fits; one per band is not
    constrained (bands without a feature of the colour filter) and is not taken."""
    truth = PLAIN
    n_true = np.linspace(1.6, 2.1, CWL.size)
    got = locate_pupil(cubes("colour_filter", "plain", (2.0, 8.0), noise=0.002, seed=5,
                             n_eff=tuple(n_true)), sensor(1.8), lens=as_lens(truth),
                       fit_n_eff=True)
    assert got.n_eff_fitted == "linear"
    assert any("n_eff not one per band" in note for note in got.notes)
    x = truth.exit_pupil_mm
    assert abs(got.exit_pupil_mm - x) < 0.01 * x
    assert abs(got.exit_pupil_mm - x) < 4 * got.exit_pupil_stderr_mm
    assert np.all(np.abs(got.n_eff - n_true) < 0.015 * n_true)
    assert np.all(np.abs(got.n_eff - n_true) < 4 * got.n_eff_stderr)
    assert 0.7 < got.chi2_red < 1.5
    assert len(got.lens.calibration["n_eff"]) == CWL.size


@pytest.mark.slow  # 45 s: thirty indices
def test_one_index_per_band_where_every_band_sees_a_feature():
    """Two families of filters (n_eff 1.7 below 680 nm, 1.9 above) behind a channel spectrum
    (a fringe in every band): neither one value nor a linear factor fits; one per band does,
    with honest errors."""
    truth = PLAIN
    n_true = np.where(CWL < 680.0, 1.7, 1.9)
    rng = np.random.default_rng(7)
    data = {}
    for f in (2.0, 8.0):
        clean = sim.target_cube(sim.channel_spectrum, cwl_nm=CWL, fwhm_nm=FWHM, n_eff=n_true,
                                f_number=f, lens=truth, shape=SHAPE, pixel_pitch_um=PITCH_UM,
                                center_px=CENTER)
        data[f] = make_cube(clean + rng.normal(0.0, 0.005, clean.shape), CWL)
    got = locate_pupil(data, sensor(1.8), lens=as_lens(truth), fit_n_eff=True)
    assert got.n_eff_fitted == "per band"
    x = truth.exit_pupil_mm
    assert abs(got.exit_pupil_mm - x) < 0.01 * x
    z = (got.n_eff - n_true) / got.n_eff_stderr
    assert np.all(np.abs(got.n_eff - n_true) < 0.015 * n_true)
    assert np.all(np.abs(z) < 4) and 0.5 < np.sqrt(np.mean(z**2)) < 2.0
