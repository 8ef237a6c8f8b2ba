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
per pixel and nothing transcendental in the loop; otherwise each pixel's weights are computed
directly.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .resample import sort_samples

__all__ = ["harmonise_spectra"]

#: The Gaussian is cut at this many standard deviations (the mass beyond: 2e-9).
_REACH = 6.0
#: The tabulated weights stop at this many (the mass beyond: 6e-5) and are renormalised to
#: sum to one: fewer terms per value, a flat spectrum still flat.
_TABLE_REACH = 4.0
_SQRT2 = math.sqrt(2.0)
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


@numba.njit(cache=True)
def _phi(z):  # pragma: no cover - compiled
    return _INV_SQRT_2PI * math.exp(-0.5 * z * z)


@numba.njit(cache=True)
def _cdf(z):  # pragma: no cover - compiled
    return 0.5 * (1.0 + math.erf(z / _SQRT2))


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


@numba.njit(cache=True)
def _value(lam, d, t, sigma, j0):  # pragma: no cover - compiled
    """``sum(w * d)`` of :func:`_segment_weights` without forming ``w``: only the segments
    within reach of ``t`` (found from ``j0`` on; ``t`` increases between calls). Returns the
    value and the first segment in reach, the next call's start."""
    n = lam.size
    if sigma <= 0.0:
        j = j0
        while j < n - 2 and lam[j + 1] < t:
            j += 1
        u = (t - lam[j]) / (lam[j + 1] - lam[j])
        return d[j] + u * (d[j + 1] - d[j]), j
    reach = _REACH * sigma
    j = j0
    while j < n - 2 and lam[j + 1] < t - reach:
        j += 1
    start = j
    acc = 0.0
    if lam[0] > t - reach:
        acc += d[0] * _cdf((lam[0] - t) / sigma)
    if lam[n - 1] < t + reach:
        acc += d[n - 1] * (1.0 - _cdf((lam[n - 1] - t) / sigma))
    za = (lam[j] - t) / sigma
    ca, pa = _cdf(za), _phi(za)
    while j < n - 1 and lam[j] <= t + reach:
        a, b = lam[j], lam[j + 1]
        zb = (b - t) / sigma
        cb, pb = _cdf(zb), _phi(zb)
        mass = cb - ca
        right = ((t - a) * mass + sigma * (pa - pb)) / (b - a)
        acc += right * d[j + 1] + (mass - right) * d[j]
        ca, pa = cb, pb
        j += 1
    return acc, start


@numba.njit(parallel=True, cache=True)
def _direct(data, scale, column, cwl, sigma, out):  # pragma: no cover - compiled
    ny, nx, nb = data.shape
    for y in numba.prange(ny):
        lam = np.empty(nb)
        d = np.empty(nb)
        for x in range(nx):
            for b in range(nb):
                lam[b] = cwl[b] * scale[y, x, column[b]]
                d[b] = data[y, x, b]
            m = sort_samples(lam, d, nb)
            j = 0
            for k in range(nb):
                t = cwl[k]
                if m < 2 or t < lam[0] or t > lam[m - 1]:
                    out[y, x, k] = np.nan
                    continue
                out[y, x, k], j = _value(lam[:m], d[:m], t, sigma[y, x, k], j)


@numba.njit(parallel=True, cache=True, fastmath={"reassoc", "contract"})
def _tabulated(data, scale, cra, nodes, W, lo, cnt, var, sigma_direct, cwl,
               out):  # pragma: no cover - compiled
    # A pixel's weights are those of its two neighbouring nodes, interpolated linearly in
    # chief-ray angle (nodes a few hundredths of a nanometre of shift apart). Below
    # sigma_direct the weights bend within a node step (a straight line's kinks are barely
    # smoothed): those values are computed directly, over the few segments in reach.
    ny, nx, nb = data.shape
    m = nodes.size
    step = (nodes[m - 1] - nodes[0]) / (m - 1) if m > 1 else 1.0
    for y in numba.prange(ny):
        lam = np.empty(nb)
        d = np.empty(nb)
        d32 = np.empty(nb, np.float32)
        for x in range(nx):
            s = scale[y, x]
            for b in range(nb):
                lam[b] = cwl[b] * s
                d[b] = data[y, x, b]
                d32[b] = d[b]
            pos = min(max((cra[y, x] - nodes[0]) / step, 0.0), m - 1.0)
            i = min(int(pos), m - 2) if m > 1 else 0
            u = pos - i
            j = 0
            for k in range(nb):
                t = cwl[k]
                if t < lam[0] or t > lam[nb - 1]:
                    out[y, x, k] = np.nan
                    continue
                v2 = (1.0 - u) * var[i, k] + u * var[i + 1, k]
                if v2 < sigma_direct * sigma_direct:
                    out[y, x, k], j = _value(lam, d, t, math.sqrt(max(v2, 0.0)), j)
                    continue
                # float32 sums (a few tens of terms: 1e-7 of the values), which vectorise
                sa = np.float32(0.0)
                sb = np.float32(0.0)
                a0, a1 = lo[i, k], lo[i + 1, k]
                wa, wb = W[i, k], W[i + 1, k]
                for q in range(cnt[i, k]):
                    sa += wa[q] * d32[a0 + q]
                for q in range(cnt[i + 1, k]):
                    sb += wb[q] * d32[a1 + q]
                out[y, x, k] = (1.0 - u) * sa + u * sb


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


def harmonise_spectra(data, scale, column, cwl_nm, sigma=None, *, cra=None, nodes=None,
                      node_scale=None, node_sigma=None, out=None):
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
        sig = np.ascontiguousarray(np.broadcast_to(sigma, data.shape), dtype=np.float64)
        _direct(data, scale, np.ascontiguousarray(column, dtype=np.int64), cwl, sig, out)
        return out
    if scale.shape[2] != 1 or cra is None:
        raise ValueError("the tabulated path needs one scale column and cra")
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
    # below ten node steps' shift of a band the weights are computed directly
    step = np.max(np.abs(np.diff(node_scale))) * cwl.max() if nodes.size > 1 else 0.0
    _tabulated(data, np.ascontiguousarray(scale[:, :, 0]),
               np.ascontiguousarray(cra, dtype=np.float64), nodes, W, lo, cnt, ns * ns,
               10.0 * step, cwl, out)
    return out
