"""The exit pupil from cubes of a spectral target: the time of a fit, and precision by target.

Cubes come from the independent simulator ``tests/oracles/spectralsim.py`` (it shares no code with
snapcorr: it samples the vignetted pupil point by point and scales each ray's whole filter
curve), the lens is the paper's (``flatsim.LensTruth``: x = 21 mm, P = 7.4236 mm,
h = 16.991 mm, m = 0.06, m_P = 1.3), the sensor a Snapscan-like one of 256 x 320 pixels of
30 um (the field reaches a chief-ray angle of 16-17 deg) with 100 Gaussian bands of 10 nm FWHM
every 4 nm, 470-866 nm, n_eff 1.7. The lens handed to ``locate_pupil`` carries the true circles
and magnifications and a wrong x (30 mm), as a user's would.

1. **Speed** (``speed``). Two 256 x 320 x 100 float32 flat-fielded cubes (f/2 and f/8) of
   ``spectralsim.rare_earth_glass`` with 1 % Gaussian noise (reflectance units), the optical
   axis off the image centre, wrapped by ``snapcorr.cube.make_cube``. ``locate_pupil`` is timed
   (a) with n_eff known and the centre found, (b) with ``fit_n_eff=True``, in a fresh process
   (``locate_pupil`` limits BLAS to one thread itself). Ratios are to references measured in
   the same process: a numpy copy of the cube pair, and one evaluation of the fit's model
   matrix (``PupilFit.model.design`` at a new x, kernels included). Errors of x and n_eff are
   given against the truth in units of the standard error the fit reports (z).
2. **Precision against the target** (``precision``). ``pupil_precision`` (the Cramer-Rao bound
   of the model ``locate_pupil`` fits) for every target of ``CANDIDATE_TARGETS`` and
   ``spectralsim.single_feature``, at 0.5, 1, 2 and 5 % noise per pixel (a fraction of the
   brightest band's signal), with the target's spectrum unknown (solved for, as the fit does
   by default) or known, and n_eff known or fitted, for the same sensor with the optical axis
   at its centre and f/2 + f/8. For two targets of the simulator (``rare_earth_glass`` and
   ``colour_filter``) the bound is checked against fits: five seeds of simulated cubes each
   (the glass at 1 % noise, n_eff known and, on the same cubes, fitted; the colour filter at
   5 %, n_eff known; every group its own seeds), the scatter of x and the mean reported
   standard error against the bound for the simulator's own spectrum.
   These fits and the bounds run on two worker processes.

Writes ``pupil.csv`` (every figure) and ``pupil.png`` (predicted standard error of x against
noise, one line per target, with the fits' realised scatter) next to this file unless
``write=False``. Quick mode (``--quick``) is a smoke run on 64 x 80 x 16-band cubes: its
figures mean nothing. ``python -m benchmarks.pupil [--quick]`` runs it.
"""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from . import pyplot, write_csv

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))

import spectralsim as sim  # noqa: E402
from flatsim import LensTruth  # noqa: E402

from snapcorr import Lens  # noqa: E402
from snapcorr.calibrate import CANDIDATE_TARGETS, locate_pupil, pupil_precision  # noqa: E402
from snapcorr.cube import Sensor, make_cube  # noqa: E402

TRUTH = LensTruth(21.0, ((7.4236, 16.991),), 0.06, 1.3, name="paper lens")
N_EFF = 1.7
X_GIVEN = 30.0  # the x of the lens handed to locate_pupil: wrong, as a user's would be
F_NUMBERS = (2.0, 8.0)
SPEED_NOISE = 0.01
NOISES = (0.005, 0.01, 0.02, 0.05)
#: Fits checked against the bound: (target, noise, n_eff fitted, seeds). Over the noise levels
#: here the fit is linear (the same seeds at 1 and 5 % gave the same z to within 0.13), so one
#: level per target, and seeds of their own.
CHECKS_FULL = (("rare-earth glass (spectralsim)", 0.01, False, (0, 1, 2, 3, 4)),
               ("rare-earth glass (spectralsim)", 0.01, True, (0, 1, 2, 3, 4)),
               ("colour filter (spectralsim)", 0.05, False, (10, 11, 12, 13, 14)))
CHECKS_QUICK = (("rare-earth glass (spectralsim)", 0.01, False, (0, 1)),)

