"""The pseudo-panchromatic image (PPI) and PPID of Mihoubi et al. 2017 against brute-force
versions of the paper's equations, written out pixel by pixel here."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from snapcorr.cube.msfa import mihoubi2017, ppid, pseudo_panchromatic


def _textured(shape, seed):
    """A frame with structure at several scales and a sharp edge, positive."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    base = 0.6 + 0.3 * np.sin(yy / 3.0 + 0.5) * np.cos(xx / 4.0) + 0.2 * (xx > shape[1] // 2)
    return base + 0.1 * rng.random(shape)


def _m_taps(n):
    """Mihoubi et al. 2017, Eq. (23): every band weighs 1/n along a tile side."""
    return np.full(n, 1.0 / n) if n % 2 else np.r_[0.5, np.ones(n - 1), 0.5] / n


def brute_average(frame, n, m):
    """Eq. (24), pixel by pixel: the kernel M's weighted mean over the values that exist in
    the frame (weights renormalised at the edges and around missing values)."""
    kernel = np.outer(_m_taps(n), _m_taps(m))
    hn, hm = kernel.shape[0] // 2, kernel.shape[1] // 2
    padded = np.pad(frame, ((hn, hn), (hm, hm)), constant_values=np.nan)
    out = np.full(frame.shape, np.nan)
    for y, x in np.ndindex(frame.shape):
        window = padded[y:y + 2 * hn + 1, x:x + 2 * hm + 1]
        ok = np.isfinite(window)
        if ok.any():
            out[y, x] = np.sum(kernel[ok] * window[ok]) / np.sum(kernel[ok])
    return out


def brute_ppi(frame, n, m, eps_fraction=mihoubi2017.EPS_FRACTION):
    """Eq. (25-28), pixel by pixel, as the module documents them: ``I(p)`` plus the weighted
    mean over the eight same-band neighbours ``q = p + step`` of ``PPI0(q) - I(q)``, weights
    ``1 / (eps + sum (2 - u)(2 - |v|) |I(a) - I(a + step)|)`` over ``a = p + u dir + v perp``,
    pairs beyond the frame or missing left out, and the ``u = 1`` pairs where the end of their
    middle pair away from ``p`` lies beyond the frame."""
    rough = brute_average(frame, n, m)
    rows, cols = frame.shape

    def value(y, x):
        return frame[y, x] if 0 <= y < rows and 0 <= x < cols else np.nan

    out = np.empty_like(rough)
    for y in range(rows):
        for x in range(cols):
            if not np.isfinite(frame[y, x]):
                out[y, x] = rough[y, x]
                continue
            eps = eps_fraction * abs(rough[y, x])
            num = den = 0.0
            for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
                perp = (dj, -di)
                for sign in (1, -1):
                    sy, sx = sign * di, sign * dj
                    qy, qx = y + sy * n, x + sx * m
                    if not np.isfinite(value(qy, qx)) or not np.isfinite(rough[qy, qx]):
                        continue
                    g = eps
                    for u in (0, 1):
                        # the u = 1 pairs count where their middle pair's end away from
                        # p lies in the frame (p + dir, or p - dir - step)
                        back = (1 - sign) // 2
                        ey, ex = y + sy - back * di * n, x + sx - back * dj * m
                        if u and not (0 <= ey < rows and 0 <= ex < cols):
                            continue
                        for v in (-1, 0, 1):
                            ay, ax = y + u * sy + v * perp[0], x + u * sx + v * perp[1]
                            d = abs(value(ay, ax) - value(ay + sy * n, ax + sx * m))
                            if np.isfinite(d):
                                g += (2 - u) * (2 - abs(v)) * d
                    num += (rough[qy, qx] - frame[qy, qx]) / g
                    den += 1 / g
            out[y, x] = frame[y, x] + num / den if den > 0 else rough[y, x]
    return out


@pytest.mark.parametrize("tile", [(4, 4), (5, 5), (3, 4), (2, 3)])
def test_the_first_stage_of_the_ppi_is_mihoubis_average(tile):
    """Eq. (23-24): the tile-wide kernel M ([1/2, 1, ..., 1, 1/2] / n for even n, 1/n for odd),
    everywhere, edges and missing values included."""
    n, m = tile
    frame = _textured((27, 29), 1)
    frame[[0, 5, 13, 26], [0, 9, 13, 28]] = np.nan
    assert_allclose(mihoubi2017._average(frame, n, m), brute_average(frame, n, m),
                    rtol=0, atol=1e-13)


@pytest.mark.parametrize("tile", [(4, 4), (5, 5), (3, 4), (2, 3)])
def test_the_pseudo_panchromatic_image_is_mihoubis_away_from_the_edges(tile):
    n, m = tile
    frame = _textured((6 * n + 7, 6 * m + 5), 2)
    frame[3 * n, 3 * m] = np.nan  # a missing value inside: left out of its neighbours
    inner = np.s_[2 * n + 2:-(2 * n + 2), 2 * m + 2:-(2 * m + 2)]
    assert_allclose(pseudo_panchromatic(frame, n, m)[inner], brute_ppi(frame, n, m)[inner],
                    rtol=0, atol=1e-13)


def test_the_pseudo_panchromatic_image_is_mihoubis_at_the_edges_too():
    n, m = 4, 4
    frame = _textured((33, 31), 2)
    assert_allclose(pseudo_panchromatic(frame, n, m), brute_ppi(frame, n, m), rtol=0,
                    atol=1e-12)


@pytest.mark.parametrize("tile", [(4, 4), (5, 5), (3, 4), (2, 3)])
def test_a_flat_scene_of_any_colour_has_the_mean_of_its_bands_as_ppi(tile):
    """Eq. (23): every band weighs the same in the PPI, so a scene of one colour (band ``b``
    everywhere ``c_b``) has the bands' mean as its PPI, and PPID gives back each ``c_b``."""
    n, m = tile
    rng = np.random.default_rng(11)
    colour = rng.uniform(0.2, 3.0, n * m)
    order = rng.permutation(n * m)
    y0, x0 = order // m, order % m
    shape = (6 * n + 1, 6 * m + 3)
    frame = np.empty(shape)
    for b in range(n * m):
        frame[y0[b]::n, x0[b]::m] = colour[b]
    inner = np.s_[2 * n + 2:-(2 * n + 2), 2 * m + 2:-(2 * m + 2)]
    assert_allclose(pseudo_panchromatic(frame, n, m)[inner], colour.mean(), rtol=1e-13)
    cube = ppid(frame, y0, x0, n, m)
    inner = np.s_[3 * n:-3 * n, 3 * m:-3 * m]
    assert_allclose(cube[inner], np.broadcast_to(colour, cube.shape)[inner], rtol=1e-12)
