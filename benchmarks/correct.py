"""Cube correction: the shift map, resampling and harmonising against a numpy copy of the cube.

A 2048 x 2048 x 150 float32 cube (2.34 GiB; 512 x 512 in quick mode) behind the paper's lens
at f/1.4, Snapscan-like sensor with 150 evenly spaced bands. Each case runs in a fresh
process, which first times ``cube.copy()`` three times (the first touch of fresh memory in
this virtual machine costs several times a later one, so the least is kept: a warm copy) and
then the case itself (the least of two runs); times are given as ratios to that process's
copy. Peak memory (resident set of the process) as a ratio to the cube's size.

Cases: the shift map (CRA of every pixel and the shift table); the Numba resampling pass
alone; ``correct_cube(resample=True)`` whole (what ``benchmarks/scaling.py`` times against
cube size), once as called by default reading the resampled cube and the corrected
wavelengths (the FWHM table waits for a read of the widths), and once reading every pixel's
widths too (``fwhm_corrected``: the table and its interpolation); and
``correct_cube(harmonise=True)`` whole.
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
from snapcorr.correct import correct_cube, cube_cra, relative_shift
from snapcorr.cube import Sensor, make_cube
n, what = int(sys.argv[1]), sys.argv[2]
lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
sensor = Sensor("bench", "snapscan", 5.5 * 2048 / n, np.linspace(470, 900, 150), 10.0, 1.7)
data = np.random.default_rng(0).random((n, n, 150), dtype=np.float32)
cube = make_cube(data, sensor.cwl_nm)
small = make_cube(np.ascontiguousarray(data[:4, :4]), sensor.cwl_nm)  # as laid out
correct_cube(small, sensor, 1.4, lens, resample=True, harmonise=True)  # compile, untimed
out = {"cube_bytes": data.nbytes}
copies = []
for _ in range(3):
    t = time.perf_counter(); c = data.copy(); copies.append(time.perf_counter() - t); del c
out["copy_s"] = min(copies)
out["copy_first_s"] = copies[0]  # fresh memory


def job():
    if what == "shiftmap":
        cra = cube_cra(cube, sensor, lens).cra_deg
        return relative_shift(1.7, 1.4, cra[:, :, 0], lens, model="vignetted",
                              tolerance_nm=0.01, cwl_max_nm=900.0)
    if what == "resample":  # the Numba pass alone
        from snapcorr.correct.resample import resample_to_nominal
        cra = cube_cra(cube, sensor, lens).cra_deg
        scale = 1.0 + relative_shift(1.7, 1.4, cra, lens, model="vignetted",
                                     tolerance_nm=0.01, cwl_max_nm=900.0)
        t = time.perf_counter()
        r = resample_to_nominal(data, scale, np.zeros(150, int), np.asarray(sensor.cwl_nm))
        return r, time.perf_counter() - t
    if what.startswith("correct_resample"):
        ds = correct_cube(cube, sensor, 1.4, lens, resample=True)
        # what the correction computes: the resampled cube and the per-pixel scale behind the
        # corrected wavelengths (a lazy coordinate, expanded only where it is read)
        read = ["wavelength_scale", "resampled"]
        if what == "correct_resample_widths":
            read.append("fwhm_corrected")  # the FWHM table and every pixel's widths
        return ds, [np.asarray(ds[v].values) for v in read]
    if what == "harmonise":
        ds = correct_cube(cube, sensor, 1.4, lens, harmonise=True)
        # the whole job: CRA, shift and FWHM tables, weights, pass
        return ds, ds["harmonised"].values
    raise ValueError(what)


runs = []
for _ in range(2):  # each result let go before the next run: one at a time in memory
    t = time.perf_counter(); r = job(); runs.append(time.perf_counter() - t)
    if what == "resample":
        runs[-1] = r[1]
        out["nan_fraction"] = float(np.isnan(r[0][::64, ::64]).mean())
    elif what == "harmonise":
        out["nan_fraction"] = float(np.isnan(r[1][::64, ::64]).mean())
        out["fwhm_nodes"] = int(r[0].sizes["fwhm_cra"])
    del r
out["seconds"] = min(runs)
out["peak_rss"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps(out))
"""

CASES = ("shiftmap", "resample", "correct_resample", "correct_resample_widths", "harmonise")


def _child(n, what):
    res = subprocess.run([sys.executable, "-c", _CHILD, str(n), what], capture_output=True,
                         text=True, check=True, timeout=1800)
    out = json.loads(res.stdout.strip().splitlines()[-1])
    out["ratio"] = out["seconds"] / out["copy_s"]
    return out


def run(*, quick=False, echo=print):
    """Measure; return a dict of the figures."""
    n = 512 if quick else 2048
    r = {what: _child(n, what) for what in CASES}
    shift, res, cor, wid, har = (r[w] for w in CASES)
    gb = res["cube_bytes"] / 2**30
    copy_s = sorted(v["copy_s"] for v in r.values())[len(r) // 2]
    echo(f"cube correction, {n} x {n} x 150 float32 ({gb:.2f} GiB), f/1.4, paper's lens; "
         "each case against a warm numpy copy in its own process:")
    echo(f"  numpy copy of the cube:        {copy_s:.2f} s (median over the cases' processes)")
    echo(f"  shift map (CRA + table):       {shift['seconds']:.2f} s")
    echo(f"  resampling onto nominal grid:  {res['seconds']:.2f} s = {res['ratio']:.2f} x the "
         f"copy (target 1.5 x); peak memory {res['peak_rss'] / res['cube_bytes']:.2f} x the "
         "cube (target 2.2 x)")
    echo(f"  correct_cube(resample=True):   {cor['seconds']:.2f} s = {cor['ratio']:.2f} x the "
         f"copy (target 2.5 x); reading every pixel's widths too {wid['seconds']:.2f} s = "
         f"{wid['ratio']:.2f} x; peak memory {cor['peak_rss'] / cor['cube_bytes']:.2f} x")
    echo(f"  correct_cube(harmonise=True):  {har['seconds']:.2f} s = {har['ratio']:.2f} x the "
         f"copy (target 3 x), all of it (CRA, shift and FWHM tables ({har['fwhm_nodes']} "
         f"angles), weights, one pass); peak memory "
         f"{har['peak_rss'] / har['cube_bytes']:.2f} x the cube (target 2.5 x)")
    return {"n": n, "copy_s": copy_s, "shift_map_s": shift["seconds"],
            "resample_s": res["seconds"], "resample_ratio": res["ratio"],
            "peak_ratio": res["peak_rss"] / res["cube_bytes"],
            "correct_resample_s": cor["seconds"], "correct_resample_ratio": cor["ratio"],
            "correct_resample_widths_s": wid["seconds"],
            "correct_resample_widths_ratio": wid["ratio"],
            "harmonise_s": har["seconds"], "harmonise_ratio": har["ratio"],
            "harmonise_peak_ratio": har["peak_rss"] / har["cube_bytes"],
            "cases": r}


if __name__ == "__main__":  # pragma: no cover
    t0 = time.perf_counter()
    r = run(quick="--quick" in sys.argv)
    if "--json" in sys.argv:
        print(json.dumps(r))
    print(f"({time.perf_counter() - t0:.0f} s)")
