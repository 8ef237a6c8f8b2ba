# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Choosing a method
#
# The mean shift of a filter behind a lens (the kernel mean, Goossens et al. 2019, Eq. 22)
# can be computed several ways, from the paper's Riemann sum to lookup tables.
# `mean_shift(..., method=...)` offers:
#
# | method | what it computes |
# |---|---|
# | `"vignetted"` | the exact kernel mean of the vignetted pupil (contour quadrature) |
# | `"ideal"` | the same without the vignetting circle |
# | `"asymptotic"` | Eq. 6, the small-angle formula of the ideal aperture |
# | `"riemann"` | the paper's left Riemann sum in wavelength, 0.01 nm step |
# | `"table"` | a `ShiftTable` over CRA per (f-number, n_eff), built from the exact method |
# | `"grid"` | a `ShiftGrid` over (f-number, CRA) per n_eff, built from the exact method |
# | `"auto"` | the cheapest of these that meets `tolerance_nm` |
#
# This notebook shows the measured trade-off between speed and accuracy (the benchmark's
# data), measures a few methods on this machine, and shows what `"auto"` picks and why.

# %%
import collections
import csv
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import snapcorr
from snapcorr import Lens, mean_shift
from snapcorr.cube import Sensor
from snapcorr.data import lens_path, sensor_path
from snapcorr.optics import choose_model, select_method
from snapcorr.optics.mean import AUTO_GRID_MIN_SIZE, AUTO_TABLE_MIN_SIZE

# %% [markdown]
# ## The benchmark's data
#
# `python -m benchmarks` times every method at several settings on many (f-number, CRA)
# pairs for two lenses, the paper's (`h < x`) and one with `h >= x`, and takes the worst
# error against the contour quadrature at 48 nodes per arc (`benchmarks/README.md` describes
# the run). Its data sit in `benchmarks/`, found here from the working directory or from the
# installed package.


# %%
def repo_root():
    """The source checkout holding benchmarks/ (from here, a parent, or the package)."""
    here = Path.cwd().resolve()
    for folder in (here, *here.parents, Path(snapcorr.__file__).resolve().parents[1]):
        if (folder / "benchmarks" / "speed_accuracy.csv").is_file():
            return folder
    raise FileNotFoundError("benchmarks/speed_accuracy.csv not found: run from a source "
                            "checkout of snapcorr")


root = repo_root()
with open(root / "benchmarks" / "speed_accuracy.csv", newline="") as fh:
    rows = list(csv.DictReader(fh))
for row in rows:
    for key in ("seconds_per_eval", "seconds_per_eval_with_setup", "worst_error_nm"):
        row[key] = float(row[key])
    row["non_finite"] = int(row["non_finite"])
    row["default"] = row["default"] == "True"
lenses = list(dict.fromkeys(row["lens"] for row in rows))

for lens_name in lenses:
    print(f"lens {lens_name}")
    print(f"  {'method':<20} {'setting':<36} {'s / evaluation':>14} {'worst error nm':>15}")
    for row in rows:
        if row["lens"] != lens_name:
            continue
        if row["non_finite"]:
            result = f"no answer for {row['non_finite']} pairs"
            print(f"  {row['method']:<20} {row['setting']:<36} {result:>30}")
        else:
            print(f"  {row['method']:<20} {row['setting']:<36} "
                  f"{row['seconds_per_eval_with_setup']:>14.2e} {row['worst_error_nm']:>15.2e}"
                  + ("  <- default" if row["default"] else ""))

# %% [markdown]
# The same as a chart: time per evaluation against worst error, both logarithmic. Times
# include any one-off set-up shared by all the pairs (building a lookup); hollow markers
# show the lookups without it. Rows with no answer for some pairs are left out.

# %%
methods = list(dict.fromkeys(row["method"] for row in rows))
colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
style = {m: (colours[i % len(colours)], "osD^v*Xp"[i % 8]) for i, m in enumerate(methods)}
fig, axes = plt.subplots(1, len(lenses), figsize=(13, 4.5), sharey=True,
                         constrained_layout=True)
