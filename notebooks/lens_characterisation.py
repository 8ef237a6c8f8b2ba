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
# # Characterising a lens from flat fields
#
# The correction needs to know how the lens cuts the cone of rays that reaches each pixel:
# the exit pupil (distance `x`, radius `R` from the f-number) and the vignetting circle, of
# radius `P` whose centre moves off axis as `h tan(CRA)` (Goossens et al. 2019, Sec. 2.7
# and 3.2). `x` comes from the lens data; `P` and `h` are measured. Flat fields of a uniform
# source at several f-numbers hold them: past the *onset* angle, where the vignetting circle
# starts to cut the pupil (Eq. 46), a pixel receives less light, and that angle moves with
# the f-number.
#
# Here the flats are simulated for the paper's Edmund Optics 16 mm lens, so the answer is
# known and the calibration can be checked against it.

# %%
import shlex
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from snapcorr import Lens, mean_shift
from snapcorr.calibrate import calibrate_lens
from snapcorr.calibrate.lens.estimator import MISFIT_CHI2
from snapcorr.cli import build_parser
from snapcorr.optics import cra_map
from snapcorr.paper_experiment import PAPER_LENS
from snapcorr.simulate import flat_frame

truth = PAPER_LENS
print(truth)

# %% [markdown]
# ## Simulated integrating-sphere flats
#
# Five f-numbers, f/1.4 to f/8, 1 % shot noise at the centre, the optical axis a little off
# the image centre. To stay fast the flats are 256 x 256 pixels of 44 um: the same chief-ray
# angles as a 2048 x 2048 sensor of 5.5 um pixels, with 64 times fewer pixels (so about eight
# times the scatter of a full-size calibration).

# %%
f_numbers = (1.4, 2.0, 2.8, 4.0, 8.0)
shape, pitch_um = (256, 256), 44.0
true_center = (118.6, 140.3)  # (row, col), pixels
rng = np.random.default_rng(2019)
flats = {f: flat_frame(shape, pitch_um, f, truth, center_rc=true_center, rng=rng)
         for f in f_numbers}
cra = cra_map(shape, pitch_um, truth.exit_pupil_mm, center_rc=true_center)
print(f"chief-ray angles up to {cra.max():.1f} deg")

fig, axes = plt.subplots(1, 3, figsize=(12, 3.4), constrained_layout=True)
panels = [(flats[1.4], "flat at f/1.4 (DN)", "gray"), (flats[8.0], "flat at f/8 (DN)", "gray"),
          (flats[1.4] / flats[8.0], "ratio f/1.4 / f/8", "magma")]
for ax, (image, title, cmap) in zip(axes, panels, strict=True):
    fig.colorbar(ax.imshow(image, cmap=cmap), ax=ax)
    ax.set_title(title)

# %% [markdown]
# Dividing by the flat at the highest f-number cancels everything that does not depend on the
# aperture (cos^4, the source's non-uniformity, the pixels' response); what is left is the
# vignetting circle cutting the pupil.
#
# ## Calibration
#
# `calibrate_lens` needs the exit-pupil distance, the pixel pitch and, for the working
# f-number of Eq. 27, the magnification and pupil magnification. It finds the optical centre
# itself (unless `center_rc` is given).

# %%
res = calibrate_lens(flats, exit_pupil_mm=21.0, pixel_pitch_um=pitch_um, magnification=0.06,
                     pupil_magnification=1.3, name="Edmund Optics 16 mm (calibrated)")
print(res.summary())

# %% [markdown]
# The paper's Fig. 8: the radial profiles (left) and the ratio profiles with the onsets found
# (circles) and the fitted model (black), its onsets dotted (right).

# %%
fig = res.plot()

