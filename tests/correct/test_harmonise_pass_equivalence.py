"""The Snapscan harmonising pass (``snapcorr.correct.harmonise._tabulated``) against the pass
it replaced, kept here as the reference: the same numbers to float32 rounding (1e-6 of the
data's range at most), NaN at the same places.

The reference is the pass as it was before the two nodes' sums were taken together, in
registers, along their common diagonals and the direct values from the line's kinks: each
node's banded matrix summed diagonal by diagonal into memory for every output in range, then
the values below ``var_direct`` overwritten by
:func:`snapcorr.correct._spectra.spectrum_value`. It runs on the weights that
:func:`snapcorr.correct.harmonise.node_weights` makes now (its rows ``W``, ``lo``, ``cnt`` are
unchanged), laid out along the diagonals as it laid them out. Compiled without ``parallel``
(cached: a few seconds the first time).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from snapcorr.correct import harmonise
from snapcorr.correct._spectra import spectrum_value
from snapcorr.correct.harmonise import harmonise_spectra, node_weights

# ---------------------------------------------------------------------------------------------
# the reference: the pass as it was


def _numpy_reach(W, lo, cnt):
    """Rows of NaN, the weights kept, each weight's diagonal (band - output) and each node's
    first and last diagonal, as numpy found them (both references below)."""
    nb, L = W.shape[1:]
    bad = np.isnan(W).any(axis=2)
    q = np.arange(L)
    keep = (q < cnt[..., None]) & (W != 0) & ~bad[..., None]
    rel = lo[..., None] + q - np.arange(nb)[:, None]  # band - output
    big = np.iinfo(np.int64).max
    off = np.where(keep, rel, big).min(axis=(1, 2))
    last = np.where(keep, rel, -big).max(axis=(1, 2))
    empty = ~keep.any(axis=(1, 2))
    off[empty], last[empty] = 0, 0
    return bad, keep, rel, off, last


def _reference_diagonals(W, lo, cnt):
    m, nb = W.shape[:2]
    _, keep, rel, off, last = _numpy_reach(W, lo, cnt)
    wid = last - off + 1
    D = np.zeros((m, int(wid.max(initial=1)), nb), np.float32)
    ii, kk, qq = np.nonzero(keep)
    D[ii, rel[ii, kk, qq] - off[ii], kk] = W[ii, kk, qq]
    return D, off, wid


def _numpy_diagonals(W, lo, cnt):
    """The layout as numpy made it before the compiled one (``_reach``, ``_lay_out``)."""
    m, nb = W.shape[:2]
    bad, keep, rel, off, last = _numpy_reach(W, lo, cnt)
    wid = last - off + 1
    near = [np.maximum(np.arange(m) - 1, 0), np.arange(m), np.minimum(np.arange(m) + 1, m - 1)]
    base = np.min([off[j] for j in near], axis=0)
    top = np.max([off[j] + wid[j] for j in near], axis=0)
    npad = -(-nb // harmonise._LANES) * harmonise._LANES
    D = np.zeros((m, int((top - base).max(initial=1)) + 1, npad), np.float32)
    ii, kk, qq = np.nonzero(keep)
    D[ii, rel[ii, kk, qq] - base[ii], kk] = W[ii, kk, qq]
    some = D != 0
    first = np.argmax(some, axis=2)
    end = npad - np.argmax(some[:, :, ::-1], axis=2)
    ks = np.where(some.any(axis=2), first // harmonise._LANES * harmonise._LANES, 0)
    ke = np.where(some.any(axis=2), -(-end // harmonise._LANES) * harmonise._LANES, 0)
    return D, base, off, wid, ks.astype(np.int64), ke.astype(np.int64), bad


@numba.njit(cache=True, fastmath={"contract"})
def _reference_diagonal_sums(acc, rows, buf, width, k0):  # pragma: no cover - compiled
    n = acc.size
    for q in range(width):
        r = rows[q, k0:k0 + n]
        b = buf[q:q + n]
        for k in range(n):
            acc[k] += r[k] * b[k]


@numba.njit(cache=True, fastmath={"contract"})
def _reference_pass(data, scale, cra, nodes, D, off, wid, nbad, W, lo, cnt, var, var_direct,
                    near_ptr, near_k, cwl, out):  # pragma: no cover - compiled
    ny, nx, nb = data.shape
    m = nodes.size
    step = (nodes[m - 1] - nodes[0]) / (m - 1) if m > 1 else 1.0
    pad = 0
    for i in range(m):
        pad = max(pad, -off[i], off[i] + wid[i])
    for y in range(ny):
        lam = np.empty(nb)
        d = np.empty(nb)
        buf = np.zeros(nb + 2 * pad, np.float32)
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
                _reference_diagonal_sums(sa[:n], D[i], buf[pad + off[i] + klo:], wid[i], klo)
                _reference_diagonal_sums(sb[:n], D[i1], buf[pad + off[i1] + klo:], wid[i1],
                                         klo)
            else:
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
                for k in range(klo, khi + 1):
                    if nbad[i, k + 1] > nbad[i, k] or nbad[i1, k + 1] > nbad[i1, k]:
                        out[y, x, k] = np.nan
            j = -1
            for c in range(near_ptr[i], near_ptr[i + 1]):
                k = near_k[c]
                if klo <= k <= khi:
                    v2 = (1.0 - u) * var[i, k] + u * var[i1, k]
                    if v2 < var_direct[i, k]:
                        if j < 0:
                            for b in range(nb):
                                lam[b] = cwl[b] * s
                                d[b] = data[y, x, b]
                            j = 0
                        out[y, x, k], j = spectrum_value(lam, d, cwl[k],
                                                         math.sqrt(max(v2, 0.0)), j)


def reference(data, scale, cwl, cra, weights):
    """The old pass on the weights ``node_weights`` makes now."""
    w = weights
    D, off, wid = _reference_diagonals(w.W, w.lo, w.cnt)
    out = np.empty(data.shape, np.float32 if data.dtype == np.float32 else np.float64)
    _reference_pass(data, np.ascontiguousarray(scale[:, :, 0]), np.ascontiguousarray(cra),
                    w.nodes, D, off, wid, w.nbad, w.W, w.lo, w.cnt, w.var, w.var_direct,
                    w.near_ptr, w.near_k, cwl, out)
    return out


# ---------------------------------------------------------------------------------------------
# the cases


def _tables(nb, n_nodes=201, cra_max=20.7, shrink=0.012, sigma_hi=3.0, sigma_lo=0.05, seed=0):
    """Snapscan-like tables: the corrected wavelengths shrink and the widening falls with the
    chief-ray angle (below the direct path's threshold at the field's edge), and grows along
    the bands."""
    rng = np.random.default_rng(seed)
    cwl = np.linspace(470.0, 900.0, nb)
    nodes = np.linspace(0.0, cra_max, n_nodes)
    node_scale = 1.0 - shrink * (nodes / cra_max) ** 2
    fall = np.linspace(sigma_hi, sigma_lo, n_nodes)[:, None]
    node_sigma = fall * np.linspace(0.7, 1.3, nb) * (1.0 + 0.05 * rng.random((n_nodes, 1)))
    return cwl, nodes, node_scale, node_sigma


def _pixels(shape, nodes, node_scale, seed=1, outside=True):
    """Chief-ray angles over the nodes (a few beyond them at each end) and their scales."""
    rng = np.random.default_rng(seed)
    cra = rng.uniform(nodes[0], nodes[-1], shape)
    if outside:
        cra.flat[:3] = nodes[0] - np.array([0.0, 0.3, 2.0])
        cra.flat[-3:] = nodes[-1] + np.array([0.0, 0.3, 2.0])
    scale = np.interp(cra, nodes, node_scale)[..., None]
    return cra, scale


def _check(got, want, data):
    """NaN at the same places, infinities equal, the rest within 1e-6 of the data's range."""
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    inf = np.isinf(want)
    np.testing.assert_array_equal(got[inf], want[inf])
    fin = np.isfinite(want)
    np.testing.assert_array_equal(np.isfinite(got), fin)
    finite = data[np.isfinite(data)]
    span = float(finite.max() - finite.min()) if finite.size else 1.0
    worst = float(np.max(np.abs(got[fin].astype(float) - want[fin]), initial=0.0))
    assert worst <= 1e-6 * span, (worst, span)
    return worst


