"""The experiment of Goossens et al. 2019 (Sec. 3), simulated end to end.

A colour filter in front of a white tile, seen by a Snapscan-like VNIR camera (150 bands,
470-900 nm, 10 nm wide, n_eff 1.7) behind the paper's 16 mm lens at f/1.4-f/8. Every pixel
looks at the same filter, so after a correct wavelength correction every pixel shows the same
spectrum. The steps are the package's own, in the order a user runs them:

1. flat fields of the lens at five f-numbers (:func:`snapcorr.simulate.flat_frame`) ->
   :func:`snapcorr.calibrate.calibrate_lens` -> a lens profile;
2. raw, dark and white cubes -> :func:`snapcorr.cube.flatfield` (Eq. 29);
3. :func:`snapcorr.correct.correct_cube` with the ideal-aperture and the vignetting model.

Each band's measured transmittance is the filter curve seen through that band's filter
(a Gaussian of the band's FWHM) smeared by the angular kernel of its pixel (Goossens Eq. 37,
as point masses from :func:`snapcorr.optics.response.kernel_bins`), computed with the true lens;
the correction uses the calibrated one. The illumination cancels in the flat-fielding and is
taken flat.
"""

from __future__ import annotations

import numpy as np

from .optics.lens import Lens
from .optics.response import kernel_bins
from .spectra import colour_filter  # re-exported: snapcorr.paper_experiment.colour_filter

__all__ = ["PAPER_LENS", "colour_filter", "measured_transmittance", "paper_metrics"]

PAPER_LENS = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm (simulated truth)")


def measured_transmittance(cwl_nm, fwhm_nm, n_eff, f_number, cra_deg, lens, *, step_nm=0.1):
    """Flat-fielded signal of each band at each CRA: shape (len(cra_deg), len(cwl_nm)).

    Band b sees ``sum_k w_k F_b(cwl_b mu_k)`` with ``F_b(delta)`` the filter curve through the
    band's Gaussian moved by ``delta`` and ``(mu_k, w_k)`` the kernel at that CRA per nm of
    central wavelength (the shift scales with the central wavelength).

    Parameters
    ----------
    cwl_nm : array_like
        The bands' central wavelengths at normal incidence, nm.
    fwhm_nm : float or array_like
        The bands' FWHM, nm (one value for every band, or one per band).
    n_eff : float
        The filters' effective index.
    f_number : float
        Nominal f-number.
    cra_deg : float or array_like
        Chief-ray angles, degrees.
    lens : Lens
        The lens the light passes (the true one).
    step_nm : float
        Step of the wavelength grid the filter curve is sampled on, nm.

    Returns
    -------
    ndarray, shape (len(cra_deg), len(cwl_nm))
    """
    cwl = np.asarray(cwl_nm, float)
    fwhm = np.broadcast_to(np.asarray(fwhm_nm, float), cwl.shape)
    lam = np.arange(cwl.min() - 150.0, cwl.max() + 60.0, step_nm)
    T = colour_filter(lam)
    # The filter curve through each band's Gaussian, as a function of where the band sits:
    # one convolution per distinct width, read off at cwl_b + delta.
    conv = {}
    for w in np.unique(fwhm):
        sig = w / 2.3548
        k = np.arange(-5 * sig, 5 * sig + step_nm, step_nm)
        g = np.exp(-0.5 * (k / sig) ** 2)
        conv[w] = np.convolve(T, g / g.sum(), mode="same")
    out = np.empty((np.size(cra_deg), cwl.size))
    for i, c in enumerate(np.atleast_1d(cra_deg)):
        mu, w = kernel_bins(1.0, n_eff, f_number, float(c), lens, step_nm=2e-4)
        for width, curve in conv.items():
            bands = np.flatnonzero(fwhm == width)
            pos = cwl[bands, None] * (1.0 + mu[None, :])  # where each kernel bin puts the band
            out[i, bands] = np.interp(pos, lam, curve) @ w
    return out


