"""The exit-pupil fit's input stage: the target's cubes checked, its spectrum, the optical
centre found from the cubes, and the block means behind it.

The centre is found in images made here as a function of each pixel's own distance from a
chosen centre; the block means are checked against the mean of each block taken one at a time.
"""

import warnings

import numpy as np
import pytest
from conftest import PAPER_LENS

from calibrate.pupil.test_precision import CWL, SHAPE, cubes, sensor
from snapcorr.calibrate import locate_pupil
from snapcorr.calibrate.pupil.precision import DEFAULT_TOLERANCE_NM
from snapcorr.calibrate.pupil.target import (
    N_EFF_START,
    FeaturelessTargetError,
    _block_mean,
    _spectrum,
    check_modelled,
    estimate_target_center,
    estimate_target_center_rc,
)
from snapcorr.cube import Sensor, make_cube


def test_a_cube_of_nan_is_refused_naming_it():
    data = cubes("glass", fs=(2.0,))
    data[8.0] = make_cube(np.full((*SHAPE, CWL.size), np.nan), CWL)
    with pytest.raises(ValueError, match=r"the f/8 cube has no finite value"):
        locate_pupil(data, sensor(), lens=PAPER_LENS, fit_n_eff=True,
                     tolerance_nm=DEFAULT_TOLERANCE_NM)


def _radial_cube(center_xy, shape=(72, 96), n_bands=6, noise=0.005, seed=0):
    """Band images that depend on each pixel's distance from ``center_xy`` (column, row)
    only: a ring pattern of its own period in every band, plus noise."""
    rng = np.random.default_rng(seed)
    r, c = np.mgrid[:shape[0], :shape[1]].astype(float)
    d2 = (r - center_xy[1]) ** 2 + (c - center_xy[0]) ** 2
    scale = d2.max()
    return np.stack([1.0 + 0.2 * np.cos((3 + b) * d2 / scale) + rng.normal(0.0, noise, shape)
                     for b in range(n_bands)])


def test_the_centre_of_a_radial_pattern_is_found_within_its_errors():
    truth = (51.3, 33.8)  # (column, row), off the middle of the image
    imgs = _radial_cube(truth)
    rows = np.arange(imgs.shape[1], dtype=float)[:, None]
    cols = np.arange(imgs.shape[2], dtype=float)[:, None]
    (cy, cx), (sy, sx) = estimate_target_center_rc(lambda b: imgs[b], imgs.shape[0], rows,
                                                   cols)
    assert abs(cx - truth[0]) < 0.2 and abs(cy - truth[1]) < 0.2
    assert abs(cx - truth[0]) < 5 * sx and abs(cy - truth[1]) < 5 * sy
    assert 0 < sx < 0.2 and 0 < sy < 0.2


def test_a_crop_finds_the_centre_in_sensor_pixels():
    """The cube's positions say where it sits: the centre comes out in the sensor's pixels."""
    truth = (51.3, 33.8)
    imgs = _radial_cube(truth)[:, 10:, 20:]
    rows = np.arange(10, 72, dtype=float)[:, None]
    cols = np.arange(20, 96, dtype=float)[:, None]
    (cy, cx), _ = estimate_target_center_rc(lambda b: imgs[b], imgs.shape[0], rows, cols)
    assert abs(cx - truth[0]) < 0.3 and abs(cy - truth[1]) < 0.3


