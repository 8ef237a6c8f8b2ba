"""The exit pupil from a target without the lens's magnifications: the spread in x and n_eff.

Cubes from ``tests/oracles/spectralsim.py`` (no snapcorr code) of lenses at m = 0.06,
m_P = 1.3. The target fixes about x n_eff and the cone over n_eff, the cone set by
1 + m / m_P: assumed at m = 0, x comes out 4 % short and n_eff 4 % high (n_eff fitted), some
thirty of the noise's errors away. Left out, the errors must cover that (z between 0.3 and 2);
given, nothing changes and nothing is said.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import spectralsim as sim
from flatsim import LensTruth

from calibrate.test_unknown_magnification import PAPER, small_data
from snapcorr import Lens
from snapcorr.calibrate import locate_pupil
from snapcorr.calibrate.lens.magnification import MagnificationWarning, ratio_range

X, N = PAPER.exit_pupil_mm, 1.7


def _z(fit):
    return ((fit.exit_pupil_mm - X) / fit.exit_pupil_stderr_mm,
            (fit.n_eff[0] - N) / fit.n_eff_stderr[0])


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_circles_from_flats_without_magnifications_widen_x_and_n_eff():
    """The representative: the circles a calibration not given m and m_P writes (P and h
    times 1 + m / m_P, recorded as assumed), given to the target fit: x and n_eff 4 % off,
    covered by their errors; the warning names this line; the profile keeps the record, so
    the assumption travels on."""
    _, cubes, sensor = small_data(1)
    k = 1.0 + PAPER.magnification / PAPER.pupil_magnification
    lens = Lens(30.0, [(P * k, h * k) for P, h in PAPER.circles], 0.0, 1.0,
                calibration={"magnification": {"assumed": True, "given": "neither"}})
    with pytest.warns(MagnificationWarning, match="no magnifications given") as seen:
        fit = locate_pupil(cubes, sensor, lens=lens, fit_n_eff=True, pupil_radiance="paper")
    assert [w.filename for w in seen if w.category is MagnificationWarning] == [__file__]
    assert abs(fit.exit_pupil_mm / X - 1) > 0.03  # the assumption's bias
    zx, zn = _z(fit)
    assert 0.3 < abs(zx) < 2 and 0.3 < abs(zn) < 2, (zx, zn)
    cal = fit.lens.calibration
    assert cal["exit_pupil_stderr_mm"] == pytest.approx(fit.exit_pupil_stderr_mm, rel=1e-2)
    assert cal["n_eff_stderr"] == pytest.approx(fit.n_eff_stderr[0], rel=1e-2)
    assert cal["magnification"]["assumed"] is True
    assert ratio_range(lens=fit.lens)[0] == "neither"
    assert any("no magnifications given" in n for n in fit.notes)


PLAIN = LensTruth(X, (), PAPER.magnification, PAPER.pupil_magnification, name="no vignetting")


def _plain_cubes(seed):
    _, _, sensor = small_data(0)
    rng = np.random.default_rng(seed)
    out = {}
    from snapcorr.cube import make_cube

    for f in (2.0, 8.0):
        data = sim.target_cube(sim.colour_filter, cwl_nm=sensor.cwl_nm, fwhm_nm=12.0,
                               n_eff=N, f_number=f, lens=PLAIN, shape=(64, 80),
                               pixel_pitch_um=66.0, center_px=(40.7, 31.0))
        out[f] = make_cube(data + rng.normal(0.0, 0.002, data.shape), sensor.cwl_nm)
    return out, sensor


@pytest.mark.slow
def test_without_a_lens_left_out_is_widened_and_given_is_exact():
    """No lens, no vignetting, m = 0.06 and m_P = 1.3: left out, x and n_eff are covered;
    given, no warning, no record, and the figures of the fit the assumption's step leaves
    alone (the same call with them given)."""
    cubes, sensor = _plain_cubes(4)
    with pytest.warns(MagnificationWarning):
        fit = locate_pupil(cubes, sensor, fit_n_eff=True, pupil_radiance="paper")
    zx, zn = _z(fit)
    assert 0.3 < abs(zx) < 2 and 0.3 < abs(zn) < 2, (zx, zn)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MagnificationWarning)
        got = locate_pupil(cubes, sensor, fit_n_eff=True, pupil_radiance="paper",
                           magnification=PAPER.magnification,
                           pupil_magnification=PAPER.pupil_magnification)
        zero = locate_pupil(cubes, sensor, fit_n_eff=True, pupil_radiance="paper",
                            magnification=0.0)
    assert "magnification" not in got.lens.calibration
    assert "magnification" not in zero.lens.calibration
    assert abs(got.exit_pupil_mm - X) < 3 * got.exit_pupil_stderr_mm
    assert got.exit_pupil_stderr_mm < 0.1 * fit.exit_pupil_stderr_mm
