"""What the exit pupil's x and n_eff rest on: the paper's pupil against a Lambertian pupil that
obeys the sine condition, fitted with the paper's model and with ``pupil_radiance="auto"``.

The paper's pupil (Goossens et al. 2019, Eq. 28) is a flat disc of radius ``x tan(theta) = x /
(2 f_W)``, rays weighted uniformly over its area. A lens obeying the sine condition has its
marginal ray at ``sin(theta) = 1 / (2 f_W)``, and a Lambertian pupil weights each ray by
``cos^4(phi)`` per unit area (uniform in direction cosines); snapcorr models both
(``Lens.pupil``). The independent simulator ``tests/oracles/spectralsim.py`` makes cubes of
``rare_earth_glass`` either way (a lens without vignetting, x = 16 mm, n_eff 1.7, 128 x 160
pixels of 44 um, 30 bands of 12 nm, 0.05 % noise, the centre given); ``locate_pupil`` fits
them with n_eff known and fitted, from f/2 + f/8 and from f/5.6 + f/11, with the paper's pupil
and with ``pupil_radiance="auto"`` (both fitted, the Lambertian kept for a chi-square gain
above 10).
The table gives the pupil chosen, the relative errors of x and n_eff and the z of x.

Writes ``pupil_model.csv`` next to this file unless ``write=False``; ``--quick`` runs one case.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from . import write_csv

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))

PITCH_UM, SHAPE = 44.0, (128, 160)
CENTER = (SHAPE[1] * 0.514, SHAPE[0] * 0.481)
CWL = np.arange(500.0, 849.0, 12.0)
X, N_EFF, NOISE = 16.0, 1.7, 0.0005
PAIRS = ((2.0, 8.0), (5.6, 11.0))
PUPILS = ("paper", "sine")
MODELS = ("paper", "auto")


def _one(job):
    import spectralsim as sim
    from flatsim import LensTruth

    from snapcorr import Lens
    from snapcorr.calibrate import locate_pupil
    from snapcorr.cube import Sensor, make_cube

    pupil, pair, fit, seed, model = job
    truth = LensTruth(X, (), 0.0, 1.0, meta={"pupil": pupil})
    rng = np.random.default_rng(seed)
    cubes = {}
    for f in pair:
        c = sim.target_cube(sim.rare_earth_glass, cwl_nm=CWL, fwhm_nm=12.0, n_eff=N_EFF,
                            f_number=f, lens=truth, shape=SHAPE, pixel_pitch_um=PITCH_UM,
                            center_px=CENTER)
        cubes[f] = make_cube(c + rng.normal(0.0, NOISE, c.shape), CWL)
    sensor = Sensor("test", "snapscan", PITCH_UM, CWL, 12.0, N_EFF)
    got = locate_pupil(cubes, sensor, lens=Lens(30.0, ()), fit_n_eff=fit,
                       center_rc=CENTER[::-1], pupil_radiance=model)
    return {"pupil": pupil, "model": model, "chosen": got.lens.pupil_radiance,
            "f_numbers": "+".join(f"f/{f:g}" for f in pair),
            "n_eff": "fitted" if fit else "known", "seed": seed,
            "x_rel_error": got.exit_pupil_mm / X - 1,
            "x_z": (got.exit_pupil_mm - X) / got.exit_pupil_stderr_mm,
            "n_eff_rel_error": float(got.n_eff[0] / N_EFF - 1) if fit else 0.0,
            "chi2_red": got.chi2_red}


def run(*, quick=False, echo=print, write=True, workers=2):
    from concurrent.futures import ProcessPoolExecutor

    jobs = ([("sine", PAIRS[1], False, 0, "auto")] if quick else
            [(p, pair, fit, s, m) for p in PUPILS for pair in PAIRS for fit in (False, True)
             for s in (0, 1) for m in MODELS])
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(workers) as pool:
            rows = list(pool.map(_one, jobs))
    else:
        rows = [_one(j) for j in jobs]
    echo("x and n_eff from a target, the paper's pupil against a Lambertian sine-condition "
         "pupil (mean of the seeds)")
    echo(f"{'pupil':<7} {'model':<6} {'chosen':<11} {'f-numbers':<12} {'n_eff':<7} "
         f"{'x error %':>9} {'z of x':>7} {'n_eff error %':>13} {'chi2':>6}")
    keys = sorted({(r["pupil"], r["model"], r["f_numbers"], r["n_eff"]) for r in rows})
    for k in keys:
        sel = [r for r in rows if (r["pupil"], r["model"], r["f_numbers"], r["n_eff"]) == k]
        mean = {c: float(np.mean([r[c] for r in sel]))
                for c in ("x_rel_error", "x_z", "n_eff_rel_error", "chi2_red")}
        chosen = "/".join(sorted({r["chosen"] for r in sel}))
        echo(f"{k[0]:<7} {k[1]:<6} {chosen:<11} {k[2]:<12} {k[3]:<7} "
             f"{100 * mean['x_rel_error']:>+9.3f} {mean['x_z']:>+7.1f} "
             + (f"{100 * mean['n_eff_rel_error']:>+13.3f}" if k[3] == "fitted" else
                f"{'-':>13}") + f" {mean['chi2_red']:>6.3f}")
    if write:
        write_csv(HERE / "pupil_model.csv", rows)
    return rows


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    run(quick=quick, write=not quick)
