"""How fast the command line answers: help and usage errors against importing numpy, and a
second ``flatfield --demosaic`` (compiled kernels cached on disk) against help plus the work.

**Answering at once.** ``python -m snapcorr --help``, ``snapcorr correct --help`` and a mistyped
option (``snapcorr flatfield --bogus``) in fresh processes, against ``python -c "import
numpy"``: each the least of five, the rounds interleaving the four. Target: at most 3 x numpy.

**Compiled once.** ``snapcorr flatfield RAW --dark D --white W --sensor mosaic_4x4_vis
--sensor-origin-px 400,800 --demosaic ri --out OUT.zarr`` on a 512 x 512 crop (uint16, uniform
random reflectance between a dark and a white), in fresh processes sharing a numba cache that
starts empty (``NUMBA_CACHE_DIR``): the first process compiles the kernels and writes them to
the cache, the second (and third: the least of the two) loads them. The work itself: the same
command through ``snapcorr.cli.main`` in one process, the least of two calls after a warm-up.
Target: the second process at most 3 x (help + the work).

Every process runs as an installed snapcorr would: with Python's bytecode cached (in a
temporary ``pycache_prefix``, compiled by a first run that is not timed). The share of the
CPUs other processes used during the timings (Linux's ``/proc/stat``, less this process's and
its children's time) is printed with them: on a busy machine every figure grows, the ratios
less so. Quick mode: a 128 x 128 crop, one round, one later process, and the kernels from
snapcorr's own numba cache (compiled by an earlier run, or by the first process; a smoke run:
its figures mean nothing). Writes ``startup.csv`` next to this file
unless ``write=False``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from . import cpu_seconds, others_share, write_csv

HERE = Path(__file__).parent
ROOT = HERE.parent
SENSOR = "mosaic_4x4_vis"
ORIGIN = "400,800"

#: The timed command lines after ``python``, by name.
QUICK_ONES = {
    "numpy": ["-c", "import numpy"],
    "help": ["-m", "snapcorr", "--help"],
    "command_help": ["-m", "snapcorr", "correct", "--help"],
    "usage_error": ["-m", "snapcorr", "flatfield", "--bogus"],
}


def _env(tmp, fresh_kernels=True):
    """The environment of every timed process: this snapcorr, bytecode cached in ``tmp``, and
    (``fresh_kernels``) a numba cache of its own, empty at the start."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    if fresh_kernels:
        env["NUMBA_CACHE_DIR"] = str(tmp / "numba")
    return env


def _run(args, env, cwd, tmp):
    """Seconds one ``python ARGS`` takes, and its exit status."""
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-X", f"pycache_prefix={tmp / 'pyc'}", *args],
                         env=env, cwd=cwd, capture_output=True, text=True, timeout=3600)
    return time.perf_counter() - t0, res


def _inputs(folder, shape):
    rng = np.random.default_rng(0)
    dark = rng.normal(64, 2, shape).astype(np.float32)
    white = rng.normal(3000, 40, shape).astype(np.float32)
    raw = np.round(dark + rng.uniform(0.1, 0.9, shape) * (white - dark)).astype(np.uint16)
    for name, a in (("dark", dark), ("white", white), ("raw", raw)):
        np.save(folder / f"{name}.npy", a)


FLATFIELD = ["flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
             SENSOR, "--sensor-origin-px", ORIGIN, "--demosaic", "ri", "--out", "out.zarr",
             "--overwrite", "--quiet"]

#: The work alone: the command twice in one process (imports and kernels loaded), timed.
WORK = f"""
import sys, time
from snapcorr.cli import main
argv = {FLATFIELD!r}
times = []
for _ in range(3):
    t0 = time.perf_counter()
    assert main(argv) == 0
    times.append(time.perf_counter() - t0)
print(min(times[1:]), file=sys.stderr)
"""


def run(*, quick=False, echo=print, write=True):
    """Seconds and ratios: one row per figure (name, seconds, ratio, target)."""
    rounds = 1 if quick else 5
    shape = (128, 128) if quick else (512, 512)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        env = _env(tmp, fresh_kernels=not quick)
        _inputs(tmp, shape)
        for args in QUICK_ONES.values():  # bytecode compiled and cached, not timed
            _run(args, env, tmp, tmp)
        start = cpu_seconds()
        times = {k: [] for k in QUICK_ONES}
        for _ in range(rounds):
            for name, args in QUICK_ONES.items():
                times[name].append(_run(args, env, tmp, tmp)[0])
        t = {k: min(v) for k, v in times.items()}
        others_quick = others_share(start)
        start = cpu_seconds()
        first, res = _run(["-m", "snapcorr", *FLATFIELD], env, tmp, tmp)
        if res.returncode:
            raise RuntimeError(f"flatfield --demosaic failed: {res.stderr}")
        later = [_run(["-m", "snapcorr", *FLATFIELD], env, tmp, tmp)[0]
                 for _ in range(1 if quick else 2)]
        _, res = _run(["-c", WORK], env, tmp, tmp)
        if res.returncode:
            raise RuntimeError(f"the in-process run failed: {res.stderr}")
        work = float(res.stderr.strip().splitlines()[-1])
        others_demosaic = others_share(start)
    t["first_flatfield"], t["second_flatfield"], t["work"] = first, min(later), work
    bound = t["help"] + work
    rows = [{"figure": k, "seconds": t[k], "ratio": t[k] / t["numpy"], "of": "numpy",
             "target": 3.0, "others_cpu": others_quick}
            for k in ("help", "command_help", "usage_error")]
    rows.append({"figure": "numpy", "seconds": t["numpy"], "ratio": 1.0, "of": "numpy",
                 "target": float("nan"), "others_cpu": others_quick})
    for k in ("first_flatfield", "second_flatfield", "work"):
        rows.append({"figure": k, "seconds": t[k], "ratio": t[k] / bound, "of": "help+work",
                     "target": 3.0 if k == "second_flatfield" else float("nan"),
                     "others_cpu": others_demosaic})
    echo(f"command line, {os.cpu_count()} cores (other processes used "
         f"{100 * others_quick:.0f} % of the CPUs meanwhile): python -c 'import numpy' "
         f"{t['numpy']:.3f} s; --help {t['help']:.3f} s = {t['help'] / t['numpy']:.2f} x, "
         f"correct --help {t['command_help']:.3f} s = {t['command_help'] / t['numpy']:.2f} x, "
         f"a mistyped option {t['usage_error']:.3f} s = {t['usage_error'] / t['numpy']:.2f} x "
         "(target <= 3 x)")
    echo(f"flatfield --demosaic ri of a {shape[0]} x {shape[1]} crop (other processes used "
         f"{100 * others_demosaic:.0f} % of the CPUs meanwhile): first process {first:.2f} s "
         f"(compiling), second {t['second_flatfield']:.2f} s; the work in a warm process "
         f"{work:.2f} s, + --help = {bound:.2f} s; second / (help + work) = "
         f"{t['second_flatfield'] / bound:.2f} x (target <= 3 x), first "
         f"{first / bound:.2f} x")
    if write:
        write_csv(HERE / "startup.csv", rows)
    return rows


if __name__ == "__main__":
    run()
