# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.7
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Finding the exit pupil of an unknown lens
#
# The correction turns a pixel's distance `d` from the optical axis into its chief-ray angle by
# `tan(CRA) = d / x` (Goossens et al. 2019, Eq. 8), so it needs the exit-pupil distance `x`.
# Lens datasheets rarely give it, and the filters' effective index `n_eff` is often only a
# design value.
#
# Both can be measured with the camera itself: image a spatially uniform target whose spectrum
# has features inside the bands (a colour filter, a rare-earth glass, a line lamp). Off axis
# the filters move to the blue, so the same target gives a different signal in each band over
# the field. What the data can tell apart:
#
# - **The field fixes `x * n_eff`.** At small angles the shift depends on
#   `sin^2(CRA) / n_eff^2 ~ d^2 / (x n_eff)^2`: a larger `x` and a smaller `n_eff` give the
#   same picture.
# - **The cone separates `n_eff`.** Every pixel also sees a cone of rays, whose own shift
#   `~ cwl tan^2(theta_cone) / (4 n_eff^2)` does not depend on `x`. Cubes at two f-numbers far
#   apart (f/2 and f/8) change the cone and leave the field: they give `n_eff`, hence `x`.
#
# `snapcorr.calibrate.locate_pupil` fits the binned cubes with the whole filter behind the lens
# (Eq. 13) by least squares in `x` (and `n_eff`), the target's spectrum solved for.
# `pupil_precision` predicts, before any measurement, the standard error of `x` a target would
# give.

# %%
import dataclasses

import matplotlib.pyplot as plt
import numpy as np

from snapcorr import Lens
from snapcorr.calibrate import (
    CANDIDATE_TARGETS,
    FeaturelessTargetError,
    locate_pupil,
    pupil_precision,
)
from snapcorr.cube import Sensor, make_cube
from snapcorr.data import lens_path, sensor_path
from snapcorr.optics import Gaussian
from snapcorr.optics.rienstra1998 import ray_bundle_weights, shift_factors

sensor = Sensor.load(sensor_path("snapscan_vnir"))
paper_lens = Lens.load(lens_path("edmund_optics_16mm"))
print(f"{sensor.name}: {sensor.n_bands} bands {sensor.cwl_nm[0]:g}-{sensor.cwl_nm[-1]:g} nm, "
      f"FWHM {sensor.fwhm_nm[0]:g} nm, n_eff {sensor.n_eff[0]:g}, "
      f"{sensor.size_px[1]} x {sensor.size_px[0]} px of {sensor.pixel_pitch_um:g} um")
print(paper_lens)

# %% [markdown]
# ## Choosing a target
#
# `pupil_precision` gives the Cramer-Rao bound of the model `locate_pupil` fits: the smallest
# standard error of `x` that cubes of a target can give, for a sensor, a lens, the f-numbers
# and the noise per pixel (here a fraction of the brightest band's signal). `CANDIDATE_TARGETS`
# holds four: a white tile, the colour filter of Goossens et al. 2019, a rare-earth glass
# (narrow absorption bands) and a mercury-argon lamp's lines. Here: the bundled Snapscan VNIR
# sensor (full frame) behind the paper's 16 mm lens at f/2 and f/8, with `n_eff` unknown too
# (16 annuli instead of the default 64, for speed: the bound changes by about 1 %).

# %%
f_numbers = (2.0, 8.0)
bounds = {name: pupil_precision(spectrum, sensor, f_numbers, paper_lens, noise=0.01,
                                fit_n_eff=True, n_bins=16)
          for name, spectrum in CANDIDATE_TARGETS.items()}
print(f"noise 1 % per pixel; x = {paper_lens.exit_pupil_mm:g} mm")
print(f"{'target':32s} {'stderr x (mm)':>14s} {'stderr n_eff':>13s}")
for name, p in bounds.items():
    if p.informative:
        print(f"{name:32s} {p.x_stderr_mm:14.2g} {p.n_eff_stderr:13.2g}")
    else:
        print(f"{name:32s} {'no information':>14s}")

# %% [markdown]
# These bounds count pixel noise only, over four million pixels and 150 bands, so they are
# tiny: a few tenths of a micrometre at 1 % noise. A real measurement will be limited long
# before by how well the model describes the camera and the target (the filters' shape, the
# target's uniformity, stray light). What the chart is for is the ranking: a target is worth
# using when its features are narrower than the bands and sit on their flanks. The bound is
# proportional to the noise (the Fisher information goes as 1 / noise^2), so one value per
# target draws its line; the white tile has none.

