"""Speed against accuracy for every way snapcorr computes the kernel-mean shift.

Workload: (f-number, CRA) pairs over f/1.2-f/16 (log-uniform) and CRA 0-30 deg, on the paper's
lens (h < x) and on a lens in the h >= x regime, 700 nm filters, n_eff 1.7. Error: the worst
absolute error against the contour quadrature with 48 nodes per arc (itself checked against 64
nodes, brute-force pupil integration and the reference table in the tests). Time: per
evaluation, vectorised where the method is, measured in this run. Writes
``speed_accuracy.png`` and ``speed_accuracy.csv`` next to this file; the Pareto front (no
method both faster and more accurate) and the default (``mean_shift(method="auto")``) are
marked.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np

from snapcorr import Lens, mean_shift
from snapcorr.optics import EffectiveIndexWarning, ShiftGrid, shift_nm
from snapcorr.optics import goossens2019 as g19
from snapcorr.optics import rienstra1998 as r98

from . import pyplot, write_csv

CWL, NEFF = 700.0, 1.7
LENSES = {
    "h<x (Edmund 16 mm)": Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm"),
    "h>=x": Lens(21.0, [(6.5, 27.0)], 0.06, 1.3, name="long tube"),
}
HERE = Path(__file__).parent


def _pairs(lens, n, rng):
    f = np.exp(rng.uniform(np.log(1.2), np.log(16.0), 3 * n))
    cra = rng.uniform(0.0, 30.0, 3 * n)
    ok = cra < lens.cutoff_cra_deg(f) - 0.05
    return f[ok][:n], cra[ok][:n]


def _geom(lens, f, cra):
    x = lens.exit_pupil_mm
    t = np.tan(np.deg2rad(cra))
    return (x, lens.exit_pupil_radius_mm(f), x * t, *lens.vignetting_args(t))


def _timed(fn, n, repeat=3):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best / n, out


def _rienstra(lens, f, cra, step):
    out = np.empty(f.size)
    for i, (fi, ci) in enumerate(zip(f, cra, strict=True)):
        theta, w = r98.ray_bundle_weights(float(lens.working_f_number(fi)), float(ci),
                                          step_deg=step, lens=lens)
        with np.errstate(invalid="ignore", divide="ignore"):  # no ring inside: NaN
            out[i] = CWL * (np.sum(w * r98.shift_factors(theta, NEFF)) / np.sum(w) - 1.0)
    return out


# the filter for the full-kernel convolution: a Gaussian of 10 nm FWHM sampled every 0.05 nm
_FILTER_NM = np.arange(CWL - 60.0, CWL + 30.0, 0.05)
_FILTER_T = np.exp(-0.5 * ((_FILTER_NM - CWL) / (10.0 / 2.3548)) ** 2)


def _convolution(lens, f, cra, step):
    """The mean shift as the centroid shift of the filter convolved with the whole kernel
    (Goossens 2019 Eq. 13): Eq. (37) sampled at bin midpoints of ``step`` nm over its support,
    the filter shifted by each bin and summed. This is the work a simulation of the filtered
    signal does; ``filter_response`` does the same with Gauss-Legendre bins whose mean it pins
    to the contour quadrature's, so its mean is not an independent estimate."""
    c0 = np.sum(_FILTER_NM * _FILTER_T) / np.sum(_FILTER_T)
    out = np.empty(f.size)
    for i, (fi, ci) in enumerate(zip(f, cra, strict=True)):
        geom = _geom(lens, fi, ci)
        lo = float(shift_nm(CWL, NEFF, g19.max_aoi_deg(*geom)))
        lam = lo + step * (np.arange(max(1, int(np.ceil(-lo / step)))) + 0.5)
        w = g19.kernel(lam, CWL, NEFF, *geom)
        shifted = np.interp(_FILTER_NM[:, None] - lam[None, :], _FILTER_NM, _FILTER_T,
                            left=0.0, right=0.0)
        with np.errstate(invalid="ignore", divide="ignore"):  # no bin sees the kernel: NaN
            r = shifted @ (w / np.sum(w))
            out[i] = np.sum(_FILTER_NM * r) / np.sum(r) - c0
    return out