def paper_metrics(spectra, wavelengths, grid):
    """The paper's comparison of spectra from different pixels: on a common grid, the worst
    correlation coefficient and the largest absolute difference over all pairs.

    Parameters
    ----------
    spectra : sequence of 1-D arrays
        The spectra, one per pixel.
    wavelengths : sequence of 1-D arrays
        The wavelengths of each spectrum's values, nm.
    grid : 1-D array
        The common wavelengths, nm; only those inside both spectra of a pair are compared.

    Returns
    -------
    worst_r, max_err : float
    """
    on_grid = [np.interp(grid, w, s, left=np.nan, right=np.nan)
               for s, w in zip(spectra, wavelengths, strict=True)]
    worst_r, max_err = 1.0, 0.0
    for i in range(len(on_grid)):
        for j in range(i + 1, len(on_grid)):
            ok = np.isfinite(on_grid[i]) & np.isfinite(on_grid[j])
            a, b = on_grid[i][ok], on_grid[j][ok]
            worst_r = min(worst_r, float(np.corrcoef(a, b)[0, 1]))
            max_err = max(max_err, float(np.max(np.abs(a - b))))
    return worst_r, max_err


def run(out, *, echo=print, seed=2019, written=None):
    """Simulate, calibrate, flat-field and correct; write figures; return summary lines.

    Writes ``calibration.png`` (the paper's Fig. 8 from the simulated flats), ``lens.toml``
    (the calibrated profile), ``spectra.png`` (the paper's Fig. 9-11: spectra at CRA 1.9, 10.3
    and 17.4 deg, uncorrected and corrected by both models, f/1.4-f/8) and ``maps.png`` (CRA
    and shift over the image at f/1.4); ``written()``, if given, is called after each step
    that wrote files (the demo's marker follows them, so an interrupted run can be rerun).
    """
    def step_done():
        if written is not None:
            written()

    from pathlib import Path

    out = Path(out)
    truth = PAPER_LENS
    f_numbers = (1.4, 2.0, 2.8, 4.0, 8.0)
    cras = (1.9, 10.3, 17.4)
    rng = np.random.default_rng(seed)
    lines = []

    # 1. the lens, from flat fields (512 x 320 at 22 um: a 2048 x 1280, 5.5 um sensor)
    flat_center = (155.4, 262.8)  # (row, col): the optical axis a little off the image centre
    cal = _calibrate(out, truth, f_numbers, flat_center, rng)
    step_done()
    lens = cal.lens
    lines.append(f"1. calibration from simulated flats (f/1.4-f/8, 1 % noise): {cal.method}, "
                 f"{cal.model} circle(s): {lens.describe_vignetting()} (true "
                 f"{truth.describe_vignetting()}), centre "
                 f"row {cal.center_rc[0]:.1f}, col {cal.center_rc[1]:.1f} px (true row "
                 f"{flat_center[0]}, col {flat_center[1]})")

    # 2. the cube: 8 x 8 binned Snapscan pixels (44 um), the same sensor area
    shape = (160, 256)
    # flat-field pixel -> cube pixel: the same point of the sensor
    center = tuple((c + 0.5) * 22.0 / 44.0 - 0.5 for c in cal.center_rc)
    true_center = tuple((c + 0.5) * 22.0 / 44.0 - 0.5 for c in flat_center)
    cwl, results = _correct_cubes(lens, truth, f_numbers, shape, center, true_center, rng)

    # 3. spectra at the paper's three positions, 5 x 5 pixels each
    spots = _spots(shape, true_center, cras)
    lines += _compare_spectra(out / "spectra.png", results, f_numbers, cras, spots, cwl)
    step_done()

    # 4. maps at f/1.4
    _draw_maps(out / "maps.png", results[1.4]["vignetted"], cwl)
    step_done()

    m = results[1.4]
    lines.append(
        f"   at f/1.4 the vignetted model aligns the spectra best (largest difference "
        f"{m['vignetted_metrics'][1]:.4f} against {m['uncorrected_metrics'][1]:.4f} "
        f"uncorrected and {m['ideal_metrics'][1]:.4f} with the ideal-aperture model, which "
        "over-corrects the field edge)")
    echo("\n".join(lines))
    return lines, results