def _run(data, scale, cwl, cra, weights):
    got = harmonise_spectra(data, scale, np.zeros(cwl.size, int), cwl, cra=cra,
                            weights=weights)
    want = reference(data, scale, cwl, cra, weights)
    return got, want


def _smooth(shape, cwl, seed):
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi, (*shape[:2], 1))
    period = rng.uniform(15.0, 120.0, (*shape[:2], 1))
    return (0.5 + 0.4 * np.sin(2 * np.pi * cwl / period + phase)).astype(np.float32)


@pytest.mark.parametrize(("nb", "sigma_hi"), [(150, 3.0), (37, 3.0), (150, 12.0)])
def test_random_and_smooth_spectra_are_the_reference(nb, sigma_hi):
    """Random and smooth spectra, float32 and float64, offsets; the last tables widen by up
    to 40 band steps, beyond the widths summed in registers (``_PAIR_MAX``)."""
    cwl, nodes, node_scale, node_sigma = _tables(nb, sigma_hi=sigma_hi)
    weights = node_weights(cwl, nodes, node_scale, node_sigma)
    widths = [max(weights.off[i] + weights.wid[i], weights.off[i + 1] + weights.wid[i + 1])
              - min(weights.off[i], weights.off[i + 1]) for i in range(nodes.size - 1)]
    assert (max(widths) > harmonise._PAIR_MAX) == (sigma_hi > 10)
    cra, scale = _pixels((24, 40), nodes, node_scale)
    rng = np.random.default_rng(2)
    for data in (rng.random((*cra.shape, nb), dtype=np.float32),
                 _smooth(cra.shape, cwl, 3),
                 rng.normal(100.0, 30.0, (*cra.shape, nb)),  # float64 data: float32 sums
                 rng.random((*cra.shape, nb), dtype=np.float32) * 1e6 - 3e5):
        got, want = _run(data, scale, cwl, cra, weights)
        _check(got, want, data)
        # the cases have both paths: values above and below the direct path's threshold
        pos = np.clip((cra - nodes[0]) / (nodes[1] - nodes[0]), 0, nodes.size - 1)
        i = np.minimum(pos.astype(int), nodes.size - 2)
        u = (pos - i)[..., None]
        v2 = (1 - u) * weights.var[i] + u * weights.var[i + 1]
        direct = np.sum(v2 < weights.var_direct[i])
        assert 0 < direct < v2.size / 2
        # and outputs outside the pixels' corrected range
        assert 0 < np.isnan(want).sum() < want.size / 10


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_values_that_are_not_finite_spoil_the_same_outputs(bad):
    nb = 60
    cwl, nodes, node_scale, node_sigma = _tables(nb, n_nodes=101)
    weights = node_weights(cwl, nodes, node_scale, node_sigma)
    cra, scale = _pixels((16, 20), nodes, node_scale, seed=4)
    rng = np.random.default_rng(5)
    data = rng.random((*cra.shape, nb), dtype=np.float32)
    flat = data.reshape(-1, nb)
    hit = rng.choice(flat.shape[0], 40, replace=False)
    flat[hit, rng.integers(0, nb, hit.size)] = bad
    flat[hit[:5], :] = bad  # whole spectra
    flat[-1, :3] = bad  # a pixel at the field's edge: direct values
    flat[-2, -2:] = bad
    got, want = _run(data, scale, cwl, cra, weights)
    _check(got, want, data)
    assert np.isnan(want).sum() > np.isnan(reference(rng.random(data.shape, np.float32), scale,
                                                     cwl, cra, weights)).sum()


