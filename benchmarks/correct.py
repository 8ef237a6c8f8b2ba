"""Cube correction: the shift map, resampling and harmonising against a numpy copy of the cube.

A 2048 x 2048 x 150 float32 cube (2.5 GB; 512 x 512 in quick mode) behind the paper's lens at
f/1.4, Snapscan-like sensor with 150 evenly spaced bands. Times are measured in this run and
given as ratios to ``cube.copy()`` measured alongside; peak memory (resident set of a fresh
process) as a ratio to the cube's size.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

_CHILD = r"""
import json, resource, sys, time
import numpy as np
from snapcorr import Lens
from snapcorr.correct import correct_cube, cube_cra_deg, relative_shift
from snapcorr.cube import Sensor, make_cube
n, what = int(sys.argv[1]), sys.argv[2]
lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
sensor = Sensor("bench", "snapscan", 5.5 * 2048 / n, np.linspace(470, 900, 150), 10.0, 1.7)
data = np.random.default_rng(0).random((n, n, 150), dtype=np.float32)
cube = make_cube(data, sensor.cwl_nm)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
out = {"cube_bytes": data.nbytes}
if what == "copy":
    t = time.perf_counter(); c = data.copy(); out["seconds"] = time.perf_counter() - t
elif what == "shiftmap":
    t = time.perf_counter()
    cra = cube_cra_deg(cube, sensor, lens)[0]
    rel = relative_shift(1.7, 1.4, cra[:, :, 0], lens, model="vignetted",
                         tolerance_nm=0.01, cwl_max_nm=900.0)
    out["seconds"] = time.perf_counter() - t
elif what == "resample":
    small = make_cube(data[:4, :4], sensor.cwl_nm)
    correct_cube(small, sensor, 1.4, lens, resample=True)  # compile once, outside the timing
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    from snapcorr.correct.resample import resample_to_nominal
    cra = cube_cra_deg(cube, sensor, lens)[0]
    scale = 1.0 + relative_shift(1.7, 1.4, cra, lens, model="vignetted",
                                 tolerance_nm=0.01, cwl_max_nm=900.0)
    t = time.perf_counter()
    r = resample_to_nominal(data, scale, np.zeros(150, int), np.asarray(sensor.cwl_nm))
    out["seconds"] = time.perf_counter() - t
    out["nan_fraction"] = float(np.isnan(r[::64, ::64]).mean())
elif what == "harmonise":
    small = make_cube(data[:4, :4], sensor.cwl_nm)
    correct_cube(small, sensor, 1.4, lens, harmonise=True)  # compile once, outside the timing
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t = time.perf_counter()
    ds = correct_cube(cube, sensor, 1.4, lens, harmonise=True)
    h = ds["harmonised"].values  # the whole job: CRA, shift and FWHM tables, weights, pass
    out["seconds"] = time.perf_counter() - t
    out["nan_fraction"] = float(np.isnan(h[::64, ::64]).mean())
    out["fwhm_nodes"] = int(ds.sizes["fwhm_cra"])
out["peak_rss"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps(out))
"""


def _child(n, what):
    res = subprocess.run([sys.executable, "-c", _CHILD, str(n), what], capture_output=True,
                         text=True, check=True, timeout=900)
    return json.loads(res.stdout.strip().splitlines()[-1])


def run(*, quick=False, echo=print):
    """Measure; return a dict of the figures."""
    n = 512 if quick else 2048
    copy = min((_child(n, "copy") for _ in range(2)), key=lambda r: r["seconds"])
    shift = _child(n, "shiftmap")
    res = min((_child(n, "resample") for _ in range(2)), key=lambda r: r["seconds"])
    har = min((_child(n, "harmonise") for _ in range(2)), key=lambda r: r["seconds"])
    gb = copy["cube_bytes"] / 2**30
    echo(f"cube correction, {n} x {n} x 150 float32 ({gb:.2f} GiB), f/1.4, paper's lens:")
    echo(f"  numpy copy of the cube:        {copy['seconds']:.2f} s")
    echo(f"  shift map (CRA + table):       {shift['seconds']:.2f} s")
    echo(f"  resampling onto nominal grid:  {res['seconds']:.2f} s = "
         f"{res['seconds'] / copy['seconds']:.2f} x the copy (target 1.5 x); peak memory "
         f"{res['peak_rss'] / res['cube_bytes']:.2f} x the cube (target 2.2 x)")
    echo(f"  correct_cube(harmonise=True):  {har['seconds']:.2f} s = "
         f"{har['seconds'] / copy['seconds']:.2f} x the copy (target 3 x), all of it (CRA, "
         f"shift and FWHM tables ({har['fwhm_nodes']} angles), weights, one pass); peak "
         f"memory {har['peak_rss'] / har['cube_bytes']:.2f} x the cube (target 2.5 x)")
    return {"n": n, "copy_s": copy["seconds"], "shift_map_s": shift["seconds"],
            "resample_s": res["seconds"], "resample_ratio": res["seconds"] / copy["seconds"],
            "peak_ratio": res["peak_rss"] / res["cube_bytes"],
            "harmonise_s": har["seconds"], "harmonise_ratio": har["seconds"] / copy["seconds"],
            "harmonise_peak_ratio": har["peak_rss"] / har["cube_bytes"]}


if __name__ == "__main__":  # pragma: no cover
    t0 = time.perf_counter()
    run(quick="--quick" in sys.argv)
    print(f"({time.perf_counter() - t0:.0f} s)")
