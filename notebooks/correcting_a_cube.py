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
# # Correcting a cube
#
# Every pixel of a thin-film filter camera sees its band at a slightly different wavelength:
# the filter moves to the blue with the chief-ray angle (CRA) of the pixel and with the cone
# of rays the aperture lets through, and the lens's vignetting circle cuts that cone off axis.
# `correct_cube` computes, for every pixel and band, where the filter really is
# (`wavelength_corrected`, Goossens et al. 2019, Eq. 23); it can also put every spectrum back
# onto the nominal wavelengths.
#
# The scene is the paper's experiment (Sec. 3), simulated: a colour filter in front of a
# white tile, seen by a Snapscan-like camera (150 bands, 470-900 nm) behind the Edmund Optics
# 16 mm lens. Every pixel looks at the same filter, so after a good correction every pixel
# shows the same spectrum.

# %%
import contextlib
import dataclasses
import io
import os
import shlex
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from snapcorr import Lens
from snapcorr.cli import main as snapcorr_cli
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, flatfield, make_cube, read_dataset, write_cube, write_dataset
from snapcorr.data import lens_path, sensor_path
from snapcorr.optics import cra_map
from snapcorr.paper_experiment import PAPER_LENS, measured_transmittance, paper_metrics
from snapcorr.simulate import relative_illumination_map

# %% [markdown]
# ## The camera and the lens
#
# The bundled sensor description has 5.5 um pixels; to keep this fast the sensor is binned
# 8 x 8 (44 um pixels), and the cube of 256 x 160 binned pixels covers the same sensor area
# (and chief-ray angles) as 2048 x 1280 pixels. The scene is simulated with the paper's lens;
# the correction uses the bundled profile of that lens (the paper's P and h, Eq. 31).

# %%
base = Sensor.load(sensor_path("snapscan_vnir"))
binning = 8
shape = (160, 256)  # rows, columns: a 2048 x 1280 sensor binned 8 x 8
sensor = dataclasses.replace(
    base, name=f"{base.name} ({binning} x {binning} binned)",
    pixel_pitch_um=base.pixel_pitch_um * binning, size_px=shape)
cwl, fwhm = np.asarray(sensor.cwl_nm), np.asarray(sensor.fwhm_nm)
lens = Lens.load(lens_path())
print(sensor.name, f"{sensor.n_bands} bands, {cwl[0]:g}-{cwl[-1]:g} nm, n_eff",
      sorted(set(sensor.n_eff)))
print("correction:", lens.name, lens.describe_vignetting())
print("simulation:", PAPER_LENS.name, PAPER_LENS.describe_vignetting())

center = (77.5, 131.0)  # optical centre (row, col), a little off the image centre
cra = cra_map(shape, sensor.pixel_pitch_um, lens.exit_pupil_mm, center_rc=center)
print(f"chief-ray angles up to {cra.max():.2f} deg")

# %% [markdown]
# ## Raw, dark and white cubes
#
# Each band's signal is the colour filter seen through that band's filter, smeared by the
# angular kernel of its pixel (`measured_transmittance`, computed on a fine CRA grid and
# interpolated to the pixels); the white tile adds the lens's fall-off (cos^4 and vignetting).
# The raw and white frames get shot noise over a 100 DN dark level; two white frames are
# averaged.

# %%
rng = np.random.default_rng(7)


def simulate(f_number, n_whites=2):
    """Raw, dark and white cubes (DN) of the colour filter on the white tile."""
    grid = np.linspace(0.0, cra.max() + 1e-6, 60)
    per_cra = measured_transmittance(cwl, fwhm, 1.7, f_number, grid, PAPER_LENS)
    transmittance = np.stack([np.interp(cra, grid, per_cra[:, b]) for b in range(cwl.size)],
                             axis=-1)
    white = 3000.0 * relative_illumination_map(shape, sensor.pixel_pitch_um, f_number,
                                               PAPER_LENS, center_rc=center)

    def frame(signal):
        return rng.poisson(signal).astype(np.float32) + np.float32(100.0)

    white_cube = np.broadcast_to(white[..., None], transmittance.shape)
    raw = make_cube(frame(transmittance * white_cube), cwl, fwhm_nm=fwhm)
    whites = [make_cube(frame(white_cube), cwl) for _ in range(n_whites)]
    dark = make_cube(np.full(transmittance.shape, 100.0, np.float32), cwl)
    return raw, dark, whites


f_number = 2.8
raw, dark, whites = simulate(f_number)
ff = flatfield(raw, dark, whites)  # (raw - dark) / (white - dark), Eq. 29
print(f"{int(ff['n_masked'])} values masked;", ff.attrs["method"])
cube = ff["reflectance"]
print(f"reflectance cube: {dict(cube.sizes)}, {cube.dtype}")

# %% [markdown]
# ## Correction
#
# `correct_cube` takes the cube, the lens profile, the sensor (central wavelengths, effective
# indices, pixel pitch) and the f-number. The optical centre is given here; without it,
# `correct_cube` takes it from the lens profile (converted through millimetres when that was
# calibrated with another pixel pitch over the same image area, refused otherwise), else the
# sensor's centre. A cube smaller than the sensor must say where it sits
# (`sensor_origin_px`). `method="auto"` (the default) takes the cheapest
# shift model that meets the tolerance (default 0.01 nm) over the cube's CRA range and says
# why.