def test_ranges_cut_on_either_side_and_single_pixels():
    """Pixels whose corrected range leaves out outputs at either end (scales above and below
    one), a spectrum with no output in range, one pixel alone, two nodes."""
    nb = 45
    cwl = np.linspace(470.0, 900.0, nb)
    nodes = np.array([0.0, 10.0])
    node_scale = np.array([1.02, 0.97])
    node_sigma = np.array([np.linspace(0.1, 4.0, nb), np.linspace(2.0, 0.01, nb)])
    weights = node_weights(cwl, nodes, node_scale, node_sigma)
    cra = np.linspace(-1.0, 11.0, 36).reshape(6, 6)
    scale = np.interp(cra, nodes, node_scale)[..., None]
    scale[0, 0] = 3.0  # nothing in range
    data = np.random.default_rng(6).random((*cra.shape, nb), dtype=np.float32)
    got, want = _run(data, scale, cwl, cra, weights)
    _check(got, want, data)
    assert np.isnan(want[0, 0]).all()
    got1, want1 = _run(data[2:3, 3:4], scale[2:3, 3:4], cwl, cra[2:3, 3:4], weights)
    _check(got1, want1, data[2:3, 3:4])
    np.testing.assert_array_equal(got1[0, 0], got[2, 3])


def test_the_benchmark_tables_are_the_reference():
    """The tables ``correct_cube`` makes for the benchmark's sensor and lens at f/1.4, on a
    cube 24 x 24 (so every pixel's angle is new)."""
    from snapcorr import Lens
    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor, make_cube

    lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3)
    n = 24
    sensor = Sensor("bench", "snapscan", 5.5 * 2048 / n, np.linspace(470, 900, 150), 10.0, 1.7)
    data = np.random.default_rng(7).random((n, n, 150), dtype=np.float32)
    seen = {}
    original = harmonise.harmonise_spectra

    def spy(d, sc, column, cwl, sigma=None, **kw):
        seen.update(scale=sc, cwl=cwl, **kw)
        return original(d, sc, column, cwl, sigma, **kw)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(harmonise, "harmonise_spectra", spy)
        got = correct_cube(make_cube(data, sensor.cwl_nm), sensor, 1.4, lens,
                           harmonise=True)["harmonised"].values
    want = reference(data, seen["scale"], seen["cwl"], seen["cra"], seen["weights"])
    _check(got, want, data)
    for smooth in (_smooth(data.shape, seen["cwl"], 8),):
        _check(harmonise_spectra(smooth, seen["scale"], np.zeros(150, int), seen["cwl"],
                                 cra=seen["cra"], weights=seen["weights"]),
               reference(smooth, seen["scale"], seen["cwl"], seen["cra"], seen["weights"]),
               smooth)