def _measure(lname, lens, f, cra, n_slow, quick):
    """Rows for one lens: every method at several settings."""
    n = f.size
    geom = _geom(lens, f, cra)
    ref = g19.mean_shift_contour(CWL, NEFF, *geom, nodes=48)
    fs, cs = f[:n_slow], cra[:n_slow]
    gs = _geom(lens, fs, cs)
    rows = []

    def add(method, setting, timed, m, default=False, setup=0.0):
        per_eval, values = timed
        err = np.abs(values - ref[:m])
        bad = int(np.sum(~np.isfinite(err)))
        rows.append({"lens": lname, "method": method, "setting": setting,
                     "seconds_per_eval": per_eval,
                     # with a one-off set-up (building a lookup) shared by these n evaluations
                     "seconds_per_eval_with_setup": per_eval + setup / n,
                     "worst_error_nm": float(np.max(err)) if bad == 0 else np.inf,
                     "non_finite": bad, "default": default})

    for step in ((0.1, 0.03) if quick else (0.3, 0.1, 0.03, 0.01)):
        try:
            timed = _timed(lambda step=step: g19.mean_shift_riemann(CWL, NEFF, *gs,
                                                                    step_nm=step), n_slow, 1)
        except ValueError:  # a kernel narrower than the step: the sum sees no sample
            rows.append({"lens": lname, "method": "Riemann sum (paper)",
                         "setting": f"step {step} nm (fails on narrow kernels)",
                         "seconds_per_eval": np.nan, "seconds_per_eval_with_setup": np.nan,
                         "worst_error_nm": np.inf,
                         "non_finite": n_slow, "default": False})
            continue
        add("Riemann sum (paper)", f"step {step} nm", timed, n_slow)
    for nodes in (2, 3, 4, 6, 12):
        add("contour quadrature", f"{nodes} nodes/arc", _timed(
            lambda nodes=nodes: g19.mean_shift_contour(CWL, NEFF, *geom, nodes=nodes), n), n)
    add("asymptotic (Eq. 6)", "-", _timed(
        lambda: mean_shift(CWL, NEFF, f, cra, lens, method="asymptotic"), n), n)
    for tol in (1e-1, 1e-2, 1e-3, 1e-4):
        t0 = time.perf_counter()
        grid = ShiftGrid.build(NEFF, lens, f_range=(1.2, 16.0), cra_max_deg=30.0,
                               tolerance_nm=tol, cwl_max_nm=CWL)
        build = time.perf_counter() - t0
        add("lookup (ShiftGrid)", f"tolerance {tol:g} nm, {grid.values.size} values",
            _timed(lambda grid=grid: grid(CWL, f, cra), n), n, setup=build)
    for step in ((1.0,) if quick else (1.0, 0.5, 0.25)):
        add("Rienstra transform", f"step {step} deg",
            _timed(lambda step=step: _rienstra(lens, fs, cs, step), n_slow, 1), n_slow)
    for step in ((0.2,) if quick else (0.5, 0.2, 0.05)):
        add("full-kernel convolution", f"kernel bins {step} nm",
            _timed(lambda step=step: _convolution(lens, fs, cs, step), n_slow, 1), n_slow)
    add("mean_shift auto", "tolerance 0.001 nm",
        _timed(lambda: mean_shift(CWL, NEFF, f, cra, lens), n), n, default=True)
    return rows


def run(*, quick=False, echo=print, write=True):
    """Measure every method at several settings; return rows (dicts)."""
    rng = np.random.default_rng(0)
    n = 2_000 if quick else 20_000
    n_slow = 50 if quick else 400  # per-pair loops and the Riemann sum
    rows = []
    warnings.simplefilter("ignore", EffectiveIndexWarning)
    for lname, lens in LENSES.items():
        f, cra = _pairs(lens, n, rng)
        rows += _measure(lname, lens, f, cra, n_slow, quick)
    for lname in LENSES:
        sel = [r for r in rows if r["lens"] == lname]
        best = np.inf
        key = "seconds_per_eval_with_setup"  # the cost of answering these n pairs once
        for r in sorted(sel, key=lambda r: (np.isnan(r[key]), r[key])):
            r["pareto"] = bool(np.isfinite(r[key]) and r["worst_error_nm"] < best)
            best = min(best, r["worst_error_nm"])
    echo(f"{'lens':<20} {'method':<22} {'setting':<34} {'s/eval':>9} {'worst nm':>9} "
         f"{'non-finite':>10}  front")
    for r in rows:
        echo(f"{r['lens']:<20} {r['method']:<22} {r['setting']:<34} "
             f"{r['seconds_per_eval']:>9.2e} {r['worst_error_nm']:>9.1e} {r['non_finite']:>10}  "
             f"{'*' if r['pareto'] else ''}{' default' if r['default'] else ''}")
    if write:
        _write(rows)
    return rows


def _write(rows):
    plt = pyplot()
    write_csv(HERE / "speed_accuracy.csv", rows)
    methods = sorted({r["method"] for r in rows})
    fig, axes = plt.subplots(1, len(LENSES), figsize=(13, 5), constrained_layout=True,
                             sharey=True)
    for ax, lname in zip(axes, LENSES, strict=True):
        sel = [r for r in rows if r["lens"] == lname]
        key = "seconds_per_eval_with_setup"
        for k, m in enumerate(methods):
            pts = sorted((r for r in sel if r["method"] == m and np.isfinite(r[key])),
                         key=lambda r: r[key])
            err = [max(r["worst_error_nm"], 1e-13) for r in pts]
            ax.plot([r[key] for r in pts], err, "o-", color=f"C{k}", label=m, ms=5)
            if any(r[key] != r["seconds_per_eval"] for r in pts):
                ax.plot([r["seconds_per_eval"] for r in pts], err, "o", color=f"C{k}",
                        mfc="none", ms=5, label=f"{m}, set-up excluded")
        front = sorted((r for r in sel if r["pareto"]), key=lambda r: r[key])
        ax.step([r[key] for r in front], [max(r["worst_error_nm"], 1e-13) for r in front],
                "k--", where="post", lw=0.8, label="Pareto front")
        d = next(r for r in sel if r["default"])
        ax.plot(d[key], max(d["worst_error_nm"], 1e-13), "*", ms=16,
                mfc="none", mec="k", label="default (auto)")
        ax.axhline(0.01, color="grey", lw=0.6, ls=":")
        ax.set(xscale="log", yscale="log",
               xlabel="time per evaluation, set-up included (s, this machine)",
               title=lname)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("worst error over f/1.2-f/16, CRA 0-30 deg (nm)")
    axes[0].legend(fontsize=8)
    fig.suptitle("Kernel-mean shift of 700 nm filters: speed against accuracy "
                 "(dotted: 0.01 nm)")
    fig.savefig(HERE / "speed_accuracy.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":  # pragma: no cover
    import sys

    run(quick="--quick" in sys.argv)
