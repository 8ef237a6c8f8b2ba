"""Do the virtual bands' error bars cover over lens types and noise?

The lens types of ``benchmarks/calibration_coverage.py`` (x = 21 mm: one circle h < x, one
circle h > x, two, three, a circle plus pixel vignetting, the optical axis near a corner)
in front of the real imec 5x5 NIR sensor (``calibration/sensors/CMV2K-SSM5x5-600_875-5.5.9.2.xml``,
n_eff 1.8). Band values from ``tests/oracles/mosaicsim.py`` (pupil rays through every
circle, each scaling the measured curves; no snapcorr code) for 300 spectra the prior never
saw (PROSPECT-D leaves, prosail's soils and mixtures), with 0.5 % and 2 % Gaussian noise, at
f/1.4 and f/4 and five chief-ray angles from the axis to the field's corner (that lens
type's field in ``calibration_coverage``, 16.7 deg, or 26.6 deg with the axis near a
corner). Each method's error is against the Gaussian virtual bands of the vendor's
wavelengths and width; z of a band is its RMS error over the spectra divided by its
``virtual_stderr``, and a case's z the RMS over the bands. RMS z should lie in [0.5, 2].

``python -m benchmarks.virtual_coverage [--quick]`` prints a line per cell and writes
``virtual_coverage.csv`` next to this file.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from . import write_csv

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))

import mosaicsim as ms  # noqa: E402
from flatsim import LensTruth  # noqa: E402

from .calibration_coverage import CASES, X, field_tan  # noqa: E402
from .virtual_bands import N_EFF, XML  # noqa: E402

METHODS = ("vendor", "fitted", "angle-aware")
NOISES = (0.005, 0.02)
F_NUMBERS = (1.4, 4.0)


def _lit_angles(truth, f, top_deg, n=5):
    """n chief-ray angles from 0 to the corner's, short of where no ray passes."""
    cra = np.linspace(0.0, top_deg, n)
    keep = []
    for c in cra:
        d = X * math.tan(math.radians(c))
        u, _, w = ms.pupil_samples(truth, f, d, theta_nodes=16, r_nodes=8)
        if w.sum() > 0 and u.size:
            keep.append(float(c))
    return keep


def run(*, quick=False, echo=print, write=True, seed=0):
    from snapcorr import Lens
    from snapcorr.correct import virtual_bands
    from snapcorr.cube import Sensor, make_cube

    sensor = dataclasses.replace(Sensor.load(XML), n_eff=(N_EFF,) * 25, pixel_pitch_um=5.5)
    mf = ms.read_older(XML)
    n = 30 if quick else 150
    spectra = np.concatenate([ms.leaves(n, 1), ms.soils_and_mixtures(n, 2)])
    truth_bands = ms.virtual_truth(mf, spectra)
    rng = np.random.default_rng(seed)
    rows = []
    cases = ("two", "off_centre") if quick else tuple(CASES)
    for case in cases:
        circles, m, mP, centre, _ = CASES[case]
        truth = LensTruth(X, tuple(circles), m, mP, name=case)
        lens = Lens(X, [tuple(c) for c in circles], m, mP, name=case)
        top = math.degrees(math.atan(field_tan(centre)))
        for f in (F_NUMBERS[:1] if quick else F_NUMBERS):
            for cra in _lit_angles(truth, f, top, n=2 if quick else 5):
                R = ms.responses(mf, truth, f, cra, N_EFF)
                clean = ms.band_values(R, spectra)[:, sensor.vendor_band]  # sensor's order
                for noise in NOISES:
                    t = time.perf_counter()
                    y = clean + noise * rng.standard_normal(clean.shape)
                    cube = make_cube(y[:, None, :].astype(np.float32), sensor.cwl_nm,
                                     name="reflectance")
                    for method in METHODS:
                        with warnings.catch_warnings():
                            warnings.simplefilter("ignore")
                            ds = virtual_bands(cube, sensor, method, f_number=f, lens=lens,
                                               cra_deg=np.full((y.shape[0], 1), cra))
                        est = ds["virtual"].values[:, 0, :]
                        err = np.sqrt(np.mean((est - truth_bands) ** 2, axis=0))
                        stderr = np.asarray(ds["virtual_stderr"].values, float)
                        stderr = stderr.reshape(-1, stderr.shape[-1]).mean(axis=0)
                        rows.append({"case": case, "noise": noise, "f_number": f,
                                     "cra_deg": round(cra, 2), "method": method,
                                     "rmse": float(np.sqrt(np.mean(err**2))),
                                     "stderr": float(np.sqrt(np.mean(stderr**2))),
                                     "z_rms": float(np.sqrt(np.mean((err / stderr) ** 2))),
                                     "seconds": time.perf_counter() - t})
        for noise in NOISES:
            cell = [r for r in rows if r["case"] == case and r["noise"] == noise]
            zs = [r["z_rms"] for r in cell]
            echo(f"{case} at {noise:.1%} noise ({len(cell)} cases: f-numbers, angles to "
                 f"{top:.1f} deg, methods): z RMS {min(zs):.2f}-{max(zs):.2f}, outside "
                 f"[0.5, 2]: {sum(not 0.5 <= z <= 2 for z in zs)}; RMSE "
                 f"{min(r['rmse'] for r in cell):.4f}-{max(r['rmse'] for r in cell):.4f}")
    if write:
        write_csv(HERE / "virtual_coverage.csv", rows)
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    run(quick=a.quick)
