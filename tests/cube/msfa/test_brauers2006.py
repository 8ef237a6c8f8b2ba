"""Weighted bilinear interpolation (Brauers & Aach 2006) called directly: the tent kernel's
convolution of each band's sparse samples, a linear ramp and a flat scene reproduced exactly,
and a missing sample kept out of every estimate."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.ndimage import convolve

from snapcorr.cube.msfa import weighted_bilinear

TILES = [(4, 4), (5, 5), (3, 4), (2, 3)]


def _bands(n, m, seed):
    """Each band's first sample row and column: the tile's positions in a shuffled order."""
    order = np.random.default_rng(seed).permutation(n * m)
    return order // m, order % m


def _tent(n, m):
    """The bilinear kernel of Brauers & Aach, (2n - 1) x (2m - 1): (1 - |i|/n)(1 - |j|/m)."""
    return np.outer(1 - np.abs(np.arange(1 - n, n)) / n, 1 - np.abs(np.arange(1 - m, m)) / m)


@pytest.mark.parametrize("tile", TILES)
def test_each_band_is_its_samples_convolved_with_the_tent_kernel(tile):
    n, m = tile
    y0, x0 = _bands(n, m, 1)
    frame = np.random.default_rng(2).uniform(0.1, 1.0, (7 * n + 2, 6 * m + 1))
    cube = weighted_bilinear(frame, y0, x0, n, m)
    inner = np.s_[n:-n, m:-m]
    for b in range(n * m):
        sparse = np.zeros_like(frame)
        sparse[y0[b]::n, x0[b]::m] = frame[y0[b]::n, x0[b]::m]
        expected = convolve(sparse, _tent(n, m), mode="constant")
        assert_allclose(cube[..., b][inner], expected[inner], rtol=0, atol=1e-12)
        assert_array_equal(cube[y0[b]::n, x0[b]::m, b], frame[y0[b]::n, x0[b]::m])


@pytest.mark.parametrize("tile", TILES)
def test_a_ramp_is_reproduced_between_the_samples_and_a_flat_scene_everywhere(tile):
    n, m = tile
    y0, x0 = _bands(n, m, 3)
    yy, xx = np.mgrid[0:5 * n + 3, 0:5 * m + 2]
    ramp = 0.5 + 0.01 * yy + 0.007 * xx
    cube = weighted_bilinear(ramp, y0, x0, n, m)
    inner = np.s_[n:-n, m:-m]
    assert_allclose(cube[inner], np.broadcast_to(ramp[..., None], cube.shape)[inner],
                    rtol=1e-13)
    flat = weighted_bilinear(np.full(ramp.shape, 0.3), y0, x0, n, m)
    assert_allclose(flat, 0.3, rtol=1e-14)


def test_a_missing_sample_is_left_out_and_stays_missing_unless_filled():
    n, m = 4, 4
    y0, x0 = _bands(n, m, 4)
    frame = np.full((6 * n, 6 * m), 2.0)
    hole = (y0[5] + 2 * n, x0[5] + 3 * m)
    frame[hole] = np.nan
    cube = weighted_bilinear(frame, y0, x0, n, m)
    missing = np.isnan(cube)
    assert missing[(*hole, 5)] and missing.sum() == 1
    assert_allclose(cube[~missing], 2.0, rtol=1e-14)
    assert_allclose(weighted_bilinear(frame, y0, x0, n, m, fill_missing=True), 2.0,
                    rtol=1e-14)
