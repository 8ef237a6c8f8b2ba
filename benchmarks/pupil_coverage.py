"""Do the exit pupil's error bars cover? z = (fit - truth) / reported standard error over seeds.

Target cubes from physical rays behind the paper lens (x = 21 mm, one circle P = 7.4236 mm,
h = 16.991 mm, m = 0.06, m_P = 1.3), at f/1.4 and f/8, ``locate_pupil(fit_n_eff=True)`` with
the lens's circles given and the optical centre found:

* ``modelled``: a Snapscan-like sensor of 128 x 160 pixels of 44 um (the field of a 1280 x 1024
  sensor of 5.5 um binned 8 x 8), 30 Gaussian bands of 12 nm FWHM every 12 nm, 500-848 nm,
  n_eff 1.7; cubes from ``tests/oracles/spectralsim.py`` (every pupil ray scales the whole filter
  curve, ``T(lambda) = T0(lambda / s)``), the rare-earth glass at 0.2 % noise.
* ``measured``: the real imec 4 x 4 VIS responses behind their band-pass
  (``tests/vendorfiles.imec_4x4``), 320 x 640 pixels of 17.6 um, n_eff 1.85 (the vendor file
  gives none: fitted from 1.7), raw mosaic frames from
  ``tests/calibrate/pupil/test_measured_target.py``'s forward model (every ray scales the whole
  measured curve; the band-pass does not move) at 0.5 %
  noise, 16 annuli, split with ``mosaic_to_cube``.
* ``one_f2``, ``one_f8``: the modelled sensor at f/2 or f/8 alone, the filters' true index 1.75
  where the sensor says 1.7: at f/2 the field pins the index; at f/8 it does not, x assumes
  the sensor's index and the z that counts is x * n_eff's.

Prints and writes ``pupil_coverage.csv``: per case and seed, x and n_eff, their reported
errors and z; then the RMS z per case. ``python -m benchmarks.pupil_coverage [CASE] [--seeds N]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))

X_MM = 21.0


_CLEAN = {}


def modelled(seed, noise=0.002):
    import spectralsim as sim
    from conftest import PAPER_LENS, PAPER_TRUTH

    from snapcorr.calibrate import locate_pupil
    from snapcorr.cube import Sensor, make_cube

    cwl = np.arange(500.0, 849.0, 12.0)
    if not _CLEAN:
        for f in (1.4, 8.0):
            _CLEAN[f] = sim.target_cube(sim.rare_earth_glass, cwl_nm=cwl, fwhm_nm=12.0,
                                        n_eff=1.7, f_number=f, lens=PAPER_TRUTH,
                                        shape=(128, 160), pixel_pitch_um=44.0,
                                        center_px=(82.3, 61.6))
    rng = np.random.default_rng(seed)
    cubes = {f: make_cube(c + rng.normal(0.0, noise, c.shape), cwl) for f, c in _CLEAN.items()}
    sensor = Sensor("modelled", "snapscan", 44.0, cwl, 12.0, 1.7)
    return locate_pupil(cubes, sensor, lens=PAPER_LENS, fit_n_eff=True), 1.7


def measured(seed):
    from calibrate.pupil import test_measured_target as tpm

    folder = Path(tempfile.gettempdir()) / "snapcorr_pupil_coverage"
    folder.mkdir(exist_ok=True)
    return tpm.fit(folder, seed, n_nodes=384), tpm.N_EFF


_ONE = {}


def one_f_number(f_number, seed, noise=0.002):
    """The modelled sensor at one f-number, its filters' index 1.75 where the sensor says 1.7."""
    import spectralsim as sim
    from conftest import PAPER_LENS, PAPER_TRUTH

    from snapcorr.calibrate import locate_pupil
    from snapcorr.cube import Sensor, make_cube

    cwl = np.arange(500.0, 849.0, 12.0)
    if f_number not in _ONE:
        _ONE[f_number] = sim.target_cube(sim.rare_earth_glass, cwl_nm=cwl, fwhm_nm=12.0,
                                         n_eff=1.75, f_number=f_number, lens=PAPER_TRUTH,
                                         shape=(128, 160), pixel_pitch_um=44.0,
                                         center_px=(82.3, 61.6))
    rng = np.random.default_rng(seed)
    clean = _ONE[f_number]
    cubes = {f_number: make_cube(clean + rng.normal(0.0, noise, clean.shape), cwl)}
    sensor = Sensor("modelled", "snapscan", 44.0, cwl, 12.0, 1.7)
    return locate_pupil(cubes, sensor, lens=PAPER_LENS, fit_n_eff=True), 1.75


CASES = {"modelled": modelled, "measured": measured,
         "one_f2": lambda seed: one_f_number(2.0, seed),
         "one_f8": lambda seed: one_f_number(8.0, seed)}


def run(cases=tuple(CASES), seeds=8, first=100, write=True):
    from . import write_csv

    rows = []
    for case in cases:
        for seed in range(first, first + seeds):
            t = time.perf_counter()
            got, n_true = CASES[case](seed)
            zx = (got.exit_pupil_mm - X_MM) / got.exit_pupil_stderr_mm
            fitted = got.n_eff_stderr is not None
            zn = (got.n_eff[0] - n_true) / got.n_eff_stderr[0] if fitted else math.nan
            zxn = (got.x_n_eff_mm - X_MM * n_true) / got.x_n_eff_stderr_mm
            rows.append({"case": case, "seed": seed, "x_mm": got.exit_pupil_mm,
                         "x_stderr_mm": got.exit_pupil_stderr_mm, "z_x": zx,
                         "n_eff": float(got.n_eff[0]),
                         "n_eff_stderr": float(got.n_eff_stderr[0]) if fitted else math.nan,
                         "z_n_eff": zn, "x_n_eff_mm": got.x_n_eff_mm,
                         "x_n_eff_stderr_mm": got.x_n_eff_stderr_mm, "z_x_n_eff": zxn,
                         "chi2_red": got.chi2_red, "mode": got.n_eff_fitted,
                         "seconds": time.perf_counter() - t})
            print(" ".join(f"{k}={v:.5g}" if isinstance(v, float) else f"{k}={v}"
                           for k, v in rows[-1].items()), flush=True)
        z = np.array([[r["z_x"], r["z_n_eff"], r["z_x_n_eff"]] for r in rows
                      if r["case"] == case])
        rms = np.sqrt(np.mean(z**2, axis=0))
        print(f"{case}: RMS z of x {rms[0]:.2f}, of n_eff {rms[1]:.2f}, of x * n_eff "
              f"{rms[2]:.2f} over {len(z)} seeds (x assumes the sensor's index where n_eff "
              "is not fitted)", flush=True)
    if write:
        name = "pupil_coverage.csv" if len(cases) == len(CASES) else \
            f"pupil_coverage_{'_'.join(cases)}.csv"
        write_csv(HERE / name, rows)
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("case", nargs="*", help=f"of {', '.join(CASES)} (default: all)")
    ap.add_argument("--seeds", type=int, default=8)
    a = ap.parse_args()
    if set(a.case) - set(CASES):
        ap.error(f"cases are {', '.join(CASES)}, got {', '.join(a.case)}")
    run(tuple(a.case or CASES), a.seeds)
