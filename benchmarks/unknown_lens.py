"""An unknown lens in one run (``calibrate_with_target``): do x, n_eff, P, h and the centre
come out within tolerance, and do their errors cover?

Flats come from ``tests/oracles/flatsim.py`` (five f-numbers f/1.4-f/8, 0.5 % noise, each with its
own exposure) and target cubes from ``tests/oracles/spectralsim.py`` (``colour_filter``, f/2 and
f/8, 30 bands of 12 nm, n_eff 1.7), two simulators that share no code with snapcorr, on a
128 x 160 sensor of 44 um pixels (the field of a 1280 x 1024, 5.5 um sensor seen through 8 x 8
binning: up to 12 deg) with the optical axis off centre. Neither is given x. Truths: the
paper's lens (one circle, h < x) and a lens with its circle behind the pupil's plane (h > x).
Per truth, target noise and index mode: eight seeds, the largest relative error of each
parameter and the RMS over the seeds of its error over the reported standard error (z).

Writes ``unknown_lens.csv`` next to this file unless ``write=False``; ``--quick`` runs one
seed of one case.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from . import write_csv

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))

PITCH_UM, SHAPE, CENTER = 44.0, (128, 160), (82.3, 61.6)
CWL = np.arange(500.0, 849.0, 12.0)
N_EFF = 1.7
FLAT_F = (1.4, 2.0, 2.8, 4.0, 8.0)
TARGET_F = (2.0, 8.0)
SEEDS = tuple(range(8))
NOISES = (0.002, 0.01)


def _truths():
    from conftest import PAPER_TRUTH
    from flatsim import LensTruth

    return {"paper lens, h < x": PAPER_TRUTH,
            "one circle, h > x": LensTruth(21.0, ((11.0, 30.0),), 0.06, 1.3, name="h > x")}


def _one(job):
    import spectralsim as sim
    from flatsim import make_flats

    from snapcorr.calibrate import calibrate_with_target
    from snapcorr.cube import Sensor, make_cube

    name, noise, fit_n_eff, seed = job
    truth = _truths()[name]
    flats = make_flats(truth, FLAT_F, shape=SHAPE, pitch_um=PITCH_UM, center_px=CENTER,
                       noise=0.005, seed=seed)
    rng = np.random.default_rng(1000 + seed)
    cubes = {}
    for f in TARGET_F:
        data = sim.target_cube(sim.colour_filter, cwl_nm=CWL, fwhm_nm=12.0, n_eff=N_EFF,
                               f_number=f, lens=truth, shape=SHAPE, pixel_pitch_um=PITCH_UM,
                               center_px=CENTER)
        cubes[f] = make_cube(data + rng.normal(0.0, noise, data.shape), CWL)
    sensor = Sensor("test", "snapscan", PITCH_UM, CWL, 12.0, N_EFF)
    got = calibrate_with_target(flats, cubes, sensor, pixel_pitch_um=PITCH_UM,
                                fit_n_eff=fit_n_eff, magnification=truth.magnification,
                                pupil_magnification=truth.pupil_magnification, max_circles=1)
    true = {"exit_pupil_mm": truth.exit_pupil_mm, "n_eff": N_EFF,
            "P_mm": truth.circles[0][0], "h_mm": truth.circles[0][1],
            "center_row_px": CENTER[1], "center_col_px": CENTER[0]}
    row = {"truth": name, "target_noise": noise, "fit_n_eff": fit_n_eff, "seed": seed,
           "model": got.calibration.model, "method": got.calibration.method,
           "notes": len(got.notes)}
    for n, v, e in zip(got.names, got.values, got.stderr, strict=True):
        row[f"{n}_rel_error"] = v / true[n] - 1
        row[f"{n}_z"] = (v - true[n]) / e
    return row


def coverage(*, quick=False, echo=print, write=True, workers=2):
    from concurrent.futures import ProcessPoolExecutor

    names = list(_truths())
    if quick:
        jobs = [(names[0], 0.002, True, 0)]
    else:
        jobs = [(n, z, k, s) for n in names for z in NOISES for k in (True, False)
                for s in SEEDS]
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(workers) as pool:
            rows = list(pool.map(_one, jobs))
    else:
        rows = [_one(j) for j in jobs]
    params = ("exit_pupil_mm", "n_eff", "P_mm", "h_mm", "center_row_px", "center_col_px")
    echo("one run for an unknown lens: largest |relative error| % / RMS z over "
         f"{len(SEEDS) if not quick else 1} seeds")
    echo(f"{'truth':<18} {'noise':>6} {'n_eff':>7}  " + "  ".join(f"{p:>15}" for p in params))
    groups = sorted({(r["truth"], r["target_noise"], r["fit_n_eff"]) for r in rows},
                    key=lambda g: (names.index(g[0]), g[1], not g[2]))
    for g in groups:
        sel = [r for r in rows if (r["truth"], r["target_noise"], r["fit_n_eff"]) == g]
        cells = []
        for p in params:
            if f"{p}_z" not in sel[0]:
                cells.append(f"{'-':>15}")
                continue
            worst = max(abs(r[f"{p}_rel_error"]) for r in sel)
            rms = np.sqrt(np.mean([r[f"{p}_z"] ** 2 for r in sel]))
            cells.append(f"{100 * worst:>7.3f} / {rms:4.2f}")
        echo(f"{g[0]:<18} {100 * g[1]:>5.1f}% {'fitted' if g[2] else 'known':>7}  "
             + "  ".join(cells))
    if write:
        keys = sorted({k for r in rows for k in r}, key=lambda k: (k not in rows[0], k))
        write_csv(HERE / "unknown_lens.csv", [{k: r.get(k, "") for k in keys} for r in rows])
    return rows


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    coverage(quick=quick, write=not quick)
