"""Cube correction against cube size, in dask blocks, and on a dask.distributed cluster.

The correction is ``correct_cube(..., resample=True)`` (the shift map, the corrected
wavelengths and the spectra resampled onto the nominal grid) for the paper's lens at f/1.4 and
a Snapscan-like sensor of 150 evenly spaced bands, 470-900 nm, on n x n x 150 float32 cubes of
uniform random values. The pixel pitch scales with 1/n, so every size spans the angles of a
2048 x 2048 sensor of 5.5 um pixels. Three measurements:

1. **Size.** n = 256, 512, 1024 and 2048 (64 and 128 in quick mode), each in a fresh process:
   the in-memory correction, the Numba resampling pass alone (as ``benchmarks/correct.py``
   times it) and a plain ``numpy`` copy of the cube. Times are given as ratios to the copy at
   the same size and in seconds per GiB. The log-log slope of time against bytes is fitted
   (1 means linear). Peak memory is the process's resident-set peak (``ru_maxrss``), minus the
   resident set just before the cube is made, over the cube's bytes; it includes the input.
2. **Dask blocks.** The same correction on a dask-backed cube in blocks of whole rows of
   about ``snapcorr.files.api.BLOCK_BYTES``, as ``snapcorr correct`` streams it. It is run twice:
   from a numpy cube in memory, computing the corrected wavelengths and the resampled cube, and
   from a zarr file to a zarr file with snapcorr's own reader and writer (the larger-than-memory
   case: the input, the corrected wavelengths, the chief-ray angles and the resampled cube are
   written, as ``snapcorr correct --resample`` does). n = 1024 and 2048 (128 in quick mode),
   against the in-memory run.
3. **Cluster.** A batch of 4 cubes of 512 x 512 x 150 (2 of 64 x 64 x 150 in quick mode)
   stored as zarr, each corrected zarr to zarr as in 2, cubes one after another (as a loop over
   ``snapcorr correct --scheduler``), the blocks of each on a ``distributed.LocalCluster`` of 1
   and of 2 worker processes with one thread each, and on the default threaded scheduler
   without a cluster. Not timed: starting the workers, and a first cube through each
   scheduler after every worker has imported zarr and loaded the compiled resampling pass.

Quick mode is a smoke run: its sizes are too small for the figures to mean anything. Writes
``scaling.png`` and ``scaling.csv`` next to this file unless ``write=False``.
"""

from __future__ import annotations

import importlib
import json
import logging
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from snapcorr import Lens
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, make_cube, read_cube, row_blocks, write_cube
from snapcorr.files.api import BLOCK_BYTES, write_dataset

from . import pyplot, write_csv

HERE = Path(__file__).parent
LENS = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
F_NUMBER = 1.4
N_BANDS = 150
SIZES, QUICK_SIZES = (256, 512, 1024, 2048), (64, 128)
DASK_SIZES, QUICK_DASK_SIZES = (1024, 2048), (128,)
BATCH, QUICK_BATCH = (4, 512), (2, 64)  # (cubes, n)
COLUMNS = ("part", "n", "cubes", "workers", "cube_gib", "seconds", "copy_s", "x_copy",
           "x_in_memory", "s_per_gib", "gib_per_s", "cubes_per_s", "peak_x_cube", "peak_mib",
           "slope", "speedup")


def sensor(n):
    """The Snapscan-like sensor, its pitch scaled so an n x n cube spans 2048 x 5.5 um."""
    return Sensor("bench", "snapscan", 5.5 * 2048 / n, np.linspace(470, 900, N_BANDS), 10.0, 1.7)