def test_the_centre_is_given_row_first_and_its_x_first_form_warns():
    """estimate_target_center_rc gives (row, col) and their errors in that order; the x-first
    estimate_target_center of 0.1 gives the same numbers swapped, start included, and warns."""
    row, col = 37.25, 81.5  # off both middles of a frame wider than tall
    imgs = _radial_cube((col, row), shape=(64, 112))
    rows = np.arange(64, dtype=float)[:, None]
    cols = np.arange(112, dtype=float)[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (r, c), (sr, sc) = estimate_target_center_rc(lambda b: imgs[b], imgs.shape[0], rows,
                                                     cols, start_rc=(30.0, 70.0))
    assert abs(r - row) < 0.2 and abs(c - col) < 0.2
    assert abs(r - row) < 5 * sr and abs(c - col) < 5 * sc and 0 < sr < 0.2 and 0 < sc < 0.2
    with pytest.warns(FutureWarning, match="estimate_target_center gives the optical centre x "
                                           "first, .* use estimate_target_center_rc"):
        old = estimate_target_center(lambda b: imgs[b], imgs.shape[0], rows, cols,
                                     start=(70.0, 30.0))
    assert old == ((c, r), (sc, sr))


def test_block_means_are_each_blocks_own_mean_and_skip_masked_pixels():
    rng = np.random.default_rng(1)
    img = rng.normal(size=(13, 18))
    img[rng.random(img.shape) < 0.2] = np.nan
    img[:4, :4] = np.nan  # one block without a finite pixel
    got = _block_mean(img, 4)
    assert got.shape == (3, 4)  # the partial blocks at the edges left out
    for i in range(3):
        for j in range(4):
            block = img[4 * i:4 * i + 4, 4 * j:4 * j + 4]
            if np.isfinite(block).any():
                assert got[i, j] == pytest.approx(np.mean(block[np.isfinite(block)]))
            else:
                assert np.isnan(got[i, j])


def _sensor(n_eff=1.7):
    return Sensor("test", "snapscan", 44.0, CWL, 12.0, n_eff)


def test_a_tabulated_spectrum_is_interpolated_and_a_flat_one_refused():
    wl = np.linspace(450.0, 900.0, 46)
    val = 0.5 + 0.3 * np.sin(wl / 30.0)
    spectrum, said = _spectrum((wl, val), _sensor())
    lam = np.linspace(470.0, 880.0, 101)
    np.testing.assert_allclose(spectrum(lam), np.interp(lam, wl, val), rtol=1e-12)
    assert "46 points" in said
    with pytest.raises(FeaturelessTargetError, match="constant"):
        _spectrum((wl, np.full(wl.size, 0.4)), _sensor())
    with pytest.raises(ValueError, match="the bands need"):  # the reddest bands not covered
        _spectrum((wl[:30], val[:30]), _sensor())
    assert _spectrum(None, _sensor())[0] is None


def test_the_index_comes_from_the_sensor_or_the_fits_start():
    np.testing.assert_array_equal(check_modelled(_sensor(1.85), "the fit"),
                                  np.full(CWL.size, 1.85))
    no_index = _sensor(None)
    np.testing.assert_array_equal(check_modelled(no_index, "the fit", fit_n_eff=True),
                                  np.full(CWL.size, N_EFF_START))
    with pytest.raises(ValueError, match="n_eff"):
        check_modelled(no_index, "the fit")


def test_the_centre_errors_cover_its_scatter_over_noise_draws():
    """At a low signal to noise (a colour filter's spread over a 64 x 80 crop, 0.04, under
    noise of 0.1 a pixel) the centre's scatter over noise draws runs several times the errors
    of the fit's Jacobian alone (RMS of (found - true) / error 3.4 in the row, 3.9 in the
    column over these 16 draws); the errors reported cover it (within 0.5-2). The cube comes
    from ``tests/oracles/spectralsim.py``, which shares no code with snapcorr."""
    import spectralsim as sim
    from flatsim import LensTruth

    col, row = 41.3, 30.7
    cwl = np.arange(500.0, 849.0, 12.0)
    clean = sim.target_cube(sim.colour_filter, cwl_nm=cwl, fwhm_nm=12.0, n_eff=1.7,
                            f_number=2.0, lens=LensTruth(16.0, (), 0.0, 1.0), shape=(64, 80),
                            pixel_pitch_um=44.0, center_px=(col, row))
    rows = np.arange(64, dtype=float)[:, None]
    cols = np.arange(80, dtype=float)[:, None]
    z = []
    for seed in range(16):
        data = clean + np.random.default_rng(seed).normal(0.0, 0.1, clean.shape)
        (r, c), (sr, sc) = estimate_target_center_rc(lambda b, d=data: d[:, :, b], cwl.size,
                                                     rows, cols)
        z.append(((r - row) / sr, (c - col) / sc))
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((rms > 0.5) & (rms < 2.0)), rms
