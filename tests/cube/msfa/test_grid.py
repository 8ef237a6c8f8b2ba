"""The compiled building blocks of the demosaicking methods: each band's sub-grid of samples
against plain slicing, and the interpolation (alone, plus a base, or a base times a gain plus
an offset) against the tent kernel's convolution written here."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.ndimage import convolve

from snapcorr.cube.msfa._grid import bilinear_at, interpolate, sub_grids


def _bands(n, m, seed):
    """Each band's first sample row and column: the tile's positions in a shuffled order."""
    order = np.random.default_rng(seed).permutation(n * m)
    return order // m, order % m


def _tent(n, m):
    """The bilinear kernel, (2n - 1) x (2m - 1): (1 - |i|/n)(1 - |j|/m)."""
    return np.outer(1 - np.abs(np.arange(1 - n, n)) / n, 1 - np.abs(np.arange(1 - m, m)) / m)


def _spread(values, y0, x0, n, m, shape):
    """A band's values at its samples put back on the frame, zero elsewhere."""
    out = np.zeros(shape)
    gy, gx = len(range(y0, shape[0], n)), len(range(x0, shape[1], m))
    out[y0::n, x0::m] = values[:gy, :gx]
    return out


def test_the_sub_grids_are_the_bands_slices_padded_with_nan():
    n, m = 3, 4
    y0, x0 = _bands(n, m, 1)
    frame = np.arange(10 * 11, dtype=float).reshape(10, 11)
    grids = sub_grids(frame, y0, x0, n, m)
    assert grids.shape == (n * m, 4, 3)
    for b in range(n * m):
        s = frame[y0[b]::n, x0[b]::m]
        assert_array_equal(grids[b, :s.shape[0], :s.shape[1]], s)
        assert np.isnan(grids[b, s.shape[0]:]).all() and np.isnan(grids[b, :, s.shape[1]:]).all()


@pytest.mark.parametrize("mode", ["alone", "plus base", "base times gain"])
def test_interpolation_is_the_tent_kernels_convolution(mode):
    n, m = 4, 3
    y0, x0 = _bands(n, m, 2)
    rng = np.random.default_rng(3)
    shape = (6 * n + 1, 7 * m + 2)
    frame = rng.uniform(0.1, 1.0, shape)
    grids = rng.uniform(-1.0, 1.0, sub_grids(frame, y0, x0, n, m).shape)
    base = rng.uniform(0.5, 2.0, shape) if mode != "alone" else None
    gain = rng.uniform(0.5, 2.0, grids.shape) if mode == "base times gain" else None
    out = interpolate(grids, frame, y0, x0, n, m, np.empty((*shape, n * m)), base=base,
                      gain=gain)
    inner = np.s_[n:-n, m:-m]
    k = _tent(n, m)
    for b in range(n * m):
        expected = convolve(_spread(grids[b], y0[b], x0[b], n, m, shape), k, mode="constant")
        if base is not None:
            g = (1.0 if gain is None else
                 convolve(_spread(gain[b], y0[b], x0[b], n, m, shape), k, mode="constant"))
            expected = base * g + expected
        own = np.zeros(shape, bool)
        own[y0[b]::n, x0[b]::m] = True
        assert_allclose(out[..., b][inner][~own[inner]],
                        expected[inner][~own[inner]], rtol=0, atol=1e-12)
        assert_array_equal(out[y0[b]::n, x0[b]::m, b], frame[y0[b]::n, x0[b]::m])


def test_bilinear_at_leaves_out_missing_samples_and_reaches_one_ring_further():
    grid = np.array([[1.0, 2.0, 4.0], [8.0, np.nan, 16.0], [32.0, 64.0, 128.0]])
    n = m = 4
    # a quarter of the way from sample (0, 0) to (1, 1): weights 9/16, 3/16, 3/16, 1/16
    assert bilinear_at(grid, 1, 1, 0, 0, n, m) == pytest.approx(
        (9 * 1.0 + 3 * 2.0 + 3 * 8.0) / 15)
    # at the missing sample itself: the twelve around it by inverse squared distance
    ring = [(i, j) for i in range(3) for j in range(3) if (i, j) != (1, 1)]
    w = np.array([1.0 / ((1 - i) ** 2 + (1 - j) ** 2) for i, j in ring])
    v = np.array([grid[i, j] for i, j in ring])
    assert bilinear_at(grid, 4, 4, 0, 0, n, m) == pytest.approx(np.sum(w * v) / np.sum(w))
    assert np.isnan(bilinear_at(np.full((3, 3), np.nan), 4, 4, 0, 0, n, m))
