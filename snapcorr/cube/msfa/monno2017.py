"""Residual interpolation guided by the pseudo-panchromatic image.

Residual interpolation (Kiku et al. [1]_ for colour filter arrays; Monno et al. [2]_ for
multispectral ones) replaces PPID's assumption that a band differs from its guide by a smooth
offset with a local linear model: in a window of the band's own samples, ``band ~ a guide +
c``, fitted by least squares (a guided filter, He et al. [3]_, on the band's sub-grid); the
fit's residuals at the samples, smooth where the model holds, are interpolated bilinearly and
added back. The guide here is the pseudo-panchromatic image of Mihoubi et al. [4]_, which
carries the frame's full-resolution structure. Where a window holds fewer than three of the
band's samples, ``a = 0`` (the band's local mean).

References
----------
.. [1] D. Kiku, Y. Monno, M. Tanaka, M. Okutomi, "Residual interpolation for color image
   demosaicking", Proc. IEEE ICIP, 2304-2308 (2013).
.. [2] Y. Monno, D. Kiku, M. Tanaka, M. Okutomi, "Adaptive residual interpolation for color
   and multispectral image demosaicking", Sensors 17, 2787 (2017).
.. [3] K. He, J. Sun, X. Tang, "Guided image filtering", IEEE Trans. Pattern Anal. Mach.
   Intell. 35, 1397-1409 (2013).
.. [4] S. Mihoubi, O. Losson, B. Mathon, L. Macaire, "Multispectral demosaicing using
   pseudo-panchromatic image", IEEE Trans. Comput. Imaging 3, 982-995 (2017).
"""

from __future__ import annotations

import numba
import numpy as np

from ._grid import interpolate, sub_grids
from .mihoubi2017 import pseudo_panchromatic

#: Half-width of the fitting window, in samples of the band's own sub-grid.
RADIUS = 1
#: The linear fit's regularisation: ``(EPS_FRACTION * |window's mean guide|)^2``.
EPS_FRACTION = 0.01


@numba.njit(cache=True)
def _box(src, radius, out, row):  # pragma: no cover - compiled
    """Window sums over ``(2 radius + 1)^2`` samples (zero beyond the edges), separable, one
    output row at a time (``row``: ``gx + 2 radius`` floats); whole-row array operations, so
    they vectorise, and a sum never depends on where the grid starts."""
    gy, gx = src.shape
    row[:] = 0.0
    for i in range(gy):
        r = row[radius:radius + gx]
        r[:] = 0.0
        for k in range(max(i - radius, 0), min(i + radius + 1, gy)):
            r += src[k]
        o = out[i]
        o[:] = row[0:gx]
        for d in range(1, 2 * radius + 1):
            o += row[d:d + gx]


@numba.njit(cache=True)
def _guided_band(values, guide, inside, radius, eps_fraction, src, box, row, a_out,
                 offset_out):  # pragma: no cover - compiled
    """One band's guided filter (see :func:`_guided`), row by row on views so the loops
    vectorise."""
    gy, gx = values.shape
    for i in range(gy):
        v, g = values[i], guide[i]
        s0, s1, s2, s3, s4 = src[0, i], src[1, i], src[2, i], src[3, i], src[4, i]
        for j in range(gx):
            ok = v[j] == v[j] and g[j] == g[j]
            vj = v[j] if ok else 0.0
            gj = g[j] if ok else 0.0
            s0[j] = 1.0 if ok else 0.0
            s1[j] = vj
            s2[j] = gj
            s3[j] = gj * gj
            s4[j] = gj * vj
    for k in range(5):
        _box(src[k], radius, box[k], row)
    for i in range(gy):
        b0, b1, b2, b3, b4 = box[0, i], box[1, i], box[2, i], box[3, i], box[4, i]
        s0, s1, s2, ins = src[0, i], src[1, i], src[2, i], inside[i]
        for j in range(gx):
            cnt = b0[j]
            inv = 1.0 / cnt if cnt > 0.0 else 0.0
            mv, mg = b1[j] * inv, b2[j] * inv
            var = max(b3[j] * inv - mg * mg, 0.0)
            cov = b4[j] * inv - mg * mv
            a = cov / (var + max((eps_fraction * mg) ** 2, 1e-30)) if cnt >= 3.0 else 0.0
            c = mv - a * mg
            has = ins[j] and cnt > 0.0
            s0[j] = 1.0 if has else 0.0
            s1[j] = a if has else 0.0
            s2[j] = c if has else 0.0
    for k in range(3):
        _box(src[k], radius, box[k], row)
    for i in range(gy):
        b0, b1, b2, ins = box[0, i], box[1, i], box[2, i], inside[i]
        v, g, ao, oo = values[i], guide[i], a_out[i], offset_out[i]
        for j in range(gx):
            w = b0[j]
            ok = ins[j] and w > 0.0
            a = b1[j] / w if ok else np.nan
            c = b2[j] / w if ok else np.nan
            ao[j] = a
            r = v[j] - a * g[j]  # the residual joins the offset
            oo[j] = r if r == r else c


@numba.njit(parallel=True, cache=True)
def _guided(values, guide, inside, radius, eps_fraction, workers, a_out,
            offset_out):  # pragma: no cover - compiled
    """Per sample, the window's least-squares ``a``, ``c`` of ``values ~ a guide + c``,
    averaged over the windows holding it (the guided filter), NaN-aware; NaN where not
    ``inside`` the frame. Returns ``a`` and the offset ``values - a guide`` (``c`` where a
    value is missing). Band by band in float64, each thread reusing its buffers."""
    nb, gy, gx = values.shape
    for w in numba.prange(workers):
        src = np.empty((5, gy, gx))
        box = np.empty((5, gy, gx))
        row = np.empty(gx + 2 * radius)
        for b in range(w, nb, workers):
            _guided_band(values[b], guide[b], inside[b], radius, eps_fraction, src, box, row,
                         a_out[b], offset_out[b])


def residual_interpolation(frame, y0, x0, n, m, *, radius=RADIUS, fill_missing=False):
    """Every band from a local linear model of its samples against the pseudo-panchromatic
    image, plus its residuals interpolated bilinearly (module docstring).

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
    y0, x0 : ndarray of int, shape (n_bands,)
        Each band's first sample row and column in the frame.
    n, m : int
        Tile rows and columns.
    radius : int
        Half-width of the fitting window, in the band's samples.
    fill_missing : bool
        Estimate a missing sample from the band's samples around it (else it stays NaN).

    Returns
    -------
    ndarray, shape (rows, cols, n_bands)
    """
    guide = pseudo_panchromatic(frame, n, m)
    values = sub_grids(frame, y0, x0, n, m)
    at_samples = sub_grids(guide, y0, x0, n, m)
    # the padding past the frame's edge holds no sample: no fit is kept there
    _, gy, gx = values.shape
    inside = ((y0[:, None, None] + n * np.arange(gy)[None, :, None] < frame.shape[0])
              & (x0[:, None, None] + m * np.arange(gx)[None, None, :] < frame.shape[1]))
    a, offset = np.empty_like(values), np.empty_like(values)
    _guided(values, at_samples, inside, int(radius), EPS_FRACTION,
            min(numba.get_num_threads(), y0.size), a, offset)
    out = np.empty((*frame.shape, y0.size), frame.dtype)
    # a guide + (c + residual), both interpolated bilinearly
    return interpolate(offset, frame, y0, x0, n, m, out, base=guide, gain=a,
                       fill=fill_missing)
