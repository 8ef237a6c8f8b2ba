"""Spectra that are the same anywhere in the field: every pixel brought to one response.

After the wavelength correction a pixel's band ``b`` still has its own width: the filter
curve spread by the pixel's kernel (:mod:`snapcorr.optics.bandwidth`), wider at larger
chief-ray angles and faster f-numbers, narrower where vignetting cuts the oblique rays. The
same material then gives different spectra at different places. Harmonising adds to every
pixel the widening it lacks against a common response (by default the widest in the field at
each band: the response of the pixel whose kernel has the largest variance): a Gaussian of
the variance its response lacks, ``cwl_b^2 (v_ref - v(y, x))`` with ``v`` the kernel's
variance in ``log(lambda)`` (:func:`snapcorr.optics.bandwidth.kernel_log_variance`), applied
to the pixel's spectrum as sampled at its corrected wavelengths. The response is the filter
convolved with the kernel in ``log(lambda)``, so response variances differ by exactly the
kernels' whatever the filter's shape; FWHMs add in quadrature only for Gaussians, and at
f/1.4 (a box-like kernel, flat-topped responses at the field's edge) the rule
``(W_b^2 - FWHM_b^2) / (8 ln 2)`` gave a pixel near the axis twice the variance it lacks at
805 nm (its response ~30 % too wide in variance; Airy filters alike): spectra of a didymium
glass then disagreed most at its 794-806 nm bands, where the kernel is wide and the
absorption sharp. A common response wider than the reference (``target_fwhm_nm``)
adds ``(W_b^2 - FWHM_ref^2) / (8 ln 2)`` to every pixel's variance.

The spectrum between samples is taken as the straight line through them (what ``resampled``
assumes), and the Gaussian is applied to that line exactly: segment by segment, with the
normal distribution's integrals (:func:`_segment_weights`). The value at a nominal wavelength
is therefore a weighted sum of the pixel's bands; with no widening it is ``resampled``
itself. Beyond the pixel's first and last corrected wavelengths the line is held at the end
values; a nominal wavelength outside that range is NaN, as in ``resampled``.

Two paths give the same numbers: for a Snapscan (one scale per pixel, one chief-ray angle per
pixel) the weights are tabulated on chief-ray-angle nodes and interpolated, a banded matrix
per pixel and nothing transcendental in the loop; otherwise each value is computed directly,
by the pass resampling uses (:func:`snapcorr.correct._spectra.spectra_pass`) given the
pixel's widening.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from ._spectra import REACH as _REACH
from ._spectra import cdf as _cdf
from ._spectra import pdf as _phi
from ._spectra import spectra_pass
from ._spectra import spectrum_value as _value

__all__ = ["NodeWeights", "harmonise_spectra", "node_weights"]

#: The tabulated weights stop at this many (the mass beyond: 6e-5) and are renormalised to
#: sum to one: fewer terms per value, a flat spectrum still flat.
_TABLE_REACH = 4.0


@numba.njit(cache=True)
def _segment_weights(lam, t, sigma, w, k_reach=_REACH):  # pragma: no cover - compiled
    """Weights ``w`` (len(lam)) such that ``sum(w * y)`` is the Gaussian (``sigma``) average
    about ``t`` of the straight-line interpolant of ``y`` at ``lam``, held constant beyond
    the ends."""
    n = lam.size
    for j in range(n):
        w[j] = 0.0
    if sigma <= 0.0:
        j = 0
        while j < n - 2 and lam[j + 1] < t:
            j += 1
        u = (t - lam[j]) / (lam[j + 1] - lam[j])
        w[j] = 1.0 - u
        w[j + 1] = u
        return
    w[0] += _cdf((lam[0] - t) / sigma)
    w[n - 1] += 1.0 - _cdf((lam[n - 1] - t) / sigma)
    reach = k_reach * sigma
    for j in range(n - 1):
        a, b = lam[j], lam[j + 1]
        if b < t - reach or a > t + reach:
            continue
        za, zb = (a - t) / sigma, (b - t) / sigma
        mass = _cdf(zb) - _cdf(za)
        first = sigma * (_phi(za) - _phi(zb))  # integral of (lambda - t) g
        right = ((t - a) * mass + first) / (b - a)  # weight of y[j + 1]
        w[j + 1] += right
        w[j] += mass - right


@numba.njit(cache=True, fastmath={"contract"})
def _diagonal_sums(acc, rows, buf, width, k0):  # pragma: no cover - compiled
    """``acc[k] += sum(rows[q, k0 + k] * buf[q + k] for q < width)``, one diagonal at a time:
    a vector operation over the outputs, and every output's sum in band order."""
    n = acc.size
    for q in range(width):
        r = rows[q, k0:k0 + n]
        b = buf[q:q + n]
        for k in range(n):
            acc[k] += r[k] * b[k]


