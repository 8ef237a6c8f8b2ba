"""The pseudo-panchromatic image (PPI) of a mosaic frame, and PPID demosaicking.

Mihoubi et al. [1]_ estimate, at every pixel, the average of all bands (the PPI), then
interpolate each band's difference from it, which is far smoother than the band itself.

* **PPI.** First a local average of the raw frame with a tile-wide kernel ``M`` in which
  every band weighs the same (Eq. 23-24: for an even tile size ``n`` the ``n + 1`` taps
  ``[1/2, 1, ..., 1, 1/2] / n``, for an odd one ``n`` taps of ``1 / n``; separable). It is then
  sharpened with the raw values (Eq. 25-28): at pixel ``p`` the PPI is ``I(p)`` plus a weighted
  mean, over the eight same-band neighbours ``q`` one tile away, of ``PPI0(q) - I(q)``, with
  weights ``1 / (eps + sum (2 - u)(2 - |v|) |I(a) - I(a + step_q)|)`` over the six pixels
  ``a = p + u dir_q + v perp_q`` (``u`` in {0, 1}, ``v`` in {-1, 0, 1}): large across an edge,
  so the neighbours on the pixel's own side count (at the frame's edges, pairs beyond it are
  left out, and the ``u = 1`` pairs wholly where the end of their middle pair away from ``p``
  lies beyond it). Where the whole
  averaging window of Eq. 24 is missing (a hole), a wider window's plain mean stands in
  (:data:`WIDEN_TILES`). The paper's constant 1 in the weight assumes
  8-bit values; here ``eps`` is 1/100 of the local average ``|PPI0(p)|``, so the result does
  not depend on the units, and a pixel's value depends on its neighbourhood only (a block of
  a larger frame gives the same values as the frame).
* **PPID.** Each band's difference ``I - PPI`` at its samples is interpolated bilinearly
  (Eq. 30-31, the WB kernel) and the PPI added back (Eq. 34).

References
----------
.. [1] S. Mihoubi, O. Losson, B. Mathon, L. Macaire, "Multispectral demosaicing using
   pseudo-panchromatic image", IEEE Trans. Comput. Imaging 3, 982-995 (2017).
"""

from __future__ import annotations

import numba
import numpy as np

from ._grid import interpolate, sub_grids

#: Where a pixel's whole averaging window is missing, the window is widened by up to this
#: many kernel widths on every side (a hole larger than that stays NaN in the PPI).
WIDEN_TILES = 2
#: The weights' floor, as a fraction of the local average (the paper's constant 1 for 8-bit
#: values, made independent of the units).
EPS_FRACTION = 0.01


def _taps(n):
    """Eq. (23): a centred tile-wide kernel in which every band weighs ``1 / n``."""
    if n % 2:
        return np.full(n, 1.0 / n)
    return np.r_[0.5, np.ones(n - 1), 0.5] / n


@numba.njit(parallel=True, cache=True)
def _average_kernel(frame, tn, tm, out):  # pragma: no cover - compiled
    """Separable weighted mean; where the window holds a missing value or passes an edge,
    the mean over the values that exist, weights renormalised (NaN if none)."""
    rows, cols = frame.shape
    hn, hm = tn.size // 2, tm.size // 2
    tmp = np.empty((rows, cols), out.dtype)
    inner = max(cols - 2 * hm, 0)
    for y in numba.prange(rows):
        # row views indexed from 0: no wraparound checks, the loops vectorise
        t = tmp[y, hm:hm + inner]
        for x in range(cols):
            tmp[y, x] = 0.0
        for k in range(tm.size):
            f = frame[y, k:k + inner]
            for x in range(inner):
                t[x] += tm[k] * f[x]
    for y in numba.prange(rows):
        o = out[y]
        if y < hn or y >= rows - hn:
            for x in range(cols):
                o[x] = np.nan
            continue
        for x in range(cols):
            o[x] = 0.0
        for k in range(tn.size):
            t = tmp[y + k - hn]
            for x in range(cols):
                o[x] += tn[k] * t[x]
        for x in range(hm):
            out[y, x] = np.nan
            out[y, cols - 1 - x] = np.nan
    for y in numba.prange(rows):
        for x in range(cols):
            if out[y, x] == out[y, x]:
                continue
            sv = 0.0
            sw = 0.0
            for ky in range(tn.size):
                yy = y + ky - hn
                if yy < 0 or yy >= rows:
                    continue
                for kx in range(tm.size):
                    xx = x + kx - hm
                    if xx < 0 or xx >= cols:
                        continue
                    v = frame[yy, xx]
                    if v == v:
                        w = tn[ky] * tm[kx]
                        sv += w * v
                        sw += w
            if sw > 1e-6:
                out[y, x] = sv / sw
                continue
            # the whole window is missing (a hole of a tile or so, or one at a corner): the
            # plain mean of a window wider by a tile on every side, then by two
            out[y, x] = np.nan
            for k in range(1, WIDEN_TILES + 1):
                sv = 0.0
                cnt = 0
                for yy in range(max(y - hn - k * tn.size, 0), min(y + hn + k * tn.size + 1,
                                                                   rows)):
                    for xx in range(max(x - hm - k * tm.size, 0),
                                    min(x + hm + k * tm.size + 1, cols)):
                        v = frame[yy, xx]
                        if v == v:
                            sv += v
                            cnt += 1
                if cnt:
                    out[y, x] = sv / cnt
                    break


