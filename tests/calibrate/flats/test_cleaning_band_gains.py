"""The lens from raw flats of a snapshot mosaic: each band's gain is the layout's, not noise.

The flats come from the independent simulator (``flatsim``: the paper's lens behind an
integrating sphere), multiplied here by a gain per tile position placed by this file's own
reading of the layout (bands in row-major order from the filter area's corner), with shot and
read noise added afterwards. The quarter scene (256 x 320 px of 28.4 um) spans the angles of
a 1024 x 1280 sensor of 7.1 um.
"""

import numpy as np
import pytest
from conftest import PAPER_TRUTH
from flatsim import make_flats, shot_noise_frames, tile_gains

from snapcorr.calibrate import calibrate_lens, noise_model, remove_band_gains
from snapcorr.cube import Sensor

SHAPE, PITCH, CENTER = (256, 320), 28.4, (174.75, 119.75)  # CENTER: (x, y) for flatsim
F_NUMBERS = (2.0, 2.8, 4.0, 5.6, 11.0)
TILE = 4
#: The 16 band gains, 0.25-1.0, in an order that is not the bands' (row-major in the tile).
GAINS = np.random.default_rng(5).permutation(np.linspace(0.25, 1.0, TILE * TILE))
#: The crop: 256 x 320 px at sensor row 5, column 7 of a larger sensor whose filters cover
#: rows 8-287 and columns 1-320: the crop's first 3 rows and last 6 columns carry none.
CROP_ORIGIN, CROP_AREA, CROP_SENSOR = (5, 7), (8, 1, 280, 320), (300, 400)
ELECTRONS_PER_DN, READ_DN, LEVEL_DN = 2.0, 3.0, 30000.0


