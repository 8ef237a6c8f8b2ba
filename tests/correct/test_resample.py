"""Resampling onto the nominal wavelengths (snapcorr.correct.resample): a cube's spectra,
block by block, are each pixel's interpolated alone."""

import numpy as np

from snapcorr.correct import resample_cube
from snapcorr.correct.resample import resample_to_nominal
from snapcorr.cube import make_cube


def test_a_cube_is_resampled_pixel_by_pixel_in_any_band_order_and_in_blocks():
    rng = np.random.default_rng(3)
    cwl = np.array([500.0, 540.0, 580.0, 620.0, 660.0])
    data = rng.random((5, 6, cwl.size)).astype(np.float32)
    scale = 1.0 - rng.uniform(0.0, 0.01, (5, 6, 1))
    column = np.zeros(cwl.size, int)
    out = resample_cube(make_cube(data, cwl), scale, column, cwl)
    assert out.dims == ("y", "x", "band") and out.dtype == np.float32
    want = resample_to_nominal(data, scale, column, cwl)
    assert np.array_equal(out.values, want, equal_nan=True)
    lam = cwl * scale[2, 3, 0]
    inside = cwl <= lam.max()
    np.testing.assert_allclose(out.values[2, 3][inside],
                               np.interp(cwl[inside], lam, data[2, 3]), rtol=1e-5)
    assert np.isnan(out.values[2, 3][~inside]).all()
    blocks = resample_cube(make_cube(data, cwl).chunk({"y": 2}), scale, column, cwl)
    assert blocks.chunks is not None and np.array_equal(blocks.values, want, equal_nan=True)
    perm = np.array([3, 0, 4, 1, 2])
    shuffled = resample_cube(make_cube(data[..., perm], cwl[perm]), scale, column, cwl[perm])
    assert np.array_equal(shuffled.values, want[..., perm], equal_nan=True)