@numba.njit(parallel=True, cache=True, fastmath={"contract"})
def _tabulated(data, scale, cra, nodes, D, off, wid, nbad, W, lo, cnt, var, sigma_direct,
               near_ptr, near_k, cwl, out):  # pragma: no cover - compiled
    # A pixel's weights are those of its two neighbouring nodes, interpolated linearly in
    # chief-ray angle (nodes a few hundredths of a nanometre of shift apart): the value is
    # (1 - u) sa + u sb, each a float32 sum over one node's banded matrix (a few tens of
    # terms: 1e-7 of the values), taken along its diagonals (``_diagonal_sums``) so that it
    # vectorises over the outputs. Below sigma_direct the weights bend within a node step (a
    # straight line's kinks are barely smoothed): those values are computed directly, over
    # the few segments in reach.
    ny, nx, nb = data.shape
    m = nodes.size
    step = (nodes[m - 1] - nodes[0]) / (m - 1) if m > 1 else 1.0
    pad = 0
    for i in range(m):
        pad = max(pad, -off[i], off[i] + wid[i])
    sd2 = sigma_direct * sigma_direct
    for y in numba.prange(ny):
        lam = np.empty(nb)
        d = np.empty(nb)
        buf = np.zeros(nb + 2 * pad, np.float32)  # the spectrum, zeros beyond its ends
        sa = np.empty(nb, np.float32)
        sb = np.empty(nb, np.float32)
        for x in range(nx):
            s = scale[y, x]
            finite = True
            for b in range(nb):
                buf[pad + b] = data[y, x, b]
                finite &= math.isfinite(buf[pad + b])
            pos = min(max((cra[y, x] - nodes[0]) / step, 0.0), m - 1.0)
            i = min(int(pos), m - 2) if m > 1 else 0
            i1 = i + 1 if m > 1 else i
            u = pos - i
            # the outputs inside the pixel's corrected range: klo...khi
            lam0, lam1 = cwl[0] * s, cwl[nb - 1] * s
            klo = 0
            while klo < nb and cwl[klo] < lam0:
                klo += 1
            khi = nb - 1
            while khi >= klo and cwl[khi] > lam1:
                khi -= 1
            for k in range(klo):
                out[y, x, k] = np.nan
            for k in range(khi + 1, nb):
                out[y, x, k] = np.nan
            n = khi + 1 - klo
            if n <= 0:
                continue
            if finite:
                sa[:n] = 0.0
                sb[:n] = 0.0
                _diagonal_sums(sa[:n], D[i], buf[pad + off[i] + klo:], wid[i], klo)
                _diagonal_sums(sb[:n], D[i1], buf[pad + off[i1] + klo:], wid[i1], klo)
            else:  # a NaN or infinity reaches only the outputs whose weights cover it
                for k in range(klo, khi + 1):
                    ta = np.float32(0.0)
                    tb = np.float32(0.0)
                    for q in range(cnt[i, k]):
                        ta += W[i, k, q] * buf[pad + lo[i, k] + q]
                    for q in range(cnt[i1, k]):
                        tb += W[i1, k, q] * buf[pad + lo[i1, k] + q]
                    sa[k - klo] = ta
                    sb[k - klo] = tb
            for k in range(n):
                out[y, x, klo + k] = (1.0 - u) * sa[k] + u * sb[k]
            if nbad[i, khi + 1] - nbad[i, klo] + nbad[i1, khi + 1] - nbad[i1, klo] > 0:
                for k in range(klo, khi + 1):  # a row never read by the data it was made for
                    if nbad[i, k + 1] > nbad[i, k] or nbad[i1, k + 1] > nbad[i1, k]:
                        out[y, x, k] = np.nan
            j = -1
            for c in range(near_ptr[i], near_ptr[i + 1]):  # outputs that may be direct
                k = near_k[c]
                if klo <= k <= khi:
                    v2 = (1.0 - u) * var[i, k] + u * var[i1, k]
                    if v2 < sd2:
                        if j < 0:
                            for b in range(nb):
                                lam[b] = cwl[b] * s
                                d[b] = data[y, x, b]
                            j = 0
                        out[y, x, k], j = _value(lam, d, cwl[k], math.sqrt(max(v2, 0.0)), j)