def _calibrate(out, truth, f_numbers, flat_center, rng):
    """Calibrate the lens from simulated flats; write its figure and profile into ``out``."""
    from .calibrate import calibrate_lens
    from .simulate import flat_frame

    flats = {f: flat_frame((320, 512), 22.0, f, truth, center_rc=flat_center, rng=rng)
             for f in f_numbers}
    cal = calibrate_lens(flats, exit_pupil_mm=21.0, pixel_pitch_um=22.0, magnification=0.06,
                         pupil_magnification=1.3, name="Edmund Optics 16 mm (demo calibration)")
    cal.save_plot(out / "calibration.png")
    cal.lens.save(out / "lens.toml", overwrite=True)
    return cal


def _correct_cubes(lens, truth, f_numbers, shape, center, true_center, rng):
    """The bands' wavelengths, and per f-number the filter's cube and its two corrections."""
    import dataclasses

    from .correct import correct_cube
    from .cube import Sensor, flatfield, make_cube
    from .data import sensor_path
    from .optics.chief_ray import cra_map
    from .simulate import relative_illumination_map

    base = Sensor.load(sensor_path("snapscan_vnir"))
    sensor = dataclasses.replace(base, name=base.name + " (8 x 8 binned)", pixel_pitch_um=44.0,
                                 size_px=shape)
    cra = cra_map(shape, 44.0, 21.0, center_rc=true_center)
    grid = np.linspace(0.0, float(cra.max()) + 1e-6, 90)
    cwl, fwhm = np.asarray(base.cwl_nm), np.asarray(base.fwhm_nm)

    def frame(signal):  # shot noise on top of a 100 DN dark level
        return rng.poisson(signal).astype(np.float32) + np.float32(100.0)

    results = {}
    for f in f_numbers:
        meas = measured_transmittance(cwl, fwhm, 1.7, f, grid, truth)  # (grid, band)
        idx = np.clip(np.searchsorted(grid, cra) - 1, 0, grid.size - 2)
        w = ((cra - grid[idx]) / (grid[idx + 1] - grid[idx]))[..., None]
        transmittance = meas[idx] * (1 - w) + meas[idx + 1] * w  # (y, x, band)
        white = 3000.0 * relative_illumination_map(shape, 44.0, f, truth,
                                                   center_rc=true_center)[..., None]
        raw = make_cube(frame(transmittance * white), cwl, fwhm_nm=fwhm)
        whites = [make_cube(frame(np.broadcast_to(white, raw.shape)), cwl) for _ in range(4)]
        darks = [make_cube(frame(np.zeros(raw.shape)), cwl) for _ in range(4)]
        ff = flatfield(raw, darks, whites)["reflectance"]
        results[f] = {m: correct_cube(ff, sensor, f, lens, center_rc=center, method=m)
                      for m in ("ideal", "vignetted")}
        results[f]["cube"] = ff
    return cwl, results


def _spots(shape, true_center, cras):
    """The (row, column) of each chief-ray angle in ``cras`` on the way to the far corner
    (``true_center`` is ``(row, col)``)."""
    pitch = 44.0e-3
    # along the line from the optical centre to the farthest corner
    corner = np.array([shape[0] - 3.0, shape[1] - 3.0])
    corner = max(([2.0, 2.0], [2.0, corner[1]], [corner[0], 2.0], corner),
                 key=lambda p: np.hypot(p[1] - true_center[1], p[0] - true_center[0]))
    u = np.subtract(corner, true_center)
    u = u / np.hypot(u[1], u[0])
    spots = []
    for c in cras:
        r = 21.0 * np.tan(np.radians(c)) / pitch
        spots.append((round(true_center[0] + r * u[0]), round(true_center[1] + r * u[1])))
    return spots


