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
from snapcorr.optics import EffectiveIndexWarning
from snapcorr.optics import goossens2019 as g19

from . import pyplot

CWL, NEFF = 700.0, 1.7
HERE = Path(__file__).parent
PAPER = Lens("Edmund Optics 16 mm", 21.0, 7.4236, 16.991, 0.06, 1.3)
METHODS = ("asymptotic", "ideal", "riemann", "auto")
EDGES = (0.01, 0.1, 1.0)
LABELS = ("< 0.01 nm", "0.01-0.1", "0.1-1", "> 1 nm", "no answer")


def _classify(err):
    cls = np.digitize(err, EDGES).astype(float)
    cls[~np.isfinite(err)] = len(EDGES) + 1
    return cls


def _errors(method, lens, f, cra):
    x = lens.exit_pupil_mm
    t = np.tan(np.deg2rad(cra))
    ref = g19.mean_shift_contour(CWL, NEFF, x, lens.exit_pupil_radius_mm(f), x * t,
                                 lens.vignetting_radius_mm,
                                 (lens.vignetting_distance_mm or 0.0) * t, nodes=48)
    out = np.full(f.shape, np.nan)
    for i in np.ndindex(f.shape):  # per element: one failure must not hide the others
        try:
            out[i] = mean_shift(CWL, NEFF, f[i], cra[i], lens, method=method)
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
                lens = Lens("grid", 21.0, b * R, a * 21.0, 0.06, 1.3)
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
            echo(f"{m:<11} {'f-number x CRA' if key == 'fc' else 'h/x x P/R':<15} "
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
    fig, axes = plt.subplots(2, len(METHODS), figsize=(4 * len(METHODS), 7.5),
                             constrained_layout=True)
    for col, m in enumerate(METHODS):
        for row, (key, a0, a1, l0, l1) in enumerate((
                ("fc", res["f"], res["cra"], "f-number", "CRA (deg)"),
                ("hp", res["hx"], res["PR"], "h / x", "P / R"))):
            ax = axes[row, col]
            im = ax.pcolormesh(a1, a0, res[(key, m)], cmap=cmap, norm=norm, shading="nearest")
            ax.set(xlabel=l1, ylabel=l0, title=f"{m}" + ("" if row == 0 else
                                                         " (f/2, CRA 15 deg)"))
            if key == "fc":
                ax.set_yscale("log")
    cb = fig.colorbar(im, ax=axes, ticks=range(5))
    cb.ax.set_yticklabels(LABELS)
    fig.suptitle("Error of each method against the exact mean (700 nm, n_eff 1.7); white: the "
                 "pupil is fully cut off")
    fig.savefig(HERE / "stability.png", dpi=100)
    plt.close(fig)


if __name__ == "__main__":  # pragma: no cover
    import sys

    run(quick="--quick" in sys.argv)
