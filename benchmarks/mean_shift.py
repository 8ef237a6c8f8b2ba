"""Throughput and accuracy of every way snapcorr computes the kernel-mean shift.

Run ``python -m benchmarks`` (``--quick`` for a seconds-long smoke run). Rates are measured in
this run, on this machine, and printed as ratios to the paper's Riemann sum measured alongside
them, so a noisy machine moves both together. Errors are against a high-precision reference:
the contour quadrature with 48 nodes per arc (itself checked against brute-force pupil
integration and the reference table in the tests, and against 64 nodes here).
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from snapcorr import Lens, ShiftTable, mean_shift
from snapcorr.optics import EffectiveIndexWarning
from snapcorr.optics import goossens2019 as g19

CWL, NEFF = 700.0, 1.7
LENSES = {
    "h<x (Edmund 16 mm)": Lens("Edmund Optics 16 mm", 21.0, 7.4236, 16.991, 0.06, 1.3),
    "h>=x": Lens("long tube", 21.0, 6.5, 27.0, 0.06, 1.3),
}


def _timed(fn, repeat=3):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _pairs(lens, n, rng):
    """(f-number, CRA) pairs over f/1.2-f/16 and CRA 0-30 deg, short of the full cut-off."""
    f = np.exp(rng.uniform(np.log(1.2), np.log(16.0), 3 * n))
    cra = rng.uniform(0.0, 30.0, 3 * n)
    ok = cra < lens.cutoff_cra_deg(f) - 0.05
    return f[ok][:n], cra[ok][:n]


def _contour(lens, f, cra, nodes):
    x = lens.exit_pupil_mm
    R = lens.exit_pupil_radius_mm(f)
    t = np.tan(np.deg2rad(cra))
    return g19.mean_shift_contour(
        CWL, NEFF, x, R, x * t, lens.vignetting_radius_mm, lens.vignetting_distance_mm * t,
        nodes=nodes,
    )


def run(quick=False, echo=print):
    """Measure and print; return the rows as dicts."""
    rng = np.random.default_rng(0)
    n = 2_000 if quick else 100_000
    n_riemann = 100 if quick else 2_000
    rows = []
    warnings.simplefilter("ignore", EffectiveIndexWarning)
    for lname, lens in LENSES.items():
        f, cra = _pairs(lens, n, rng)
        ref = _contour(lens, f, cra, 48)
        check = np.max(np.abs(ref - _contour(lens, f, cra, 64)))
        echo(f"\n== arbitrary (f-number, CRA) pairs, {lname}: {f.size} pairs, "
             f"reference self-check {check:.1e} nm")
        t_r, v_r = _timed(lambda: mean_shift(CWL, NEFF, f[:n_riemann], cra[:n_riemann], lens,
                                             method="riemann"), repeat=1)
        rate_r = n_riemann / t_r
        err_r = np.max(np.abs(v_r - ref[:n_riemann]))
        cases = [("riemann (paper, 0.01 nm)", rate_r, err_r)]
        for nodes in (4, 6, 8, 12):
            t, v = _timed(lambda nodes=nodes: _contour(lens, f, cra, nodes))
            cases.append((f"contour, {nodes} nodes/arc", f.size / t, np.max(np.abs(v - ref))))
        for method in ("vignetted", "ideal", "asymptotic", "auto"):
            t, v = _timed(lambda method=method: mean_shift(CWL, NEFF, f, cra, lens,
                                                           method=method))
            cases.append((f"mean_shift({method!r})", f.size / t, np.max(np.abs(v - ref))))
        echo(f"{'method':<30} {'evals/s':>12} {'x riemann':>10} {'max error nm':>14}")
        for name, rate, err in cases:
            echo(f"{name:<30} {rate:>12.3g} {rate / rate_r:>10.1f} {err:>14.2e}")
            rows.append(dict(workload="pairs", lens=lname, method=name, rate=rate,
                             ratio=rate / rate_r, error=err))

        # A cube: one f-number, millions of CRAs.
        m = 20_000 if quick else 1_000_000
        for fn in (1.4, 4.0):
            cmax = min(30.0, float(lens.cutoff_cra_deg(fn)) - 0.05)
            c = rng.uniform(0, cmax, m)
            exact = _contour(lens, np.full(min(m, 200_000), fn), c[:200_000], 48)
            t_b, table = _timed(lambda fn=fn, cmax=cmax: ShiftTable.build(
                NEFF, fn, lens, cra_max_deg=cmax, tolerance_nm=0.001, cwl_max_nm=CWL), repeat=1)
            t_e, v = _timed(lambda table=table, c=c: table(CWL, c))
            err = np.max(np.abs(v[:200_000] - exact))
            t_a, _ = _timed(lambda fn=fn, c=c: mean_shift(CWL, NEFF, fn, c, lens), repeat=1)
            echo(f"one f-number (f/{fn:g}), {m} CRAs: table of {len(table)} nodes built in "
                 f"{t_b * 1e3:.1f} ms; {m / t_e:.3g} evals/s ({m / t_e / rate_r:.0f} x riemann), "
                 f"max error {err:.1e} nm; mean_shift('auto') end to end {m / t_a:.3g} evals/s")
            rows.append(dict(workload=f"cube f/{fn:g}", lens=lname, method="ShiftTable",
                             rate=m / t_e, ratio=m / t_e / rate_r, error=err))
    return rows
