"""Before the exit-pupil fit: the precision a target's cubes can give, and a target that
cannot reach the shift precision asked refused in one line (``tolerance_nm``).

Cubes from ``tests/oracles/spectralsim.py`` (physical rays behind the paper lens, every ray scaling
the whole Gaussian curve), f/1.4 + f/8, 1 % noise, on the 128 x 160 field of 44 um of
``tests/calibrate/pupil/test_locate.py`` in 64 x 80 pixels of 88 um, 30 bands of 12 nm every 12 nm.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import spectralsim as sim
from conftest import PAPER_LENS, PAPER_TRUTH

from snapcorr import Lens
from snapcorr.calibrate import ImpreciseTargetError, locate_pupil, pupil_precision
from snapcorr.calibrate.pupil.measured_target import target_model
from snapcorr.calibrate.pupil.precision import DEFAULT_TOLERANCE_NM, target_precision
from snapcorr.calibrate.pupil.solver import _Problem
from snapcorr.calibrate.pupil.target import _annuli
from snapcorr.cube import Sensor, make_cube

PITCH_UM, SHAPE = 88.0, (64, 80)
CWL = np.arange(500.0, 849.0, 12.0)
CENTER = (41.15, 30.8)  # (column, row)
FS = (1.4, 8.0)


def straight_line(lam):
    """Nearly featureless: a reflectance rising in a straight line, 0.45 -> 0.75 over 470-900 nm."""
    return 0.45 + 0.30 * (np.asarray(lam, float) - 470.0) / 430.0


TARGETS = {"glass": sim.rare_earth_glass, "line": straight_line}


@functools.cache
def clean(target, f):
    return sim.target_cube(TARGETS[target], cwl_nm=CWL, fwhm_nm=12.0, n_eff=1.7, f_number=f,
                           lens=PAPER_TRUTH, shape=SHAPE, pixel_pitch_um=PITCH_UM,
                           center_px=CENTER, n_radii=96)


def sensor():
    return Sensor("test", "snapscan", PITCH_UM, CWL, 12.0, 1.7, size_px=SHAPE)


def cubes(target, seed=0, noise=0.01, fs=FS):
    rng = np.random.default_rng(seed)
    return {f: make_cube(clean(target, f) + rng.normal(0.0, noise, (*SHAPE, CWL.size)), CWL)
            for f in fs}


def predicted(target, fs=FS):
    bins, *_ = _annuli(cubes(target, fs=fs), sensor(), PAPER_LENS, None, CENTER[::-1], 48)
    n = np.full(CWL.size, 1.7)
    problem = _Problem(target_model(bins, sensor(), PAPER_LENS, n_eff_design=n,
                                    max_shift_rel=0.15), n)
    return target_precision(problem, 21.0, len(fs) > 1, 4.6, float(CWL.max()))


@pytest.mark.slow  # two targets' 30-band cubes and models: about 16 s of CPU
def test_a_wavelength_standard_reaches_the_default_and_a_straight_line_does_not():
    glass, line = predicted("glass"), predicted("line")
    assert glass.shift_stderr_nm < DEFAULT_TOLERANCE_NM / 2, glass
    assert line.shift_stderr_nm > 2 * DEFAULT_TOLERANCE_NM, line
    assert line.x_stderr_mm > 5 * glass.x_stderr_mm
    assert "predicted: this target can give x +-" in glass.summary()
    # one index per band: a glass with 11 absorption bands does not pin all 30 bands' to 1 %
    assert glass.n_eff_band_stderr.shape == (CWL.size,)
    assert np.max(glass.n_eff_band_stderr) > 0.01 * 1.7
    assert "above 1 %: one for the sensor" in glass.summary()


@pytest.mark.slow  # the coarse scan before the refusal: ~20 s of CPU
def test_a_straight_line_is_refused_before_the_fit_in_one_line():
    said = []
    with pytest.raises(ImpreciseTargetError, match=r"cannot pin x and n_eff to the shift "
                       r"precision asked: .* above the tolerance of 0.05 nm") as err:
        locate_pupil(cubes("line"), sensor(), lens=PAPER_LENS, fit_n_eff=True,
                     center_rc=CENTER[::-1], n_bins=48, tolerance_nm=DEFAULT_TOLERANCE_NM,
                     report=said.append)
    assert "\n" not in str(err.value)
    assert len(said) == 1 and said[0].startswith("predicted:")


def test_one_f_number_and_a_tolerance_that_is_not_a_number():
    with pytest.raises(ValueError, match="tolerance_nm must be > 0"):
        locate_pupil(cubes("glass", fs=(2.0,)), sensor(), lens=PAPER_LENS,
                     center_rc=CENTER[::-1], n_bins=48, tolerance_nm=float("nan"))
    one = predicted("glass", fs=(8.0,))
    assert one.n_eff_stderr is None and np.isfinite(one.x_stderr_mm)


@pytest.mark.slow  # a whole fit
def test_predicted_precision_is_what_the_fit_reports():
    """Predicted at the search's start, achieved by the fit on the same cubes."""
    got = locate_pupil(cubes("glass"), sensor(), lens=PAPER_LENS, fit_n_eff=True,
                       center_rc=CENTER[::-1], n_bins=48, tolerance_nm=DEFAULT_TOLERANCE_NM)
    p = got.predicted
    assert 0.7 < got.exit_pupil_stderr_mm / p.x_stderr_mm < 1.4, (got.exit_pupil_stderr_mm, p)
    assert 0.7 < got.n_eff_stderr[0] / p.n_eff_stderr < 1.4
    assert got.lens.calibration["predicted_before_fit"]["tolerance_nm"] == DEFAULT_TOLERANCE_NM


