"""Record the one-vignetting-circle optics of snapcorr as a reference for later versions.

Generated from commit 89809d72eb972876708e87b087c1f93e983e47ae (1920 cases, 223 kB),
a version whose ``Lens`` takes a single circle as
``Lens(name, exit_pupil_mm, vignetting_radius_mm, vignetting_distance_mm, magnification,
pupil_magnification)``. Run it against a checkout of that commit:

    git worktree add /tmp/snap_head 89809d7
    PYTHONPATH=/tmp/snap_head python tests/data/make_one_circle_reference.py

It writes ``one_circle_reference.npz`` next to itself: for a seeded random set of cases (one
lens per case), the inputs

    x, P, h (NaN for a lens without a circle), m, mP, f, cra, cwl, n, family

and the outputs of ``mean_shift`` with the methods "vignetted", "ideal", "asymptotic",
"table" and "auto" (tolerance 1e-3 nm), plus ``relative_illumination``, ``onset_cra_deg`` and
``cutoff_cra_deg``. ``tests/optics/test_discs.py`` checks that a lens with the same single
circle, given in the newer form with any number of circles, reproduces these numbers.
"""

from __future__ import annotations

import subprocess
import warnings
from pathlib import Path

import numpy as np

import snapcorr
from snapcorr import Lens, mean_shift

SEED = 20190412
N_PER_FAMILY = 160
METHODS = ("vignetted", "ideal", "asymptotic", "table", "auto")
TOLERANCE_NM = 1e-3
CRA_MAX_DEG = 35.0

#: Case families: how the circle sits relative to the exit pupil.
FAMILIES = (
    "none",          # no vignetting circle
    "h<x",           # 0 < h < x
    "h>x",           # h > x
    "h=x",           # pixel vignetting
    "h<0",           # circle moving against the chief ray
    "h=0",           # fixed stop, P > R (never cuts) or P < R (cuts everywhere)
    "P<R",           # vignetted on axis, any h
    "near_cutoff",   # CRA just below the full cut-off
    "never",         # a circle that never reaches the pupil below 35 deg
    "mP!=1",         # pupil magnification away from 1, magnification > 0
    "m=0,h<x",       # focus at infinity
    "small_area",    # relative illumination of a few percent
)


def _radius(x, f, m, mP):
    return x / (2.0 * (1.0 + m / mP) * f)


def _cutoff(P, R, h):
    return np.inf if h == 0 else np.rad2deg(np.arctan((P + R) / abs(h)))


def draw_case(rng, family):
    """One case: (x, P, h, m, mP, f, cra, cwl, n); P = h = NaN for no circle."""
    for _ in range(10_000):
        x = rng.uniform(8.0, 60.0)
        f = float(np.exp(rng.uniform(np.log(1.2), np.log(22.0))))
        m = 0.0 if rng.random() < 0.5 else rng.uniform(0.0, 0.5)
        mP = 1.0 if rng.random() < 0.6 else rng.uniform(0.5, 2.5)
        cwl = rng.uniform(400.0, 1000.0)
        n = rng.uniform(1.4, 2.4)
        if family == "mP!=1":
            m, mP = rng.uniform(0.05, 0.5), rng.uniform(0.5, 2.5)
        if family == "m=0,h<x":
            m = 0.0
        R = _radius(x, f, m, mP)
        P = R * rng.uniform(1.0, 3.0)
        if family == "none":
            P = h = np.nan
        elif family in ("h<x", "mP!=1", "m=0,h<x"):
            h = x * rng.uniform(0.1, 0.97)
        elif family == "h>x":
            h = x * rng.uniform(1.03, 3.0)
        elif family == "h=x":
            h = x
        elif family == "h<0":
            h = -x * rng.uniform(0.05, 1.5)
        elif family == "h=0":
            h = 0.0
            P = R * (rng.uniform(0.4, 0.95) if rng.random() < 0.5 else rng.uniform(1.01, 2.0))
        elif family == "P<R":
            P = R * rng.uniform(0.3, 0.97)
            h = x * rng.choice([rng.uniform(-1.5, -0.05), rng.uniform(0.05, 0.97), 1.0,
                                rng.uniform(1.03, 3.0)])
        elif family in ("near_cutoff", "small_area"):
            P = R * rng.uniform(0.5, 2.0)
            h = x * rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 3.0)
        elif family == "never":
            h = x * rng.uniform(0.2, 2.0) * rng.choice([-1.0, 1.0])
            P = R + abs(h) * np.tan(np.deg2rad(CRA_MAX_DEG)) * rng.uniform(1.02, 1.5)
        else:
            raise ValueError(family)
        cut = CRA_MAX_DEG if np.isnan(P) else min(CRA_MAX_DEG, _cutoff(P, R, h))
        if family == "near_cutoff":
            if _cutoff(P, R, h) >= CRA_MAX_DEG:
                continue
            cra = cut * (1.0 - 10.0 ** rng.uniform(-4.0, -2.0))
        elif family == "small_area":
            if _cutoff(P, R, h) >= CRA_MAX_DEG:
                continue
            cra = cut * rng.uniform(0.85, 0.97)
        else:
            cra = rng.uniform(0.0, 0.995 * cut) if rng.random() < 0.9 else 0.0
        return x, P, h, m, mP, f, cra, cwl, n
    raise RuntimeError(f"no case found for {family}")


def make_lens(x, P, h, m, mP):
    if np.isnan(P):
        return Lens("reference", x, None, None, m, mP)
    return Lens("reference", x, P, h, m, mP)


OUT = Path(__file__).with_name("one_circle_reference.npz")


def main(out=OUT):
    rng = np.random.default_rng(SEED)
    rows, family = [], []
    for k, fam in enumerate(FAMILIES):
        for _ in range(N_PER_FAMILY):
            rows.append(draw_case(rng, fam))
            family.append(k)
    cases = np.array(rows)
    names = ("x", "P", "h", "m", "mP", "f", "cra", "cwl", "n")
    data = {k: cases[:, i] for i, k in enumerate(names)}
    results = {f"shift_{m}": np.empty(len(cases)) for m in METHODS}
    for k in ("relative_illumination", "onset_cra_deg", "cutoff_cra_deg"):
        results[k] = np.empty(len(cases))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", snapcorr.EffectiveIndexWarning)
        for i, (x, P, h, m, mP, f, cra, cwl, n) in enumerate(rows):
            lens = make_lens(x, P, h, m, mP)
            for method in METHODS:
                results[f"shift_{method}"][i] = mean_shift(
                    cwl, n, f, cra, lens, method=method, tolerance_nm=TOLERANCE_NM)
            results["relative_illumination"][i] = lens.relative_illumination(f, cra)
            results["onset_cra_deg"][i] = lens.onset_cra_deg(f)
            results["cutoff_cra_deg"][i] = lens.cutoff_cra_deg(f)
    src = Path(snapcorr.__file__).resolve().parents[1]
    commit = subprocess.run(["git", "-C", str(src), "rev-parse", "HEAD"], capture_output=True,
                            text=True, check=False).stdout.strip()
    np.savez_compressed(
        out, **data, **results, family=np.array(family), family_names=np.array(FAMILIES),
        tolerance_nm=TOLERANCE_NM, commit=np.array(commit), seed=SEED,
    )
    print(f"{len(rows)} cases from {commit or 'unknown commit'} -> {out} "
          f"({out.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
