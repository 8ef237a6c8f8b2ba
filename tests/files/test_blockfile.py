"""Raw files read in row blocks: the same values as numpy's own reading, in every layout."""

import numpy as np
import pytest

from snapcorr.files.blockfile import RowBlockFile, lazy_file_array

KEYS = [np.s_[:], np.s_[2:5], np.s_[::2, 1:3], np.s_[3], np.s_[[1, 4, 6], :, 2], np.s_[5:2],
        np.s_[-1], np.s_[1:6:2, ::-1]]


@pytest.mark.parametrize("dtype", [">u2", "<i4", "<f4", ">f8", "u1"])
@pytest.mark.parametrize("interleave, axes", [("bip", (0, 1, 2)), ("bil", (0, 2, 1)),
                                              ("bsq", (2, 0, 1))])
def test_blocks_equal_numpy_in_every_layout_and_byte_order(tmp_path, dtype, interleave, axes):
    rng = np.random.default_rng(0)
    cube = rng.integers(0, 200, (7, 5, 3)).astype(dtype)
    path = tmp_path / "c.raw"
    path.write_bytes(b"HEADER" + np.ascontiguousarray(cube.transpose(axes)).tobytes())
    f = RowBlockFile(path, dtype, cube.shape, offset=6, interleave=interleave)
    native = cube.astype(np.dtype(dtype).newbyteorder("="))
    for key in KEYS:
        got = f[key]
        np.testing.assert_array_equal(got, native[key])
        assert got.dtype.byteorder in ("=", "|")
    lazy = lazy_file_array(path, dtype, cube.shape, offset=6, interleave=interleave,
                           rows_per_block=3)
    assert lazy.chunks[0] == (3, 3, 1)
    np.testing.assert_array_equal(lazy.compute(), native)


def test_a_short_file_is_an_error_not_garbage(tmp_path):
    path = tmp_path / "c.raw"
    path.write_bytes(np.zeros(10, np.uint16).tobytes())
    with pytest.raises(OSError, match="ends early"):
        RowBlockFile(path, np.uint16, (4, 2, 2))[:]
