"""Lens calibration with 0, 1 or 2 vignetting circles, judged by the shift it predicts.

Flats come from the independent simulator ``tests/oracles/flatsim.py`` (it shares no code with
snapcorr): five f-numbers f/2-f/11, each with its own exposure (+-20 %), the optical axis off
the image centre, the user's 1280 x 1024 sensor (7.1 um pixels here: field up to 16.7 deg),
Gaussian noise of a given fraction of every pixel's signal. For
each truth, noise level and seed the calibrated lens is judged as
``tests/calibrate/lens/test_calibration_circles.py`` judges it: the largest |mean-shift
error| (Goossens 2019, Eq. 22, 1000 nm filters, n_eff 1.5) over the field and the f-numbers
against the true lens, the model chosen, and the errors in P and h of the circles
identifiable in the field; beside it the standard error of the shift the calibration reports,
and the Cramér-Rao bound of the flats (``tests/oracles/cramer_rao.py``: the smallest standard
deviation any unbiased estimator can reach
from them, with each pixel's gain unknown). The chart
(``calibration_circles.png``) and its data (``calibration_circles.csv``) are written next to
this file. ``full_size_time`` prints the time to calibrate five 2048 x 2048 flats.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from . import pyplot, write_csv

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))

from calibrate.lens.test_calibration_circles import (  # noqa: E402
    FULL,
    HALF,
    TRUTHS,
    calibrate,
    cramer_rao,
)
from flatsim import LensTruth, make_flats  # noqa: E402

from snapcorr.calibrate import calibrate_lens  # noqa: E402

CASES = ("one_h_lt_x", "one_h_gt_x", "two_front_rear", "circle_pixel")
NOISES = (0.005, 0.01, 0.02, 0.05, 0.1)
SEEDS = (0, 1, 2, 3, 4)
TOLERANCE = {1: 0.01, 2: 0.02}


def _row(key, out, seconds):
    errs = [e for e in out.circle_errors if e is not None]
    worst = max((max(abs(a), abs(b)) for a, b in errs), default=np.nan)
    return {
        "truth": key, "true_circles": len(out.truth.circles), "noise": out.noise,
        "seed": out.seed, "model": out.model, "circles": len(out.circles),
        "circles_mm": " ".join(f"{P:.4f}/{h:.3f}" for P, h in out.circles),
        "shift_error_nm": out.shift_error_nm, "worst_f": out.worst_at[0],
        "worst_cra_deg": out.worst_at[1],
        "identifiable": len(out.circle_errors), "missed": sum(e is None for e in out.circle_errors),
        "max_Ph_error_pct": worst, "spurious": len(out.spurious),
        "center_error_px": out.center_error_px, "pixel_shift_error_nm": out.pixel_error_nm,
        "reported_sd_nm": float(np.nanmax(out.res.shift_stderr_nm, initial=0.0)),
        "cramer_rao_sd_nm": cramer_rao(out)[0],
        "seconds": round(seconds, 2),
    }


def noise_sweep(*, quick=False, echo=print, write=True):
    """Model chosen and max |mean-shift error| against noise, for one- and two-circle truths."""
    if quick:
        cases, noises, seeds = ("one_h_gt_x",), (0.01,), (0,)
        scene = dict(shape=(128, 160), pitch_um=56.8, center_px=(87.5, 60.0))
    else:
        cases, noises, seeds, scene = CASES, NOISES, SEEDS, FULL
    rows = []
    echo(f"calibration with vignetting circles: {scene['shape'][1]} x {scene['shape'][0]} "
         f"flats of {scene['pitch_um']:g} um, f/2-f/11, {len(seeds)} seed(s); error = max "
         "|mean-shift error| over the field and f-numbers (1000 nm, n_eff 1.5)")
    echo(f"{'truth':<16} {'noise':>6}  {'models chosen':<22} {'shift error nm':>26} "
         f"{'reported sd':>11} {'bound sd':>9} {'max P/h err %':>14} {'spurious':>8}")
    for key in cases:
        truth = TRUTHS[key]
        for noise in noises:
            batch = []
            for seed in seeds:
                t0 = time.perf_counter()
                out = calibrate(truth, noise=noise, seed=seed, scene=scene)
                batch.append(_row(key, out, time.perf_counter() - t0))
            rows += batch
            err = np.array([r["shift_error_nm"] for r in batch])
            models = {}
            for r in batch:
                models[r["model"]] = models.get(r["model"], 0) + 1
            ph = np.array([r["max_Ph_error_pct"] for r in batch], float)
            ph_txt = f"{np.nanmax(ph):.3f}" if np.isfinite(ph).any() else "-"
            echo(f"{key:<16} {100 * noise:>5.1f}%  "
                 f"{', '.join(f'{k} x{v}' for k, v in models.items()):<22} "
                 f"median {np.median(err):.4f} max {err.max():.4f} "
                 f"{np.median([r['reported_sd_nm'] for r in batch]):>11.4f} "
                 f"{batch[0]['cramer_rao_sd_nm']:>9.4f}  {ph_txt:>14} "
                 f"{sum(r['spurious'] for r in batch):>8}")
    if write:
        _write(rows)
    return rows


def _write(rows):
    plt = pyplot()
    write_csv(HERE / "calibration_circles.csv", rows)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    keys = list(dict.fromkeys(r["truth"] for r in rows))
    for k, key in enumerate(keys):
        sel = [r for r in rows if r["truth"] == key]
        noise = np.array([r["noise"] for r in sel]) * 100
        err = np.array([r["shift_error_nm"] for r in sel])
        jitter = noise * (1 + 0.04 * (k - 1))
        axes[0].plot(jitter, np.maximum(err, 1e-5), "o", ms=4, alpha=0.6, color=f"C{k}")
        levels = sorted(set(noise))
        axes[0].plot(levels, [np.median(err[noise == lv]) for lv in levels], "-",
                     color=f"C{k}", label=f"{key} ({sel[0]['true_circles']} circle(s))")
        bound = [next(r["cramer_rao_sd_nm"] for r in sel if r["noise"] * 100 == lv)
                 for lv in levels]
        axes[0].plot(levels, bound, "--", color=f"C{k}", lw=0.9)
        ncirc = np.array([r["circles"] for r in sel])
        axes[1].plot(jitter, ncirc + 0.05 * (k - 1), "o", ms=5, alpha=0.5, color=f"C{k}",
                     label=key)
        axes[1].axhline(sel[0]["true_circles"] + 0.05 * (k - 1), color=f"C{k}", lw=0.8,
                        ls=":")
    for tol in (0.01, 0.02):
        axes[0].axhline(tol, color="k", lw=0.6, ls=":")
    axes[0].set(xscale="log", yscale="log", xlabel="noise per pixel (%)",
                ylabel="max |mean-shift error| (nm)",
                title="error: points = seeds, line = median, dashed = Cramér-Rao sd")
    axes[0].legend(fontsize=8)
    axes[1].set(xscale="log", xlabel="noise per pixel (%)", ylabel="circles in the profile",
                yticks=[0, 1, 2, 3], title="circles chosen (dotted: the truth)")
    axes[1].legend(fontsize=8)
    fig.suptitle("Calibration against noise, flats from the independent simulator "
                 "(f/2-f/11); dotted left: the 0.01 / 0.02 nm requirements")
    fig.savefig(HERE / "calibration_circles.png", dpi=110)
    plt.close(fig)


def full_size_time(*, quick=False, echo=print):
    """Seconds to calibrate five 2048 x 2048 flats for truths of 0, 1 and 2 circles."""
    n = 256 if quick else 2048
    scene = dict(shape=(n, n), pitch_um=4.1 * 2048 / n, center_px=(n * 0.537, n * 0.478))
    truths = {0: LensTruth(21.0, (), 0.0, 1.0, name="no circle"),
              1: TRUTHS["one_h_gt_x"], 2: TRUTHS["two_front_rear"]}
    out = {}
    for k, truth in truths.items():
        flats = make_flats(truth, noise=0.01, seed=0, **scene)
        t0 = time.perf_counter()
        res = calibrate_lens(flats, exit_pupil_mm=truth.exit_pupil_mm,
                             pixel_pitch_um=scene["pitch_um"],
                             magnification=truth.magnification,
                             pupil_magnification=truth.pupil_magnification)
        out[k] = time.perf_counter() - t0
        echo(f"calibrating five {n} x {n} flats (1 % noise), truth with {k} circle(s): "
             f"{out[k]:.1f} s on this machine ({res.model})")
    return out


#: Truths, noise levels and seeds of the coverage sweep.
COVERAGE_CASES = ("one_h_lt_x", "one_h_gt_x", "two_front_rear", "circle_pixel", "no_circle")
COVERAGE_NOISES = (0.005, 0.02, 0.05)
COVERAGE_SEEDS = tuple(range(8))


def shift_errors_nm(truth, res, scene, f_numbers, n=121):
    """Largest |mean-shift error| over the field at each f-number (1000 nm, n_eff 1.5),
    the calibrated lens against the truth, where both pass light
    (``test_calibration_circles.shift_errors_by_f``, the tests' own judge)."""
    from calibrate.lens.test_calibration_circles import field_cra_deg, shift_errors_by_f

    field = field_cra_deg(scene, truth.exit_pupil_mm)
    return np.array([e for e, _ in shift_errors_by_f(truth, res.lens, f_numbers, field, n)])


def _coverage_one(job):
    import warnings

    key, noise, seed, scene = job
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    out = calibrate(TRUTHS[key], noise=noise, seed=seed, scene=scene)
    res = out.res
    err = shift_errors_nm(out.truth, res, scene, res.f_numbers)
    sd = np.asarray(res.shift_stderr_nm, float)
    # the z-score where the reported error is largest (the f-number that matters most)
    if sd.size and np.isfinite(sd).any() and np.nanmax(sd) > 0:
        k = int(np.nanargmax(sd))
        z = float(err[k] / sd[k])
    else:
        z = float("nan")
    return {"truth": key, "noise": noise, "seed": seed, "method": res.method,
            "model": res.model, "circles": len(res.lens.vignetting),
            "shift_error_nm": float(err.max()), "reported_sd_nm": float(np.nanmax(sd))
            if sd.size else float("nan"), "z": z,
            "reduced_chi2": float(res.fits[res.model].reduced_chi2),
            "cramer_rao_sd_nm": cramer_rao(out)[0] if seed == 0 else float("nan"),
            "seconds": round(time.perf_counter() - t0, 2)}


def coverage_sweep(*, quick=False, echo=print, write=True, workers=2):
    """Do the reported shift errors cover? Over seeds, for every truth and noise level: the
    largest shift error, the error over the reported standard error (z) and its RMS, which
    should be near 1 (a range of [0.5, 2] is asked for), the estimator and model chosen."""
    from concurrent.futures import ProcessPoolExecutor

    if quick:
        cases, noises, seeds = ("one_h_gt_x",), (0.02,), (0,)
        scene = dict(shape=(128, 160), pitch_um=56.8, center_px=(87.5, 60.0))
    else:
        cases, noises, seeds = COVERAGE_CASES, COVERAGE_NOISES, COVERAGE_SEEDS
        scene = HALF
    jobs = [(k, n, s, scene) for k in cases for n in noises for s in seeds]
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(workers) as pool:
            rows = list(pool.map(_coverage_one, jobs))
    else:
        rows = [_coverage_one(j) for j in jobs]
    echo(f"coverage of the reported shift error: {scene['shape'][1]} x {scene['shape'][0]} "
         f"flats, f/2-f/11, {len(seeds)} seeds; z = error / reported error at the f-number "
         "where it is largest")
    echo(f"{'truth':<16} {'noise':>6}  {'estimator, model':<24} {'max error nm':>12} "
         f"{'reported sd':>11} {'bound sd':>9} {'RMS z':>6}")
    for key in cases:
        for noise in noises:
            sel = [r for r in rows if r["truth"] == key and r["noise"] == noise]
            z = np.array([r["z"] for r in sel])
            z = z[np.isfinite(z)]
            chosen = {}
            for r in sel:
                label = f"{r['method']} {r['model']}"
                chosen[label] = chosen.get(label, 0) + 1
            rms = f"{np.sqrt(np.mean(z * z)):.2f}" if z.size else "-"
            echo(f"{key:<16} {100 * noise:>5.1f}%  "
                 f"{', '.join(f'{k} x{v}' for k, v in chosen.items()):<24} "
                 f"{max(r['shift_error_nm'] for r in sel):>12.4f} "
                 f"{np.nanmedian([r['reported_sd_nm'] for r in sel]):>11.4f} "
                 f"{sel[0]['cramer_rao_sd_nm']:>9.4f} {rms:>6}")
    if write:
        write_csv(HERE / "calibration_coverage.csv", rows)
    return rows


def main(quick=False):
    noise_sweep(quick=quick, write=not quick)
    coverage_sweep(quick=quick, write=not quick)
    full_size_time(quick=quick)


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