def _compare_spectra(path, results, f_numbers, cras, spots, cwl):
    """Plot the spots' spectra to ``path``, add the metrics to ``results``, return lines."""
    from matplotlib.figure import Figure

    from .files.png import save_png

    common = np.arange(500.0, 880.0, 1.0)
    fig = Figure(figsize=(12, 2.3 * len(f_numbers)), layout="constrained")
    axes = fig.subplots(len(f_numbers), 3, sharex=True, sharey=True)
    lines = ["2. spectra of one colour filter at CRA 1.9, 10.3, 17.4 deg: worst correlation "
             "coefficient and largest difference between any two (the paper's metrics)",
             f"   {'f/#':>5} {'uncorrected':>20} {'ideal (Eq. 7)':>20} "
             f"{'vignetted (Eq. 23)':>20}"]
    for row, f in enumerate(f_numbers):
        cells = []
        for col, model in enumerate(("uncorrected", "ideal", "vignetted")):
            spectra, waves = [], []
            for (yy, xx), c in zip(spots, cras, strict=True):
                sl = (slice(yy - 2, yy + 3), slice(xx - 2, xx + 3))
                s = results[f]["cube"].values[sl].mean(axis=(0, 1))
                if model == "uncorrected":
                    lam = cwl
                else:
                    lam = results[f][model]["wavelength_corrected"].values[sl].mean(axis=(0, 1))
                spectra.append(s)
                waves.append(lam.astype(float))
                axes[row, col].plot(lam, s, lw=1, label=f"CRA {c:g} deg")
            r, err = paper_metrics(spectra, waves, common)
            results[f][model + "_metrics"] = (r, err)
            cells.append(f"r {r:.5f}, max {err:.4f}")
            axes[row, col].set_title(f"f/{f:g} {model}: r = {r:.4f}, max diff {err:.3f}",
                                     fontsize=9)
        lines.append(f"   {f:>5g} " + " ".join(f"{c:>20}" for c in cells))
    for ax in axes[-1]:
        ax.set_xlabel("wavelength (nm)")
    for ax in axes[:, 0]:
        ax.set_ylabel("transmittance")
    axes[0, 0].legend(fontsize=8)
    save_png(fig, path, dpi=110)
    return lines


def _draw_maps(path, vig, cwl):
    """The chief-ray angle and one band's shift of the vignetted model's result, to ``path``."""
    from .files.png import save_png

    save_png(_maps_figure(vig, cwl), path, dpi=110)


def _maps_figure(vig, cwl):
    """The figure :func:`_draw_maps` writes: ``vig`` needs ``cra_deg`` (y, x) and
    ``wavelength_corrected`` (y, x, band), each with ``.values``."""
    from matplotlib.figure import Figure

    band = int(np.argmin(np.abs(cwl - 700.0)))
    fig = Figure(figsize=(11, 3.6), layout="constrained")
    a1, a2 = fig.subplots(1, 2)
    im = a1.imshow(vig["cra_deg"].values, cmap="viridis")
    fig.colorbar(im, ax=a1, label="chief-ray angle (deg)")
    a1.set_title("chief-ray angle")
    im = a2.imshow(vig["wavelength_corrected"].values[..., band] - cwl[band], cmap="magma")
    fig.colorbar(im, ax=a2, label="wavelength shift (nm)")
    a2.set_title(f"shift of the {cwl[band]:.0f} nm band at f/1.4 (vignetted model)")
    for ax in (a1, a2):  # the cube's pixels (8 x 8 binned sensor pixels, 44 um)
        ax.set_xlabel("x (px)")
        ax.set_ylabel("y (px)")
    return fig
