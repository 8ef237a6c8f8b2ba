"""Where each method fails: error classes over (f-number, CRA) and over (h/x, P/R).

Classes: below 0.01 nm, 0.01-0.1, 0.1-1, above 1 nm, and no answer (an exception or a
non-finite value). The reference is the contour quadrature at 48 nodes per arc. Writes
``stability.png`` and ``stability.csv``; ``tests/test_benchmarks.py`` asserts that
``mean_shift(method="auto")`` lands in no class above its tolerance.
"""

from __future__ import annotations

import csv
import warnings
from pathlib import Path

import numpy as np

from snapcorr import Lens, mean_shift
from snapcorr.optics import EffectiveIndexWarning, ShiftGrid
from snapcorr.optics import goossens2019 as g19
from snapcorr.optics import rienstra1998 as r98

from . import pyplot

CWL, NEFF = 700.0, 1.7
HERE = Path(__file__).parent
PAPER = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
EDGES = (0.01, 0.1, 1.0)
LABELS = ("< 0.01 nm", "0.01-0.1", "0.1-1", "> 1 nm", "no answer")


def _geometry(lens, f, cra):
    x = lens.exit_pupil_mm
    t = np.tan(np.deg2rad(cra))
    return (x, lens.exit_pupil_radius_mm(f), x * t, *lens.vignetting_args(t))


def _api(method, **kw):
    return lambda lens, f, cra: mean_shift(CWL, NEFF, f, cra, lens, method=method, **kw)


def _contour(nodes):
    return lambda lens, f, cra: g19.mean_shift_contour(CWL, NEFF, *_geometry(lens, f, cra),
                                                       nodes=nodes)


def _riemann(step):
    return lambda lens, f, cra: g19.mean_shift_riemann(CWL, NEFF, *_geometry(lens, f, cra),
                                                       step_nm=step)


def _grid(tolerance):
    cache = {}

    def fn(lens, f, cra):
        if lens not in cache:  # built once per lens over the whole chart, as auto caches it
            cache.clear()
            cache[lens] = ShiftGrid.build(NEFF, lens, f_range=(1.2, 16.0), cra_max_deg=30.0,
                                          tolerance_nm=tolerance, cwl_max_nm=CWL)
        return cache[lens](CWL, f, cra)
    return fn


def _rienstra(step):
    def fn(lens, f, cra):
        theta, w = r98.ray_bundle_weights(float(lens.working_f_number(f)), float(cra),
                                          step_deg=step, lens=lens)
        with np.errstate(invalid="ignore", divide="ignore"):  # no ring inside: NaN
            return CWL * (np.sum(w * r98.shift_factors(theta, NEFF)) / np.sum(w) - 1.0)
    return fn


# label -> (function of (lens, f-number, CRA), one setting of each method on the chart)
METHODS = {
    "asymptotic": _api("asymptotic"),
    "ideal": _api("ideal"),
    "riemann 0.01 nm": _riemann(0.01),
    "riemann 0.1 nm": _riemann(0.1),
    "rienstra 1 deg": _rienstra(1.0),
    "contour 2 nodes": _contour(2),
    "contour 4 nodes": _contour(4),
    "grid 0.01 nm": _grid(0.01),
    "table 0.01 nm": _api("table", tolerance_nm=0.01),
    "auto": _api("auto"),
}


def _classify(err):
    cls = np.digitize(err, EDGES).astype(float)
    cls[~np.isfinite(err)] = len(EDGES) + 1
    return cls


def _errors(method, lens, f, cra):
    ref = g19.mean_shift_contour(CWL, NEFF, *_geometry(lens, f, cra), nodes=48)
    fn = METHODS[method]
    out = np.full(f.shape, np.nan)
    for i in np.ndindex(f.shape):  # per element: one failure must not hide the others
        try:
            out[i] = fn(lens, f[i], cra[i])
        except ValueError:
            pass
    return np.abs(out - ref)


