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
# # Mosaic cameras as they ship
#
# A snapshot-mosaic camera comes with the vendor's calibration file: each band's measured
# response (all its peaks), the band-pass in front of the sensor, the mosaic layout and its
# active area, and a correction matrix that turns the physical bands into "virtual bands" with
# the crosstalk removed. That matrix was computed for light at normal incidence; behind a lens
# every pixel's responses shift and widen with its chief-ray angle (CRA) and the f-number.
#
# This notebook reads a real 5x5 NIR file (bundled as `imec_5x5_nir`, with the pixel pitch and
# an effective index the file does not give), simulates frames of a uniform target through
# the lens, and compares the vendor's virtual bands with snapcorr's fitted and angle-aware
# ones across the field.

# %%
import matplotlib.pyplot as plt
import numpy as np

import snapcorr.data
from snapcorr import Lens
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, flatfield, mosaic_to_cube

sensor = Sensor.load(snapcorr.data.sensor_path("imec_5x5_nir"))
lens = Lens.load(snapcorr.data.lens_path("edmund_optics_16mm"))
print("\n".join(sensor.describe().splitlines()[:6]))
print(sensor.describe().splitlines()[-1])

# %% [markdown]
# The bands' measured responses through the band-pass: narrow main peaks, with side lobes and
# leaks of a few percent to tens of percent. Below, what the vendor's matrix makes of them.

# %%
from snapcorr.quicklook import plot_sensor  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

out = Path(tempfile.mkdtemp())
plot_sensor(sensor, out / "filters.png")
print("drew", out / "filters.png")
r = sensor.responses
fig, ax = plt.subplots(figsize=(9, 3))
for b in range(sensor.n_bands):
    ax.plot(r.wavelength_nm, r.effective[b] / r.effective[b].max(), lw=0.7)
ax.plot(r.wavelength_nm, r.system / r.system.max(), "k--", label=r.system_name)
ax.set(xlim=(580, 900), xlabel="wavelength (nm)", ylabel="relative response")
ax.legend(fontsize=8);

# %% [markdown]
# ## Raw frames cut to the active area
#
# `mosaic_frames` simulates whole-sensor frames: a uniform target (its reflectance peaks in
# the middle of the bands), a dark and a white frame, at f/2.8 behind the bundled lens; every
# pixel sees its band's measured curve shifted and widened by its own cone of rays. A frame of
# the whole sensor is cut to the file's filter area (rows 3-1082) by `mosaic_to_cube`; each
# band keeps its sensor position.

# %%
raw, dark, white = snapcorr.data.mosaic_frames("imec_5x5_nir", f_number=2.8)
cubes = [mosaic_to_cube(frame, sensor) for frame in (raw, dark, white)]
print(raw.shape, "->", cubes[0].shape, cubes[0].attrs["mosaic_area_px"])
ff = flatfield(*cubes, saturation=sensor.full_scale_dn)["reflectance"]

# %% [markdown]
# ## Virtual bands across the field
#
# `correct_cube(..., virtual_bands=...)` adds `virtual(y, x, virtual_band)`:
#
# - `vendor`: the file's matrix (an irradiance matrix, given the white for flat-fielded values);
# - `fitted`: a Wiener estimate from the measured responses at normal incidence;
# - `angle-aware`: the same for each pixel's responses behind the lens.
#
# The target is known, so each pixel's error against the ideal virtual bands (Gaussians of the
# vendor's wavelengths and 15 nm width) can be measured.

# %%
target = snapcorr.data.mosaic_target(sensor)
results = {m: correct_cube(ff, sensor, 2.8, lens, virtual_bands=m)
           for m in ("vendor", "fitted", "angle-aware")}
