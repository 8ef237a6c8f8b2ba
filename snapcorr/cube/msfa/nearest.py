"""Tile replication: every pixel of a tile takes each band's value from that tile."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def _nearest_present(frame, yy, xx, n, m):  # pragma: no cover - compiled
    """``frame[yy, xx]``, or where that is missing (NaN, or beyond the frame's far edge), the
    next sample of the band below, right or diagonally (else above, left)."""
    rows, cols = frame.shape
    if yy < rows and xx < cols and frame[yy, xx] == frame[yy, xx]:
        return frame[yy, xx]
    for k in range(1, 7):
        s = 1 if k < 4 else -1
        kk = k if k < 4 else k - 3
        ny, nx = yy + s * (kk & 1) * n, xx + s * (kk >> 1) * m
        if 0 <= ny < rows and 0 <= nx < cols and frame[ny, nx] == frame[ny, nx]:
            return frame[ny, nx]
    return np.nan


@numba.njit(parallel=True, cache=True)
def _replicate(frame, y0, x0, n, m, fill, out):  # pragma: no cover - compiled
    rows, cols = frame.shape
    nb = y0.size
    # column phase p of a pixel x = t m + p -> band b's sample column t m + xoff[p, b]: the
    # tile-sized window grid starts at each band's own sample
    xoff = np.empty((m, nb), np.int64)
    for p in range(m):
        for b in range(nb):
            xoff[p, b] = ((p - x0[b]) // m) * m + x0[b]
    for y in numba.prange(rows):
        yy = np.empty(nb, np.int64)
        for b in range(nb):
            yy[b] = y0[b] + ((y - y0[b]) // n) * n
            if yy[b] < 0:
                yy[b] += n
        for t in range(-(-cols // m)):
            for p in range(min(m, cols - t * m)):
                x = t * m + p
                for b in range(nb):
                    xx = t * m + xoff[p, b]
                    if xx < 0:
                        xx += m
                    own = yy[b] == y and xx == x
                    if own and (not fill or frame[y, x] == frame[y, x]):
                        out[y, x, b] = frame[y, x]  # the band's own sample, as measured
                    else:
                        out[y, x, b] = _nearest_present(frame, yy[b], xx, n, m)


def tile_replication(frame, y0, x0, n, m, *, fill_missing=False):
    """Each band's value of the tile-sized window holding the pixel (the nearest sample at or
    before it along each axis): no interpolation, the baseline every method must beat. Where
    that sample is missing (NaN, or beyond the frame's far edge), the next one below, right or
    diagonally (else above, left) stands in.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
    y0, x0 : ndarray of int, shape (n_bands,)
        Each band's first sample row and column in the frame (``0 <= y0 < n``).
    n, m : int
        Tile rows and columns.
    fill_missing : bool
        A missing sample takes the next sample as the other pixels do (else it stays NaN).

    Returns
    -------
    ndarray, shape (rows, cols, n_bands)
    """
    out = np.empty((*frame.shape, y0.size), frame.dtype)
    _replicate(frame, y0, x0, n, m, bool(fill_missing), out)
    return out