def maps(*, quick=False):
    """Error classes of each method over (f-number, CRA) on the paper's lens, and over
    (h/x, P/R) at f/2, CRA 15 deg; returns a dict of arrays."""
    warnings.simplefilter("ignore", EffectiveIndexWarning)
    k = 8 if quick else 24
    f = np.exp(np.linspace(np.log(1.2), np.log(16.0), k))
    cra = np.linspace(0.0, 30.0, k)
    F, C = np.meshgrid(f, cra, indexing="ij")
    ok = C < PAPER.cutoff_cra_deg(F) - 0.05
    out = {"f": f, "cra": cra, "hx": None, "PR": None}
    for m in METHODS:
        e = np.full(F.shape, np.nan)
        e[ok] = _errors(m, PAPER, F[ok], C[ok])
        out[("fc", m)] = np.where(ok, _classify(e), np.nan)
        out[("worst", m)] = float(np.max(np.where(ok, np.nan_to_num(e, nan=np.inf), 0.0)))
    hx = np.linspace(0.3, 2.0, k)
    pr = np.linspace(0.5, 2.5, k)
    R = float(PAPER.exit_pupil_radius_mm(2.0))
    out["hx"], out["PR"] = hx, pr
    for m in METHODS:
        cls = np.full((k, k), np.nan)
        for i, a in enumerate(hx):
            for j, b in enumerate(pr):
                lens = Lens(21.0, [(b * R, a * 21.0)], 0.06, 1.3, name="grid")
                if 15.0 >= lens.cutoff_cra_deg(2.0) - 0.05:
                    continue
                e = _errors(m, lens, np.array([2.0]), np.array([15.0]))
                cls[i, j] = _classify(e)[0]
                worst = float(np.nan_to_num(e[0], nan=np.inf))
                out[("worst", m)] = max(out[("worst", m)], worst)
        out[("hp", m)] = cls
    return out


def run(*, quick=False, echo=print, write=True):
    res = maps(quick=quick)
    for m in METHODS:
        for key in ("fc", "hp"):
            c = res[(key, m)]
            c = c[np.isfinite(c)]
            counts = [int(np.sum(c == i)) for i in range(len(LABELS))]
            echo(f"{m:<16} {'f-number x CRA' if key == 'fc' else 'h/x x P/R':<15} "
                 + "  ".join(f"{lab}: {n}" for lab, n in zip(LABELS, counts, strict=True)))
    if write:
        _write(res)
    return res


def _write(res):
    from matplotlib.colors import BoundaryNorm, ListedColormap

    with open(HERE / "stability.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["map", "method", "axis0", "axis1", "class"])
        for key, a0, a1 in (("fc", res["f"], res["cra"]), ("hp", res["hx"], res["PR"])):
            for m in METHODS:
                for i, u in enumerate(a0):
                    for j, v in enumerate(a1):
                        c = res[(key, m)][i, j]
                        w.writerow([key, m, f"{u:.4g}", f"{v:.4g}",
                                    "" if np.isnan(c) else LABELS[int(c)]])
    plt = pyplot()
    cmap = ListedColormap(["#1a9850", "#a6d96a", "#fdae61", "#d73027", "#000000"])
    norm = BoundaryNorm(np.arange(-0.5, 5.5), cmap.N)
    ncol = (len(METHODS) + 1) // 2
    fig, axes = plt.subplots(4, ncol, figsize=(3.3 * ncol, 12.5), constrained_layout=True)
    for k, m in enumerate(METHODS):
        for block, (key, a0, a1, l0, l1) in enumerate((
                ("fc", res["f"], res["cra"], "f-number", "CRA (deg)"),
                ("hp", res["hx"], res["PR"], "h / x", "P / R"))):
            ax = axes[2 * block + k // ncol, k % ncol]
            im = ax.pcolormesh(a1, a0, res[(key, m)], cmap=cmap, norm=norm, shading="nearest")
            ax.set(xlabel=l1, ylabel=l0, title=m + ("" if block == 0 else " (f/2, CRA 15)"))
            if key == "fc":
                ax.set_yscale("log")
    if len(METHODS) % 2:  # an odd number of methods leaves one panel of each map empty
        axes[1, -1].set_visible(False)
        axes[3, -1].set_visible(False)
    cb = fig.colorbar(im, ax=axes, ticks=range(5))
    cb.ax.set_yticklabels(LABELS)
    fig.suptitle("Error of each method against the exact mean (700 nm, n_eff 1.7); white: the "
                 "pupil is fully cut off")
    fig.savefig(HERE / "stability.png", dpi=100)
    plt.close(fig)


if __name__ == "__main__":  # pragma: no cover
    import sys

    run(quick="--quick" in sys.argv)