axes[0].set_ylabel("worst error (nm)")
for ax, lens_name in zip(axes, lenses, strict=True):
    for method, (colour, marker) in style.items():
        sel = [r for r in rows if r["lens"] == lens_name and r["method"] == method
               and not r["non_finite"] and np.isfinite(r["worst_error_nm"])]
        if not sel:
            continue
        err = [r["worst_error_nm"] for r in sel]
        ax.plot([r["seconds_per_eval_with_setup"] for r in sel], err, marker, color=colour,
                ms=9 if method == "mean_shift auto" else 6, label=method)
        if method.startswith("lookup"):
            ax.plot([r["seconds_per_eval"] for r in sel], err, marker, mfc="none",
                    color=colour)
    ax.set(xscale="log", yscale="log", xlabel="seconds per evaluation",
           title=f"lens {lens_name}")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)

# %% [markdown]
# Where each method fails, from the stability maps (`benchmarks/stability.csv`): the error
# class of each method over a grid of f-numbers and chief-ray angles on the paper's lens
# (cells where the pupil is fully cut off are left out).

# %%
with open(root / "benchmarks" / "stability.csv", newline="") as fh:
    cells = [r for r in csv.DictReader(fh) if r["map"] == "fc" and r["class"]]
order = ("< 0.01 nm", "0.01-0.1", "0.1-1", "> 1 nm", "no answer")
found = {r["class"] for r in cells}
classes = [c for c in order if c in found] + sorted(found - set(order))
counts = collections.Counter((r["method"], r["class"]) for r in cells)
methods_on_map = list(dict.fromkeys(r["method"] for r in cells))
print(f"{'method':<18}" + "".join(f"{c:>12}" for c in classes))
for m in methods_on_map:
    print(f"{m:<18}" + "".join(f"{counts[m, c]:>12}" for c in classes))

# %% [markdown]
# ## Measured here
#
# A small live measurement on the bundled lens profile: a 700 nm filter (n_eff 1.7) at five
# f-numbers and 401 chief-ray angles from 0 to 20 deg. The reference is
# `method="vignetted"`. Times are the best of three calls, divided by the number of
# evaluations; "first call" includes any set-up (`"table"` builds its tables on every call,
# `"grid"` keeps its grids in a cache, so later calls only look up). The Riemann sum is timed
# on every fifth pair.

# %%
lens = Lens.load(lens_path())
f_grid, cra_grid = np.meshgrid([1.4, 2.0, 2.8, 4.0, 8.0], np.linspace(0.0, 20.0, 401),
                               indexing="ij")
f_grid, cra_grid = f_grid.ravel(), cra_grid.ravel()
reference = mean_shift(700.0, 1.7, f_grid, cra_grid, lens, method="vignetted")


def measure(method, every=1):
    f, c = f_grid[::every], cra_grid[::every]
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        value = mean_shift(700.0, 1.7, f, c, lens, method=method)
        times.append((time.perf_counter() - t0) / f.size)
    return times[0], min(times), float(np.max(np.abs(value - reference[::every])))


live = {m: measure(m) for m in ("asymptotic", "ideal", "vignetted", "table", "grid", "auto")}
live["riemann"] = measure("riemann", every=5)

fig, ax = plt.subplots(figsize=(6.5, 4), constrained_layout=True)
for m, (_, best, err) in live.items():
    ax.plot(best, max(err, 1e-13), "o", label=m)
ax.set(xscale="log", yscale="log", xlabel="seconds per evaluation (best of 3)",
       ylabel="worst error against 'vignetted' (nm)", title="measured on this machine")
ax.grid(alpha=0.3, which="both")
ax.legend(fontsize=8)
print(f"{f_grid.size} pairs")
print(f"{'method':>11} {'first call':>12} {'best of 3':>12} {'worst error nm':>15}")
for m, (first, best, err) in live.items():
    print(f"{m:>11} {first:>10.2e} s {best:>10.2e} s {err:>15.2e}")

