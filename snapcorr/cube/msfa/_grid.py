"""Compiled building blocks: each band's samples on its own sub-grid, and bilinear
interpolation between them (the weighted bilinear kernel of Brauers & Aach 2006 is exactly
that), fused with what a method adds to it.

Interpolation is separable: for each output row, every band's two neighbouring sample rows
are blended once (a short row per band), then every pixel blends two entries of it. A pixel
whose blend meets a missing sample (NaN, or the frame's edge) is recomputed by
:func:`bilinear_at`, which leaves missing samples out.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def bilinear_at(grid, y, x, y0, x0, n, m):  # pragma: no cover - compiled
    """Value at frame pixel ``(y, x)`` interpolated from ``grid``, a band's samples (sample
    ``(i, j)`` at frame pixel ``(y0 + i n, x0 + j m)``): the four surrounding samples weighed
    bilinearly; samples outside the grid or NaN are left out and the weights renormalised.
    If none of the four is left, the ring of twelve around them by inverse squared distance
    (NaN only in a hole more than a sample wide on every side)."""
    gy, gx = grid.shape
    # integer arithmetic first: the weights do not depend on where the frame starts
    i0 = (y - y0) // n
    j0 = (x - x0) // m
    ty = ((y - y0) - i0 * n) / n
    tx = ((x - x0) - j0 * m) / m
    acc = 0.0
    wsum = 0.0
    for di in range(2):
        i = i0 + di
        wy = ty if di else 1.0 - ty
        if i < 0 or i >= gy or wy == 0.0:
            continue
        for dj in range(2):
            j = j0 + dj
            wx = tx if dj else 1.0 - tx
            if j < 0 or j >= gx or wx == 0.0:
                continue
            v = grid[i, j]
            if v == v:  # not NaN
                w = wy * wx
                acc += w * v
                wsum += w
    if wsum > 0.0:
        return acc / wsum
    # all four missing (NaN or beyond an edge): the samples one ring further out, weighed by
    # inverse squared distance, so a missing sample is never spread to its neighbours
    for i in range(i0 - 1, i0 + 3):
        if i < 0 or i >= gy:
            continue
        for j in range(j0 - 1, j0 + 3):
            if j < 0 or j >= gx:
                continue
            v = grid[i, j]
            if v == v:
                w = 1.0 / (((i0 - i) + ty) ** 2 + ((j0 - j) + tx) ** 2)
                acc += w * v
                wsum += w
    if wsum > 0.0:
        return acc / wsum
    return np.nan


def sub_grids(frame, y0, x0, n, m):
    """Every band's samples of ``frame``, ``(n_bands, gy, gx)``: band ``b``'s from
    ``(y0[b], x0[b])``, every ``n`` rows and ``m`` columns, padded with NaN where a band has
    one sample fewer along an edge."""
    rows, cols = frame.shape
    gy, gx = -(-rows // n), -(-cols // m)
    out = np.full((y0.size, gy, gx), np.nan, frame.dtype)
    for b in range(y0.size):
        s = frame[y0[b]::n, x0[b]::m]
        out[b, :s.shape[0], :s.shape[1]] = s
    return out


@numba.njit(cache=True, inline="always")
def _blend_rows(grid, b, y, y0, n, row):  # pragma: no cover - compiled
    """``row[1 + j, b]``: band ``b``'s samples interpolated to frame row ``y`` (NaN where a
    sample row is missing), with a NaN pad at both ends."""
    gy, gx = grid.shape[1], grid.shape[2]
    i0 = (y - y0) // n
    ty = ((y - y0) - i0 * n) / n
    row[0, b] = np.nan
    row[gx + 1, b] = np.nan
    if i0 < 0 or i0 >= gy or (ty != 0.0 and i0 + 1 >= gy):
        for j in range(gx):
            row[j + 1, b] = np.nan
    elif ty == 0.0:
        for j in range(gx):
            row[j + 1, b] = grid[b, i0, j]
    else:
        for j in range(gx):
            row[j + 1, b] = (1.0 - ty) * grid[b, i0, j] + ty * grid[b, i0 + 1, j]


def _column_weights(x0, m):
    """For a pixel at column phase ``p`` of a tile (``x = t m + p``), band ``b``'s weights on
    the samples of tile columns ``t - 1``, ``t`` and ``t + 1``: ``(m, 3, n_bands)``."""
    nb = x0.size
    w = np.zeros((m, 3, nb))
    for p in range(m):
        for b in range(nb):
            jl = (p - x0[b]) // m  # -1 or 0: the left sample's tile column, relative
            tx = ((p - x0[b]) - jl * m) / m
            w[p, jl + 1, b] = 1.0 - tx
            w[p, jl + 2, b] += tx
    return w


@numba.njit(cache=True, fastmath={"reassoc"})
def _any_nan(v):  # pragma: no cover - compiled
    """Whether ``v`` holds a NaN (or an infinity): a sum that vectorises (reassociation only;
    NaN is not assumed away)."""
    acc = v.dtype.type(0)
    for k in range(v.size):
        acc += v[k] - v[k]
    return acc != acc


@numba.njit(parallel=True, cache=True)
def _compose(gain, offset, base, frame, y0, x0, n, m, mode, wx, fill,
             out):  # pragma: no cover
    rows, cols, nb = out.shape
    gx = offset.shape[2]
    for y in numba.prange(rows):
        ro = np.empty((gx + 2, nb), wx.dtype)
        rg = np.empty((gx + 2, nb), wx.dtype) if mode == 2 else ro
        for b in range(nb):
            _blend_rows(offset, b, y, y0[b], n, ro)
            if mode == 2:
                _blend_rows(gain, b, y, y0[b], n, rg)
        orow = out[y]
        for t in range(-(-cols // m)):
            r0, r1, r2 = ro[t], ro[t + 1], ro[t + 2]
            g0, g1, g2 = rg[t], rg[t + 1], rg[t + 2]
            for p in range(min(m, cols - t * m)):
                x = t * m + p
                o = orow[x]
                w0, w1, w2 = wx[p, 0], wx[p, 1], wx[p, 2]
                # row views and no branch inside the band loop: it vectorises
                if mode == 2:
                    s = base[y, x]
                    for b in range(nb):
                        o[b] = (s * (w0[b] * g0[b] + w1[b] * g1[b] + w2[b] * g2[b])
                                + (w0[b] * r0[b] + w1[b] * r1[b] + w2[b] * r2[b]))
                elif mode == 1:
                    s = base[y, x]
                    for b in range(nb):
                        o[b] = s + (w0[b] * r0[b] + w1[b] * r1[b] + w2[b] * r2[b])
                else:
                    for b in range(nb):
                        o[b] = w0[b] * r0[b] + w1[b] * r1[b] + w2[b] * r2[b]
        # a missing sample or the frame's edge met a zero weight as NaN: recompute those,
        # looking pixel by pixel only in the tiles that hold one
        flat = orow.reshape(-1)
        for t in range(-(-cols // m)):
            lo, hi = t * m, min((t + 1) * m, cols)
            if not _any_nan(flat[lo * nb:hi * nb]):
                continue
            for x in range(lo, hi):
                o = orow[x]
                for b in range(nb):
                    if o[b] != o[b]:
                        s = base[y, x] if mode != 0 else 0.0
                        c = bilinear_at(offset[b], y, x, y0[b], x0[b], n, m)
                        if mode == 2:
                            o[b] = s * bilinear_at(gain[b], y, x, y0[b], x0[b], n, m) + c
                        else:
                            o[b] = s + c
        # each band's own samples as measured (missing ones stay missing, unless filled)
        for b in range(nb):
            if (y - y0[b]) % n == 0:
                for x in range(x0[b], cols, m):
                    v = frame[y, x]
                    if v == v or not fill:
                        out[y, x, b] = v


def interpolate(grids, frame, y0, x0, n, m, out, *, base=None, gain=None, fill=False):
    """Fill ``out[y, x, b]`` with band ``b``'s grid interpolated bilinearly at every pixel:
    alone, plus ``base[y, x]``, or (with ``gain``) ``base * gain + grids``, both interpolated;
    at band ``b``'s own samples, the frame's value (where that is missing: NaN, or with
    ``fill`` the estimate from the samples around it).

    Parameters
    ----------
    grids : ndarray, shape (n_bands, gy, gx)
        Each band's values at its samples (:func:`sub_grids`).
    frame : ndarray, shape (rows, cols)
        The measured values.
    y0, x0 : ndarray of int, shape (n_bands,)
        Each band's first sample row and column.
    n, m : int
        Tile rows and columns.
    out : ndarray, shape (rows, cols, n_bands)
    base : ndarray, shape (rows, cols), optional
    gain : ndarray like ``grids``, optional (needs ``base``)
    fill : bool
        Estimate a missing sample from the samples around it instead of leaving it NaN.
    """
    mode = 0 if base is None else (1 if gain is None else 2)
    if base is None:
        base = np.zeros((1, 1), out.dtype)
    _compose(grids if gain is None else gain, grids, base, frame, y0, x0, n, m, mode,
             _column_weights(x0, m).astype(out.dtype), bool(fill), out)
    return out