@pytest.mark.slow  # the measured curves' offset tables for two models: about a minute
def test_predict_for_a_sensor_with_measured_responses(tmp_path):
    import calibrate.pupil.test_measured_target as tpm
    from snapcorr.calibrate import pupil_precision
    from snapcorr.calibrate.pupil.precision import rare_earth_glass, white_tile

    path, _ = tpm.vendor_file(tmp_path)
    vendor = Sensor.load(path)
    assert vendor.responses is not None and vendor.n_eff is None
    glass = pupil_precision(rare_earth_glass, vendor, (1.4, 8.0), PAPER_LENS, noise=0.005,
                            fit_n_eff=True, n_bins=16)
    white = pupil_precision(white_tile, vendor, (1.4, 8.0), PAPER_LENS, noise=0.005,
                            fit_n_eff=True, n_bins=16)
    assert glass.informative and not white.informative
    # the fit on cubes of this sensor at 0.5 % reports 0.041-0.046 mm (16 annuli, a crop)
    assert 0.001 < glass.x_stderr_mm < 0.2
    with pytest.raises(ValueError, match="n_eff"):  # no index and none fitted: refused
        pupil_precision(rare_earth_glass, vendor, (8.0,), PAPER_LENS)



@pytest.mark.parametrize("x_mm", [1e-3, 1e6])
def test_a_lens_at_the_bounds_of_x_is_predicted(x_mm):
    """x = 1e-3 mm and 1e6 mm are a lens's: its bound is computed (a central difference about
    1e6 mm reached 1000010 mm and was refused as a lens's input)."""
    p = pupil_precision(sim.rare_earth_glass, sensor(), FS, Lens(x_mm), fit_n_eff=True)
    assert p.exit_pupil_mm == x_mm
    assert p.x_stderr_mm > 0 and p.n_eff_stderr > 0


def test_the_chart_is_judged_where_the_corner_shifts_the_bands():
    """Bands from 392 nm (FWHM 4 nm: responding from 382 nm) were judged by the chart's
    380-780 nm spectra at normal incidence; at the corner of a 1088 x 2048 sensor behind a
    21 mm exit pupil at f/1.4 the ray from the pupil's far rim tilts them to about 361 nm,
    where the chart says nothing. Recomputed here from a tilted filter's law, lambda * sqrt(1 -
    sin^2(phi) / n^2), phi that ray's angle: tan(phi) = (r + R) / x, R the pupil's radius."""
    import math

    from snapcorr import Lens
    from snapcorr.calibrate import OutsideChartError, colour_chart_precision
    from snapcorr.cube import Sensor

    lens = Lens(21.0, (), 0.0, 1.0)
    pitch_um, size, n = 5.5, (1088, 2048), 1.7
    blue = Sensor("blue", "snapscan", pitch_um, np.arange(392.0, 700.0, 20.0), 4.0, n,
                  size_px=size)
    r_mm = 0.5 * math.hypot(size[0] - 1, size[1] - 1) * pitch_um / 1000
    phi = math.atan((r_mm + lens.exit_pupil_radius_mm(1.4)) / 21.0)
    reach = 382.0 * math.sqrt(1 - math.sin(phi) ** 2 / n**2)
    assert reach < 380 and 350 < reach  # the case: inside at normal incidence, not at the corner
    with pytest.raises(OutsideChartError, match=rf"responds over 382-702 nm \({reach:.0f} nm "
                                                r"at the sensor's corner: its chief ray at "
                                                r"16\.9 deg and the f/1\.4 cone\)"):
        colour_chart_precision(blue, [1.4, 8.0], lens)
    # the same bands on a sensor small enough (64 x 64) that the corner keeps them above 380 nm
    small = Sensor("blue", "snapscan", pitch_um, np.arange(392.0, 700.0, 20.0), 4.0, n,
                   size_px=(64, 64))
    from snapcorr.calibrate.pupil import precision

    assert precision._beyond_the_chart(small, *precision._corner_scale(
        small, lens, [8.0], (64, 64), np.array([n]))[:1]) is None