#: Full and quick scenes: same field (7.7 x 9.6 mm), fewer pixels and bands in quick mode.
#: ``fit_bins`` and ``bound_bins`` are the annuli of locate_pupil and pupil_precision
#: (their defaults in the full run).
FULL = dict(shape=(256, 320), cwl=tuple(np.arange(470.0, 867.0, 4.0)), fwhm=10.0,
            pitch_um=30.0, center=(171.3, 119.6), fit_bins=96, bound_bins=64)
QUICK = dict(shape=(64, 80), cwl=tuple(np.arange(560.0, 711.0, 10.0)), fwhm=10.0,
             pitch_um=120.0, center=(42.8, 29.9), fit_bins=32, bound_bins=32)

#: Targets of the precision chart (snapcorr's candidates, plus the simulator's single line).
TARGETS = {**CANDIDATE_TARGETS, "single feature (spectralsim)": sim.single_feature}
#: Targets checked against fits to simulated cubes (the simulator's own spectra).
CHECKS = {"rare-earth glass (spectralsim)": sim.rare_earth_glass,
          "colour filter (spectralsim)": sim.colour_filter}
QUICK_TARGETS = ("white tile", "rare-earth glass")

COLUMNS = ("part", "target", "spectrum", "n_eff_mode", "noise", "seed", "seconds",
           "x_copy", "x_design", "x_mm", "x_stderr_mm", "z_x", "n_eff", "n_eff_stderr", "z_n",
           "bound_x_stderr_mm", "bound_n_eff_stderr", "chi2_red", "note")


def _row(**kw):
    row = dict.fromkeys(COLUMNS)
    row.update(kw)
    return row


def _sensor(scene, *, size=False):
    return Sensor("bench", "snapscan", scene["pitch_um"], np.asarray(scene["cwl"]),
                  scene["fwhm"], N_EFF, size_px=tuple(scene["shape"]) if size else None)


def _lens(x):
    return Lens(x, TRUTH.circles, TRUTH.magnification, TRUTH.pupil_magnification)


def _clean(target, scene, f_number, center):
    return sim.target_cube(target, cwl_nm=np.asarray(scene["cwl"]), fwhm_nm=scene["fwhm"],
                           n_eff=N_EFF, f_number=f_number, lens=TRUTH, shape=scene["shape"],
                           pixel_pitch_um=scene["pitch_um"], center_px=center)


def _cra_max_deg(scene, center):
    ny, nx = scene["shape"]
    dx = max(center[0], nx - 1 - center[0])
    dy = max(center[1], ny - 1 - center[1])
    return math.degrees(math.atan(math.hypot(dx, dy) * scene["pitch_um"] * 1e-3
                                  / TRUTH.exit_pupil_mm))


def _cubes(paths, seed, sigma, cwl):
    """Cubes from the clean ones on disk: noise of standard deviation ``sigma``, float32."""
    rng = np.random.default_rng(seed)
    out = {}
    for f, path in paths.items():
        data = np.load(path)
        data = (data + rng.normal(0.0, sigma, data.shape)).astype(np.float32)
        out[float(f)] = make_cube(data, np.asarray(cwl))
    return out


def _fit_summary(fit):
    n_se = None if fit.n_eff_stderr is None else float(fit.n_eff_stderr[0])
    return {"x_mm": fit.exit_pupil_mm, "x_stderr_mm": fit.exit_pupil_stderr_mm,
            "n_eff": float(fit.n_eff[0]), "n_eff_stderr": n_se, "n_eff_mode": fit.n_eff_fitted,
            "chi2_red": fit.chi2_red,
            "center_px": [fit.center_rc[1], fit.center_rc[0]],  # x first, as the table says it
            "notes": list(fit.notes)}


