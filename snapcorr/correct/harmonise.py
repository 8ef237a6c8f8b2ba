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

**Measured responses** (a vendor file's curves behind a band-pass) are not harmonised so. Their
bands are no filter convolved with a kernel: the band-pass does not move while the curves do,
every band has side lobes and leaks (on the real imec 4x4 VIS file 12-38 % of a band's light
comes from outside its main lobe; the red bands, 590-620 nm, have a second lobe at 460-475
nm, on the band-pass edge), and neighbouring bands
have main lobes of different shapes, so a value taken between two bands' samples mixes two
different responses. Measured there (f/2.8, the paper's lens, a leaf's reflectance, spots at
CRA 1-16 deg) the Gaussian widening left 0.0074 against 0.0058 resampled: worse. With the
curves cut to their main lobes behind the band-pass it left 0.0031, with those lobes moving as
whole filters (no band-pass: the case the widening is exact for) still 0.0055, in bands whose
main lobes are 40-60 nm wide with shoulders. Instead each band's value through its common
response (:func:`snapcorr.optics.measured.common_responses`) is estimated from all the pixel's
bands: a linear estimate from known responses to a known target, the Wiener estimate of
:mod:`snapcorr.optics.wiener` (Pratt & Mancill 1976) with the pixel's bands behind the lens as
the responses and the common responses as the target (:func:`matched_table`), tabulated on
chief-ray-angle nodes and applied per pixel and band at the band's own angle
(:func:`harmonise_matched`). On the same leaf it leaves 0.0004.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from ._spectra import REACH as _REACH
from ._spectra import cdf as _cdf
from ._spectra import line_slopes as _slopes
from ._spectra import pdf as _phi
from ._spectra import smoothed_line_value as _smoothed
from ._spectra import spectra_pass
from ._spectra import spectrum_value as _value
from .matched import (
    MATCH_ALPHA,
    MATCH_PRIOR_MEAN,
    MATCH_TOLERANCE,
    MatchedTable,
    harmonise_matched,
    matched_table,
)

__all__ = ["MATCH_ALPHA", "MATCH_PRIOR_MEAN", "MATCH_TOLERANCE", "MatchedTable", "NodeWeights",
           "harmonise_matched", "harmonise_spectra", "matched_table", "node_weights"]

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


#: The widest pair of banded matrices (in diagonals) summed with the sums in registers
#: (:func:`_pair_sums`, one compiled version per even width); wider ones diagonal by diagonal.
_PAIR_MAX = 24
#: The outputs are padded to a multiple of this (a vector of float32), and the diagonals'
#: output ranges for :func:`_banded` start and end on multiples of it.
_LANES = 8


@numba.njit(cache=True, fastmath={"contract"})
def _pair_sums(o, A, B, x, u, width):  # pragma: no cover - compiled
    """``o[k] = (1 - u) sum(A[q, k] x[k + q]) + u sum(B[q, k] x[k + q])`` over ``q < width``
    (even): two nodes' banded matrices along their common diagonals, each output's two sums
    in registers, each as two partial sums (even and odd diagonals, in band order, added at
    the end: two chains of dependent additions half as long; ``width`` a compile-time
    constant: the loop over the diagonals is unrolled, the one over the outputs vectorised;
    the data read once for both)."""
    width = numba.literally(width)
    uf = np.float32(u)  # (interpolated in float32 too: no conversions in the loop)
    for k in range(o.size):
        sa = np.float32(0.0)
        sb = np.float32(0.0)
        ta = np.float32(0.0)
        tb = np.float32(0.0)
        for q in range(0, width, 2):
            v = x[k + q]
            sa += A[q][k] * v
            sb += B[q][k] * v
            v = x[k + q + 1]
            ta += A[q + 1][k] * v
            tb += B[q + 1][k] * v
        o[k] = (sa + ta) * (np.float32(1.0) - uf) + (sb + tb) * uf


@numba.njit(cache=True, fastmath={"contract"})
def _pair(o, A, B, x, u, width):  # pragma: no cover - compiled
    """:func:`_pair_sums` for ``width`` up to ``_PAIR_MAX``, taken to the next even number
    (half as many versions to compile; ``A`` and ``B`` have a row of zeros to spare, which
    leaves every sum as it is); False (nothing done) beyond."""
    if width <= 2:
        _pair_sums(o, A, B, x, u, 2)
    elif width <= 4:
        _pair_sums(o, A, B, x, u, 4)
    elif width <= 6:
        _pair_sums(o, A, B, x, u, 6)
    elif width <= 8:
        _pair_sums(o, A, B, x, u, 8)
    elif width <= 10:
        _pair_sums(o, A, B, x, u, 10)
    elif width <= 12:
        _pair_sums(o, A, B, x, u, 12)
    elif width <= 14:
        _pair_sums(o, A, B, x, u, 14)
    elif width <= 16:
        _pair_sums(o, A, B, x, u, 16)
    elif width <= 18:
        _pair_sums(o, A, B, x, u, 18)
    elif width <= 20:
        _pair_sums(o, A, B, x, u, 20)
    elif width <= 22:
        _pair_sums(o, A, B, x, u, 22)
    elif width <= 24:
        _pair_sums(o, A, B, x, u, 24)
    else:
        return False
    return True


@numba.njit(cache=True, fastmath={"contract"})
def _banded(acc, rows, ks, ke, buf, width, k0, k1):  # pragma: no cover - compiled
    """``acc[k] = sum(rows[q, k] * buf[q + k] for q < width)`` for ``k0 <= k < k1``, one
    diagonal at a time (a vector operation over the outputs, every output's sum in band order),
    each over only the outputs where it has weights (``ks[q]...ke[q]``: ``rows`` is zero
    elsewhere, so the sums are those over the whole band): the matrices wider than
    ``_PAIR_MAX``."""
    acc[k0:k1] = 0.0
    for q in range(width):
        a = max(ks[q], k0)
        b = min(ke[q], k1)
        if a >= b:
            continue
        r = rows[q, a:b]
        x = buf[q + a:]
        s = acc[a:b]
        for k in range(b - a):
            s[k] += r[k] * x[k]


@numba.njit(cache=True, fastmath={"contract"})
def _row_sums(o, W, lo, cnt, i, i1, u, spectrum, ta, tb):  # pragma: no cover - compiled
    """``o[k]`` for ``ta <= k <= tb`` from the two nodes' weights row by row (``W[i, k]`` on
    ``spectrum[lo[i, k]:]``): a spectrum with a NaN or infinity, which spoils only the
    outputs whose weights reach it."""
    for k in range(ta, tb + 1):
        t_a = np.float32(0.0)
        t_b = np.float32(0.0)
        for q in range(cnt[i, k]):
            t_a += W[i, k, q] * spectrum[lo[i, k] + q]
        for q in range(cnt[i1, k]):
            t_b += W[i1, k, q] * spectrum[lo[i1, k] + q]
        o[k] = (1.0 - u) * t_a + u * t_b


@numba.njit(cache=True)
def _direct_values(o, lam, d, slope, cwl, direct, var, i, i1, u, near,
                   finite):  # pragma: no cover - compiled
    """``o[k]`` for the outputs marked in ``direct`` (among ``near``, in increasing order;
    the marks cleared): the line through ``(lam, d)`` averaged with the Gaussian of the
    nodes' interpolated variance, from its kinks (``slope`` a buffer for them) where the
    spectrum is finite."""
    if finite:
        _slopes(lam, d, slope)
    j = 0
    for k in near:
        if direct[k]:
            direct[k] = False
            sig = math.sqrt(max((1.0 - u) * var[i, k] + u * var[i1, k], 0.0))
            if finite:
                o[k], j = _smoothed(lam, d, slope, cwl[k], sig, j)
            else:
                o[k], j = _value(lam, d, cwl[k], sig, j)


@numba.njit(parallel=True, cache=True, fastmath={"contract"})
def _tabulated(data, scale, cra, nodes, D, base, off, wid, ks, ke, nbad, W, lo, cnt, var,
               var_direct, near_ptr, near_k, cwl, out):  # pragma: no cover - compiled
    # A pixel's weights are those of its two neighbouring nodes, interpolated linearly in
    # chief-ray angle (nodes a few hundredths of a nanometre of shift apart): the value is
    # (1 - u) sa + u sb, each a float32 sum over one node's banded matrix (a few tens of
    # terms: 1e-7 of the values), taken along its diagonals so that it vectorises over the
    # outputs, both nodes at once (``_pair``; row r of D[i] is diagonal base[i] + r, zero
    # beyond the node's own, so the two share their rows' diagonals). Below var_direct (ten
    # times the band's shift or change of widening over the node step, squared) the weights
    # bend within a node step (a straight line's kinks are barely smoothed): those values are
    # computed directly, from the few kinks in reach.
    ny, nx, nb = data.shape
    npad = D.shape[2]
    m = nodes.size
    step = (nodes[m - 1] - nodes[0]) / (m - 1) if m > 1 else 1.0
    pad = 1  # (a diagonal to spare for an odd width taken even)
    for i in range(m):
        pad = max(pad, -base[i], off[i] + wid[i] + 1)
    for y in numba.prange(ny):
        lam = np.empty(nb)
        d = np.empty(nb)
        buf = np.zeros(npad + 2 * pad, np.float32)  # the spectrum, zeros beyond its ends
        sa = np.zeros(npad, np.float32)
        sb = np.zeros(npad, np.float32)
        slope = np.empty(nb)
        direct = np.zeros(nb, np.bool_)
        res = np.zeros(npad, np.float32)
        for x in range(nx):
            s = scale[y, x]
            src = data[y, x]
            spectrum = buf[pad:pad + nb]  # (indices from zero up: no negative index to wrap)
            finite = True
            for b in range(nb):
                spectrum[b] = src[b]
                finite &= math.isfinite(spectrum[b])
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
            # the outputs computed directly (no diagonals summed for them if they are at the
            # ends of the range, all of them at the field's edge): the others are ta...tb
            n_direct = 0
            for c in range(near_ptr[i], near_ptr[i + 1]):
                k = near_k[c]
                if klo <= k <= khi and (1.0 - u) * var[i, k] + u * var[i1, k] < \
                        var_direct[i, k]:
                    direct[k] = True
                    n_direct += 1
            ta, tb = klo, khi
            while ta <= tb and direct[ta]:
                ta += 1
            while tb >= ta and direct[tb]:
                tb -= 1
            if ta <= tb:
                d0 = min(off[i], off[i1])
                width = max(off[i] + wid[i], off[i1] + wid[i1]) - d0
                if not finite:  # a NaN or infinity reaches only the outputs it weighs in
                    _row_sums(out[y, x], W, lo, cnt, i, i1, u, buf[pad:], ta, tb)
                elif _pair(res, D[i, d0 - base[i]:], D[i1, d0 - base[i1]:], buf[pad + d0:],
                           u, width):  # every output, a whole number of vectors
                    o = out[y, x]  # (those outside ta...tb are written again below)
                    for k in range(nb):
                        o[k] = res[k]
                else:
                    ra, rb = off[i] - base[i], off[i1] - base[i1]
                    k0, k1 = ta - ta % _LANES, min(tb + _LANES - tb % _LANES, npad)
                    _banded(sa, D[i, ra:], ks[i, ra:], ke[i, ra:], buf[pad + off[i]:], wid[i],
                            k0, k1)
                    _banded(sb, D[i1, rb:], ks[i1, rb:], ke[i1, rb:], buf[pad + off[i1]:],
                            wid[i1], k0, k1)
                    va, vb, o = sa[ta:tb + 1], sb[ta:tb + 1], out[y, x, ta:tb + 1]
                    for k in range(tb + 1 - ta):
                        o[k] = (1.0 - u) * va[k] + u * vb[k]
                if nbad[i, tb + 1] - nbad[i, ta] + nbad[i1, tb + 1] - nbad[i1, ta] > 0:
                    for k in range(ta, tb + 1):  # a row never read by the data it was made for
                        if nbad[i, k + 1] > nbad[i, k] or nbad[i1, k + 1] > nbad[i1, k]:
                            out[y, x, k] = np.nan
            for k in range(klo):
                out[y, x, k] = np.nan
            for k in range(khi + 1, nb):
                out[y, x, k] = np.nan
            if n_direct:
                for b in range(nb):
                    lam[b] = cwl[b] * s
                    d[b] = data[y, x, b]
                _direct_values(out[y, x], lam, d, slope, cwl, direct, var, i, i1, u,
                               near_k[near_ptr[i]:near_ptr[i + 1]], finite)


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
    along the diagonals of its banded matrix: ``D[i, r, k]`` weighs band ``k + base[i] + r``
    (zero where row ``k`` has no weight there; the outputs padded with zeros to a multiple of
    ``_LANES``). A node's own diagonals are ``off[i]...off[i] + wid[i] - 1``; its rows reach
    over its neighbours' too (zeros), and one further, so that a pixel between two nodes reads
    both along the same diagonals, an even number of them. ``ks[i, r] <= k < ke[i, r]``
    (multiples of ``_LANES``) are the outputs row ``r`` has weights for (the rows' reach
    shifts along the bands, so most diagonals have weights for only some of the outputs), for
    the matrices too wide for registers. Rows of NaN (outputs far beyond the node's corrected
    range: no weight reaches them) are left out and marked in ``bad``."""
    m, nb = W.shape[:2]
    bad, off, last = _reach(W, lo, cnt)
    wid = last - off + 1
    near = [np.maximum(np.arange(m) - 1, 0), np.arange(m), np.minimum(np.arange(m) + 1, m - 1)]
    base = np.min([off[j] for j in near], axis=0)
    top = np.max([off[j] + wid[j] for j in near], axis=0)
    npad = -(-nb // _LANES) * _LANES
    D = _aligned_zeros((m, int((top - base).max(initial=1)) + 1, npad), np.float32)
    ks = np.zeros(D.shape[:2], np.int64)
    ke = np.zeros(D.shape[:2], np.int64)
    _lay_out(W, lo, cnt, bad, base, D, ks, ke)
    return D, base, off, wid, ks, ke, bad


#: Byte boundary of the diagonals' first element: with rows a whole number of vectors long,
#: every vector the pass reads from them is on a boundary of its own size and none straddles
#: two cache lines (numpy's arrays start on 16 bytes; the pass took 12 % longer so, measured).
_ALIGN = 64


def _aligned(a):
    """``a`` itself when it starts on an ``_ALIGN``-byte boundary, else a copy that does (a
    table made here does; one unpickled, as a dask worker receives it, may not)."""
    if a.ctypes.data % _ALIGN == 0:
        return a
    out = _aligned_zeros(a.shape, a.dtype)
    out[...] = a
    return out


def _aligned_zeros(shape, dtype):
    """Zeros starting on an ``_ALIGN``-byte boundary."""
    size = math.prod(shape) * np.dtype(dtype).itemsize
    raw = np.zeros(size + _ALIGN, np.uint8)
    start = -raw.ctypes.data % _ALIGN
    return raw[start:start + size].view(dtype).reshape(shape)


@numba.njit(cache=True)
def _reach(W, lo, cnt):  # pragma: no cover - compiled
    """Rows of NaN (``bad``), and each node's first and last diagonal with a weight (0, 0 for
    a node without any)."""
    m, nb, L = W.shape
    bad = np.zeros((m, nb), np.bool_)
    off = np.zeros(m, np.int64)
    last = np.zeros(m, np.int64)
    for i in range(m):
        first, end, seen = 0, 0, False
        for k in range(nb):
            for q in range(L):
                if math.isnan(W[i, k, q]):
                    bad[i, k] = True
            if bad[i, k]:
                continue
            for q in range(cnt[i, k]):
                if W[i, k, q] != 0:
                    r = lo[i, k] + q - k
                    if not seen or r < first:
                        first = r
                    if not seen or r > end:
                        end = r
                    seen = True
        off[i], last[i] = first, end
    return bad, off, last


@numba.njit(cache=True)
def _lay_out(W, lo, cnt, bad, base, D, ks, ke):  # pragma: no cover - compiled
    """``D[i, r, k]``: the weights along the diagonals from ``base``; ``ks``/``ke``: the
    outputs each row has weights for, widened to whole vectors."""
    m, nb = W.shape[:2]
    R, npad = D.shape[1], D.shape[2]
    for i in range(m):
        for k in range(nb):
            if bad[i, k]:
                continue
            for q in range(cnt[i, k]):
                if W[i, k, q] != 0:
                    D[i, lo[i, k] + q - k - base[i], k] = W[i, k, q]
        for r in range(R):
            first, end = -1, -1
            for k in range(npad):
                if D[i, r, k] != 0:
                    if first < 0:
                        first = k
                    end = k + 1
            if first >= 0:
                ks[i, r] = first // _LANES * _LANES
                ke[i, r] = -(-end // _LANES) * _LANES


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
        Array to write the result into (default: a new one): C-ordered, of the result's
        dtype, sharing no memory with ``data``.

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
    dtype = np.float32 if data.dtype == np.float32 else np.float64
    if out is None:
        out = np.empty(data.shape, dtype)
    elif (not isinstance(out, np.ndarray) or out.shape != data.shape or out.dtype != dtype
          or not out.flags.c_contiguous or not out.flags.writeable
          or np.shares_memory(out, data)):
        # (the compiled passes write without bounds checks, and read the data after writing)
        raise ValueError(f"out must be a new writeable C-ordered {np.dtype(dtype).name} array "
                         f"of shape {data.shape}, apart from the data")
    # C-ordered data: a strided view (a slice of bands, a transposed block) is copied once
    # rather than each compiled pass compiled again for its layout (the tabulated one: 20 s
    # of CPU, measured)
    data = np.ascontiguousarray(data)
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
    # rows handed to the threads a few at a time as they ask, not in one half each: the
    # field's edge (values computed directly) costs more, and a thread slowed by other work
    # is not waited for
    rows = max(1, min(8, data.shape[0] // (4 * numba.get_num_threads())))
    with numba.parallel_chunksize(rows):
        _tabulated(data, np.ascontiguousarray(scale[:, :, 0]),
                   np.ascontiguousarray(cra, dtype=np.float64), w.nodes, _aligned(w.D),
                   w.base, w.off, w.wid, w.ks, w.ke, w.nbad, w.W, w.lo, w.cnt, w.var,
                   w.var_direct, w.near_ptr, w.near_k, cwl, out)
    return out


class NodeWeights(NamedTuple):
    """The Snapscan path's weights on its chief-ray-angle nodes (:func:`node_weights`)."""

    cwl: np.ndarray
    nodes: np.ndarray
    D: np.ndarray
    base: np.ndarray
    off: np.ndarray
    wid: np.ndarray
    ks: np.ndarray
    ke: np.ndarray
    nbad: np.ndarray
    W: np.ndarray
    lo: np.ndarray
    cnt: np.ndarray
    var: np.ndarray
    var_direct: np.ndarray
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
    D, base, off, wid, ks, ke, bad = _diagonals(W, lo, cnt)
    # rows of NaN before each output, per node
    nbad = np.concatenate([np.zeros((nodes.size, 1), np.int64),
                           np.cumsum(bad, axis=1, dtype=np.int64)], axis=1)
    # the weights bend within a node step where the widening is below ten times what
    # changes over that step (the band's shift, or the widening itself; both in nm, that
    # band's, over that step): those values are computed directly. The outputs of each
    # interval between nodes where that may happen (either node's variance below it, with
    # a margin for the rounding of the interpolated variance)
    var = ns * ns
    var_direct = (10.0 * _node_step_change(node_scale, ns, cwl)) ** 2
    low = np.minimum(var, np.concatenate([var[1:], var[-1:]])) < \
        var_direct * (1.0 + 1e-9) + 1e-300
    near_ptr = np.concatenate([[0], np.cumsum(low.sum(axis=1))]).astype(np.int64)
    near_k = np.nonzero(low)[1].astype(np.int64)
    return NodeWeights(cwl, nodes, D, base, off, wid, ks, ke, nbad, W, lo, cnt, var,
                       var_direct, near_ptr, near_k)


def _node_step_change(node_scale, node_sigma, cwl):
    """``(n_nodes, nb)``: the larger of how far each band moves between node ``i`` and
    ``i + 1`` and how much its widening changes there (nm; the last node repeats the last
    interval's). The weights are smooth functions of both on the scale of the widening."""
    if node_scale.size < 2:
        return np.zeros((node_scale.size, cwl.size))
    shift = np.abs(np.diff(node_scale))[:, None] * cwl[None, :]
    change = np.maximum(shift, np.abs(np.diff(node_sigma, axis=0)))
    return np.concatenate([change, change[-1:]])