some = results["vendor"]
wl, fw = some["virtual_wavelength"].values, some["virtual_fwhm"].values
grid = np.arange(400.0, 1001.0)
G = np.exp(-4 * np.log(2) * ((grid[None] - wl[:, None]) / fw[:, None]) ** 2)
truth = G @ target(grid) / G.sum(axis=1)
cra = some["cra_deg"].mean("band").values
edges = np.arange(0.0, cra.max() + 2.0, 2.0)
fig, ax = plt.subplots(figsize=(7, 4))
for m, ds in results.items():
    err = np.sqrt(np.mean((ds["virtual"].values - truth) ** 2, axis=2))
    rms = [np.sqrt(np.mean(err[(cra >= a) & (cra < b)] ** 2)) for a, b in zip(edges, edges[1:])]
    ax.plot(edges[:-1] + 1.0, rms, marker="o", label=m)
    print(f"{m:12s} RMSE on the axis {rms[0]:.4f}, at the edge {rms[-1]:.4f}; "
          f"virtual_stderr up to {float(ds['virtual_stderr'].max()):.4f}")
ax.set(xlabel="chief-ray angle (deg)", ylabel="RMSE of the virtual bands", yscale="log")
ax.legend();

# %% [markdown]
# The vendor's matrix is worst (the virtual bands it gives are narrower than their stated
# 15 nm, and it was made for normal incidence); the fitted one is good on the axis and drifts
# off it; the angle-aware one stays put across the field, within the noise of the frames.
# `virtual_stderr` says how large each method's error is expected to be, the largest over the
# field: it counts a matrix's misfit off the axis.
#
# Spectra of a corner tile and of the centre:

# %%
ny, nx = cra.shape
fig, axes = plt.subplots(1, 3, figsize=(12, 3.5), sharey=True)
for ax, (m, ds) in zip(axes, results.items(), strict=True):
    order = np.argsort(wl)
    for (y, x), label in (((ny // 2, nx // 2), "centre"), ((2, 2), "corner")):
        v = ds["virtual"].values[y - 2:y + 3, x - 2:x + 3].reshape(-1, wl.size).mean(axis=0)
        ax.plot(wl[order], v[order], marker=".", label=f"{label} ({cra[y, x]:.0f} deg)")
    ax.plot(grid, target(grid), "k:", lw=1, label="target")
    ax.set(title=m, xlim=(600, 880), xlabel="wavelength (nm)")
axes[0].set_ylabel("reflectance")
axes[0].legend(fontsize=8);

# %% [markdown]
# ## Every band at every pixel
#
# A tile cube has one spectrum per 5 x 5 pixels. `demosaic` estimates every band at every
# pixel of the flat-fielded frame; here a corner of the frame with a sharp edge painted into it
# (half the reflectance on its right), by tile replication, weighted bilinear interpolation and
# residual interpolation (the default). The tiles blur the edge over five pixels and leave
# colour fringes; residual interpolation keeps it where it is.

# %%
from snapcorr.cube import demosaic  # noqa: E402

ff_frame = flatfield(raw, dark, white, saturation=sensor.full_scale_dn)
edge = ff_frame["reflectance"].values.copy()
edge[:, 1000:] *= 0.5  # an edge, sharper than any lens would give
crop = (slice(500, 540), slice(975, 1025))
fig, axes = plt.subplots(1, 3, figsize=(12, 3), sharey=True)
for ax, method in zip(axes, ("nearest", "bilinear", "ri"), strict=True):
    full = demosaic(edge[crop], sensor, method, sensor_origin_px=(500, 975))
    ax.imshow(full.values[..., 12], cmap="gray", vmin=0, vmax=0.6)
    ax.set(title=f"{method}, band {full.wavelength.values[12]:.0f} nm")
print("full-resolution cube of the whole frame:",
      demosaic(ff_frame, sensor, "ri")["reflectance"].shape)

# %% [markdown]
# ## On the command line
#
# ```bash
# snapcorr sensor CMV2K-SSM5x5-600_875-5.5.9.2.xml --plot filters.png --toml camera.toml
# # add n_eff (and the pixel pitch where the file says 0) to camera.toml
# snapcorr flatfield raw.npy --dark dark.npy --white white.npy --sensor camera.toml \
#     --out scene_ff.zarr                    # one spectrum per tile; or every pixel's:
# snapcorr flatfield raw.npy --dark dark.npy --white white.npy --sensor camera.toml \
#     --demosaic ri --out scene_full.zarr
# snapcorr correct scene_ff.zarr --lens my_lens.toml --sensor camera.toml --f-number 2.8 \
#     --virtual-bands angle-aware --out scene_corrected.zarr
# ```
