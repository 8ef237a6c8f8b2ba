"""The compiled passes of ``snapcorr.correct`` against their output before the pass shared by
resampling and harmonising was factored out (``tests/data/correct_kernels_reference.npz``,
made by ``tests/data/make_correct_kernels_reference.py`` at commit 2a152ec)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from snapcorr.correct.harmonise import harmonise_spectra, node_weights
from snapcorr.correct.resample import resample_to_nominal

REF = Path(__file__).parent.parent / "data" / "correct_kernels_reference.npz"


@pytest.fixture(scope="module")
def ref():
    with np.load(REF) as z:
        return {k: z[k] for k in z.files}


def _same(got, want, tol=None):
    """Equal where the reference is (NaN at the same places), to rounding: erf and exp may
    differ by an ulp between platforms' libraries (on the machine that made the reference the
    linear and direct passes are bit for bit the same)."""
    assert got.dtype == want.dtype and got.shape == want.shape
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    if tol is None:
        tol = 1e-6 if want.dtype == np.float32 else 1e-12
    np.testing.assert_allclose(got, want, rtol=tol, atol=tol)


def test_resampling_reproduces_the_reference(ref):
    one = np.zeros(ref["cwl_even"].size, int)
    _same(resample_to_nominal(ref["data"], ref["scale"], ref["column"], ref["cwl_uneven"]),
          ref["resample_64"])
    _same(resample_to_nominal(ref["data"].astype(np.float32), ref["scale"], ref["column"],
                              ref["cwl_uneven"]), ref["resample_32"])
    _same(resample_to_nominal(ref["data"].astype(np.float32), ref["scale_one"], one,
                              ref["cwl_even"]), ref["resample_uniform_32"])


def _brute_harmonised(data, scale, column, cwl, sigma, points=40001):
    """The direct pass by brute force: each pixel's samples sorted (equal wavelengths
    averaged), the straight line through them held constant beyond the ends (``np.interp``),
    averaged with a Gaussian by the trapezoid rule on a fine grid six widths either side
    (1e-8 of the values)."""
    out = np.full(data.shape, np.nan)
    for y, x in np.ndindex(data.shape[:2]):
        lam = cwl * scale[y, x, column]
        uniq, inv = np.unique(lam, return_inverse=True)
        d = np.bincount(inv, data[y, x].astype(float)) / np.bincount(inv)
        for k, t in enumerate(cwl):
            if uniq.size < 2 or not uniq[0] <= t <= uniq[-1]:
                continue
            s = sigma[y, x, k]
            if s <= 0:
                out[y, x, k] = np.interp(t, uniq, d)
                continue
            g = np.linspace(t - 6 * s, t + 6 * s, points)  # with the kinks: exact between
            g = np.union1d(g, uniq[(uniq > g[0]) & (uniq < g[-1])])
            w = np.exp(-0.5 * ((g - t) / s) ** 2)
            out[y, x, k] = np.trapezoid(w * np.interp(g, uniq, d), g) / np.trapezoid(w, g)
    return out


def test_the_direct_pass_is_the_gaussian_average_of_the_line(ref):
    """Against a brute-force average written here, with widths that jump from band to band
    (zero, then wide, then narrow): a wider Gaussian than the last one reaches back over
    segments the last one did not (the reference below, recorded before that was fixed, left
    them out)."""
    args = ref["data"], ref["scale"], ref["column"], ref["cwl_uneven"], ref["sigma"]
    want = _brute_harmonised(*args)
    got = harmonise_spectra(*args)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, rtol=0, atol=5e-8)
    # the recorded reference differs where a widening jumped (so this test can tell)
    old = ref["harmonise_64"]
    assert np.nanmax(np.abs(old - want)) > 1e-3


def test_harmonising_reproduces_the_reference(ref):
    d32 = ref["data"].astype(np.float32)
    one = np.zeros(ref["cwl_even"].size, int)
    # the direct pass where its reach never widened past the last value's (elsewhere, 67 of
    # the 400 values, the reference left segments out: checked against brute force above)
    args = ref["scale"], ref["column"], ref["cwl_uneven"], ref["sigma"]
    want = _brute_harmonised(ref["data"], *args)
    same = np.isnan(want) | (np.abs(ref["harmonise_64"] - want) < 5e-8)
    assert same.mean() > 0.8
    for got, old in ((harmonise_spectra(ref["data"], *args), ref["harmonise_64"]),
                     (harmonise_spectra(d32, *args), ref["harmonise_32"])):
        _same(np.where(same, got, 0).astype(got.dtype), np.where(same, old, 0).astype(old.dtype),
              tol=1e-7)  # (a segment's mass the reference left out may be 5e-8 there)
    # the tabulated pass sums its weights in float32 whatever the data (now in pairs of
    # diagonals, as the compiler vectorised it): the same to float32 rounding of values up to
    # 2, where it takes the path it took then. Its values are computed directly below ten
    # times what changes over a node step: then the largest shift of any band over any step
    # (a few values here); now each band's shift or change of widening over its step, and
    # these tables' widenings jump from node to node (zero at a fifth of them): those values
    # are the direct pass's (each pixel's own scale, which these tables do not match)
    w = node_weights(ref["cwl_even"], ref["nodes"], ref["node_scale"], ref["node_sigma"])
    pos = np.clip((ref["cra"] - ref["nodes"][0]) / (ref["nodes"][1] - ref["nodes"][0]), 0,
                  ref["nodes"].size - 1)
    i = np.minimum(pos.astype(int), ref["nodes"].size - 2)
    u = (pos - i)[..., None]
    v2 = (1 - u) * w.var[i] + u * w.var[i + 1]
    then_limit = (10 * np.max(np.abs(np.diff(ref["node_scale"]))) * ref["cwl_even"].max()) ** 2
    then = v2 < then_limit
    now = v2 < w.var_direct[i]
    assert np.all(now[then]) and 0.1 < np.mean(now == then) < 0.9 and not np.all(now)
    # (values within rounding of either threshold could go either way: left out)
    clear = (np.abs(v2 - then_limit) > 1e-9 * then_limit) & \
        (np.abs(v2 - w.var_direct[i]) > 1e-9 * w.var_direct[i])
    assert clear.mean() > 0.99
    for bits, d in (("32", d32), ("64", ref["data"])):
        got = harmonise_spectra(d, ref["scale_one"], one, ref["cwl_even"], cra=ref["cra"],
                                nodes=ref["nodes"], node_scale=ref["node_scale"],
                                node_sigma=ref["node_sigma"])
        old = ref[f"harmonise_tabulated_{bits}"]
        np.testing.assert_array_equal(np.isnan(got), np.isnan(old))
        same = (now == then) & clear
        _same(np.where(same, got, 0).astype(got.dtype), np.where(same, old, 0).astype(old.dtype),
              tol=1e-6)
        direct = harmonise_spectra(d, ref["scale_one"], one, ref["cwl_even"], np.sqrt(v2))
        moved = now & ~then & clear & np.isfinite(direct)
        assert moved.sum() > 100
        np.testing.assert_allclose(got[moved], direct[moved], rtol=0, atol=1e-6)


def test_no_widening_is_resampling_and_a_scalar_widening_is_a_cube_of_it(ref):
    """One pass serves both: harmonising with zero widening gives ``resampled`` bit for bit,
    and a scalar widening (a broadcast view) the same as the cube of it."""
    args = ref["data"], ref["scale"], ref["column"], ref["cwl_uneven"]
    np.testing.assert_array_equal(harmonise_spectra(*args, 0.0), resample_to_nominal(*args))
    np.testing.assert_array_equal(harmonise_spectra(*args, 2.5),
                                  harmonise_spectra(*args, np.full(ref["data"].shape, 2.5)))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_value_that_is_not_finite_reaches_only_the_outputs_it_weighs_in(bad):
    """The tabulated pass sums each node's banded matrix along its diagonals for speed; a
    pixel with a NaN or infinity is summed row by row instead, so it spoils only the outputs
    whose weights cover it, and every other value is the same bit for bit."""
    rng = np.random.default_rng(11)
    nb = 60
    cwl = np.linspace(470.0, 900.0, nb)
    nodes = np.linspace(0.0, 20.0, 41)
    node_scale = np.linspace(1.0, 0.98, 41)
    node_sigma = 1.0 + 3.0 * rng.random((41, 1)) * np.linspace(0.5, 1.0, nb)
    data = rng.random((6, 8, nb), dtype=np.float32)
    cra = rng.uniform(0.0, 20.0, (6, 8))
    scale = np.interp(cra, nodes, node_scale)[..., None]

    def run(d):
        return harmonise_spectra(d, scale, np.zeros(nb, int), cwl, cra=cra, nodes=nodes,
                                 node_scale=node_scale, node_sigma=node_sigma)

    clean = run(data)
    spoiled = data.copy()
    spoiled[2, 3, 30] = bad
    got = run(spoiled)
    others = np.ones(data.shape[:2], bool)
    others[2, 3] = False
    np.testing.assert_array_equal(got[others], clean[others])
    hit = ~np.isfinite(got[2, 3]) & np.isfinite(clean[2, 3])
    assert hit[30] and 0 < hit.sum() < 20
    assert np.all(np.diff(np.flatnonzero(hit)) == 1)  # one run about the band
    np.testing.assert_array_equal(got[2, 3][~hit], clean[2, 3][~hit])


def test_a_cube_in_blocks_makes_the_weights_once_and_gives_the_same_values(monkeypatch):
    """``correct_cube(harmonise=True)`` on a dask cube: the Snapscan path's weights depend on
    the nodes, not on the pixels, so they are made once for all blocks."""
    import dask
    import xarray as xr

    import snapcorr.correct.harmonise as harmonise
    from snapcorr import Lens
    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor, make_cube

    lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3)
    sensor = Sensor("t", "snapscan", 60.0, np.linspace(470.0, 900.0, 40), 10.0, 1.7)
    cube = make_cube(np.random.default_rng(5).random((30, 36, 40), dtype=np.float32),
                     sensor.cwl_nm)
    calls = []
    original = harmonise.node_weights

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(harmonise, "node_weights", counted)
    whole = correct_cube(cube, sensor, 1.4, lens, harmonise=True)
    blocks = correct_cube(cube.chunk({"y": 7, "x": 10}), sensor, 1.4, lens, harmonise=True)
    with dask.config.set(scheduler="threads"):
        got = blocks["harmonised"].compute()
    assert len(calls) == 2 and blocks["harmonised"].data.npartitions == 20
    xr.testing.assert_identical(got, whole["harmonised"])