@numba.njit(parallel=True, cache=True)
def _node_weights(cwl, node_scale, node_sigma, W, lo, cnt):  # pragma: no cover - compiled
    m, nb = node_sigma.shape
    L = W.shape[2]
    for i in numba.prange(m):
        lam = cwl * node_scale[i]
        w = np.empty(nb)
        for k in range(nb):
            _segment_weights(lam, cwl[k], node_sigma[i, k], w, _TABLE_REACH)
            if node_sigma[i, k] > 0.0:  # cut at the reach: renormalised
                t = cwl[k]
                total = 0.0
                for j in range(nb):
                    lo_j = lam[j - 1] if j > 0 else lam[0]
                    hi_j = lam[j + 1] if j < nb - 1 else lam[nb - 1]
                    if hi_j < t - _TABLE_REACH * node_sigma[i, k] or \
                            lo_j > t + _TABLE_REACH * node_sigma[i, k]:
                        w[j] = 0.0
                    total += w[j]
                for j in range(nb):
                    w[j] /= total
            first = 0  # the end tails are always there, if tiny: skip what is negligible
            while first < nb - 1 and abs(w[first]) < 1e-13:
                first += 1
            first = min(first, max(nb - L, 0))
            lo[i, k] = first
            last = min(first + L, nb)
            while last > first + 1 and abs(w[last - 1]) < 1e-13:
                last -= 1
            cnt[i, k] = last - first
            for q in range(last - first):
                W[i, k, q] = w[first + q]


def _diagonals(W, lo, cnt):
    """Each node's weights (row ``k``: ``W[i, k, :cnt[i, k]]`` on the bands from ``lo[i, k]``)
    along the diagonals of its banded matrix: ``D[i, q, k]`` weighs band ``k + off[i] + q``
    for ``q < wid[i]`` (zero where row ``k`` has no weight there). Rows of NaN (outputs far
    beyond the node's corrected range: no weight reaches them) are left out and marked in
    ``bad``."""
    m, nb, L = W.shape
    bad = np.isnan(W).any(axis=2)
    q = np.arange(L)
    keep = (q < cnt[..., None]) & (W != 0) & ~bad[..., None]
    rel = lo[..., None] + q - np.arange(nb)[:, None]  # band - output
    big = np.iinfo(np.int64).max
    off = np.where(keep, rel, big).min(axis=(1, 2))
    last = np.where(keep, rel, -big).max(axis=(1, 2))
    empty = ~keep.any(axis=(1, 2))
    off[empty], last[empty] = 0, 0
    wid = last - off + 1
    D = np.zeros((m, int(wid.max(initial=1)), nb), np.float32)
    ii, kk, qq = np.nonzero(keep)
    D[ii, rel[ii, kk, qq] - off[ii], kk] = W[ii, kk, qq]
    return D, off, wid, bad


def harmonise_spectra(data, scale, column, cwl_nm, sigma=None, *, cra=None, nodes=None,
                      node_scale=None, node_sigma=None, weights=None, out=None):
    """Each pixel's spectrum widened by its own Gaussian and put on the nominal wavelengths.

    Either ``sigma`` (``(ny, nx, nb)``: the widening's standard deviation per pixel and
    output band, nm; any layout) for the direct path, or the Snapscan path's tables:
    ``cra`` (``(ny, nx)``), ``nodes`` (increasing chief-ray angles), ``node_scale``
    (``(n_nodes,)``: the corrected/nominal factor at each node) and ``node_sigma``
    (``(n_nodes, nb)``); then ``scale`` must have one column.

    Parameters
    ----------
    data : ndarray, shape (ny, nx, nb)
        Bands sorted by increasing nominal wavelength.
    scale : ndarray, shape (ny, nx, m)
        Corrected / nominal wavelength; band ``b`` uses column ``column[b]``.
    column : ndarray of int, shape (nb,)
    cwl_nm : ndarray, shape (nb,)
        Nominal wavelengths, increasing.
    sigma : array_like, optional
        The direct path's widening (above), nm; broadcast to ``(ny, nx, nb)``.
    cra, nodes, node_scale, node_sigma : ndarray, optional
        The Snapscan path's tables (above); ``nodes`` evenly spaced, degrees; ``node_sigma``
        in nm.
    weights : NodeWeights, optional
        The Snapscan path's weights made from those tables by :func:`node_weights`, for a
        cube harmonised block by block (then ``nodes``, ``node_scale`` and ``node_sigma``
        are not used).
    out : ndarray, shape (ny, nx, nb), optional
        Array to write the result into (default: a new one).

    Returns
    -------
    ndarray
        Float32 for float32 data, else float64; NaN outside each pixel's corrected range.

    Examples
    --------
    With no widening it is linear interpolation:

    >>> data = np.array([[[0.0, 10.0, 20.0]]])
    >>> cwl = np.array([500.0, 600.0, 700.0])
    >>> harmonise_spectra(data, np.full((1, 1, 1), 0.99), np.zeros(3, int), cwl,
    ...                   np.zeros((1, 1, 3)))[0, 0].round(3)
    array([ 0.505, 10.606,    nan])
    """
    data = np.asarray(data)
    cwl = np.ascontiguousarray(cwl_nm, dtype=np.float64)
    if data.ndim != 3 or data.shape[2] != cwl.size or cwl.size < 2:
        raise ValueError(f"data must be (ny, nx, {cwl.size}) with at least two bands")
    if not np.all(np.diff(cwl) > 0):
        raise ValueError("nominal wavelengths must be increasing")
    if out is None:
        out = np.empty(data.shape, np.float32 if data.dtype == np.float32 else np.float64)
    scale = np.ascontiguousarray(scale, dtype=np.float64)
    if sigma is not None:
        # a view when it is float64 already (a scalar: zero strides), not a float64 cube
        sig = np.broadcast_to(np.asarray(sigma, dtype=np.float64), data.shape)
        spectra_pass(data, scale, np.ascontiguousarray(column, dtype=np.int64), cwl, sig,
                     out)
        return out
    if scale.shape[2] != 1 or cra is None:
        raise ValueError("the tabulated path needs one scale column and cra")
    if weights is None:
        weights = node_weights(cwl, nodes, node_scale, node_sigma)
    elif weights.cwl.shape != cwl.shape or np.any(weights.cwl != cwl):
        raise ValueError("the weights were made for other nominal wavelengths")
    w = weights
    _tabulated(data, np.ascontiguousarray(scale[:, :, 0]),
               np.ascontiguousarray(cra, dtype=np.float64), w.nodes, w.D, w.off, w.wid,
               w.nbad, w.W, w.lo, w.cnt, w.var, w.sigma_direct, w.near_ptr, w.near_k, cwl,
               out)
    return out


