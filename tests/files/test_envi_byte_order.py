"""An ENVI header whose 'byte order' is the wrong one for its data is refused: read as stated,
a little-endian float32 cube came out as +-2.4e38 and a uint16 one as noise of tens of
thousands, without a word. Data whose header is right read whichever order they are in."""

from __future__ import annotations

import re

import numpy as np
import pytest

from snapcorr.cube import make_cube, read_cube

WL = np.linspace(450.0, 650.0, 8)


def _envi(path, values, order):
    """An ENVI pair written here (not by snapcorr): BSQ, ``order`` 0 or 1 stated, the data in
    the byte order ``values`` carry."""
    rows, cols, bands = values.shape
    dtype = {np.dtype("float32"): 4, np.dtype("uint16"): 12, np.dtype("int16"): 2,
             np.dtype("float64"): 5}[values.dtype.newbyteorder("=")]
    np.ascontiguousarray(values.transpose(2, 0, 1)).tofile(path.with_suffix(".img"))
    path.write_text(
        "ENVI\n"
        f"samples = {cols}\nlines = {rows}\nbands = {bands}\nheader offset = 0\n"
        f"file type = ENVI Standard\ndata type = {dtype}\ninterleave = bsq\n"
        f"byte order = {order}\nwavelength units = nm\n"
        "wavelength = {" + ", ".join(f"{w:g}" for w in WL) + "}\n")
    return path


def _cube(kind, rng):
    yy, xx = np.mgrid[0:40, 0:48]
    smooth = 0.3 + 0.2 * np.sin(yy / 9.0)[..., None] * np.cos(xx / 11.0)[..., None] \
        + 0.02 * np.arange(8)
    if kind == "reflectance":
        return (smooth + rng.normal(0, 0.01, smooth.shape)).astype("<f4")
    if kind == "counts":  # 12-bit counts under shot noise
        return np.round(3000 * smooth + rng.normal(0, 30, smooth.shape)).astype("<u2")
    return np.round(400 * (smooth - 0.4) + rng.normal(0, 3, smooth.shape)).astype("<i2")


@pytest.mark.parametrize("kind", ["reflectance", "counts", "signed"])
def test_a_header_stating_the_other_byte_order_is_refused(tmp_path, kind):
    values = _cube(kind, np.random.default_rng(0))
    hdr = _envi(tmp_path / "lie.hdr", values, order=1)  # the data are little-endian
    with pytest.raises(ValueError, match=re.escape("lie.hdr: its 'byte order' 1 (big-endian) "
                                                   "does not fit the data in lie.img")):
        read_cube(hdr)
    big = _envi(tmp_path / "big.hdr", values.astype(values.dtype.newbyteorder(">")), order=0)
    with pytest.raises(ValueError, match="'byte order' 0 \\(little-endian\\) does not fit"):
        read_cube(big)


@pytest.mark.parametrize("kind", ["reflectance", "counts", "signed"])
def test_data_in_either_byte_order_with_a_true_header_read(tmp_path, kind):
    values = _cube(kind, np.random.default_rng(1))
    little = read_cube(_envi(tmp_path / "le.hdr", values, order=0))
    big = read_cube(_envi(tmp_path / "be.hdr", values.astype(values.dtype.newbyteorder(">")),
                          order=1))
    np.testing.assert_array_equal(little.values, values)
    np.testing.assert_array_equal(big.values, values)


@pytest.mark.parametrize("values", [
    np.random.default_rng(2).integers(0, 65536, (40, 48, 8)).astype("<u2"),  # white noise
    np.full((40, 48, 8), 0x0101, "<u2"),  # the same either way
    np.random.default_rng(3).integers(0, 200, (40, 48, 8)).astype("<u2"),  # 8-bit values
    np.zeros((40, 48, 8), "<f4")], ids=["noise", "symmetric", "small", "zeros"])
def test_data_that_cannot_tell_the_order_are_read_as_stated(tmp_path, values):
    np.testing.assert_array_equal(read_cube(_envi(tmp_path / "c.hdr", values, 0)).values,
                                  values)


def test_snapcorrs_own_results_read_back(tmp_path):
    from snapcorr.cube import write_cube

    cube = make_cube(_cube("reflectance", np.random.default_rng(4)), WL)
    write_cube(cube, tmp_path / "r.hdr")
    np.testing.assert_array_equal(read_cube(tmp_path / "r.hdr").values, cube.values)


def test_values_in_the_high_byte_with_a_true_header_read(tmp_path):
    """8-bit values left-aligned in uint16 (v * 256): as stated they step by hundreds, read the
    other way by ones, yet the header is right; a low byte that never changes is not judged."""
    rng = np.random.default_rng(7)
    values = (np.clip(_cube("counts", rng) // 16, 0, 255).astype("<u2") * 256)
    np.testing.assert_array_equal(read_cube(_envi(tmp_path / "hi.hdr", values, 0)).values,
                                  values)