# -- 1. speed --------------------------------------------------------------------------------
def _speed_child(spec):
    """In a fresh process: the references, then locate_pupil (a) and (b); JSON to stdout."""
    scene = spec["scene"]
    sensor = _sensor(scene)
    arrays = {float(f): np.load(p) for f, p in spec["paths"].items()}
    cubes = {f: make_cube(a, np.asarray(scene["cwl"])) for f, a in arrays.items()}
    copies = []
    for _ in range(5):
        t0 = time.perf_counter()
        _ = [a.copy() for a in arrays.values()]
        copies.append(time.perf_counter() - t0)
    out = {"copy_s": min(copies), "bytes": int(sum(a.nbytes for a in arrays.values()))}
    for case, fit_n in (("a", False), ("b", True)):
        t0 = time.perf_counter()
        fit = locate_pupil(cubes, sensor, lens=_lens(X_GIVEN), fit_n_eff=fit_n,
                           n_bins=scene["fit_bins"])
        out[case] = {"seconds": time.perf_counter() - t0, **_fit_summary(fit)}
        if case == "a":
            # one evaluation of the model matrix at a new x (its kernels are not cached)
            design = []
            for k in range(3):
                x = fit.exit_pupil_mm * (1.0 + 1e-6 * (k + 1))
                t0 = time.perf_counter()
                fit.model.design(x, fit.n_eff)
                design.append(time.perf_counter() - t0)
            out["design_s"] = min(design)
    print(json.dumps(out))


