"""Tile replication called directly: every pixel takes each band's sample of the tile-sized
window holding it, worked out here by index arithmetic."""

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from snapcorr.cube.msfa import tile_replication


def _bands(n, m, seed):
    """Each band's first sample row and column: the tile's positions in a shuffled order."""
    order = np.random.default_rng(seed).permutation(n * m)
    return order // m, order % m


@pytest.mark.parametrize("tile", [(4, 4), (5, 5), (3, 4), (2, 3)])
def test_each_pixel_takes_the_sample_at_or_before_it(tile):
    """Along each axis the band's sample at or before the pixel, the next one where there is
    none before it; where the one before lies past the frame's far edge (none here), the
    frame ends."""
    n, m = tile
    y0, x0 = _bands(n, m, 5)
    shape = (5 * n + 2, 6 * m + 1)
    frame = np.random.default_rng(6).uniform(0.1, 1.0, shape)
    cube = tile_replication(frame, y0, x0, n, m)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    for b in range(n * m):
        sy = y0[b] + (yy - y0[b]) // n * n
        sx = x0[b] + (xx - x0[b]) // m * m
        sy[sy < 0] += n
        sx[sx < 0] += m
        inside = (sy < shape[0]) & (sx < shape[1])
        assert_array_equal(cube[..., b][inside], frame[sy[inside], sx[inside]])
        assert np.isfinite(cube[..., b]).all()


def test_a_missing_sample_takes_the_next_one_only_when_filled():
    n, m = 3, 4
    y0, x0 = _bands(n, m, 7)
    frame = np.arange(6 * n * 6 * m, dtype=float).reshape(6 * n, 6 * m)
    hole = (y0[2] + 2 * n, x0[2] + 3 * m)
    frame[hole] = np.nan
    kept = tile_replication(frame, y0, x0, n, m)
    filled = tile_replication(frame, y0, x0, n, m, fill_missing=True)
    # the tile's other pixels take the next sample below, missing or not
    below = frame[hole[0] + n, hole[1]]
    assert np.isnan(kept[(*hole, 2)]) and filled[(*hole, 2)] == below
    assert np.isnan(kept[..., 2]).sum() == 1 and np.isfinite(filled).all()
