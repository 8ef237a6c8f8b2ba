"""Do the lens calibration's error bars cover? Flats from rays counted through the pupil.

Flats come from ``tests/oracles/raysim.py``, a simulator that shares no code with snapcorr nor with
``tests/oracles/flatsim.py``: a pixel's light is the number of rays of a fine grid in the exit-pupil
plane that pass the pupil and every vignetting circle. For each lens type, noise level and
seed the lens is calibrated with ``calibrate_lens`` as a user would (x, m, m_P and the pitch
given; the optical centre, the circles and their number found), and every error it reports is
set against the error it makes:

* the mean shift (Goossens 2019, Eq. 22; 1000 nm filter, n_eff 1.5): at each f-number the
  largest |shift error| over the field where both lenses pass light (both shifts from
  ``flatsim.mean_shift_nm``, a quadrature independent of snapcorr), over the profile's
  ``shift_stderr_nm`` there; z is taken at the f-number where the reported error is largest;
* each circle's P and h against its standard error (circles matched to the truth's; a
  circle held at h = x has no error of h).

RMS z over the seeds should lie in [0.5, 2]. Five f-numbers f/2-f/11 with their own
exposures (+-20 %), 160 x 128 pixels of 56.8 um (the angles of a 1280 x 1024 sensor of
7.1 um; small, for the time: the joint fit runs on one block per pixel), x = 21 mm.
``main`` writes ``calibration_rays.csv`` next to this file and prints the table (as in
``benchmarks/README.md``); ``--quick`` runs one case. The estimator is the joint fit
(``METHOD``).
"""

from __future__ import annotations

import itertools
import math
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from . import write_csv

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))

import raysim  # noqa: E402
from flatsim import LensTruth, mean_shift_nm  # noqa: E402
from flatsim import relative_illumination as flatsim_ri  # noqa: E402

X = 21.0
F_NUMBERS = (2.0, 2.8, 4.0, 5.6, 11.0)
SCENE = dict(shape=(128, 160), pitch_um=56.8, center_rc=(59.75, 87.25))
PAPER = (7.4236, 16.991)
#: name -> (circles, m, m_P, optical centre (row, column), description)
CASES = {
    "one_h_lt_x": ((PAPER,), 0.06, 1.3, SCENE["center_rc"], "one circle, h < x (the paper's)"),
    "one_h_gt_x": (((9.5, 26.0),), 0.0, 1.0, SCENE["center_rc"], "one circle, h > x"),
    "two": (((6.2, 12.0), (10.0, 30.0)), 0.0, 1.0, SCENE["center_rc"],
            "two circles (front h < x, rear h > x)"),
    "three": (((6.2, 12.0), (10.0, 30.0), (6.5, -10.0)), 0.0, 1.0, SCENE["center_rc"],
              "three circles (front, rear, one on the other side)"),
    "circle_pixel": ((PAPER, (8.5, X)), 0.06, 1.3, SCENE["center_rc"],
                     "circle plus pixel vignetting (h = x)"),
    "off_centre": (((9.5, 26.0),), 0.0, 1.0, (15.0, 147.0),
                   "one circle, h > x, optical axis near a corner"),
}
NOISES = (0.005, 0.02)
SEEDS = tuple(range(4))
CACHE = Path("/tmp/snapcorr_coverage_flats")
#: The estimator: the joint fit (``auto`` chose it in every run of the table, and its
#: leave-one-out comparison with the paper's onsets is what takes the time).
METHOD = "joint"


