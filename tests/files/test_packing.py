"""uint16 CF packing in one pass (snapcorr.files._packing), against the formula written out
with numpy in the test."""

import numpy as np
import pytest

from snapcorr.files._packing import pack_uint16


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_codes_are_the_rounded_clipped_formula_and_nan_is_the_fill(dtype):
    rng = np.random.default_rng(3)
    offset, scale, top, fill = np.float32(-0.5), np.float32(4.0 / 65534), 65534, 65535
    v = rng.uniform(-1.0, 4.0, (7, 9, 3)).astype(dtype)
    v[0, 0, 0], v[1, 2, 1] = np.nan, offset + scale * dtype(2.5)  # NaN and a half step
    t = np.dtype(dtype).type
    want = np.rint(np.clip((v - t(offset)) / t(scale), 0, top))
    want = np.where(np.isnan(v), fill, np.nan_to_num(want)).astype(np.uint16)
    got = pack_uint16(v, offset, scale, top, fill)
    assert got.shape == v.shape and got.dtype == np.uint16
    np.testing.assert_array_equal(got, want)
    assert got[0, 0, 0] == fill and got.max() <= fill