def _sensor(size_px, filter_area_px=None):
    bands = TILE * TILE
    return Sensor("raw mosaic 4x4", "mosaic", PITCH, tuple(500.0 + 10 * np.arange(bands)),
                  10.0, 1.7, mosaic_shape=(TILE, TILE),
                  band_offset=tuple((b // TILE, b % TILE) for b in range(bands)),
                  size_px=size_px, filter_area_px=filter_area_px)


def _pattern(origin=(0, 0), area=None):
    """The gain of every pixel of a frame at ``origin`` (sensor row, column), bands in
    row-major order; outside the filter area ``area`` no filter (gain 1.6: brighter)."""
    return tile_gains(SHAPE, GAINS.reshape(TILE, TILE), origin, area, unfiltered_gain=1.6)


@pytest.fixture(scope="module")
def light():
    """The light on each pixel (DN at gain 1), without noise, per f-number."""
    _, clean, _ = make_flats(PAPER_TRUTH, F_NUMBERS, shape=SHAPE, pitch_um=PITCH,
                             center_px=CENTER, noise=0.0, seed=1, integer=False,
                             return_truth_maps=True)
    return {f: img * (LEVEL_DN / 45000.0) for f, img in clean.items()}


def _raw(light, pattern):
    """Raw frames: the light times the gains, shot and read noise, whole DN."""
    return shot_noise_frames(light, pattern, ELECTRONS_PER_DN, READ_DN)


def _calibrate(flats, **kw):
    t = PAPER_TRUTH
    return calibrate_lens(flats, exit_pupil_mm=t.exit_pupil_mm, pixel_pitch_um=PITCH,
                          magnification=t.magnification,
                          pupil_magnification=t.pupil_magnification, max_circles=1,
                          method="joint", **kw)


def _worst_shift_error(res):
    return float(np.max(res.shift_stderr_nm))


def _check_lens(res):
    (P, h), = res.lens.vignetting
    (P_true, h_true), = PAPER_TRUTH.circles
    assert abs(P / P_true - 1) < 0.01 and abs(h / h_true - 1) < 0.01, (P, h)


@pytest.fixture(scope="module")
def without_pattern(light):
    """The same light and noise on a sensor without a tile pattern."""
    return _calibrate(_raw(light, 1.0))


def test_band_gains_are_found_and_divided_out_at_every_f_number(light):
    """Whole sensor and a crop off the tile grid: the gains (relative to their mean) to 0.3 %,
    the flat left smooth (the tile pattern gone to the noise), no filter: NaN."""
    truth = GAINS / GAINS.mean()
    for sensor, origin, area in ((_sensor(SHAPE), None, None),
                                 (_sensor(CROP_SENSOR, CROP_AREA), CROP_ORIGIN, CROP_AREA)):
        pattern = _pattern(origin or (0, 0), area)
        raw = _raw(light, pattern)
        for f in (2.0, 11.0):  # the most and the least vignetted (and 30 times darker)
            flat, gains = remove_band_gains(raw[f], sensor, origin_px=origin)
            assert np.max(np.abs(gains / truth - 1)) < 0.003, (f, origin)
            lit = np.isfinite(flat) & (light[f] > 0.5 * light[f].max())
            # every band's pixels now say the same of the light: the pattern is gone
            per_band = [np.median(flat[lit & (pattern == g)] / light[f][lit & (pattern == g)])
                        for g in GAINS]
            assert np.max(np.abs(np.array(per_band) / GAINS.mean() - 1)) < 0.003, f
        if area is not None:  # no filter: not used
            assert np.isnan(flat[:3]).all() and np.isnan(flat[:, -6:]).all()
            assert np.isfinite(flat[3:, :-6]).mean() > 0.999


@pytest.mark.slow  # two calibrations, about 15 s; the default suite: the gains above, and
# test_cli_calibrate.py's raw mosaic flats (P and h within 1 %)
def test_raw_mosaic_flats_calibrate_as_flats_without_the_pattern(light, without_pattern):
    """Whole sensor: P and h within 1 %, and the mean shift pinned within 1.5 times as well as
    the same flats without the pattern (measured 1.34-1.36 over three seeds: the weak bands'
    fewer electrons, averaged unweighted in the fit's blocks, cost sqrt(mean(1 / g)))."""
    res = _calibrate(_raw(light, _pattern()), sensor=_sensor(SHAPE))
    _check_lens(without_pattern)
    _check_lens(res)
    ratio = _worst_shift_error(res) / _worst_shift_error(without_pattern)
    assert ratio < 1.5, ratio
    gains = res.lens.calibration["band_gains"]
    assert gains["removed"] and gains["sensor"] == "raw mosaic 4x4"
    assert gains["sensor_origin_rc"] == "whole sensor" and sorted(gains["gains"]) == sorted(
        f"f/{f:g}" for f in F_NUMBERS)
    assert np.allclose(gains["gains"]["f/2"], GAINS / GAINS.mean(), rtol=0.003)


@pytest.mark.slow
def test_a_crop_off_the_tile_grid_calibrates_as_well(light, without_pattern):
    """A crop at row 5, column 7 of a sensor whose filters start at row 8, column 1 (and
    brighter unfiltered pixels outside them): the layout follows the origin (the error 1.41-1.43
    times the pattern-free flats' over three seeds: the unfiltered rim is not used)."""
    res = _calibrate(_raw(light, _pattern(CROP_ORIGIN, CROP_AREA)),
                     sensor=_sensor(CROP_SENSOR, CROP_AREA), sensor_origin_px=CROP_ORIGIN)
    _check_lens(res)
    assert _worst_shift_error(res) / _worst_shift_error(without_pattern) < 1.5
    assert res.lens.calibration["band_gains"]["sensor_origin_rc"] == list(CROP_ORIGIN)
    # the centre, measured on the crop, is placed on the sensor by the origin it records
    from snapcorr.correct.geometry import optical_center_rc
    from snapcorr.cube import make_cube

    sensor = _sensor(CROP_SENSOR, CROP_AREA)
    cube = make_cube(np.ones((*CROP_SENSOR, 1)), [500.0])
    (row, col), _ = optical_center_rc(cube, sensor, res.lens)
    assert abs(row - (CENTER[1] + CROP_ORIGIN[0])) < 0.5
    assert abs(col - (CENTER[0] + CROP_ORIGIN[1])) < 0.5


def test_a_crop_without_a_tile_pattern_records_its_origin(light):
    """Flats that are a crop of a sensor without a tile pattern (a Snapscan camera's region
    of interest) at ``sensor_origin_px``: the profile records the origin, and the centre found
    on the crop is placed on a 300 x 400 px sensor by it (by hand: the crop's centre plus the
    origin); an origin that is not two whole numbers >= 0 is refused before any fit."""
    from snapcorr.correct.geometry import optical_center_rc
    from snapcorr.cube import make_cube

    res = _calibrate(_raw(light, 1.0), sensor_origin_px=CROP_ORIGIN)
    _check_lens(res)
    assert res.lens.calibration["sensor_origin_rc"] == list(CROP_ORIGIN)
    assert "band_gains" not in res.lens.calibration
    scan = Sensor("scan", "snapscan", PITCH, (500.0,), 10.0, 1.7, size_px=CROP_SENSOR)
    (row, col), source = optical_center_rc(make_cube(np.ones((*SHAPE, 1)), [500.0]), scan,
                                           res.lens)
    assert abs(row - (CENTER[1] + CROP_ORIGIN[0])) < 0.5, row
    assert abs(col - (CENTER[0] + CROP_ORIGIN[1])) < 0.5, col
    assert "cropped at sensor row 5, column 7" in source
    flats = _raw(light, 1.0)
    for bad in ((-1, 0), (1.5, 2), (1, 2, 3)):
        with pytest.raises(ValueError, match="sensor_origin_px"):
            _calibrate(flats, sensor_origin_px=bad)


def test_sensor_mistakes_are_value_errors(light):
    raw = _raw(light, _pattern())[11.0]
    with pytest.raises(ValueError, match="is not a mosaic"):
        _calibrate({2.0: raw, 11.0: raw}, sensor=Sensor("scan", "snapscan", PITCH, (500.0,),
                                                        10.0, 1.7))
    with pytest.raises(ValueError, match="f/2: the frame is 256 x 320 px but the sensor"):
        _calibrate({2.0: raw, 11.0: raw}, sensor=_sensor(CROP_SENSOR, CROP_AREA))
    with pytest.raises(TypeError, match="must be a Sensor"):
        remove_band_gains(raw, "mosaic_4x4_vis")
    # without the sensor the flats repeat the tile's gains: the error says why
    with pytest.raises(ValueError, match=r"repeats a 4 x 4 pattern of pixel gains .* raw "
                                         "frames of a snapshot mosaic; give its sensor"):
        _calibrate({2.0: raw, 11.0: raw})


def test_noise_of_a_flat_with_its_band_gains_divided_out():
    """The raw frame's photon-transfer curve (read noise 3 DN, 2 e-/DN) measured in a flat
    whose band gains (0.25-1.0) were divided out: a pixel of gain g has variance
    ``a / g^2 + b signal / g + c signal^2``, within 8 % of the truth for every band from 2000
    to 20000 DN (as the curve of a flat without gains: the read noise is lost under the shot
    noise). Without the gains the curve is an average over the bands, far too low for the
    weakest."""
    rng = np.random.default_rng(3)
    gain = tile_gains((512, 512), GAINS.reshape(TILE, TILE))
    yy, xx = np.mgrid[:512, :512]
    light = 2000.0 + 20000.0 * np.exp(-((xx - 300) ** 2 + (yy - 200) ** 2) / 300.0**2)
    raw = rng.poisson(light * gain * 2.0) / 2.0 + 3.0 * rng.standard_normal(light.shape)
    flat = raw / gain
    ok = np.ones(flat.shape, bool)
    a, b, c = noise_model(flat, ok, gain=gain)
    level, g = np.array([2000.0, 20000.0])[:, None], GAINS[None, :]
    truth = 9.0 / g**2 + 0.5 * level / g
    assert np.max(np.abs((a / g**2 + b * level / g + c * level**2) / truth - 1)) < 0.08
    a, b, c = noise_model(flat, ok)
    assert np.max(truth / (a + b * level + c * level**2)) > 2.0