# %%
ds = correct_cube(cube, sensor, f_number, lens, center_rc=center, resample=True)
print(ds.attrs["method"], "--", ds.attrs["method_reason"])
print(ds)

# %% [markdown]
# The chief-ray angle of every pixel, and where the filter of the band nearest 700 nm really
# is:

# %%
band = int(np.argmin(np.abs(cwl - 700.0)))
fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.4), constrained_layout=True)
fig.colorbar(a1.imshow(ds["cra_deg"], cmap="viridis"), ax=a1, label="deg")
a1.set_title("chief-ray angle")
fig.colorbar(a2.imshow(ds["wavelength_corrected"][..., band], cmap="magma"), ax=a2,
             label="nm")
a2.set_title(f"corrected wavelength of the {cwl[band]:.1f} nm band at f/{f_number:g}")
print(f"{cwl[band]:.1f} nm band: from {float(ds['wavelength_corrected'][..., band].min()):.2f}"
      f" to {float(ds['wavelength_corrected'][..., band].max()):.2f} nm over the field")

# %% [markdown]
# ## Spectra at three chief-ray angles, with each model
#
# The paper compares the spectra of 5 x 5 pixel spots at CRA 1.9, 10.3 and 17.4 deg by their
# worst correlation coefficient and largest difference on a common grid (`paper_metrics`).
# Besides `auto`, the models can be asked for by name: `none` (nominal wavelengths),
# `asymptotic` (Eq. 6, small angles, no vignetting), `ideal` (exact, no vignetting) and
# `vignetted` (exact, with the vignetting circle).

# %%
inner = np.zeros(shape, bool)
inner[2:-2, 2:-2] = True  # a 5 x 5 spot must fit in the image
spots = {}
for c in (1.9, 10.3, 17.4):
    y, x = np.unravel_index(np.argmin(np.where(inner, np.abs(cra - c), np.inf)), shape)
    spots[c] = (slice(y - 2, y + 3), slice(x - 2, x + 3))
common = np.arange(500.0, 880.0, 1.0)


def spot_spectra(result):
    """Mean spectrum and mean corrected wavelengths of each spot."""
    out = {}
    for c, (sy, sx) in spots.items():
        s = result[cube.name].values[sy, sx].mean(axis=(0, 1))
        w = result["wavelength_corrected"].values[sy, sx].mean(axis=(0, 1)).astype(float)
        out[c] = (s, w)
    return out


results = {m: correct_cube(cube, sensor, f_number, lens, center_rc=center, method=m)
           for m in ("none", "asymptotic", "ideal", "vignetted")}
print(f"{'model':>11} {f'{cwl[band]:.1f} nm band at 17.4 deg':>24} {'worst r':>9} "
      f"{'max diff':>9}")
for m, result in results.items():
    sp = spot_spectra(result)
    r, err = paper_metrics([s for s, _ in sp.values()], [w for _, w in sp.values()], common)
    print(f"{m:>11} {sp[17.4][1][band]:>21.2f} nm {r:>9.5f} {err:>9.4f}")

# %%
fig, axes = plt.subplots(1, 3, figsize=(13, 3.6), sharey=True, constrained_layout=True)
for ax, m in zip(axes, ("none", "ideal", "vignetted"), strict=True):
    for c, (s, w) in spot_spectra(results[m]).items():
        ax.plot(w, s, lw=1, label=f"CRA {c:g} deg")
    ax.set(xlim=(600, 830), xlabel="wavelength (nm)",
           title="uncorrected" if m == "none" else f"{m} model")
    if m == "none":
        ax.set_ylabel("transmittance")
        ax.legend(fontsize=8)

# %% [markdown]
# Uncorrected, the filter's edge and notch sit at different nominal wavelengths in different
# parts of the image. At f/2.8 the onset of vignetting is inside the field, so the ideal
# aperture over-corrects the spots past it; the vignetted model aligns them.
#
# ## Resampling onto the nominal wavelengths
#
# With `resample=True` every pixel's spectrum is interpolated from its corrected wavelengths
# onto the nominal ones (`resampled`), so that a cube can be used as if the filters sat where
# the sensor description says. Where that would need extrapolation the value is NaN: the
# filters moved to the blue, so the reddest nominal wavelengths lie beyond a pixel's reddest
# filter, the more so the larger the shift.

# %%
fig, ax = plt.subplots(figsize=(7, 3.6), constrained_layout=True)
resampled = {}
for c, (sy, sx) in spots.items():
    resampled[c] = ds["resampled"].values[sy, sx].mean(axis=(0, 1))
    ax.plot(cwl, resampled[c], lw=1, label=f"CRA {c:g} deg")
    print(f"CRA {c:4.1f} deg: {int(np.isnan(resampled[c]).sum())} band(s) NaN")