def block_rows(n):
    """Rows per block of an n x n x 150 float32 cube, as ``snapcorr correct`` chunks it."""
    return max(1, BLOCK_BYTES // (n * N_BANDS * 4))


def correct_file(src, dst, n):
    """``snapcorr correct SRC --resample --out DST`` at f/1.4, without the command line.

    Read lazily as stored, blocks of about ``BLOCK_BYTES`` whole rows (``row_blocks``), written by
    ``write_dataset`` (on the active dask scheduler, a cluster's when a client is open).
    """
    sens = sensor(n)
    cube = row_blocks(read_cube(src, wavelength_nm=sens.cwl_nm, chunks={}))
    ds = correct_cube(cube, sens, F_NUMBER, LENS, resample=True)
    return write_dataset(ds, dst)


def write_input(path, n, seed=0):
    """A random n x n x 150 float32 cube as zarr, in blocks (never whole in memory)."""
    import dask.array as da

    data = da.random.default_rng(seed).random((n, n, N_BANDS), dtype=np.float32,
                                               chunks=(block_rows(n), n, N_BANDS))
    return write_cube(make_cube(data, sensor(n).cwl_nm), path)


# -- one measurement per fresh process ---------------------------------------------------------


def _rss():
    """Resident set now, bytes (Linux); the peak so far elsewhere."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * resource.getpagesize()
    except OSError:
        return _peak()


def _peak():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _child():
    """Entry point of the measuring process: ``MODE N [SRC DST]``; prints one JSON line."""
    mode, n = sys.argv[1], int(sys.argv[2])
    sens = sensor(n)
    tiny = make_cube(np.random.default_rng(1).random((4, 4, N_BANDS), dtype=np.float32),
                     sens.cwl_nm)
    correct_cube(tiny, sens, F_NUMBER, LENS, resample=True)  # compile once, outside the timing
    if mode != "memory":
        import dask

        dask.compute(correct_cube(tiny.chunk({"y": 2}), sens, F_NUMBER, LENS,
                                  resample=True)["resampled"].data)
    if mode == "zarr":  # the reader and writer's imports and first calls
        with tempfile.TemporaryDirectory() as tmp:
            write_cube(tiny, Path(tmp) / "tiny.zarr")
            correct_file(Path(tmp) / "tiny.zarr", Path(tmp) / "tiny_out.zarr", n)
    out = {"cube_bytes": n * n * N_BANDS * 4}
    base = _rss()
    if mode == "memory":
        data = np.random.default_rng(0).random((n, n, N_BANDS), dtype=np.float32)
        cube = make_cube(data, sens.cwl_nm)
        # The copies first: a virtual machine's first touch of fresh memory is several times
        # slower than later ones, so both are timed on memory the process has used before.
        copies = []
        for _ in range(3):
            t = time.perf_counter()
            c = data.copy()
            copies.append(time.perf_counter() - t)
            del c
        out["copy_s"] = min(copies)
        runs = []
        for _ in range(2):
            t = time.perf_counter()
            ds = correct_cube(cube, sens, F_NUMBER, LENS, resample=True)
            # what the correction computes: the resampled cube and the per-pixel scale behind
            # the corrected wavelengths (a lazy coordinate, expanded only where it is read)
            result = [np.asarray(ds[v].values) for v in ("wavelength_scale", "resampled")]
            runs.append(time.perf_counter() - t)
            del ds, result
        out["seconds"] = min(runs)
        out["peak_bytes"] = _peak() - base
        from snapcorr.correct import cube_cra, relative_shift
        from snapcorr.correct.resample import resample_to_nominal

        cra = cube_cra(cube, sens, LENS).cra_deg
        scale = 1.0 + relative_shift(1.7, F_NUMBER, cra, LENS, model="vignetted",
                                     tolerance_nm=0.01, cwl_max_nm=900.0)
        t = time.perf_counter()
        resample_to_nominal(data, scale, np.zeros(N_BANDS, int), np.asarray(sens.cwl_nm))
        out["kernel_s"] = time.perf_counter() - t
    elif mode == "dask":
        import dask
        import dask.array as da

        data = np.random.default_rng(0).random((n, n, N_BANDS), dtype=np.float32)
        cube = make_cube(da.from_array(data, chunks=(block_rows(n), -1, -1)), sens.cwl_nm)
        t = time.perf_counter()
        ds = correct_cube(cube, sens, F_NUMBER, LENS, resample=True)
        dask.compute(ds["wavelength_corrected"].data, ds["resampled"].data)
        out["seconds"] = time.perf_counter() - t
        out["peak_bytes"] = _peak() - base
    elif mode == "zarr":
        t = time.perf_counter()
        correct_file(sys.argv[3], sys.argv[4], n)
        out["seconds"] = time.perf_counter() - t
        out["peak_bytes"] = _peak() - base
    else:
        raise ValueError(f"unknown mode {mode!r}")
    print(json.dumps(out))


def _measure(mode, n, *paths):
    res = subprocess.run(
        [sys.executable, "-c", "from benchmarks.scaling import _child; _child()", mode, str(n),
         *map(str, paths)], cwd=HERE.parent, capture_output=True, text=True, timeout=3600)
    if res.returncode:
        raise RuntimeError(f"{mode} n={n} failed:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


# -- the three measurements --------------------------------------------------------------------


def _row(part, n, **figures):
    row = dict.fromkeys(COLUMNS)
    row.update(part=part, n=n, cube_gib=n * n * N_BANDS * 4 / 2**30, **figures)
    return row


def _slope(rows):
    gib = np.log([r["cube_gib"] for r in rows])
    sec = np.log([r["seconds"] for r in rows])
    return float(np.polyfit(gib, sec, 1)[0])


def sizes(*, quick=False, echo=print):
    """In-memory correction, its Numba pass and a copy against cube size; rows."""
    repeats = 1 if quick else 2
    copy, kernel, memory = [], [], []
    for n in QUICK_SIZES if quick else SIZES:
        runs = [_measure("memory", n) for _ in range(repeats)]
        best = min(runs, key=lambda r: r["seconds"])
        gib = best["cube_bytes"] / 2**30
        copy_s = min(r["copy_s"] for r in runs)
        copy.append(_row("numpy copy", n, cubes=1, seconds=copy_s, copy_s=copy_s, x_copy=1.0,
                         s_per_gib=copy_s / gib))
        kernel.append(_row("Numba pass alone", n, cubes=1, seconds=best["kernel_s"],
                           copy_s=copy_s, x_copy=best["kernel_s"] / copy_s,
                           s_per_gib=best["kernel_s"] / gib))
        memory.append(_row("in memory", n, cubes=1, seconds=best["seconds"], copy_s=copy_s,
                           x_copy=best["seconds"] / copy_s, x_in_memory=1.0,
                           s_per_gib=best["seconds"] / gib, gib_per_s=gib / best["seconds"],
                           peak_x_cube=best["peak_bytes"] / best["cube_bytes"],
                           peak_mib=best["peak_bytes"] / 2**20))
    for rows in (copy, kernel, memory):
        s = _slope(rows)
        for r in rows:
            r["slope"] = s
    echo(f"correct_cube(..., resample=True), n x n x {N_BANDS} float32, {LENS.name} at "
         f"f/{F_NUMBER:g}, in memory; best of {repeats} fresh process(es) per size:")
    echo(f"{'n':>6} {'cube GiB':>9} {'copy s':>8} {'correct s':>10} {'x copy':>7} "
         f"{'s/GiB':>7} {'peak x cube':>12} {'Numba pass x copy':>18}")
    for c, k, m in zip(copy, kernel, memory, strict=True):
        echo(f"{m['n']:>6} {m['cube_gib']:>9.3f} {c['seconds']:>8.3f} {m['seconds']:>10.2f} "
             f"{m['x_copy']:>7.1f} {m['s_per_gib']:>7.2f} {m['peak_x_cube']:>12.2f} "
             f"{k['x_copy']:>18.2f}")
    echo(f"log-log slope of time against bytes (1 = linear): correction "
         f"{memory[0]['slope']:.2f}, Numba pass {kernel[0]['slope']:.2f}, "
         f"copy {copy[0]['slope']:.2f}")
    return copy + kernel + memory


def dask_blocks(memory_rows, *, quick=False, echo=print):
    """The correction in dask blocks, in memory and zarr to zarr, against in memory; rows."""
    by_n = {r["n"]: r for r in memory_rows if r["part"] == "in memory"}
    rows = []
    for n in QUICK_DASK_SIZES if quick else DASK_SIZES:
        ref = by_n[n]
        with tempfile.TemporaryDirectory() as tmp:
            src, dst = Path(tmp) / "cube.zarr", Path(tmp) / "corrected.zarr"
            write_input(src, n)
            runs = {"dask, in memory": _measure("dask", n),
                    "dask, zarr to zarr": _measure("zarr", n, src, dst)}
        for part, r in runs.items():
            gib = r["cube_bytes"] / 2**30
            rows.append(_row(part, n, cubes=1, seconds=r["seconds"], copy_s=ref["copy_s"],
                             x_copy=r["seconds"] / ref["copy_s"],
                             x_in_memory=r["seconds"] / ref["seconds"],
                             s_per_gib=r["seconds"] / gib, gib_per_s=gib / r["seconds"],
                             peak_x_cube=r["peak_bytes"] / r["cube_bytes"],
                             peak_mib=r["peak_bytes"] / 2**20))
    echo(f"dask blocks of {BLOCK_BYTES / 2**20:.0f} MiB (whole rows), default threaded "
         "scheduler, against the in-memory correction at the same size:")
    echo(f"{'n':>6} {'run':<20} {'s':>8} {'x in memory':>12} {'x copy':>7} {'s/GiB':>7} "
         f"{'peak x cube':>12} {'peak MiB':>9}")
    for r in [*(by_n[n] for n in sorted({r['n'] for r in rows})), *rows]:
        echo(f"{r['n']:>6} {r['part']:<20} {r['seconds']:>8.2f} {r['x_in_memory']:>12.2f} "
             f"{r['x_copy']:>7.1f} {r['s_per_gib']:>7.2f} {r['peak_x_cube']:>12.3f} "
             f"{r['peak_mib']:>9.0f}")
    return rows


def cluster(*, quick=False, echo=print):
    """A batch of zarr cubes corrected on LocalClusters of 1 and 2 workers; rows."""
    from distributed import Client, LocalCluster

    from snapcorr.correct.resample import resample_to_nominal

    n_cubes, n = QUICK_BATCH if quick else BATCH
    gib = n * n * N_BANDS * 4 / 2**30
    tiny = (np.ones((2, 2, N_BANDS), np.float32), np.full((2, 2, 1), 0.99),
            np.zeros(N_BANDS, int), np.asarray(sensor(n).cwl_nm))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        srcs = [write_input(Path(tmp) / f"cube{i}.zarr", n, seed=i) for i in range(n_cubes)]

        def batch(tag):
            correct_file(srcs[0], Path(tmp) / f"warm_{tag}.zarr", n)  # first calls, untimed
            t = time.perf_counter()
            for i, src in enumerate(srcs):
                correct_file(src, Path(tmp) / f"out_{tag}_{i}.zarr", n)
            return time.perf_counter() - t

        for workers in (0, 1, 2):
            if workers == 0:
                seconds = batch("threads")
            else:
                # no fixed port anywhere (the scheduler's HTTP server would take 8787): two
                # runs on one machine must not collide
                with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                  dashboard_address=None, silence_logs=logging.ERROR,
                                  scheduler_kwargs={"dashboard_address": "127.0.0.1:0"}) as lc, \
                        Client(lc) as client:
                    client.run(importlib.import_module, "zarr")
                    client.run(resample_to_nominal, *tiny)  # every worker loads the pass
                    seconds = batch(f"w{workers}")
            rows.append(_row("cluster" if workers else "threads, no cluster", n,
                             cubes=n_cubes, workers=workers, seconds=seconds,
                             s_per_gib=seconds / (n_cubes * gib),
                             gib_per_s=n_cubes * gib / seconds,
                             cubes_per_s=n_cubes / seconds))
    one = next(r for r in rows if r["workers"] == 1)
    for r in rows:
        r["speedup"] = one["seconds"] / r["seconds"]
    echo(f"batch of {n_cubes} cubes of {n} x {n} x {N_BANDS} float32 ({gib:.3f} GiB each), each "
         f"zarr to zarr in blocks of {block_rows(n)} rows, cubes in turn:")
    echo(f"{'scheduler':<38} {'s':>7} {'cubes/s':>8} {'GiB/s':>7} {'x 1 worker':>11}")
    for r in rows:
        label = ("default threads, no cluster" if not r["workers"] else
                 f"LocalCluster, {r['workers']} worker{'s' if r['workers'] > 1 else ''} "
                 "x 1 thread")
        echo(f"{label:<38} {r['seconds']:>7.2f} {r['cubes_per_s']:>8.2f} "
             f"{r['gib_per_s']:>7.3f} {r['speedup']:>11.2f}")
    return rows


def run(*, quick=False, echo=print, write=True):
    """Measure all three; return the rows (dicts with ``COLUMNS``)."""
    rows = sizes(quick=quick, echo=echo)
    echo("")
    rows += dask_blocks(rows, quick=quick, echo=echo)
    echo("")
    rows += cluster(quick=quick, echo=echo)
    if write:
        write_files(rows)
    return rows


def write_files(rows, folder=HERE):
    """``scaling.csv`` and ``scaling.png`` of the rows in ``folder``."""
    folder = Path(folder)
    plt = pyplot()
    write_csv(folder / "scaling.csv", rows)
    fig, axes = plt.subplots(2, 2, figsize=(12, 9), constrained_layout=True)
    styles = {"numpy copy": ("k", "s--"), "Numba pass alone": ("C2", "^--"),
              "in memory": ("C0", "o-"), "dask, in memory": ("C1", "D"),
              "dask, zarr to zarr": ("C3", "v")}

    def series(part):
        return sorted((r for r in rows if r["part"] == part), key=lambda r: r["cube_gib"])

    ax = axes[0, 0]
    for part, (color, style) in styles.items():
        pts = series(part)
        label = part + (f" (slope {pts[0]['slope']:.2f})" if pts[0]["slope"] else "")
        ax.loglog([r["cube_gib"] for r in pts], [r["seconds"] for r in pts], style,
                  color=color, label=label, ms=6)
    for r in series("in memory"):
        ax.annotate(f"{r['n']}²", (r["cube_gib"], r["seconds"]), textcoords="offset points",
                    xytext=(4, -12), fontsize=8)
    ax.set(xlabel="cube size, GiB (n x n x 150 float32)", ylabel="seconds",
           title="time against cube size (log-log; slope 1 = linear)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)

    ax = axes[0, 1]
    for part, (color, style) in styles.items():
        if part == "numpy copy":
            continue
        pts = series(part)
        ax.semilogx([r["cube_gib"] for r in pts], [r["x_copy"] for r in pts], style,
                    color=color, label=part, ms=6)
    ax.axhline(1, color="k", lw=0.8, ls="--")
    ax.set_yscale("log")
    ax.set(xlabel="cube size, GiB", ylabel="time / numpy copy of the cube",
           title="time as a multiple of copying the cube")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)

    ax = axes[1, 0]
    for part in ("in memory", "dask, in memory", "dask, zarr to zarr"):
        color, style = styles[part]
        pts = series(part)
        ax.semilogx([r["cube_gib"] for r in pts], [r["peak_x_cube"] for r in pts], style,
                    color=color, label=part, ms=6)
    for r in series("dask, zarr to zarr"):
        ax.annotate(f"{r['peak_mib']:.0f} MiB", (r["cube_gib"], r["peak_x_cube"]),
                    textcoords="offset points", xytext=(6, 4), fontsize=8)
    ax.set(xlabel="cube size, GiB", ylabel="peak resident memory / cube bytes",
           title="peak memory, input cube included")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)

    ax = axes[1, 1]
    batch = [r for r in rows if r["workers"] is not None]
    labels = ["threads,\nno cluster" if not r["workers"] else
              f"{r['workers']} worker{'s' if r['workers'] > 1 else ''}" for r in batch]
    bars = ax.bar(labels, [r["gib_per_s"] for r in batch],
                  color=["0.6" if not r["workers"] else "C0" for r in batch])
    for b, r in zip(bars, batch, strict=True):
        ax.annotate(f"{r['cubes_per_s']:.2f} cubes/s\n{r['speedup']:.2f} x 1 worker",
                    (b.get_x() + b.get_width() / 2, b.get_height()), ha="center",
                    va="bottom", fontsize=8, textcoords="offset points", xytext=(0, 2))
    r = batch[0]
    ax.set(ylabel="GiB/s", title=f"batch of {r['cubes']} cubes {r['n']}² x 150, zarr to zarr, "
           "1 thread per worker")
    ax.set_ylim(top=max(x["gib_per_s"] for x in batch) * 1.3)
    fig.suptitle(f"cube correction (resample=True), {LENS.name} at f/{F_NUMBER:g}, "
                 f"{N_BANDS} bands")
    fig.savefig(folder / "scaling.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":  # pragma: no cover
    t0 = time.perf_counter()
    run(quick="--quick" in sys.argv, write="--quick" not in sys.argv)
    print(f"({time.perf_counter() - t0:.0f} s)")