def test_the_direct_path_is_unchanged_for_per_band_scales():
    """Per-band scales (several columns) take the direct pass, which the tabulated pass's
    changes leave alone: its values against ``spectrum_value`` pixel by pixel, walked as the
    pass walks them (widenings that change slowly along the bands, as they do)."""
    nb = 30
    cwl = np.linspace(470.0, 900.0, nb)
    rng = np.random.default_rng(10)
    column = np.arange(nb) % 3
    scale = 1.0 - 0.02 * rng.random((5, 6, 3))
    sigma = rng.uniform(0.0, 6.0, (5, 6, 1)) * np.linspace(0.5, 1.0, nb)
    data = rng.random((5, 6, nb), dtype=np.float32)
    got = harmonise_spectra(data, scale, column, cwl, sigma)
    for y, x in np.ndindex(5, 6):
        lam = cwl * scale[y, x, column]
        o = np.argsort(lam, kind="stable")
        lam, d = lam[o], data[y, x, o].astype(float)
        j = 0
        for k in range(nb):
            if cwl[k] < lam[0] or cwl[k] > lam[-1]:
                assert np.isnan(got[y, x, k])
                continue
            want, j = spectrum_value(lam, d, cwl[k], sigma[y, x, k], j)
            assert got[y, x, k] == np.float32(want)


def test_the_compiled_layout_is_the_numpy_one():
    """``_diagonals`` (compiled) lays the weights out as the numpy version before it did: the
    benchmark-like tables, widenings up to 40 band steps, nodes whose scale puts some outputs
    beyond every band (rows of NaN), a node with no weight at all, and one node."""
    cases = []
    for nb, sigma_hi in ((150, 3.0), (37, 12.0), (60, 0.0)):
        cwl, nodes, node_scale, node_sigma = _tables(nb, n_nodes=41, sigma_hi=sigma_hi,
                                                     sigma_lo=0.0 if sigma_hi == 0 else 0.05)
        cases.append((cwl, nodes, node_scale, node_sigma))
    cwl = np.linspace(470.0, 900.0, 40)
    cases.append((cwl, np.array([0.0, 5.0, 10.0]), np.array([1.0, 1.3, 0.6]),
                  np.array([np.full(40, 2.0), np.full(40, 0.5), np.full(40, 8.0)])))
    cases.append((cwl, np.array([1.0]), np.array([0.99]), np.full((1, 40), 1.5)))
    bad_rows = 0
    for cwl, nodes, node_scale, node_sigma in cases:
        w = node_weights(cwl, nodes, node_scale, node_sigma)
        got = harmonise._diagonals(w.W, w.lo, w.cnt)
        want = _numpy_diagonals(w.W, w.lo, w.cnt)
        for a, b in zip(got, want, strict=True):
            assert a.dtype == b.dtype and a.shape == b.shape
            np.testing.assert_array_equal(a, b)
        bad_rows += int(got[-1].sum())
    W = w.W.copy()
    W[0] = 0.0  # a node without a weight
    for a, b in zip(harmonise._diagonals(W, w.lo, w.cnt), _numpy_diagonals(W, w.lo, w.cnt),
                    strict=True):
        np.testing.assert_array_equal(a, b)
    assert bad_rows > 0