def _average(frame, n, m):
    """Eq. (24), NaN-aware: the kernel's weighted mean over the samples that exist."""
    out = np.empty_like(frame)
    _average_kernel(frame, _taps(n), _taps(m), out)
    return out


#: The four steps between a pixel and its same-band neighbours (the other four are their
#: opposites), as (row, column) directions; the step is one tile along each.
_STEPS = np.array([(1, 0), (0, 1), (1, 1), (1, -1)], np.int64)


@numba.njit(parallel=True, cache=True)
def _gradients(frame, n, m, out):  # pragma: no cover - compiled
    """``out[s, a]``: sum over ``v`` in {-1, 0, 1} of ``(2 - |v|) |I(a') - I(a' + step_s)|``
    with ``a' = a + v perp_s`` (pairs beyond the frame or missing left out)."""
    rows, cols = frame.shape
    diff = np.zeros((rows + 2, cols + 2), out.dtype)  # |I(a) - I(a + step)|, zero-padded
    for s in range(4):
        i, j = _STEPS[s, 0], _STEPS[s, 1]
        x_lo, x_hi = max(0, -j * m), min(cols, cols - j * m)
        width = max(x_hi - x_lo, 0)
        for y in numba.prange(rows - i * n):
            # row views indexed from 0: no wraparound checks, the loops vectorise
            a = frame[y, x_lo:x_lo + width]
            b = frame[y + i * n, x_lo + j * m:x_lo + j * m + width]
            d_row = diff[y + 1, x_lo + 1:x_lo + 1 + width]
            for x in range(width):
                d = a[x] - b[x]
                d_row[x] = abs(d) if d == d else 0.0
        for y in numba.prange(rows):
            lo = diff[y + 1 + j, 1 - i:1 - i + cols]
            mid = diff[y + 1, 1:1 + cols]
            hi = diff[y + 1 - j, 1 + i:1 + i + cols]
            o = out[s, y]
            for x in range(cols):
                o[x] = lo[x] + 2.0 * mid[x] + hi[x]
        for y in numba.prange(rows + 2):
            for x in range(cols + 2):
                diff[y, x] = 0.0


@numba.njit(cache=True, inline="always")
def _sharpen_at(frame, rough, grad, y, x, n, m, eps_fraction):  # pragma: no cover
    """Eq. (25-28) at one pixel, every bound and missing value checked."""
    rows, cols = frame.shape
    fp = frame[y, x]
    r = rough[y, x]
    if fp != fp:  # a missing sample: the local average stands in
        return r
    eps = max(eps_fraction * abs(r) if r == r else 0.0, 1e-30)
    num = 0.0
    den = 0.0
    for s in range(4):
        i, j = _STEPS[s, 0], _STEPS[s, 1]
        for sign in range(-1, 2, 2):
            qy, qx = y + sign * i * n, x + sign * j * m
            if qy < 0 or qy >= rows or qx < 0 or qx >= cols:
                continue
            fq, pq = frame[qy, qx], rough[qy, qx]
            if fq != fq or pq != pq:
                continue
            # u = 0 and u = 1 along the direction; towards -step the pairs are the +step
            # pairs one tile back
            back = (1 - sign) // 2
            cy, cx = y - back * i * n, x - back * j * m
            g = eps + 2.0 * grad[s, cy, cx]
            uy, ux = cy + sign * i, cx + sign * j
            if 0 <= uy < rows and 0 <= ux < cols:
                g += grad[s, uy, ux]
            w = 1.0 / g
            num += w * (pq - fq)
            den += w
    return fp + num / den if den > 0.0 else r


