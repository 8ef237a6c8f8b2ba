"""Virtual bands across the field: none, the vendor's matrix, fitted and angle-aware.

**Accuracy.** The real 5x5 NIR sensor (``calibration/sensors/CMV2K-SSM5x5-600_875-5.5.9.2.xml``:
25 measured responses, its band-pass, its vendor matrix) behind the paper's lens. Band values
come from the independent simulator ``tests/oracles/mosaicsim.py`` (pupil rays of
``spectralsim.pupil_samples`` scaling the measured curves; it shares no code with snapcorr), for
PROSPECT-D leaves, soils and their mixtures (prosail), spectra the prior was not fitted to,
with 0.3 % Gaussian noise. Each method's error is taken against the ideal virtual bands
(Gaussians of the vendor's wavelengths and its 15 nm width), RMS over the spectra and the
virtual bands, at chief-ray angles 0-18 deg and f/1.4, f/2.8 and f/8. ``none`` takes the
physical bands as the virtual ones (the vendor's virtual bands sit at their main peaks).
``z`` is the RMS of the errors over ``virtual_stderr``, per virtual band.

**Speed.** Applying the angle-aware table (a matrix per pixel, interpolated in its chief-ray
angle) to a 2048 x 1088 x 16 float32 cube, against a single-matrix ``np.einsum`` and a BLAS
matrix product of the same cube, measured in the same run (the least of three); and the time
to build the tables (16 bands: the real imec 4x4 VIS responses of ``tests/data`` behind a
band-pass; 25 bands: the 5x5 file).

**Demosaicked frames of textured scenes.** ``tests/oracles/fieldsim.py`` (independent of
snapcorr) lays a textured scene of leaves and soils (``msfasim``'s layout, or a dead-leaves
scene) at the sensor's centre and in its corner, every pixel's band through its own chief ray's
responses (every pupil ray scaling the measured curves) at f/2.8 with 0.3 % noise; snapcorr
RI-demosaicks it and computes each method's virtual bands. Errors are taken against the
Gaussian virtual bands of the true scene, as RMSE of 16 x 16 block means and per pixel, and
the centre's block means against the corner's ("alike"); ``z`` as above. "before": the same
cube without its ``demosaic_method``, which is how the virtual bands were computed before they
knew of the demosaicking. Sensors: the 4x4 VIS responses with a vendor-like matrix and the
real 5x5 NIR file with its own.

Writes ``virtual_bands.csv``, ``virtual_bands_demosaicked.csv`` and ``virtual_bands.png``
(error against CRA).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from . import pyplot, write_csv

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))

import mosaicsim as ms  # noqa: E402
from flatsim import LensTruth  # noqa: E402

from snapcorr import Lens  # noqa: E402
from snapcorr.correct import virtual_bands  # noqa: E402
from snapcorr.cube import Sensor, make_cube  # noqa: E402

XML = HERE.parent / "calibration" / "sensors" / "CMV2K-SSM5x5-600_875-5.5.9.2.xml"
TRUTH = LensTruth(21.0, ((7.4236, 16.991),), 0.06, 1.3, name="paper lens")
LENS = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
N_EFF = 1.8
NOISE = 0.003
METHODS = ("none", "vendor", "fitted", "angle-aware")


def _spectra(quick):
    n = 30 if quick else 150
    return np.concatenate([ms.leaves(n, 1), ms.soils_and_mixtures(n, 2)])


def accuracy(*, quick=False, echo=print):
    """Rows of (f-number, CRA, method, RMSE, z) on the independent simulator."""
    sensor = dataclasses.replace(Sensor.load(XML), n_eff=(N_EFF,) * 25, pixel_pitch_um=5.5)
    mf = ms.read_older(XML)
    X = _spectra(quick)
    truth = ms.virtual_truth(mf, X)
    nearest = [int(np.argmin(np.abs(np.asarray(sensor.cwl_nm) - w))) for w in mf.virtual_nm]
    rng = np.random.default_rng(0)
    rows = []
    f_numbers = (2.8,) if quick else (1.4, 2.8, 8.0)
    angles = (0.0, 15.0) if quick else (0.0, 3.0, 6.0, 9.0, 12.0, 15.0, 18.0)
    for f in f_numbers:
        for cra in angles:
            R = ms.responses(mf, TRUTH, f, cra, N_EFF)
            y = ms.band_values(R, X) + NOISE * rng.standard_normal((X.shape[0], 25))
            y = y[:, sensor.vendor_band]  # the file's order of the bands into the sensor's
            cube = make_cube(y[:, None, :].astype(np.float32), sensor.cwl_nm, name="reflectance")
            for method in METHODS:
                if method == "none":
                    est, stderr = y[:, nearest], None
                else:
                    ds = virtual_bands(cube, sensor, method, f_number=f, lens=LENS,
                                       cra_deg=np.full((X.shape[0], 1), cra))
                    est, stderr = ds["virtual"].values[:, 0, :], ds["virtual_stderr"].values
                err = np.sqrt(np.mean((est - truth) ** 2, axis=0))
                z = float(np.sqrt(np.mean((err / stderr) ** 2))) if stderr is not None else np.nan
                rows.append({"f_number": f, "cra_deg": cra, "method": method,
                             "rmse": float(np.sqrt(np.mean(err**2))), "z_rms": z})
    for f in f_numbers:
        centre = {r["method"]: r["rmse"] for r in rows if r["f_number"] == f
                  and r["cra_deg"] == 0.0}
        worst = {m: max(r["rmse"] for r in rows if r["f_number"] == f and r["method"] == m
                        and r["cra_deg"] >= 12.0) for m in METHODS}
        zs = [r["z_rms"] for r in rows if r["f_number"] == f and np.isfinite(r["z_rms"])]
        echo(f"virtual bands, f/{f:g}, {X.shape[0]} held-out spectra, 0.3 % noise: RMSE on "
             f"the axis / worst at CRA >= 12 deg: "
             + ", ".join(f"{m} {centre[m]:.4f} / {worst[m]:.4f}" for m in METHODS)
             + "; angle-aware off axis / vendor on axis "
             f"{worst['angle-aware'] / centre['vendor']:.2f} (target <= 0.85); error bars z "
             f"RMS {min(zs):.2f}-{max(zs):.2f}")
    return rows


def _imec_4x4():
    """The real imec 4x4 VIS responses behind a band-pass (tests/oracles/vendorfiles.py's
    fixture)."""
    from vendorfiles import imec_4x4

    from snapcorr.cube.responses import FilterResponses

    fx = imec_4x4()
    bp = np.interp(fx.grid, fx.components[0][1], fx.components[0][2])
    return FilterResponses(fx.grid, fx.curves, bp, fx.peaks, system_name="band-pass")


def _best_of(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def speed(*, quick=False, echo=print):
    """Application against np.einsum and a matrix product; table build times."""
    from snapcorr.correct.virtual import apply_table
    from snapcorr.optics.wiener import VirtualTable, gaussian_targets

    ny, nx = (272, 512) if quick else (1088, 2048)
    rng = np.random.default_rng(1)
    data = rng.random((ny, nx, 16), dtype=np.float32)
    from snapcorr.optics import cra_map

    cra = cra_map((ny, nx), 5.5 * 2048 / nx, LENS.exit_pupil_mm)  # the full 2048 x 1088 field
    r16 = _imec_4x4()
    targets = gaussian_targets(r16.wavelength_nm, np.linspace(470, 620, 16), 12.0)
    build16 = _best_of(lambda: VirtualTable.build(r16, targets, 1.7, 2.0, LENS,
                                                  cra_max_deg=float(cra.max()), alpha=1e-5),
                       repeat=1 if quick else 3)
    table = VirtualTable.build(r16, targets, 1.7, 2.0, LENS, cra_max_deg=float(cra.max()),
                               alpha=1e-5)
    A = table.matrices[0].astype(np.float32)
    apply_table(data[:2], cra[:2], table)  # compile outside the timing
    t_einsum = _best_of(lambda: np.einsum("yxb,vb->yxv", data, A))
    t_matmul = _best_of(lambda: data @ A.T)
    t_table = _best_of(lambda: apply_table(data, cra, table))
    s25 = Sensor.load(XML)
    t25 = gaussian_targets(s25.responses.wavelength_nm, s25.matrices[0].wavelength_nm, 15.0)
    build25 = _best_of(lambda: VirtualTable.build(s25.responses, t25, N_EFF, 2.0, LENS,
                                                  cra_max_deg=float(cra.max()), alpha=1e-5),
                       repeat=1 if quick else 3)
    out = {"cube": f"{nx} x {ny} x 16 float32", "einsum_s": t_einsum, "matmul_s": t_matmul,
           "angle_aware_s": t_table, "nodes": int(table.cra_deg.size),
           "build16_s": build16, "build25_s": build25}
    echo(f"angle-aware virtual bands on a {out['cube']} cube: {t_table:.3f} s, "
         f"{t_table / t_einsum:.2f} x a single-matrix np.einsum ({t_einsum:.3f} s; target <= 3 x)"
         f", {t_table / t_matmul:.2f} x a BLAS matrix product ({t_matmul:.3f} s); tables built "
         f"in {build16:.2f} s (16 bands, {out['nodes']} CRA nodes to {float(cra.max()):.1f} deg)"
         f" and {build25:.2f} s (25 bands; target < 1 s)")
    return out


def demosaicked(*, quick=False, echo=print):
    """Rows of (sensor, scene, seed, when, place, method, block and pixel RMSE, z, alike) on
    demosaicked textured frames, before and after the virtual bands knew of the
    demosaicking."""
    import tempfile

    import fieldsim as fs
    from correct import test_virtual_demosaicked as tvd

    rows = []
    size = 64 if quick else 128
    with tempfile.TemporaryDirectory() as tmp:
        sensors = {"4x4 VIS": tvd.vis_camera(Path(tmp))}
        if not quick:
            sensors["5x5 NIR"] = tvd.nir_camera()
        for name, (cam, sensor) in sensors.items():
            for scene in ("dead leaves",) if quick else ("dead leaves", "msfasim"):
                for seed in (0,) if quick else (0, 1, 2):
                    weights, spectra, shade = fs.textured_scene((size, size), 10, seed)
                    if scene == "dead leaves":
                        weights = fs.dead_leaves((size, size), 10, seed)
                    for when, keep in (("before", False), ("after", True)):
                        got, alike = tvd.figures(cam, sensor, weights, spectra, shade,
                                                 10 * seed + 1, keep_demosaicking=keep)
                        rows += [{"sensor": name, "scene": scene, "seed": seed, "when": when,
                                  "place": place, "method": m, **v, "alike": alike[m]}
                                 for (place, m), v in got.items()]
    for name in dict.fromkeys(r["sensor"] for r in rows):
        for when in ("before", "after"):
            sel = [r for r in rows if r["sensor"] == name and r["when"] == when]

            def mean(key, m, place, sel=sel):
                return np.mean([r[key] for r in sel if r["method"] == m and r["place"] == place])

            zs = [r["z"] for r in sel if np.isfinite(r["z"])]
            echo(f"demosaicked frames, {name}, {when}: RMSE of 16 x 16 block means centre / "
                 "corner (mean over scenes and seeds) "
                 + ", ".join(f"{m} {mean('block', m, 'centre'):.4f} / "
                             f"{mean('block', m, 'corner'):.4f}" for m in ("nominal", *tvd.METHODS))
                 + "; per pixel " + ", ".join(
                     f"{m} {mean('pixel', m, 'centre'):.4f} / {mean('pixel', m, 'corner'):.4f}"
                     for m in ("nominal", *tvd.METHODS))
                 + "; centre vs corner " + ", ".join(
                     f"{m} {mean('alike', m, 'centre'):.4f}" for m in ("nominal", *tvd.METHODS))
                 + f"; z RMS {min(zs):.2f}-{max(zs):.2f}")
    return rows


def write_files(rows, directory=HERE, demosaicked_rows=None):
    """``virtual_bands.csv``, ``virtual_bands_demosaicked.csv`` and ``virtual_bands.png``."""
    write_csv(directory / "virtual_bands.csv", rows)
    if demosaicked_rows:
        write_csv(directory / "virtual_bands_demosaicked.csv", demosaicked_rows)
    plt = pyplot()
    f_numbers = sorted({r["f_number"] for r in rows})
    fig, axes = plt.subplots(1, len(f_numbers), figsize=(4.2 * len(f_numbers), 3.8),
                             sharey=True, layout="constrained")
    axes = np.atleast_1d(axes)
    styles = {"none": ("0.5", ":"), "vendor": ("C3", "-"), "fitted": ("C0", "--"),
              "angle-aware": ("C2", "-")}
    for ax, f in zip(axes, f_numbers, strict=True):
        for m, (colour, ls) in styles.items():
            pts = sorted((r["cra_deg"], r["rmse"]) for r in rows
                         if r["f_number"] == f and r["method"] == m)
            ax.plot(*zip(*pts, strict=True), color=colour, ls=ls, marker="o", ms=3, label=m)
        ax.set_yscale("log")
        ax.set_title(f"f/{f:g}")
        ax.set_xlabel("chief-ray angle (deg)")
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("RMSE of the virtual bands (reflectance)")
    axes[0].legend(fontsize=8)
    fig.suptitle("imec 5x5 NIR behind the paper's lens: leaves and soils, 0.3 % noise "
                 "(independent simulator)", fontsize=10)
    fig.savefig(directory / "virtual_bands.png", dpi=110)
    plt.close(fig)


def run(*, quick=False, echo=print, write=True):
    rows = accuracy(quick=quick, echo=echo)
    frames = [] if quick else demosaicked(echo=echo)  # minutes: the slow tests check it
    timing = speed(quick=quick, echo=echo)
    if write:
        write_files(rows, demosaicked_rows=frames)
    return rows, timing