# %% [markdown]
# The reference's own error is zero by definition (plotted at 1e-13). On so few pairs the
# lookups' set-up is not repaid: `"table"` builds a table per f-number on every call, and
# `"grid"` is fast only once its grid is cached. They pay off on large inputs, which is why
# `"auto"` uses them only above a size threshold (below).
#
# ## What `"auto"` does in `mean_shift`
#
# Element by element, the cheapest exact-enough model: Eq. 6 where the pixel is not
# vignetted and four times Eq. 6's fourth-order error term is below the tolerance (default
# 0.001 nm); the exact ideal aperture where the pixel is not vignetted (before the onset the
# two kernels are the same); the exact vignetted aperture elsewhere. `select_method` says
# which each element got. Large groups sharing an f-number and n_eff (a cube) go through a
# `ShiftTable` instead, large scattered remainders through a cached `ShiftGrid`, both built to
# the same tolerance:

# %%
print(f"ShiftTable from {AUTO_TABLE_MIN_SIZE} elements sharing (f-number, n_eff); ShiftGrid "
      f"from {AUTO_GRID_MIN_SIZE} scattered elements")
chosen = select_method(1.7, f_grid, cra_grid, lens, cwl_nm=700.0)
for f in np.unique(f_grid):
    sel = f_grid == f
    picked = collections.Counter(chosen[sel])
    onset = float(lens.onset_cra_deg(f))
    print(f"f/{f:<4g} onset {onset:5.2f} deg: "
          + ", ".join(f"{m} {n}" for m, n in sorted(picked.items())))

# %% [markdown]
# ## What `"auto"` does for a cube
#
# `correct_cube` chooses one model for the whole cube with `choose_model`: the cheapest
# whose error stays below its tolerance (default 0.01 nm) over the cube's chief-ray angles and
# bands: `none` when no band moves by more than the tolerance, then Eq. 6, then the exact
# ideal aperture while every CRA is below the onset of vignetting, else the vignetted
# aperture. The choice and its reason are recorded in the result's attrs. For the bundled
# Snapscan-like sensor (150 bands, 470-900 nm) behind the bundled lens, with three centred
# fields of view (2048 x 1280 pixels is the area of the `correcting_a_cube` notebook):

# %%
sensor = Sensor.load(sensor_path("snapscan_vnir"))
cwl, n_eff = np.asarray(sensor.cwl_nm), np.asarray(sensor.n_eff)


def cra_max_deg(width_px, height_px):
    """Largest chief-ray angle of a field of view centred on the optical axis."""
    half_diagonal_mm = 0.5 * np.hypot(width_px, height_px) * sensor.pixel_pitch_mm
    return float(np.degrees(np.arctan(half_diagonal_mm / lens.exit_pupil_mm)))


cases = [(1.4, (2048, 1280), 0.01), (8.0, (2048, 1280), 0.01), (8.0, (256, 256), 0.01),
         (16.0, (64, 64), 0.5)]
for f, (w, h), tol in cases:
    c = cra_max_deg(w, h)
    method, reason = choose_model(cwl, n_eff, f, c, lens, tolerance_nm=tol)
    print(f"f/{f:g}, {w} x {h} px (CRA <= {c:.2f} deg), tolerance {tol:g} nm -> {method}")
    print(f"    {reason}")

# %% [markdown]
# ## Which to use
#
# - **Cubes:** `correct_cube(..., method="auto")` (or `snapcorr correct`). It picks the model
#   from the lens, f-number and field, and builds one table per effective index, so its cost
#   is negligible next to reading the cube. Ask for a model by name only to compare models.
# - **Scattered (f-number, CRA) pairs in your own code:** `mean_shift(..., method="auto")`.
#   For many pairs it goes through a cached lookup grid; `"grid"` asks for that directly.
# - **A reference or a check:** `"vignetted"`, the exact kernel mean; `"ideal"` is exact for
#   lenses without a vignetting circle and, on any lens, up to the onset of vignetting.
# - **Eq. 6 (`"asymptotic"`):** the fastest, but only for small angles at small apertures and
#   no vignetting; past the onset it can be off by many nanometres.
# - **The paper's Riemann sum (`"riemann"`):** a baseline to compare with the paper; it is
#   the slowest and fails when the kernel is narrower than its step.
