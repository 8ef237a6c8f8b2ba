"""``harmonised`` in a correction's result (snapcorr.correct.harmonised): in blocks, for a
mosaic, for bands listed out of order, and the common response asked for."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, make_cube

from .test_harmonise import CWL, PAPER, PITCH, as_lens


def test_blocks_give_identical_values_and_the_target_is_checked():
    sensor = Sensor("t", "snapscan", PITCH, CWL, 12.0, 1.8)
    data = np.random.default_rng(2).random((24, 40, CWL.size)).astype(np.float32)
    cube = make_cube(data, CWL)
    lens = as_lens(PAPER)
    a = correct_cube(cube, sensor, 1.4, lens, harmonise=True, center_px=(3.0, 2.0))
    b = correct_cube(cube.chunk({"y": 7, "x": 9}), sensor, 1.4, lens, harmonise=True,
                     center_px=(3.0, 2.0))
    xr.testing.assert_identical(a["harmonised"], b["harmonised"].compute())
    widest = float(a["fwhm_harmonised"].max())
    wide = correct_cube(cube, sensor, 1.4, lens, harmonise=True, center_px=(3.0, 2.0),
                        target_fwhm_nm=widest + 2.0)
    assert np.all(wide["fwhm_harmonised"].values == widest + 2.0)
    assert "asked for" in wide["harmonised"].attrs["common_response"]
    with pytest.raises(ValueError, match="only widens"):
        correct_cube(cube, sensor, 1.4, lens, harmonise=True, center_px=(3.0, 2.0),
                     target_fwhm_nm=12.0)
    with pytest.raises(ValueError, match="harmonise=True"):
        correct_cube(cube, sensor, 1.4, lens, target_fwhm_nm=20.0)


def test_a_mosaic_is_harmonised_band_by_band():
    from snapcorr.cube import mosaic_to_cube
    from snapcorr.data import sensor_path

    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    cube = mosaic_to_cube(np.ones((64, 96), np.float32), sensor, sensor_origin_px=(400, 800))
    ds = correct_cube(cube, sensor, 1.4, as_lens(PAPER), center_px=(0.0, 0.0),
                      harmonise=True, resample=True)
    h = ds["harmonised"].values
    # a flat spectrum stays flat: the weights of every output sum to one
    assert np.allclose(h[np.isfinite(h)], 1.0, atol=1e-5)
    np.testing.assert_array_equal(np.isnan(h), np.isnan(ds["resampled"].values))


def test_bands_listed_out_of_order_give_the_same_spectra():
    """A sensor may list its bands in any order (a mosaic's tile order): the result is the
    ordered one's, band for band."""
    cwl = np.linspace(500.0, 880.0, 20)
    perm = np.random.default_rng(4).permutation(cwl.size)
    data = np.random.default_rng(5).random((12, 20, cwl.size)).astype(np.float32)
    lens = as_lens(PAPER)
    ref = correct_cube(make_cube(data, cwl), Sensor("a", "snapscan", PITCH, cwl, 12.0,
                                                          1.8), 1.4, lens, harmonise=True,
                       center_px=(1.0, 2.0))
    got = correct_cube(make_cube(data[..., perm], cwl[perm]),
                       Sensor("b", "snapscan", PITCH, cwl[perm], 12.0, 1.8), 1.4, lens,
                       harmonise=True, center_px=(1.0, 2.0))
    np.testing.assert_array_equal(got["harmonised"].values, ref["harmonised"].values[..., perm])
    np.testing.assert_array_equal(got["fwhm_harmonised"].values,
                                  ref["fwhm_harmonised"].values[perm])
