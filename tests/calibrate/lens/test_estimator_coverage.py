"""Do the lens calibration's error bars cover? Judged on flats from rays counted through the
pupil (``tests/oracles/raysim.py``), over lens types and noise levels (``benchmarks/
calibration_coverage.py`` runs the table; the full table is ``slow``).

The default tests check the simulator itself (its row-by-row count is the ray-by-ray count;
it agrees with ``tests/oracles/flatsim.py``'s quadrature, a different method) and what the profile
says its error is made of: the advice of the note is true for the part that sets it.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import raysim
from flatsim import LensTruth, mean_shift_nm, relative_illumination

from snapcorr.calibrate.lens.estimator import _what_sets_it

THREE = ((6.2, 12.0), (10.0, 30.0), (6.5, -10.0))


@pytest.mark.parametrize("t", [0.0, 0.09, 0.17, 0.21, 0.26, 0.29])
def test_row_counts_are_the_ray_by_ray_count(t):
    n, _ = raysim.count_rays(21.0, THREE, 0.0, 1.0, 2.0, [t], rows=80)
    assert n[0] == raysim.count_rays_loop(21.0, THREE, 0.0, 1.0, 2.0, t, rows=80)
    assert n[0] > 0


def test_counted_rays_agree_with_the_quadrature():
    """Two methods, neither snapcorr's: the ray count and flatsim's Gauss-Legendre quadrature
    of the half-chords (to the count's quantisation, ~1e-5 at 2000 rows)."""
    truth = LensTruth(21.0, THREE, 0.06, 1.3)
    t = np.linspace(0.0, 0.3, 40)
    for f in (2.0, 2.8, 5.6):
        ri = raysim.relative_illumination(21.0, THREE, 0.06, 1.3, f, t, rows=2000)
        assert np.max(np.abs(ri - relative_illumination(truth, f, t))) < 2e-5
    # the mean shift averaged over the same rays, against the quadrature's
    cra = np.array([0.0, 8.0, 14.0])
    got = raysim.mean_shift_rays(21.0, THREE, 0.06, 1.3, 2.0, cra, rows=600)
    assert np.max(np.abs(got - mean_shift_nm(truth, 1000.0, 1.5, 2.0, cra))) < 2e-3


def test_flats_follow_the_counts():
    """Noise-free flats are the count times cos^4 times the exposure, and the noise is the
    fraction asked for."""
    fl, e = raysim.flats(21.0, ((9.5, 26.0),), shape=(16, 20), pitch_um=300.0,
                         center_rc=(8.0, 10.0), noise=0.0, rows=1000, n_table=400,
                         f_numbers=(2.0,))
    fn, _ = raysim.flats(21.0, ((9.5, 26.0),), shape=(16, 20), pitch_um=300.0,
                         center_rc=(8.0, 10.0), noise=0.02, rows=1000, n_table=400,
                         f_numbers=(2.0,))
    rr, cc = np.mgrid[0:16, 0:20]
    tan = np.hypot(rr - 8.0, cc - 10.0) * 0.3 / 21.0
    ri = raysim.relative_illumination(21.0, ((9.5, 26.0),), 0.0, 1.0, 2.0, tan.ravel(), 1000)
    want = 40000.0 * e[2.0] * ri.reshape(tan.shape) / (1 + tan**2) ** 2
    # whole DN, and the table's linear interpolation (400 points)
    assert np.max(np.abs(fl[2.0] - want)) <= 0.5 + 40000.0 * 5e-5
    rel = (fn[2.0] - fl[2.0]) / np.maximum(fl[2.0], 1.0)
    assert 0.015 < np.std(rel) < 0.025


def test_flats_of_an_axis_near_a_corner_stay_usable():
    """The optical axis at row 15, column 147 of 128 x 160 (the field reaching tan CRA 0.5):
    at f/5.6 part of the frame is cut off to a few stray counts, and the noise curve fitted
    there came out 0, so 88 % of the flat was masked as outliers and the calibration was
    refused ("13 % usable pixels"). Counted rays; every flat keeps more than 98 %."""
    from snapcorr.calibrate.flats.cleaning import clean_flat

    for seed in (0, 3):
        fl, _ = raysim.flats(21.0, ((9.5, 26.0),), f_numbers=(2.0, 5.6, 11.0), shape=(128, 160),
                             pitch_um=56.8, center_rc=(15.0, 147.0), noise=0.005, seed=seed,
                             rows=1500, n_table=400)
        for f, img in fl.items():
            _, ok, var = clean_flat(img)
            assert ok.mean() > 0.98, (seed, f, ok.mean())
            # the curve is the noise asked for (0.5 % of the signal) where there is light
            lit = img > 0.3 * img.max()
            assert np.median(np.sqrt(var[lit]) / img[lit]) == pytest.approx(0.005, rel=0.1)


def _errs(total, fit, noise, model):
    return {"shift_stderr_nm": np.array([total]), "shift_stderr_fit_nm": np.array([fit]),
            "shift_stderr_noise_nm": np.array([noise]),
            "shift_stderr_model_nm": np.array([model]) if model else np.zeros(0)}


def test_the_note_names_the_part_that_sets_the_error():
    # the noise's part: averaging k frames divides it by sqrt(k)
    note = _what_sets_it(_errs(0.008, 0.008, 0.008, 0.0), 0, 1.0)
    assert "noise sets it" in note and "sqrt(k)" in note and "rest" not in note
    # the choice between models dominates: averaging is not said to divide it by sqrt(k)
    model = 0.0075
    note = _what_sets_it(_errs(math.hypot(0.002, model), 0.002, 0.002, model), 0, 1.0)
    assert "choice between models" in note and "does not shrink as sqrt(k)" in note
    # a misfit: more frames do not lower it
    note = _what_sets_it(_errs(0.009, 0.009, 0.009, 0.0), 0, 9.0)
    assert "misfit sets it" in note and "more frames do not lower it" in note
    # noise leads but the rest is large: the note says the rest does not shrink
    note = _what_sets_it(_errs(0.01, 0.01, 0.008, 0.0), 0, 1.0)
    assert "noise sets it" in note and "does not shrink so" in note


def test_a_dropped_circle_weighs_at_least_its_akaike_weight():
    """The model choice's part of the shift's error: a pixel circle (one parameter more) that
    lowers the floored chi-square by G over 102400 blocks weighs at least its Akaike weight
    ``1 / (1 + exp((2 - G) / 2))`` (Burnham & Anderson 2002, section 2.9), worked out here
    from the AIC's definition. Counted-ray flats at 2 % noise gave G = 0.79 for a pixel
    circle that is there (0.209 nm of shift) and 1.61 for one fitted to noise: the BIC's
    weight (0.005) left the first at z 11, and so did a floor that was zero below G = 2.
    A rival with as many circles (a free h instead of h = x) keeps the BIC's weight."""
    from types import SimpleNamespace as Fit

    from snapcorr.calibrate.lens.choice import _choice_weight

    n, one = 102400, Fit(model="one", k=20488, n=102400)
    pixel = Fit(model="two", k=20489, n=n)

    def akaike(g, dk=1):
        aic_one, aic_more = 2 * one.k, -g + 2 * (one.k + dk)  # chi-square of "one" at 0
        best = min(aic_one, aic_more)
        w_one, w_more = math.exp(-(aic_one - best) / 2), math.exp(-(aic_more - best) / 2)
        return w_more / (w_one + w_more)

    for g in (0.0, 0.79, 1.61, 2.0, 6.3, 40.0):
        bic_gap = math.log(n) - g
        bic_weight = 1.0 / (1.0 + math.exp(bic_gap / 2))
        assert bic_weight < akaike(g)
        assert _choice_weight(pixel, bic_gap, one, 0.0) == pytest.approx(akaike(g), rel=1e-12)
    assert _choice_weight(pixel, math.log(n) - 0.79, one, 0.0) > 0.3
    assert _choice_weight(pixel, math.log(n) - 2.0, one, 0.0) == pytest.approx(0.5)
    free = Fit(model="two", k=20490, n=n)
    assert _choice_weight(free, math.log(n) - 2.5, pixel, 0.0) == pytest.approx(
        1.0 / (1.0 + math.exp((math.log(n) - 2.5) / 2)))
    # a model with fewer circles: the BIC's weight, however close its AIC
    assert _choice_weight(one, 3.0, pixel, 0.0) == pytest.approx(1.0 / (1.0 + math.exp(1.5)))


@pytest.mark.parametrize("key, noise, seed, z_range", [
    # the pixel circle dropped at 2 %: its fit lowers the chi-square by 0.79 and moves the
    # shift by 0.134 nm; 0.209 nm off, reported as 0.019 nm before (z 11.2)
    ("circle_pixel", 0.02, 8, (0.5, 3.0)),
    # no pixel circle at 0.5 %: one fitted to noise moves the shift by 0.021 nm, under its own
    # error (0.042 nm); counted as a dropped circle it made z 0.18
    ("one_h_lt_x", 0.005, 0, (0.5, 2.0)),
])
def test_a_dropped_circle_counts_beyond_its_own_noise(key, noise, seed, z_range, tmp_path,
                                                       monkeypatch):
    """The model choice's part of the shift's error on counted-ray flats
    (``benchmarks/calibration_coverage.py``'s cells and seeds): a circle the flats cannot rule
    out counts with its Akaike weight, less the noise of its own shift difference."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[3]))
    from benchmarks import calibration_coverage as cc

    monkeypatch.setattr(cc, "CACHE", tmp_path)
    row = cc.one((key, noise, seed))
    assert z_range[0] <= abs(row["z_shift"]) <= z_range[1], row


@pytest.mark.slow
def test_every_reported_error_covers():
    """The table of benchmarks/README.md, four seeds a cell (lens type x noise): the errors
    over the reported errors of the shift, and of each P and each h where every seed found
    every circle, are as a unit normal's. Four draws decide little (the RMS of four unit
    normals lies below 0.5 one time in eleven), so each cell's RMS must lie in the band that
    holds it with probability 1 - 1 % / (the number of RMS tested), from the chi-square law;
    the table's [0.5, 2] is for its 8-16 seeds. Where the rules kept a circle in some seeds
    only, they kept it where the noise made it look stronger than it is: its z there is
    conditional on that choice, not a coverage figure (the shift's error carries the
    choice, through its model-choice term)."""
    from scipy.stats import chi2

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks import calibration_coverage as cc

    rows = cc.main(workers=2, out="calibration_rays_test.csv")
    (Path(cc.HERE) / "calibration_rays_test.csv").unlink(missing_ok=True)
    draws = {}  # (case, noise, what) -> the z of every seed
    for r in rows:
        cell = (r["case"], r["noise"])
        draws.setdefault((*cell, "shift"), []).append(r["z_shift"])
        for col in ("z_P", "z_h"):
            for i, v in enumerate(r[col].split()):
                draws.setdefault((*cell, f"{col} {i}"), []).append(float(v))
    seeds = {}
    for r in rows:
        seeds[(r["case"], r["noise"])] = seeds.get((r["case"], r["noise"]), 0) + 1
    tested = {k: np.asarray(v, float) for k, v in draws.items()
              if k[2] == "shift" or len(v) == seeds[k[:2]]}
    tested = {k: v[np.isfinite(v)] for k, v in tested.items()}  # h held at x: no z
    tested = {k: v for k, v in tested.items() if v.size}
    alpha = 0.01 / len(tested)
    bad = {}
    for k, v in tested.items():
        n = v.size
        lo, hi = (math.sqrt(chi2.ppf(q, n) / n) for q in (alpha / 2, 1 - alpha / 2))
        rms = math.sqrt(np.mean(v * v))
        if not lo <= rms <= hi:
            bad[k] = (round(rms, 2), round(lo, 2), round(hi, 2))
    assert len(tested) >= 30 and not bad, bad