# %%
noise = np.logspace(-3, -1, 20)
limit = 0.2 * paper_lens.exit_pupil_mm  # locate_pupil refuses a relative error above 20 %
wl = np.arange(430.0, 925.0, 0.05)  # fine enough for the lamp's 0.3 nm lines
fig, (ax_s, ax) = plt.subplots(1, 2, figsize=(12, 4), constrained_layout=True,
                               gridspec_kw={"width_ratios": [1, 1.5]})
for i, (name, spectrum) in enumerate(CANDIDATE_TARGETS.items()):
    s = spectrum(wl)
    ax_s.plot(wl, s / s.max(), lw=1, color=f"C{i}", label=name)
    p = bounds[name]
    if p.informative:
        ax.loglog(100 * noise, p.x_stderr_mm * noise / p.noise, color=f"C{i}", label=name)
ax_s.axvspan(sensor.cwl_nm[0], sensor.cwl_nm[-1], color="0.92", zorder=0)
ax_s.set_xlabel("wavelength (nm); grey: the sensor's bands")
ax_s.set_ylabel("spectrum / its maximum")
ax_s.set_title("the candidate targets")
ax_s.legend(fontsize=7, loc="lower left")
ax.axhspan(limit, 1e2, color="0.85")
ax.text(0.12, 2 * limit, "no information (standard error > 20 % of x):\nthe white tile, at "
        "any noise", fontsize=8, va="bottom")
ax.set_ylim(1e-6, 1e2)
ax.set_xlabel("noise per pixel (% of the brightest band)")
ax.set_ylabel("predicted standard error of x (mm)")
ax.set_title(f"{sensor.name} behind the paper's lens, f/2 and f/8, n_eff fitted")
ax.legend(fontsize=8, loc="center right")
ax.grid(True, which="major", alpha=0.3)

# %% [markdown]
# ## An unknown lens
#
# Now a lens whose `x` we pretend not to know: 24.5 mm, with a vignetting circle that starts
# to cut the cone at f/2 a little below 8 degrees, magnification 0.05 and pupil magnification
# 1.2. The filters' true index is 1.78; the sensor file holds the design value 1.7.
#
# To stay fast, the sensor is the bundled one binned 16 x 16 (128 x 128 pixels of 88 um: the
# same field and chief-ray angles) with every fifth band (30 bands), the noise is 1 % of the
# white level per pixel, and the fits below use 24 annuli per cube (`n_bins=24`; the default
# 96 is the one to keep for real cubes). The target is the rare-earth glass.

# %%
truth = Lens(24.5, [(8.6, 19.8)], 0.05, 1.2, name="the unknown lens")
N_EFF_TRUE = 1.78
binned = dataclasses.replace(
    sensor, name="snapscan-vnir, binned 16 x 16", pixel_pitch_um=16 * sensor.pixel_pitch_um,
    size_px=(128, 128), cwl_nm=sensor.cwl_nm[::5], fwhm_nm=sensor.fwhm_nm[::5],
    n_eff=sensor.n_eff[::5])
true_center = (61.2, 66.3)  # (row, col), pixels: the optical axis off the image centre
target = CANDIDATE_TARGETS["rare-earth glass"]
rows, cols = np.indices(binned.size_px)
d_max = np.hypot(rows - true_center[0], cols - true_center[1]).max() * binned.pixel_pitch_mm
print(f"chief-ray angles up to {np.degrees(np.arctan(d_max / truth.exit_pupil_mm)):.1f} deg; "
      f"the circle starts to cut the cone at {float(truth.onset_cra_deg(2.0)):.1f} deg at f/2")

# %% [markdown]
# The cubes are simulated with Rienstra's ray bundle (`snapcorr.optics.rienstra1998`): the cone
# of a pixel is cut into thin rings of equal incidence angle (the vignetting circle taken into
# account), each ring scales the whole filter curve by the shift law, and the flat-fielded
# value is the target seen through the summed curve over a white tile seen through the same.
# That is a different route from the closed-form kernel `locate_pupil` fits; the tests judge
# the method on a simulator that shares no code with snapcorr at all (`tests/oracles/spectralsim.py`).