def _run_child(spec):
    code = ("import json, sys; from benchmarks.pupil import _speed_child; "
            "_speed_child(json.loads(sys.argv[1]))")
    res = subprocess.run([sys.executable, "-c", code, json.dumps(spec)], capture_output=True,
                         text=True, cwd=HERE.parent, timeout=3600)
    if res.returncode:
        raise RuntimeError(f"the timing process failed:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def _version():
    """The commit measured, and whether snapcorr/ differs from it."""
    try:
        git = ["git", "-C", str(HERE.parent)]
        head = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run([*git, "status", "--porcelain", "--", "snapcorr"],
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "commit unknown"
    return f"commit {head}" + (" with snapcorr/ modified" if dirty else "")


def speed(*, quick=False, echo=print):
    """Seconds of locate_pupil on a cube pair, as ratios to references of the same process."""
    scene = QUICK if quick else FULL
    ny, nx = scene["shape"]
    nb = len(scene["cwl"])
    center = scene["center"]
    load = os.getloadavg()[0]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        rng = np.random.default_rng(0)
        paths = {}
        for f in F_NUMBERS:
            data = _clean(sim.rare_earth_glass, scene, f, center)
            data = (data + rng.normal(0.0, SPEED_NOISE, data.shape)).astype(np.float32)
            paths[f] = str(Path(tmp) / f"f{f:g}.npy")
            np.save(paths[f], data)
        sim_s = time.perf_counter() - t0
        echo(f"locate_pupil on a {ny} x {nx} x {nb} float32 cube pair (f/2, f/8): rare-earth "
             f"glass, {100 * SPEED_NOISE:g} % noise, {scene['pitch_um']:g} um pixels (field to "
             f"CRA {_cra_max_deg(scene, center):.1f} deg), the paper's lens (x = "
             f"{TRUTH.exit_pupil_mm:g} mm), lens given with x = {X_GIVEN:g} mm; "
             f"{_version()}, {os.cpu_count()} cores, load average {load:.1f} at the start; "
             f"simulating the pair took {sim_s:.1f} s")
        echo(f"{'case':<30} {'s':>7} {'x copy':>8} {'x design':>9} "
             f"{'x mm':>9} {'stderr':>8} {'z(x)':>6} {'n_eff':>8} {'stderr':>8} {'z(n)':>6} "
             f"{'chi2_red':>8}")
        spec = {"scene": scene, "paths": {str(f): p for f, p in paths.items()}}
        res = _run_child(spec)
    for case, text in (("a", "n_eff known, centre found"), ("b", "fit_n_eff=True, centre found")):
        r = res[case]
        z_x = (r["x_mm"] - TRUTH.exit_pupil_mm) / r["x_stderr_mm"]
        z_n = None if r["n_eff_stderr"] is None else (r["n_eff"] - N_EFF) / r["n_eff_stderr"]
        rows.append(_row(
            part="speed", target="rare-earth glass (spectralsim)", spectrum="unknown",
            n_eff_mode="fitted" if case == "b" else "known", noise=SPEED_NOISE, seed=0,
            seconds=r["seconds"], x_copy=r["seconds"] / res["copy_s"],
            x_design=r["seconds"] / res["design_s"], x_mm=r["x_mm"],
            x_stderr_mm=r["x_stderr_mm"], z_x=z_x, n_eff=r["n_eff"],
            n_eff_stderr=r["n_eff_stderr"], z_n=z_n, chi2_red=r["chi2_red"],
            note=f"n_eff_fitted {r['n_eff_mode']}; copy of the pair {res['copy_s']:.3g} s, one "
                 f"model matrix {res['design_s']:.3f} s; centre {r['center_px'][0]:.2f}, "
                 f"{r['center_px'][1]:.2f} (true {center[0]}, {center[1]})"))
        n_txt = (f"{r['n_eff']:>8.5f} {r['n_eff_stderr']:>8.2g} {z_n:>+6.2f}"
                 if z_n is not None else f"{'(given)':>8} {'':>8} {'':>6}")
        echo(f"{text:<30} {r['seconds']:>7.1f} {rows[-1]['x_copy']:>8.0f} "
             f"{rows[-1]['x_design']:>9.1f} {r['x_mm']:>9.4f} {r['x_stderr_mm']:>8.2g} "
             f"{z_x:>+6.2f} {n_txt} {r['chi2_red']:>8.3f}")
    echo(f"references: numpy copy of the pair ({res['bytes'] / 2**20:.0f} MiB) "
         f"{res['copy_s']:.3g} s, one model matrix (PupilFit.model.design at a new x) "
         f"{res['design_s']:.3f} s")
    worst = max(r["seconds"] for r in rows)
    echo(f"requirement: a {ny} x {nx} x {nb} cube pair in under a minute -> slowest case "
         f"{worst:.1f} s: {'met' if worst < 60 else 'NOT met'} on this machine at this load "
         f"(load average {os.getloadavg()[0]:.1f} now)")
    return rows


# -- 2. precision against target ---------------------------------------------------------------
def _job(spec):
    """One unit of work in a worker process: a bound or a fit."""
    scene = spec["scene"]
    if spec["kind"] == "bound":
        target = {**TARGETS, **CHECKS}[spec["target"]]
        t0 = time.perf_counter()
        p = pupil_precision(target, _sensor(scene, size=True), F_NUMBERS,
                            _lens(TRUTH.exit_pupil_mm), noise=spec["noise"],
                            fit_n_eff=spec["fit_n"],
                            spectrum_known=spec["known"], n_bins=scene["bound_bins"],
                            absolute_noise=spec.get("absolute", False))
        return {"x_stderr_mm": p.x_stderr_mm, "n_eff_stderr": p.n_eff_stderr,
                "informative": p.informative, "seconds": time.perf_counter() - t0}
    cubes = _cubes(spec["paths"], spec["seed"], spec["sigma"], scene["cwl"])
    t0 = time.perf_counter()
    fit = locate_pupil(cubes, _sensor(scene), lens=_lens(X_GIVEN), fit_n_eff=spec["fit_n"],
                       n_bins=scene["fit_bins"])
    return {"seconds": time.perf_counter() - t0, **_fit_summary(fit)}


def _pool(workers):
    """Fresh worker processes (spawned: no state shared with this one)."""
    return ProcessPoolExecutor(max_workers=workers,
                               mp_context=multiprocessing.get_context("spawn"))


def precision(*, quick=False, echo=print, workers=2):
    """The bound of every target, and the bound against fits for two simulated targets."""
    scene = QUICK if quick else FULL
    ny, nx = scene["shape"]
    center = ((nx - 1) / 2, (ny - 1) / 2)  # pupil_precision's sensor is centred on the axis
    targets = QUICK_TARGETS if quick else tuple(TARGETS)
    noises = (0.01,) if quick else NOISES
    variants = [(known, fit_n) for known in (False, True) for fit_n in (False, True)]
    checks = CHECKS_QUICK if quick else CHECKS_FULL
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        paths, peak = {}, {}
        for name in dict.fromkeys(c[0] for c in checks):
            paths[name] = {}
            top = 0.0
            for f in F_NUMBERS:
                data = _clean(CHECKS[name], scene, f, center)
                top = max(top, float(np.nanmax(data)))
                paths[name][str(f)] = str(Path(tmp) / f"{len(paths)}_{f:g}.npy")
                np.save(paths[name][str(f)], data)
            peak[name] = top
        jobs = []
        for name in targets:
            for known, fit_n in variants:
                for nz in noises:
                    jobs.append({"kind": "bound", "scene": scene, "target": name, "noise": nz,
                                 "known": known, "fit_n": fit_n})
        for name, nz, fit_n, seeds in checks:
            sigma = nz * peak[name]  # the noise as a fraction of the brightest band
            jobs.append({"kind": "bound", "scene": scene, "target": name, "noise": sigma,
                         "known": False, "fit_n": fit_n, "absolute": True, "rel": nz})
            for seed in seeds:
                jobs.append({"kind": "fit", "scene": scene, "target": name, "sigma": sigma,
                             "rel": nz, "seed": seed, "fit_n": fit_n, "paths": paths[name]})
        with _pool(workers) as pool:
            # the fits first: they are the long jobs
            order = sorted(range(len(jobs)), key=lambda i: jobs[i]["kind"] != "fit")
            futures = {i: pool.submit(_job, jobs[i]) for i in order}
            results = [futures[i].result() for i in range(len(jobs))]
    wall = time.perf_counter() - t_start
    rows = []
    bound_of = {}
    for job, res in zip(jobs, results, strict=True):
        mode = "fitted" if job["fit_n"] else "known"
        if job["kind"] == "bound":
            spectrum = "known" if job["known"] else "unknown"
            noise = job.get("rel", job["noise"])
            bound_of[(job["target"], spectrum, mode, noise)] = res
            rows.append(_row(part="bound" if "rel" not in job else "bound (check)",
                             target=job["target"], spectrum=spectrum, n_eff_mode=mode,
                             noise=noise, seconds=res["seconds"],
                             bound_x_stderr_mm=res["x_stderr_mm"],
                             bound_n_eff_stderr=res["n_eff_stderr"],
                             note="" if res["informative"] else "not informative"))
    for job, res in zip(jobs, results, strict=True):
        if job["kind"] != "fit":
            continue
        mode = "fitted" if job["fit_n"] else "known"
        b = bound_of[(job["target"], "unknown", mode, job["rel"])]
        z_n = (None if res["n_eff_stderr"] is None
               else (res["n_eff"] - N_EFF) / res["n_eff_stderr"])
        rows.append(_row(part="fit", target=job["target"], spectrum="unknown", n_eff_mode=mode,
                         noise=job["rel"], seed=job["seed"],
                         seconds=res["seconds"], x_mm=res["x_mm"],
                         x_stderr_mm=res["x_stderr_mm"],
                         z_x=(res["x_mm"] - TRUTH.exit_pupil_mm) / res["x_stderr_mm"],
                         n_eff=res["n_eff"], n_eff_stderr=res["n_eff_stderr"], z_n=z_n,
                         bound_x_stderr_mm=b["x_stderr_mm"],
                         bound_n_eff_stderr=b["n_eff_stderr"], chi2_red=res["chi2_red"],
                         note=f"n_eff_fitted {res['n_eff_mode']}; noise sd "
                              f"{job['sigma']:.4g} (reflectance); centre "
                              f"{res['center_px'][0]:.2f}, {res['center_px'][1]:.2f}"))
    _echo_bounds(rows, targets, noises, scene, echo)
    _echo_checks(rows, checks, echo)
    fits = [r for r in rows if r["part"] == "fit"]
    bounds = [r for r in rows if r["part"] != "fit"]
    echo(f"{len(bounds)} bounds ({np.median([r['seconds'] for r in bounds]):.1f} s each, "
         f"median) and {len(fits)} fits ({np.median([r['seconds'] for r in fits]):.1f} s each) "
         f"on {workers} worker processes: {wall:.0f} s")
    return rows


def _echo_bounds(rows, targets, noises, scene, echo):
    ny, nx = scene["shape"]
    echo(f"\npredicted standard error of x (mm; the Cramér-Rao bound of pupil_precision), "
         f"{ny} x {nx} x {len(scene['cwl'])} sensor centred on the axis, f/2 + f/8, "
         f"x = {TRUTH.exit_pupil_mm:g} mm; noise per pixel as a fraction of the brightest band")
    echo(f"{'target':<32} {'spectrum':<8} {'n_eff':<7} "
         + " ".join(f"{100 * nz:>7g} %" for nz in noises) + f"  {'n_eff sd at 1 %':>15}")
    for name in targets:
        for spectrum in ("unknown", "known"):
            for mode in ("known", "fitted"):
                sel = {r["noise"]: r for r in rows if r["part"] == "bound"
                       and r["target"] == name and r["spectrum"] == spectrum
                       and r["n_eff_mode"] == mode}
                n_sd = sel.get(0.01, {}).get("bound_n_eff_stderr")
                echo(f"{name:<32} {spectrum:<8} {mode:<7} "
                     + " ".join(f"{sel[nz]['bound_x_stderr_mm']:>9.3g}" for nz in noises)
                     + f"  {'-' if n_sd is None else format(n_sd, '.2g'):>15}")


def _check_summary(rows, name, noise, mode):
    sel = [r for r in rows if r["part"] == "fit" and r["target"] == name
           and r["noise"] == noise and r["n_eff_mode"] == mode]
    x = np.array([r["x_mm"] for r in sel])
    se = np.array([r["x_stderr_mm"] for r in sel])
    z = np.array([r["z_x"] for r in sel])
    out = {"n": len(sel), "bound": sel[0]["bound_x_stderr_mm"],
           "sd": float(np.std(x, ddof=1)) if len(sel) > 1 else math.nan,
           "rms": float(np.sqrt(np.mean((x - TRUTH.exit_pupil_mm) ** 2))),
           "se": float(np.mean(se)), "max_z": float(np.max(np.abs(z))),
           "rms_z": float(np.sqrt(np.mean(z**2))),
           "chi2_red": float(np.mean([r["chi2_red"] for r in sel]))}
    if mode == "fitted":
        n = np.array([r["n_eff"] for r in sel])
        out["n_sd"] = float(np.std(n, ddof=1)) if len(sel) > 1 else math.nan
        out["n_se"] = float(np.mean([r["n_eff_stderr"] for r in sel]))
        out["n_bound"] = sel[0]["bound_n_eff_stderr"]
        zn = np.array([r["z_n"] for r in sel])
        out["n_max_z"] = float(np.max(np.abs(zn)))
        out["n_rms_z"] = float(np.sqrt(np.mean(zn**2)))
        out["n_rms"] = float(np.sqrt(np.mean((n - N_EFF) ** 2)))
    return out


def _echo_checks(rows, checks, echo):
    echo("\nthe bound against fits: spectrum solved for, centre found, the simulator's own "
         "spectrum in the bound (x in mm; z = error / reported se)")
    echo(f"{'target':<32} {'n_eff':<7} {'noise':>6} {'seeds':>5} {'bound':>9} {'sd(x)':>9} "
         f"{'rms err':>9} {'mean se':>9} {'sd/bound':>8} {'se/bound':>8} {'rms z':>6} "
         f"{'max|z|':>6} {'chi2_red':>8}")
    for name, nz, fit_n, seeds in checks:
        mode = "fitted" if fit_n else "known"
        s = _check_summary(rows, name, nz, mode)
        echo(f"{name:<32} {mode:<7} {100 * nz:>5g}% {len(seeds):>5} {s['bound']:>9.3g} "
             f"{s['sd']:>9.3g} {s['rms']:>9.3g} {s['se']:>9.3g} {s['sd'] / s['bound']:>8.2f} "
             f"{s['se'] / s['bound']:>8.2f} {s['rms_z']:>6.2f} {s['max_z']:>6.2f} "
             f"{s['chi2_red']:>8.3f}")
        if mode == "fitted":
            echo(f"{'':<32} {'n_eff:':<7} {'':>6} {'':>5} {s['n_bound']:>9.3g} "
                 f"{s['n_sd']:>9.3g} {s['n_rms']:>9.3g} {s['n_se']:>9.3g} "
                 f"{s['n_sd'] / s['n_bound']:>8.2f} {s['n_se'] / s['n_bound']:>8.2f} "
                 f"{s['n_rms_z']:>6.2f} {s['n_max_z']:>6.2f}")
    n = min(len(c[3]) for c in checks)
    if n > 1:
        lo, hi = (math.sqrt(v / (n - 1)) for v in _chi2_interval(n - 1))
        lo_r, hi_r = (math.sqrt(v / n) for v in _chi2_interval(n))
        echo(f"({n} seeds: a standard deviation from them falls within {lo:.2f}-{hi:.2f} of the "
             f"true one, an rms error about the truth within {lo_r:.2f}-{hi_r:.2f}, 90 % "
             "intervals)")


def _chi2_interval(dof):
    from scipy import stats

    return stats.chi2.ppf(0.05, dof), stats.chi2.ppf(0.95, dof)


# -- files -------------------------------------------------------------------------------------
def write_files(rows, directory=HERE):
    """``pupil.csv`` and ``pupil.png`` in ``directory``."""
    directory = Path(directory)
    write_csv(directory / "pupil.csv", rows)
    plt = pyplot()
    from matplotlib.ticker import NullFormatter

    fig, axes = plt.subplots(1, 2, figsize=(12, 6), sharey=True, layout="constrained")
    bounds = [r for r in rows if r["part"] == "bound"]
    names = list(dict.fromkeys(r["target"] for r in bounds))
    colour = {name: f"C{k}" for k, name in enumerate(names)}
    analogue = {"rare-earth glass (spectralsim)": "rare-earth glass",
                "colour filter (spectralsim)": "colour filter (Goossens 2019)"}
    finite = [r["bound_x_stderr_mm"] for r in bounds if r["note"] == ""]
    top = 10 * max(finite) if finite else 1.0
    for ax, mode in zip(axes, ("known", "fitted"), strict=True):
        off = []
        for name in names:
            for spectrum, style in (("unknown", "-"), ("known", ":")):
                sel = sorted((r for r in bounds if r["target"] == name
                              and r["spectrum"] == spectrum and r["n_eff_mode"] == mode),
                             key=lambda r: r["noise"])
                if not sel:
                    continue
                nz = [100 * r["noise"] for r in sel]
                se = [r["bound_x_stderr_mm"] for r in sel]
                if min(se) > top:
                    if spectrum == "unknown":
                        off.append(f"{name} (bound {min(se):.2g} mm or more)")
                    continue
                ax.plot(nz, se, style, marker="o" if spectrum == "unknown" else None, ms=3,
                        color=colour[name], label=f"{name}" if spectrum == "unknown" else None)
        checks = [r for r in rows if r["part"] == "fit" and r["n_eff_mode"] == mode]
        for k, name in enumerate(dict.fromkeys(r["target"] for r in checks)):
            c = colour.get(analogue.get(name), f"C{len(names) + k}")
            levels = sorted({r["noise"] for r in checks if r["target"] == name})
            stats_ = [_check_summary(rows, name, nz, mode) for nz in levels]
            nz = np.array(levels) * 100
            ax.plot(nz, [s["bound"] for s in stats_], "_", color=c, ms=22, mew=2,
                    label=f"{name}: bound")
            ax.plot(nz * 0.95, [s["sd"] for s in stats_], "D", color=c, ms=6,
                    label=f"{name}: sd of x over {stats_[0]['n']} seeds")
            ax.plot(nz * 1.05, [s["se"] for s in stats_], "D", mfc="none", color=c, ms=6,
                    label=f"{name}: mean reported se")
        ax.set(xscale="log", yscale="log", xlabel="noise per pixel (% of the brightest band)",
               title=f"n_eff {mode}" + (" (one value, f/2 + f/8)" if mode == "fitted" else ""))
        levels = sorted({100 * r["noise"] for r in bounds})
        ax.set_xticks(levels, labels=[f"{v:g}" for v in levels])
        ax.xaxis.set_minor_formatter(NullFormatter())
        if off:
            ax.text(0.02, 0.97, "off the chart: " + ", ".join(off),
                    transform=ax.transAxes, va="top", fontsize=8)
        sec = ax.secondary_yaxis("right", functions=(
            lambda v: 100 * v / TRUTH.exit_pupil_mm, lambda v: v * TRUTH.exit_pupil_mm / 100))
        sec.set_ylabel("% of x" if mode == "fitted" else "")
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
    axes[0].set_ylabel("standard error of x (mm)")
    legend = {}
    for ax in axes:
        for h, label in zip(*ax.get_legend_handles_labels(), strict=True):
            legend.setdefault(label, h)
    fig.legend(legend.values(), legend.keys(), loc="outside lower center", ncol=3, fontsize=8)
    fig.suptitle("Exit pupil from target cubes: predicted standard error of x (Cramér-Rao "
                 "bound; solid: spectrum solved for, dotted: known)\nand fits to simulated "
                 "cubes (bars: their bound; diamonds: realised)", fontsize=10)
    fig.savefig(directory / "pupil.png", dpi=110)
    plt.close(fig)


def run(*, quick=False, echo=print, write=True):
    rows = speed(quick=quick, echo=echo)
    echo("")
    rows += precision(quick=quick, echo=echo)
    if write:
        write_files(rows)
    return rows


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    t0 = time.perf_counter()
    run(quick=quick, write=not quick)
    print(f"({'quick' if quick else 'full'} run: {time.perf_counter() - t0:.0f} s)")