ax.set(xlim=(600, 830), xlabel="nominal wavelength (nm)", ylabel="transmittance",
       title="resampled spectra")
ax.legend(fontsize=8)
stack = np.array(list(resampled.values()))
ok = np.isfinite(stack).all(axis=0)
print(f"largest difference between the spots on the nominal grid: "
      f"{np.ptp(stack[:, ok], axis=0).max():.4f}")

# %% [markdown]
# ## One response per band: spectra the same anywhere in the field
#
# Resampling puts every band where the sensor description says, but not with the same width:
# a pixel's band is its filter spread over the pixel's kernel of ray angles (Goossens Eq. 13),
# wider off axis, narrower again where vignetting cuts the oblique rays. `fwhm_corrected`
# holds every pixel's width. With `harmonise=True` every pixel's spectrum is also widened to
# one common response per band (the widest in the field; `fwhm_harmonised`), so the same
# material gives the same spectrum anywhere (`harmonised`, NaN where `resampled` is).

# %%
dh = correct_cube(cube, sensor, f_number, lens, center_rc=center, resample=True,
                  harmonise=True)
fw = dh["fwhm_corrected"].values[..., band]
print(f"{cwl[band]:.1f} nm band: FWHM {fw.min():.2f}-{fw.max():.2f} nm over the field "
      f"(filter {fwhm[band]:g} nm); common response {float(dh['fwhm_harmonised'][band]):.2f} nm")
spread = {}
fig, axes = plt.subplots(1, 3, figsize=(13, 3.6), constrained_layout=True)
axes[0].imshow(fw, cmap="cividis")
fig.colorbar(axes[0].images[0], ax=axes[0], label="nm")
axes[0].set_title(f"fwhm_corrected, {cwl[band]:.1f} nm band")
for ax, name in zip(axes[1:], ("resampled", "harmonised"), strict=True):
    spectra = []
    for c, (sy, sx) in spots.items():
        s = dh[name].values[sy, sx].mean(axis=(0, 1))
        spectra.append(s)
        ax.plot(cwl, s, lw=1, label=f"CRA {c:g} deg")
    stack = np.array(spectra)
    ok = np.isfinite(stack).all(axis=0)
    spread[name] = float(np.ptp(stack[:, ok], axis=0).max())
    ax.set(xlim=(600, 830), xlabel="nominal wavelength (nm)",
           title=f"{name}: largest difference {spread[name]:.4f}")
axes[1].set_ylabel("transmittance")
axes[1].legend(fontsize=8)
print({k: round(v, 4) for k, v in spread.items()})
if os.environ.get("SNAPCORR_FIGURES"):  # the README's figure
    fig.savefig(Path(os.environ["SNAPCORR_FIGURES"]) / "harmonise.png", dpi=110)

# %% [markdown]
# ## Provenance
#
# The Dataset keeps the input cube unchanged, the CRA map, and how the result was made:

# %%
for key, value in ds.attrs.items():
    print(f"{key:>22}: {value}")

# %% [markdown]
# ## Writing the result
#
# `write_dataset` writes `.nc` (netCDF 4) or `.zarr`, atomically, and refuses to replace an
# existing file unless asked. The corrected wavelengths are stored compactly, as the per-pixel
# `wavelength_scale` and each band's `scale_index`; `read_dataset` rebuilds the
# `wavelength_corrected` coordinate lazily (with plain xarray:
# `back.wavelength * back.wavelength_scale.isel(scale=back.scale_index)`).

# %%
tmp = tempfile.TemporaryDirectory(prefix="snapcorr-cube-")
out = Path(tmp.name)
path = write_dataset(ds, out / "scene_corrected.nc")
back = read_dataset(path)
print(path.name, list(back.data_vars), "| method:", back.attrs["method"])
print(f"{path.stat().st_size / cube.nbytes:.2f} x the cube's bytes on disk")

# %% [markdown]
# ## The same from the command line
#
# `snapcorr flatfield` makes the flat-fielded cube from raw, dark and white files, and
# `snapcorr correct` corrects it. The cell below writes the flat-fielded cube, the binned
# sensor and the lens profile to the temporary folder, prints the command and runs it there
# through the command line's own entry point, then compares its output with the library's.

# %%
write_cube(cube, out / "scene_ff.nc")
sensor.save(out / "sensor.toml")
lens.save(out / "lens.toml")
args = ["correct", "scene_ff.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
        "--f-number", f"{f_number:g}", "--center", f"{center[0]:g},{center[1]:g}",
        "--out", "scene_corrected_cli.nc", "--resample"]
print("snapcorr " + shlex.join(args))
log = io.StringIO()
with contextlib.chdir(out), contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
    status = snapcorr_cli(args)
print(log.getvalue().strip())
assert status == 0, log.getvalue()
cli = read_dataset(out / "scene_corrected_cli.nc")
for name in ("wavelength_corrected", "resampled"):
    diff = np.nanmax(np.abs(cli[name].values - ds[name].values))
    print(f"{name}: largest difference from the library's result {diff:.2g}")

# %%
tmp.cleanup()