@numba.njit(parallel=True, cache=True)
def _sharpen(frame, rough, grad, n, m, eps_fraction, out):  # pragma: no cover - compiled
    rows, cols = frame.shape
    y_lo, y_hi = n + 1, rows - n - 1
    x_lo, x_hi = m + 1, cols - m - 1
    for y in numba.prange(rows):
        if y < y_lo or y >= y_hi or x_hi <= x_lo:
            for x in range(cols):
                out[y, x] = _sharpen_at(frame, rough, grad, y, x, n, m, eps_fraction)
            continue
        num = np.zeros(cols, np.float64)
        den = np.zeros(cols, np.float64)
        eps = np.empty(cols, np.float64)
        for x in range(cols):
            eps[x] = max(eps_fraction * abs(rough[y, x]), 1e-30)
        for s in range(4):  # away from the edges: no bounds, vectorised along the row
            i, j = _STEPS[s, 0], _STEPS[s, 1]
            for sign in range(-1, 2, 2):
                dy, dx = sign * i * n, sign * j * m
                back = (1 - sign) // 2
                cy, cdx = y - back * i * n, -back * j * m
                uy, udx = cy + sign * i, cdx + sign * j
                # row views starting at the first pixel: indices from 0, so no wraparound
                # checks and the loop vectorises
                g0 = grad[s, cy, x_lo + cdx:x_hi + cdx]
                g1 = grad[s, uy, x_lo + udx:x_hi + udx]
                rq = rough[y + dy, x_lo + dx:x_hi + dx]
                fq = frame[y + dy, x_lo + dx:x_hi + dx]
                ep, nu, de = eps[x_lo:x_hi], num[x_lo:x_hi], den[x_lo:x_hi]
                for k in range(x_hi - x_lo):
                    w = 1.0 / (ep[k] + 2.0 * g0[k] + g1[k])
                    nu[k] += w * (rq[k] - fq[k])
                    de[k] += w
        for x in range(cols):
            if x < x_lo or x >= x_hi:
                out[y, x] = _sharpen_at(frame, rough, grad, y, x, n, m, eps_fraction)
                continue
            v = frame[y, x] + num[x] / den[x]
            # a missing value nearby made it NaN: checked pixel by pixel
            out[y, x] = v if v == v else _sharpen_at(frame, rough, grad, y, x, n, m,
                                                      eps_fraction)


def pseudo_panchromatic(frame, n, m):
    """The frame's pseudo-panchromatic image (module docstring; Eq. 23-28 of [1]_).

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        Float values, NaN where missing.
    n, m : int
        Tile rows and columns.

    Returns
    -------
    ndarray, shape (rows, cols)
    """
    rough = _average(frame, n, m)
    grad = np.empty((4, *frame.shape), frame.dtype)
    _gradients(frame, n, m, grad)
    out = np.empty_like(rough)
    _sharpen(frame, rough, grad, n, m, EPS_FRACTION, out)
    return out


def ppid(frame, y0, x0, n, m, *, fill_missing=False):
    """PPID: each band's difference from the pseudo-panchromatic image, interpolated
    bilinearly, plus that image (Eq. 30-34 of [1]_).

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
    y0, x0 : ndarray of int, shape (n_bands,)
        Each band's first sample row and column in the frame.
    n, m : int
        Tile rows and columns.
    fill_missing : bool
        Estimate a missing sample from the band's samples around it (else it stays NaN).

    Returns
    -------
    ndarray, shape (rows, cols, n_bands)
    """
    ppi = pseudo_panchromatic(frame, n, m)
    out = np.empty((*frame.shape, y0.size), frame.dtype)
    return interpolate(sub_grids(frame - ppi, y0, x0, n, m), frame, y0, x0, n, m, out,
                       base=ppi, fill=fill_missing)