# %%
def target_cubes(spectrum, f_numbers, noise, rng, *, n_radii=64, step_deg=0.02):
    """Flat-fielded cubes of a uniform target behind `truth`, keyed by f-number."""
    d2 = ((rows - true_center[0]) ** 2 + (cols - true_center[1]) ** 2) * binned.pixel_pitch_mm**2
    r2 = np.linspace(0.0, d2.max(), n_radii)  # values at these radii, interpolated to pixels
    # per band: the target and a white tile through the curve scaled by s (a tabulation in s)
    s_grid = np.linspace(0.9, 1.0, 401)
    seen, white = [], []
    for cwl, fwhm in zip(binned.cwl_nm, binned.fwhm_nm, strict=True):
        lam = np.arange(0.88 * cwl - 3 * fwhm, cwl + 3 * fwhm, 0.1)
        curves = Gaussian(cwl, fwhm)(lam[:, None] / s_grid[None, :])
        seen.append(spectrum(lam) @ curves)
        white.append(curves.sum(axis=0))
    seen, white = np.array(seen), np.array(white)
    cubes = {}
    for f in f_numbers:
        f_w = float(truth.working_f_number(f))
        values = np.empty((n_radii, binned.n_bands))
        for i, cra in enumerate(np.degrees(np.arctan(np.sqrt(r2) / truth.exit_pupil_mm))):
            theta, weight = ray_bundle_weights(f_w, cra, step_deg=step_deg, lens=truth)
            s = shift_factors(theta, N_EFF_TRUE)
            on_grid = np.array([np.interp(s, s_grid, row) for row in np.vstack([seen, white])])
            values[i] = (on_grid[:binned.n_bands] @ weight) / (on_grid[binned.n_bands:] @ weight)
        data = np.stack([np.interp(d2, r2, v) for v in values.T], axis=-1)
        cubes[f] = make_cube(data + rng.normal(0.0, noise, data.shape), binned.cwl_nm)
    return cubes


rng = np.random.default_rng(2019)
cubes = target_cubes(target, (2.0, 8.0), 0.01, rng)
for f, cube in cubes.items():
    band = cube.isel(band=23).values
    print(f"f/{f:g}: {cube.sizes['y']} x {cube.sizes['x']} x {cube.sizes['band']}; band "
          f"{binned.cwl_nm[23]:.1f} nm from {band[61, 66]:.3f} at the centre to "
          f"{band[127, 0]:.3f} in the farthest corner")

# %% [markdown]
# ### A first pass: nothing known but the magnifications
#
# Before `x` is known, the vignetting circle cannot be measured either (`snapcorr calibrate`
# needs `x`), so the first fit knows only the magnifications (they set the working f-number,
# hence the cone). `fit_n_eff=True` fits one index for all bands (the sensor's values times
# one factor). The optical centre is found from the cubes.

# %%
first = locate_pupil(cubes, binned, fit_n_eff=True, magnification=0.05,
                     pupil_magnification=1.2, n_bins=24)
print(first.summary())

# %%
def against_truth(fit):
    x, sx = fit.exit_pupil_mm, fit.exit_pupil_stderr_mm
    n, sn = fit.n_eff[0], fit.n_eff_stderr[0]
    print(f"x     {x:8.4f} +- {sx:.2g} mm, truth {truth.exit_pupil_mm:g}: "
          f"{x - truth.exit_pupil_mm:+.4f} mm = {(x - truth.exit_pupil_mm) / sx:+.1f} "
          "standard errors")
    print(f"n_eff {n:8.4f} +- {sn:.2g}, truth {N_EFF_TRUE:g}: "
          f"{(n - N_EFF_TRUE) / sn:+.1f} standard errors")


against_truth(first)

# %% [markdown]
# `x` is within a percent but several standard errors off, and `n_eff` is far off: at f/2 the
# vignetting circle cuts the cones of the outer field, which this fit takes as whole, and it
# makes up for that with a wrong index. The reduced chi-square says the model misses
# something. The way on is to measure the vignetting circle with the `x` found
# (integrating-sphere flats and `snapcorr calibrate`, see `lens_characterisation`) and fit
# again with it. (A first pass at slower f-numbers, where the circle cuts less of the field,
# suffers less from this.)
#
# ### With the vignetting circle known
#
# Here the true circle stands in for the calibrated one. The lens given to `locate_pupil`
# supplies its circle and magnifications; its `x` (here the first pass's) is not used as an
# answer.

# %%
known = Lens(first.exit_pupil_mm, truth.vignetting, truth.magnification,
             truth.pupil_magnification, name="P and h from snapcorr calibrate")
fit = locate_pupil(cubes, binned, lens=known, fit_n_eff=True, n_bins=24)
print(fit.summary())
against_truth(fit)

# %% [markdown]
# The bound `pupil_precision` gives for this binned sensor and noise (1 % of the white level,
# `absolute_noise=True`), next to the errors the fit reports:

# %%
pred = pupil_precision(target, binned, (2.0, 8.0), truth, noise=0.01, absolute_noise=True,
                       fit_n_eff=True, n_bins=16)
print(f"predicted stderr of x {pred.x_stderr_mm:.2g} mm, n_eff {pred.n_eff_stderr:.2g}; "
      f"reported {fit.exit_pupil_stderr_mm:.2g} mm, {fit.n_eff_stderr[0]:.2g}")

# %% [markdown]
# The picture: left, the annulus means of the most informative bands against the distance
# from the axis at both f-numbers, with the fitted model; right, chi-square against `x` with
# the target re-fitted at each `x`, and the parabola the standard error implies.

# %%
fig = fit.plot()

# %% [markdown]
# `fit.lens` is the profile to save (`fit.lens.save("my_lens.toml")`): `x`, the circle and
# magnifications it was given, and a `[calibration]` table with the errors, the fitted index,
# the optical centre and the f-numbers.
#
# ## One f-number only
#
# With one cube the cone cannot be told from the field at small angles: there only `x * n_eff`
# is fixed. Over a wide field with a fast cone the field's curvature (`sin^2` against `tan^2`
# of the chief-ray angle) and the cone's tilt off axis pin the index too, so `locate_pupil`
# fits it with `x` and keeps it where it is known to 1 %. At f/8 it is not: `x` is then fitted
# again at the sensor file's index (a note says so) and is off by about the ratio of the
# indices, while `x * n_eff` comes from the fit with the index free, its error including how
# little the index is known.

# %%
one = locate_pupil({8.0: cubes[8.0]}, binned, lens=known, fit_n_eff=True, n_bins=24)
print(one.summary())
product = truth.exit_pupil_mm * N_EFF_TRUE
print(f"x * n_eff {one.x_n_eff_mm:.4g} +- {one.x_n_eff_stderr_mm:.2g} mm, truth {product:.4g} "
      f"({(one.x_n_eff_mm - product) / one.x_n_eff_stderr_mm:+.1f} standard errors)")
print(f"x with the file's n_eff 1.7: {one.exit_pupil_mm:.4g} mm; truth * 1.78 / 1.7 = "
      f"{truth.exit_pupil_mm * N_EFF_TRUE / 1.7:.4g} mm")

# %% [markdown]
# ## A white tile is refused
#
# A target without spectral features looks the same everywhere whatever `x` is. Rather than
# return a meaningless number, `locate_pupil` raises `FeaturelessTargetError`:

# %%
white = target_cubes(CANDIDATE_TARGETS["white tile"], (8.0,), 0.01, rng, n_radii=8)
try:
    locate_pupil(white, binned, lens=known, n_bins=24)
except FeaturelessTargetError as err:
    print("FeaturelessTargetError:", err)

# %% [markdown]
# ## The same from the command line
#
# With the flat-fielded cubes in files (any format snapcorr reads), each step above is a
# command. Before measuring, compare the targets:
#
# ```bash
# snapcorr pupil --predict --sensor snapscan_vnir --lens edmund_optics_16mm \
#     --f-number 2 --f-number 8 --noise-pct 1 --fit-n-eff
# ```
#
# Then `x` and `n_eff` from cubes of the target at two f-numbers, nothing known but the
# magnifications:
#
# ```bash
# snapcorr pupil --cube 2=target_f2_ff.nc --cube 8=target_f8_ff.nc --sensor snapscan_vnir \
#     --magnification 0.05 --pupil-magnification 1.2 --fit-n-eff --out lens_x.toml
# ```
#
# With that `x` (and the magnifications, read from `lens_x.toml`), the vignetting circle
# (P and h) from integrating-sphere flats:
#
# ```bash
# snapcorr calibrate --flat 1.4=flat_f1.4.tif --flat 2=flat_f2.tif --flat 2.8=flat_f2.8.tif \
#     --flat 4=flat_f4.tif --flat 8=flat_f8.tif --dark dark.tif --lens lens_x.toml \
#     --pixel-pitch-um 5.5 --out lens_with_P_h.toml
# ```
#
# and `x` again with the circle known, which writes the finished profile:
#
# ```bash
# snapcorr pupil --cube 2=target_f2_ff.nc --cube 8=target_f8_ff.nc --sensor snapscan_vnir \
#     --lens lens_with_P_h.toml --fit-n-eff --out my_lens.toml --plot my_lens.png \
#     --sensor-out my_sensor.toml
# ```
#
# (`my_sensor.toml` is the sensor with the fitted `n_eff`, for `snapcorr correct`.)
#
# If the second `x` differs from the first by more than a little, calibrate again with it.