class NodeWeights(NamedTuple):
    """The Snapscan path's weights on its chief-ray-angle nodes (:func:`node_weights`)."""

    cwl: np.ndarray
    nodes: np.ndarray
    D: np.ndarray
    off: np.ndarray
    wid: np.ndarray
    nbad: np.ndarray
    W: np.ndarray
    lo: np.ndarray
    cnt: np.ndarray
    var: np.ndarray
    sigma_direct: float
    near_ptr: np.ndarray
    near_k: np.ndarray


def node_weights(cwl_nm, nodes, node_scale, node_sigma):
    """The weights of the Snapscan path of :func:`harmonise_spectra`, once for every block of
    a cube (they depend on the nodes, not on the pixels).

    Parameters
    ----------
    cwl_nm : ndarray, shape (nb,)
        Nominal wavelengths, increasing.
    nodes, node_scale, node_sigma : ndarray
        As for :func:`harmonise_spectra`.

    Returns
    -------
    NodeWeights
    """
    cwl = np.ascontiguousarray(cwl_nm, dtype=np.float64)
    nodes = np.ascontiguousarray(nodes, dtype=np.float64)
    if nodes.size > 1 and not np.allclose(np.diff(nodes), (nodes[-1] - nodes[0]) /
                                          (nodes.size - 1), rtol=1e-6, atol=1e-12):
        raise ValueError("the tabulated path needs evenly spaced nodes")
    ns = np.ascontiguousarray(node_sigma, dtype=np.float64)
    node_scale = np.ascontiguousarray(node_scale, dtype=np.float64)
    # every weight of an output lies within the Gaussian's reach of it (plus the segment
    # on each side): the band of columns to keep
    spacing = float(np.min(np.diff(cwl)) * node_scale.min())
    L = min(cwl.size, int(np.ceil(2 * _TABLE_REACH * float(ns.max(initial=0.0)) / spacing))
            + 4)
    W = np.zeros((nodes.size, cwl.size, L), np.float32)
    lo = np.zeros((nodes.size, cwl.size), np.int64)
    cnt = np.zeros((nodes.size, cwl.size), np.int64)
    _node_weights(cwl, node_scale, ns, W, lo, cnt)
    D, off, wid, bad = _diagonals(W, lo, cnt)
    # rows of NaN before each output, per node
    nbad = np.concatenate([np.zeros((nodes.size, 1), np.int64),
                           np.cumsum(bad, axis=1, dtype=np.int64)], axis=1)
    # below ten node steps' shift of a band the weights are computed directly: the outputs
    # of each interval between nodes where that may happen (either node's variance below
    # it, with a margin for the rounding of the interpolated variance)
    step = np.max(np.abs(np.diff(node_scale))) * cwl.max() if nodes.size > 1 else 0.0
    var = ns * ns
    low = np.minimum(var, np.concatenate([var[1:], var[-1:]])) < \
        (10.0 * step) ** 2 * (1.0 + 1e-9) + 1e-300
    near_ptr = np.concatenate([[0], np.cumsum(low.sum(axis=1))]).astype(np.int64)
    near_k = np.nonzero(low)[1].astype(np.int64)
    return NodeWeights(cwl, nodes, D, off, wid, nbad, W, lo, cnt, var, float(10.0 * step),
                       near_ptr, near_k)