# %% [markdown]
# ## Against the truth
#
# `calibrate_lens` runs three estimators on the same flats and keeps all of them:
#
# - **`joint`** fits the vignetted-pupil area model to every ratio image at once, together
#   with the optical centre, with no circle and one to three vignetting circles. It uses
#   every pixel. The number of circles is chosen by three rules (`snapcorr.calibrate.lens.choice`):
#   every circle identifiable (its onset inside the field at two f-numbers, P and h to 5 %,
#   h clear of 0), a gain in an information criterion that allows a 0.1 % systematic floor,
#   and a change of the predicted mean shift larger than a tolerance (0.005 nm).
# - **`onset-ratio`** is the paper's way: where each ratio profile starts to fall (a
#   change-point fit), then `P` and `h` from the onsets by the least squares of Eq. 26.
# - **`onset-model`** fits the area model to each ratio profile separately, takes its onset,
#   then Eq. 26: a check on the other two.

# %%
one = res.fits["one"]
estimates = {
    "joint": (one.params["P_mm"], one.stderr["P_mm"], one.params["h_mm"], one.stderr["h_mm"]),
    **{f"onset-{det}": (of.P_mm, of.P_stderr_mm, of.h_mm, of.h_stderr_mm)
       for det, of in res.onset_fits.items() if of is not None},
}
P0, h0 = truth.vignetting[0][0], truth.vignetting[0][1]
print(f"{'estimator':>12} {'P (mm)':>18} {'error':>8} {'h (mm)':>18} {'error':>8}")
print(f"{'truth':>12} {P0:>18.4f} {'':>8} {h0:>18.3f}")
for name, (P, dP, h, dh) in estimates.items():
    print(f"{name:>12} {P:>9.4f} +- {dP:<6.4f} {100 * (P / P0 - 1):>+7.2f}% "
          f"{h:>9.3f} +- {dh:<6.3f} {100 * (h / h0 - 1):>+7.2f}%")
row, col = res.center_rc
print(f"optical centre row {row:.2f}, col {col:.2f} px from the {res.center_source}, "
      f"true row {true_center[0]}, col {true_center[1]}")
print(f"chosen: {res.method}, {res.model} circle")

# %% [markdown]
# What the errors mean for the correction: the mean shift of a 700 nm filter (n_eff 1.7) at
# f/1.4 behind the calibrated lens and behind the true one.

# %%
cras = np.array([1.9, 10.3, 17.4])
true_shift = mean_shift(700.0, 1.7, 1.4, cras, truth)
found_shift = mean_shift(700.0, 1.7, 1.4, cras, res.lens)
for c, a, b in zip(cras, true_shift, found_shift, strict=True):
    print(f"CRA {c:4.1f} deg: true {a:7.3f} nm, calibrated {b:7.3f} nm, difference "
          f"{b - a:+.4f} nm")

# %% [markdown]
# ## When the area model does not fit: `auto`'s fallback
#
# `method="auto"` (the default) takes the joint fit unless its reduced chi-square says the
# area model does not describe the flats. Real lenses can have a fall-off that changes with
# the aperture (natural vignetting that depends on the aperture size, pupil aberrations)
# which the model lacks. Then only *where* the fall-off starts is trusted, and `auto` falls
# back to the paper's onsets. Here such a fall-off, `1 - tan^2(CRA) / N` at f-number `N`,
# is added to the same flats; the optical centre found above is given (`center_rc`), which
# also spares the fit two parameters:

# %%
tan2 = np.tan(np.deg2rad(cra)) ** 2
distorted = {f: img * (1.0 - tan2 / f) for f, img in flats.items()}
res2 = calibrate_lens(distorted, exit_pupil_mm=21.0, pixel_pitch_um=pitch_um,
                      magnification=0.06, pupil_magnification=1.3, center_rc=res.center_rc)
one2 = res2.fits["one"]
print(f"misfit threshold: reduced chi2 > {MISFIT_CHI2}")
print(f"joint fit: P = {one2.params['P_mm']:.4f} mm ({100 * (one2.params['P_mm'] / P0 - 1):+.2f}"
      f" %), h = {one2.params['h_mm']:.3f} mm ({100 * (one2.params['h_mm'] / h0 - 1):+.2f} %),"
      f" reduced chi2 {one2.reduced_chi2:.2f}")