def _flats(key, noise, seed):
    circles, m, mP, center, _ = CASES[key]
    path = CACHE / f"{key}_{noise:g}_{seed}_{SCENE['shape'][1]}x{SCENE['shape'][0]}.npz"
    if path.exists():
        with np.load(path) as z:
            return {float(k): z[k] for k in z.files}
    fl, _ = raysim.flats(X, circles, m=m, mP=mP, f_numbers=F_NUMBERS, shape=SCENE["shape"],
                         pitch_um=SCENE["pitch_um"], center_rc=center, noise=noise, seed=seed,
                         rows=4000, n_table=1200)
    CACHE.mkdir(exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.npz")
    np.savez(tmp, **{str(k): v.astype(np.float32) for k, v in fl.items()})
    tmp.replace(path)
    return fl


def field_tan(center):
    rows, cols = SCENE["shape"]
    rho = max(math.hypot(r - center[0], c - center[1])
              for r in (0, rows - 1) for c in (0, cols - 1)) * SCENE["pitch_um"] * 1e-3
    return rho / X


def shift_errors(truth, got, field_t, n=61):
    """Largest |mean-shift error| over the field at each f-number, where both pass light."""
    t = np.linspace(0.0, field_t, n)
    cra = np.rad2deg(np.arctan(t))
    out = []
    for f in F_NUMBERS:
        lit = (flatsim_ri(truth, f, t) > 1e-6) & (flatsim_ri(got, f, t) > 1e-6)
        if not lit.any():
            out.append(0.0)
            continue
        d = mean_shift_nm(got, 1000.0, 1.5, f, cra[lit]) - mean_shift_nm(truth, 1000.0, 1.5, f,
                                                                        cra[lit])
        out.append(float(np.nanmax(np.abs(d))))
    return np.array(out)


def _match(true_c, got_c):
    """The permutation of the fitted circles closest to the true ones (relative)."""
    best = None
    for perm in itertools.permutations(range(len(got_c))):
        cost = sum(((got_c[j][0] - P) / P) ** 2 + ((got_c[j][1] - h) / max(abs(h), 1.0)) ** 2
                   for (P, h), j in zip(true_c, perm, strict=True))
        if best is None or cost < best[0]:
            best = (cost, perm)
    return best[1]


def one(job):
    from snapcorr.calibrate import calibrate_lens
    from snapcorr.calibrate.lens.table import _circle_stderrs

    key, noise, seed = job
    warnings.simplefilter("ignore")
    circles, m, mP, center, _ = CASES[key]
    flats = _flats(key, noise, seed)
    t0 = time.perf_counter()
    res = calibrate_lens(flats, exit_pupil_mm=X, pixel_pitch_um=SCENE["pitch_um"],
                         magnification=m, pupil_magnification=mP, method=METHOD)
    seconds = time.perf_counter() - t0
    got_c = [(float(P), float(h)) for P, h in res.lens.vignetting]
    truth = LensTruth(X, circles, m, mP)
    err = shift_errors(truth, LensTruth(X, tuple(got_c), m, mP), field_tan(center))
    sd = np.asarray(res.shift_stderr_nm, float)
    fit_sd = np.asarray(res.shift_stderr_fit_nm, float)
    mod_sd = np.asarray(res.shift_stderr_model_nm, float)
    row = {"case": key, "noise": noise, "seed": seed, "method": res.method,
           "model": res.model, "circles": len(got_c), "true_circles": len(circles),
           "shift_error_nm": float(err.max())}
    if sd.size and np.isfinite(sd).any() and np.nanmax(sd) > 0:
        k = int(np.nanargmax(sd))
        row.update(reported_nm=float(sd[k]), z_shift=float(err[k] / sd[k]),
                   fit_part_nm=float(fit_sd[k]) if fit_sd.size else 0.0,
                   model_part_nm=float(mod_sd[k]) if mod_sd.size else 0.0)
    else:
        row.update(reported_nm=math.nan, z_shift=math.nan, fit_part_nm=math.nan,
                   model_part_nm=math.nan)
    zP, zh = [], []
    if len(got_c) == len(circles) and circles:
        sP, sh = _circle_stderrs(res)
        perm = _match(circles, got_c)
        for (P, h), j in zip(circles, perm, strict=True):
            zP.append((got_c[j][0] - P) / sP[j] if sP[j] > 0 else math.nan)
            zh.append((got_c[j][1] - h) / sh[j] if sh[j] > 0 else math.nan)
    row["z_P"] = " ".join(f"{v:+.2f}" for v in zP)
    row["z_h"] = " ".join(f"{v:+.2f}" for v in zh)
    row["notes"] = " | ".join(res.notes)
    row["seconds"] = round(seconds, 1)
    return row


def _rms(v):
    v = np.asarray([x for x in v if np.isfinite(x)], float)
    return float(np.sqrt(np.mean(v * v))) if v.size else math.nan


def summarise(rows, echo=print):
    """One line per case and noise: models chosen, worst error, RMS z of the shift, of every
    P and of every h (per circle, in the truth's order)."""
    echo(f"{'lens':<13} {'noise':>5}  {'models':<18} {'max err nm':>10} {'median rep.':>11} "
         f"{'RMS z shift':>11}  {'RMS z P (per circle)':<22} {'RMS z h (per circle)':<22}")
    lines = []
    for key in dict.fromkeys(r["case"] for r in rows):
        for noise in sorted({r["noise"] for r in rows if r["case"] == key}):
            sel = [r for r in rows if r["case"] == key and r["noise"] == noise]
            models = {}
            for r in sel:
                models[r["model"]] = models.get(r["model"], 0) + 1

            def per_circle(col, sel=sel):
                """RMS z of each circle over the seeds that found every circle, and how
                many did: where fewer than all, the circles were kept where the noise made
                them look stronger, and their z is conditional on that choice."""
                vals = [[float(v) for v in r[col].split()] for r in sel if r[col]]
                if not vals:
                    return [], 0
                n = max(map(len, vals))
                kept = [v for v in vals if len(v) == n]
                return [_rms([v[i] for v in kept]) for i in range(n)], len(kept)

            def text(rms, kept, sel=sel):
                if not rms:
                    return "-"
                said = " ".join(f"{v:.2f}" for v in rms)
                return said if kept == len(sel) else f"{said} ({kept} of {len(sel)} seeds)"

            (zP, nP), (zh, nh) = per_circle("z_P"), per_circle("z_h")
            line = dict(case=key, noise=noise,
                        models=", ".join(f"{k} x{v}" for k, v in models.items()),
                        max_err=max(r["shift_error_nm"] for r in sel),
                        reported=float(np.nanmedian([r["reported_nm"] for r in sel])),
                        z_shift=_rms([r["z_shift"] for r in sel]),
                        z_P=text(zP, nP), z_h=text(zh, nh), z_P_values=zP, z_h_values=zh,
                        circles_found=nP, seeds=len(sel))
            lines.append(line)
            echo(f"{key:<13} {100 * noise:>4.1f}%  {line['models']:<18} "
                 f"{line['max_err']:>10.4f} {line['reported']:>11.4f} {line['z_shift']:>11.2f}"
                 f"  {line['z_P']:<22} {line['z_h']:<22}")
    return lines


def main(quick=False, echo=print, workers=2, out="calibration_rays.csv", seeds=SEEDS,
         log=None):
    """Run the table (``log``: a file each row is appended to as JSON when done)."""
    import json
    from concurrent.futures import ProcessPoolExecutor, as_completed

    if quick:
        jobs = [("one_h_gt_x", 0.02, 0)]
    else:
        jobs = [(k, n, s) for s in seeds for k in CASES for n in NOISES]
    echo(f"coverage of the calibration's error bars: raysim flats {SCENE['shape'][1]} x "
         f"{SCENE['shape'][0]}, f/2-f/11, seeds {tuple(seeds) if not quick else (0,)}")
    rows = []

    def done(row):
        rows.append(row)
        if log:
            with open(log, "a") as fh:
                fh.write(json.dumps(row) + "\n")

    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(workers) as pool:
            for fut in as_completed([pool.submit(one, j) for j in jobs]):
                done(fut.result())
    else:
        for j in jobs:
            done(one(j))
    order = {j: i for i, j in enumerate((k, n, s) for k in CASES for n in NOISES for s in seeds)}
    rows.sort(key=lambda r: order.get((r["case"], r["noise"], r["seed"]), 0))
    summarise(rows, echo)
    if not quick:
        write_csv(HERE / out, rows)
    return rows


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)


def markdown(rows):
    """The summary as the rows of a Markdown table (for benchmarks/README.md)."""
    out = ["| lens | noise | seeds | models chosen | max error nm | median reported nm | "
           "RMS z shift | RMS z P (per circle) | RMS z h (per circle) |",
           "|---|---|---|---|---|---|---|---|---|"]
    for line in summarise(rows, echo=lambda *_: None):
        seeds = sorted(r["seed"] for r in rows
                       if r["case"] == line["case"] and r["noise"] == line["noise"])
        out.append(f"| {line['case']} | {100 * line['noise']:g} % | "
                   f"{','.join(map(str, seeds))} | {line['models']} | {line['max_err']:.4f} | "
                   f"{line['reported']:.4f} | {line['z_shift']:.2f} | {line['z_P']} | "
                   f"{line['z_h']} |")
    return "\n".join(out)