lens2 = res2.lens
print(f"chosen: {res2.method}: P = {lens2.vignetting[0][0]:.4f} mm "
      f"({100 * (lens2.vignetting[0][0] / P0 - 1):+.2f} %), h = "
      f"{lens2.vignetting[0][1]:.3f} mm ({100 * (lens2.vignetting[0][1] / h0 - 1):+.2f}"
      " %)")
print("why:", res2.reason)

# %% [markdown]
# ## Two circles: a front and a rear element
#
# Many lenses vignette at more than one aperture. Here the same sensor looks through a lens
# with a front circle (h < x) and a rear one (h > x); the summary lists every model tried and
# why it was kept or refused, and the profile keeps both circles.

# %%
two_truth = Lens(21.0, [(7.4236, 16.991), (8.5, 30.0)], 0.06, 1.3, name="front and rear")
two_flats = {f: flat_frame(shape, pitch_um, f, two_truth, center_rc=true_center, rng=rng)
             for f in flats}
res3 = calibrate_lens(two_flats, exit_pupil_mm=21.0, pixel_pitch_um=pitch_um,
                      magnification=0.06, pupil_magnification=1.3)
for name, verdict in res3.verdicts.items():
    print(f"{name:>6}: {'chosen' if verdict.chosen else 'rejected'}: {verdict.why}")
print("profile:", res3.lens.describe_vignetting(), "| truth:", two_truth.describe_vignetting())
shift_err = mean_shift(700.0, 1.7, 2.0, cras, res3.lens) - mean_shift(700.0, 1.7, 2.0, cras,
                                                                       two_truth)
print("mean-shift error at f/2 (nm):", np.round(shift_err, 4))

# %% [markdown]
# A single flat cannot tell `P` from `h` (one onset, two unknowns): give `h`
# (`vignetting_distance_mm`) in that case. A lens whose vignetting circle never reaches the
# field gives "no optical vignetting", and the profile then says the ideal-aperture model
# suffices.
#
# ## The profile: save and read back
#
# The profile is a TOML file: the `[lens]` table the correction uses, and a `[calibration]`
# table recording how it was obtained (f-numbers, onsets, every model's parameters and
# errors, the optical centre, pixel pitch, method and why, date, version).

# %%
tmp = tempfile.TemporaryDirectory(prefix="snapcorr-lens-")
out = Path(tmp.name)
path = res.lens.save(out / "my_lens.toml")
lens = Lens.load(path)
print(lens)
print("same lens as calibrated:", lens == res.lens)
print({k: lens.calibration[k] for k in ("method", "model", "center_rc", "center_source",
                                        "pixel_pitch_um", "image_shape_px")})
print(path.read_text().split("[calibration]")[0].strip())

# %% [markdown]
# ## The same from the command line
#
# With the flats in files (any of `.npy`, `.tif`, `.exr`, ENVI, `.nc`, `.zarr`),
# `snapcorr calibrate` does the same, prints the summary above, writes the profile and, with
# `--plot`, the figure. The cell below saves the flats to the temporary folder and prints the
# command to run there (until the last cell removes the folder); its arguments are checked by
# the command line's own parser.

# %%
for f, img in flats.items():
    np.save(out / f"flat_f{f:g}.npy", img)
args = ["calibrate", *(a for f in f_numbers for a in ("--flat", f"{f:g}=flat_f{f:g}.npy")),
        "--exit-pupil-mm", "21", "--pixel-pitch-um", f"{pitch_um:g}", "--magnification", "0.06",
        "--pupil-magnification", "1.3", "--out", "cli_lens.toml", "--plot", "cli_lens.png"]
parsed = build_parser().parse_args(args)
print(f"cd {out}")
print("snapcorr " + shlex.join(args))
print("estimator:", parsed.method, "| flats:", [f"f/{f:g}" for f, _ in parsed.flat])

# %%
tmp.cleanup()
