"""``snapcorr flatfield`` and ``snapcorr correct`` from files: peak memory and time against size.

Each measurement runs the command line itself (``snapcorr.cli.main``) in a fresh process, on
files written beforehand, and reports the process's resident-set peak (``VmHWM``; see
``_peak`` for why not ``ru_maxrss``) and the wall time of the command. Before the timed run
the process runs the same command once on a tiny cube of the same formats (imports, the
compiled resampling pass, dask's threads), so the peak includes what Python, numpy, numba,
dask and zarr hold once loaded, as a user's process would. Written data are flushed to disk
(``os.sync``) before every measurement, so no run pays for the previous one's writes.

The inputs, simulated for a line-scan camera: a 12-bit uint16 raw cube of ny x nx x 150 bands
(a smooth scene, its white and dark levels varying across the line and with band, and noise),
and one-row dark and white strips (the camera's references, broadcast along the scan axis by
``flatfield``), each as ENVI BIL, ENVI BSQ (raw bytes and a header) and ``.npy``. The
measured commands:

1. ``snapcorr flatfield RAW --dark DARK --white WHITE --sensor S --out FF.zarr`` from each
   of the three formats (float32 result, the default);
2. ``snapcorr correct CUBE --lens edmund_optics_16mm.toml --sensor S --f-number 1.4
   --resample --out OUT.zarr`` from the flat-fielded ``FF.zarr`` (of the ``.npy`` input) and
   from a float32 ``.npy`` cube of the same reflectance.

The sensor S is Snapscan-like: 150 evenly spaced bands, 470-900 nm, ``size_px`` the cube's,
its pitch scaled so the cube's longer side spans 2048 pixels of 5.5 um.

The reference, in a fresh process of its own: numpy reading the input cube's bytes
(``np.fromfile`` of the ENVI data, ``np.load`` of a ``.npy``; for the ``.zarr`` input the
float32 ``.npy`` of the same cube) and writing as many bytes as the command's output holds
uncompressed (``tofile``), on the same disk; the best of three. Each command runs twice (once
in quick mode), each time in a fresh process: the time is the faster run's, the peak the
higher one's. Times are given as ``x_numpy_io``, the command's time over the reference's.
Peak memory is given in MiB and over the input cube's bytes as stored; the target is a peak
of at most 1.5 GB (1.5e9 bytes, 1431 MiB) whatever the cube's size.

The last size runs under an address-space limit smaller than the cube: after the warm-up,
the measuring process reads its own address space (``VmSize``, the baseline: interpreter,
libraries, thread stacks and allocator arenas) and sets ``RLIMIT_AS`` to the baseline plus
``LIMIT_HEADROOM``; a command that needed the cube in memory (or mapped) would fail there.

Quick mode is a smoke run on 64 x 64 x 16 cubes, every case once and under the limit (about
half a minute: each process imports snapcorr afresh); its figures mean nothing. Writes
``io_memory.csv`` and ``io_memory.png`` next to this file unless ``write=False``.
"""

from __future__ import annotations

import contextlib
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from . import pyplot, write_csv

HERE = Path(__file__).parent
N_BANDS, QUICK_BANDS = 150, 16
SIZES, QUICK_SIZES = ((512, 512), (1024, 1024), (2048, 1024)), ()  # (ny, nx)
LIMITED, QUICK_LIMITED = (2048, 2048), (64, 64)  # run under the address-space limit
LIMIT_HEADROOM, QUICK_LIMIT_HEADROOM = 768 * 2**20, 256 * 2**20
TARGET_BYTES = 1.5e9
F_NUMBER = 1.4
REPEATS, QUICK_REPEATS = 2, 1  # fresh processes per command and size
NUMPY_REPEATS = 3
GEN_ROWS = 64  # rows simulated at a time (the values do not depend on the files' layout)
WARM = (8, 8)  # the warm-up cube
WARM_OUT = "<warm-up output>"  # replaced in the measuring process by a path of its own
CASES = (("flatfield", "ENVI BIL"), ("flatfield", "ENVI BSQ"), ("flatfield", ".npy"),
         ("correct", ".zarr"), ("correct", ".npy"))
COLUMNS = ("command", "input", "ny", "nx", "bands", "cube_gib", "input_bytes", "output_bytes",
           "output_disk_bytes", "seconds", "numpy_io_s", "x_numpy_io", "peak_mib",
           "base_mib", "peak_x_input", "limit_mib", "baseline_vm_mib", "vm_peak_mib",
           "target_met", "status")


def lens_file():
    """The bundled Edmund Optics 16 mm profile (``calibration/lenses``)."""
    from snapcorr.data import lens_path

    return Path(lens_path("edmund_optics_16mm"))


# -- the simulated camera and its files ---------------------------------------------------------


def references(nx, nb):
    """One-row dark and white strips, uint16 ``(1, nx, nb)``: a line-scan camera's references."""
    u = np.linspace(-1.0, 1.0, nx)[:, None]
    b = np.linspace(0.0, 1.0, nb)[None, :]
    dark = 64.0 + 6.0 * np.cos(3.0 * u) + 10.0 * b
    white = dark + 3400.0 * (1.0 - 0.35 * u**2) * (0.55 + 0.45 * np.sin(np.pi * b))
    return (np.rint(dark)[None].astype(np.uint16), np.rint(white)[None].astype(np.uint16))


def raw_rows(shape, r0, r1, dark, white, seed=0):
    """Rows ``r0:r1`` (multiples of ``GEN_ROWS`` apart from the end) of the raw uint16 cube."""
    _, nx, nb = shape
    y = np.arange(r0, r1, dtype=float)[:, None, None]
    x = np.linspace(0.0, 1.0, nx)[None, :, None]
    b = np.linspace(0.0, 1.0, nb)[None, None, :]
    scene = 0.45 + 0.3 * np.sin(y / 37.0 + 6.0 * x) * np.cos(4.0 * b + x) + 0.15 * b
    noise = np.random.default_rng((seed, r0)).normal(0.0, 6.0, (r1 - r0, nx, nb))
    d, w = dark.astype(float), white.astype(float)
    return np.clip(np.rint(d + (w - d) * scene + noise), 0, 4095).astype(np.uint16)


def _blocks(shape, dark, white):
    for r0 in range(0, shape[0], GEN_ROWS):
        r1 = min(shape[0], r0 + GEN_ROWS)
        yield r0, r1, raw_rows(shape, r0, r1, dark, white)


def _npy_header(fh, shape, dtype):
    np.lib.format.write_array_header_1_0(
        fh, {"descr": np.lib.format.dtype_to_descr(np.dtype(dtype)), "fortran_order": False,
             "shape": tuple(shape)})


def _envi_header(hdr, shape, interleave, wavelengths):
    ny, nx, nb = shape
    wl = ", ".join(f"{w:.3f}" for w in wavelengths)
    hdr.write_text(f"ENVI\ndescription = {{simulated line-scan cube}}\nsamples = {nx}\n"
                   f"lines = {ny}\nbands = {nb}\nheader offset = 0\nfile type = ENVI Standard\n"
                   f"data type = 12\ninterleave = {interleave}\nbyte order = 0\n"
                   f"wavelength units = Nanometers\nwavelength = {{{wl}}}\n")


def _write_envi(stem, shape, interleave, wavelengths, blocks):
    """Raw bytes (little-endian uint16) and a header; ``blocks`` yields ``(r0, r1, rows)``."""
    ny, nx, nb = shape
    _envi_header(stem.with_suffix(".hdr"), shape, interleave, wavelengths)
    data = stem.with_suffix(".raw")
    if interleave == "bil":
        with open(data, "wb") as fh:
            for _, _, rows in blocks:
                np.ascontiguousarray(rows.transpose(0, 2, 1)).astype("<u2").tofile(fh)
    else:  # bsq: band after band, each a whole image
        out = np.memmap(data, dtype="<u2", mode="w+", shape=(nb, ny, nx))
        for r0, r1, rows in blocks:
            out[:, r0:r1, :] = rows.transpose(2, 0, 1)
        out.flush()
        del out


def sensor_for(shape, wavelengths):
    """The Snapscan-like sensor of a cube: its size, a pitch spanning 2048 x 5.5 um."""
    from snapcorr.cube import Sensor

    ny, nx, _ = shape
    return Sensor("bench-snapscan", "snapscan", 5.5 * 2048 / max(ny, nx), wavelengths, 10.0,
                  1.7, size_px=(ny, nx))


def write_inputs(folder, shape):
    """Every input of one size in ``folder``: raw, dark and white strips as ENVI BIL and BSQ
    and ``.npy``, the float32 ``.npy`` cube of their flat field and the sensor; returns
    their paths by name."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    _, nx, nb = shape
    wl = np.linspace(470.0, 900.0, nb)
    dark, white = references(nx, nb)
    paths = {"sensor": sensor_for(shape, wl).save(folder / "sensor.toml", overwrite=True)}
    for tag in ("bil", "bsq"):
        for name, strip in (("dark", dark), ("white", white)):
            _write_envi(folder / f"{name}_{tag}", (1, nx, nb), tag, wl,
                        [(0, 1, strip)])
            paths[f"{name}_{tag}"] = folder / f"{name}_{tag}.hdr"
        _write_envi(folder / f"raw_{tag}", shape, tag, wl, _blocks(shape, dark, white))
        paths[f"raw_{tag}"] = folder / f"raw_{tag}.hdr"
    for name, strip in (("dark", dark), ("white", white)):
        np.save(folder / f"{name}.npy", strip)
        paths[f"{name}_npy"] = folder / f"{name}.npy"
    d, w = dark.astype(np.float64), white.astype(np.float64)
    with open(folder / "raw.npy", "wb") as fr, open(folder / "cube_f32.npy", "wb") as fc:
        _npy_header(fr, shape, np.uint16)
        _npy_header(fc, shape, np.float32)
        for _, _, rows in _blocks(shape, dark, white):
            rows.tofile(fr)
            ((rows - d) / (w - d)).astype(np.float32).tofile(fc)
    paths["raw_npy"], paths["cube_f32"] = folder / "raw.npy", folder / "cube_f32.npy"
    return paths


def expected_flatfield(folder):
    """Eq. 29 of the ``.npy`` inputs in ``folder``, computed with numpy alone (float64)."""
    raw = np.load(Path(folder) / "raw.npy").astype(np.float64)
    dark = np.load(Path(folder) / "dark.npy").astype(np.float64)
    white = np.load(Path(folder) / "white.npy").astype(np.float64)
    return (raw - dark) / (white - dark)


def cli_args(case, paths, out):
    """The command line of a case (``CASES``) on the inputs ``paths`` (``write_inputs``)."""
    command, fmt = case
    if command == "flatfield":
        tag = {"ENVI BIL": "bil", "ENVI BSQ": "bsq", ".npy": "npy"}[fmt]
        return ["flatfield", str(paths[f"raw_{tag}"]), "--dark", str(paths[f"dark_{tag}"]),
                "--white", str(paths[f"white_{tag}"]), "--sensor", str(paths["sensor"]),
                "--out", str(out)]
    src = paths["ff_zarr"] if fmt == ".zarr" else paths["cube_f32"]
    return ["correct", str(src), "--lens", str(lens_file()), "--sensor", str(paths["sensor"]),
            "--f-number", f"{F_NUMBER:g}", "--resample", "--out", str(out)]


def _input_file(case, paths):
    """The file numpy reads for the reference, its dtype and offset (None: ``np.load``)."""
    command, fmt = case
    if command == "flatfield" and fmt.startswith("ENVI"):
        tag = fmt.split()[1].lower()
        return paths[f"raw_{tag}"].with_suffix(".raw"), "<u2"
    if command == "flatfield":
        return paths["raw_npy"], None
    return paths["cube_f32"], None


def _tree_bytes(path):
    path = Path(path)
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def zarr_bytes(path):
    """Uncompressed bytes of every array in a zarr store (what the command wrote)."""
    import zarr

    def walk(group):
        total = 0
        for _, arr in group.arrays():
            total += int(arr.nbytes)
        for _, sub in group.groups():
            total += walk(sub)
        return total

    return walk(zarr.open_group(str(path), mode="r"))


# -- one measurement per fresh process ----------------------------------------------------------


def _status(key):
    """A ``/proc/self/status`` figure in bytes (Linux), or None."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def _peak():
    """The process's resident-set peak, bytes: ``VmHWM``, else ``ru_maxrss``.

    On Linux ``ru_maxrss`` of a process started by ``subprocess`` begins at its parent's
    resident set at the fork (the kernel carries it over the exec), so a large parent would
    hide the child's own peak; ``VmHWM`` is the high-water mark of the process's own memory
    since it started.
    """
    return _status("VmHWM") or resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _child():
    """Entry point of a measuring process: one JSON argument; prints one JSON line."""
    spec = json.loads(sys.argv[1])
    out = {}
    if spec["mode"] == "numpy":
        t = time.perf_counter()
        if spec["dtype"] is None:
            data = np.load(spec["src"])
        else:
            data = np.fromfile(spec["src"], dtype=spec["dtype"])
        out["read_s"] = time.perf_counter() - t
        flat = data.reshape(-1).view(np.uint8)
        left = spec["out_bytes"]
        t = time.perf_counter()
        with open(spec["dst"], "wb") as fh:
            while left > 0:
                n = min(left, flat.size)
                flat[:n].tofile(fh)
                left -= n
        out["write_s"] = time.perf_counter() - t
        out["seconds"] = out["read_s"] + out["write_s"]
        out["peak_bytes"] = _peak()
        print(json.dumps(out))
        return
    import io

    from snapcorr.cli import main

    with contextlib.redirect_stdout(io.StringIO()):
        with tempfile.TemporaryDirectory() as tmp:  # the warm-up's output goes there
            args = [str(Path(tmp) / "warm.zarr") if a == WARM_OUT else a for a in spec["warm"]]
            if main(args):  # imports, compiled passes, dask's threads
                raise RuntimeError(f"warm-up failed: snapcorr {' '.join(args)}")
    out["base_bytes"] = _status("VmRSS") or _peak()
    out["baseline_vm_bytes"] = _status("VmSize")
    if spec.get("headroom"):
        limit = out["baseline_vm_bytes"] + spec["headroom"]
        resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
        out["limit_bytes"] = limit
    messages = io.StringIO()
    t = time.perf_counter()
    with contextlib.redirect_stdout(messages):
        try:
            rc = main(spec["args"])
        except MemoryError:
            rc = "MemoryError"
    out["seconds"] = time.perf_counter() - t
    out["rc"] = rc
    out["peak_bytes"] = _peak()
    out["vm_peak_bytes"] = _status("VmPeak")
    out["message"] = messages.getvalue().strip()[-300:]
    print(json.dumps(out))


def _measure(spec, env=None):
    os.sync()  # earlier runs' writes go to disk now, not during this run
    res = subprocess.run(
        [sys.executable, "-c", "from benchmarks.io_memory import _child; _child()",
         json.dumps(spec)], cwd=HERE.parent, capture_output=True, text=True, timeout=7200,
        env={**os.environ, **(env or {})})
    try:
        out = json.loads(res.stdout.strip().splitlines()[-1])
    except (IndexError, ValueError):
        out = {"rc": res.returncode, "seconds": float("nan"), "peak_bytes": float("nan")}
    out["stderr"] = res.stderr.strip().splitlines()[-1] if res.stderr.strip() else ""
    return out


# -- the measurements ---------------------------------------------------------------------------


def measure_size(shape, work, warm_paths, *, cases=CASES, headroom=None, repeats=1,
                 echo=print, keep=False):
    """The cases (of ``CASES``) on one size, each run ``repeats`` times; rows. Inputs and
    outputs go in ``work``."""
    ny, nx, nb = shape
    folder = Path(work) / f"{ny}x{nx}x{nb}"
    paths = write_inputs(folder, shape)
    rows = []
    for case in cases:
        command, fmt = case
        tag = fmt.strip(". ").replace(" ", "_").lower()
        out = folder / f"{command}_{tag}.zarr"
        if case == ("correct", ".zarr"):
            paths["ff_zarr"] = folder / "flatfield_npy.zarr"
            if not paths["ff_zarr"].exists():  # its flat field failed or was not measured
                from snapcorr.cli import main

                main(cli_args(("flatfield", ".npy"), paths, paths["ff_zarr"]))
        spec = {"mode": "cli", "args": cli_args(case, paths, out),
                "warm": cli_args(case, warm_paths, WARM_OUT), "headroom": headroom}
        runs = []
        for _ in range(repeats):
            shutil.rmtree(out, ignore_errors=True)
            runs.append(_measure(spec))
            if runs[-1].get("rc") != 0 or not out.exists():
                break
        ok = all(x.get("rc") == 0 for x in runs) and out.exists()
        # the fastest run's time, the highest peak of all (a failed run's figures as they are)
        r = {**runs[-1], "seconds": min(x["seconds"] for x in runs),
             "peak_bytes": max(x["peak_bytes"] for x in runs),
             "vm_peak_bytes": max(x.get("vm_peak_bytes") or 0 for x in runs) or None}
        row = dict.fromkeys(COLUMNS)
        src, dtype = _input_file(case, paths)
        in_bytes = ny * nx * nb * (2 if command == "flatfield" else 4)
        row.update(command=command, input=fmt, ny=ny, nx=nx, bands=nb,
                   cube_gib=ny * nx * nb * 4 / 2**30, input_bytes=in_bytes,
                   seconds=r["seconds"], peak_mib=r["peak_bytes"] / 2**20,
                   base_mib=r.get("base_bytes", float("nan")) / 2**20,
                   peak_x_input=r["peak_bytes"] / in_bytes,
                   limit_mib=r["limit_bytes"] / 2**20 if r.get("limit_bytes") else None,
                   baseline_vm_mib=(r["baseline_vm_bytes"] / 2**20
                                    if r.get("baseline_vm_bytes") else None),
                   vm_peak_mib=r["vm_peak_bytes"] / 2**20 if r.get("vm_peak_bytes") else None,
                   target_met=bool(ok and r["peak_bytes"] <= TARGET_BYTES),
                   status="ok" if ok else f"failed ({r.get('rc')}): "
                   f"{r.get('message') or r.get('stderr')}"[:300])
        if ok:
            row["output_bytes"] = zarr_bytes(out)
            row["output_disk_bytes"] = _tree_bytes(out)
            refs = []
            for _ in range(NUMPY_REPEATS):
                refs.append(_measure({"mode": "numpy", "src": str(src), "dtype": dtype,
                                      "out_bytes": row["output_bytes"],
                                      "dst": str(folder / "numpy.out")}))
                (folder / "numpy.out").unlink(missing_ok=True)
            ref = min(refs, key=lambda x: x["seconds"])
            row["numpy_io_s"] = ref["seconds"]
            row["x_numpy_io"] = r["seconds"] / ref["seconds"]
        rows.append(row)
        echo(_line(row))
        if not keep and command == "correct":
            shutil.rmtree(out, ignore_errors=True)
    if not keep:
        shutil.rmtree(folder, ignore_errors=True)
    return rows


def _header():
    return (f"{'command':<9} {'input':<9} {'size':>16} {'GiB f32':>7} {'s':>7} "
            f"{'numpy s':>7} {'x numpy':>7} {'peak MiB':>8} {'x input':>7} {'limit MiB':>9} "
            f"{'<=1.5 GB':>8}")


def _line(r):
    def num(v, fmt):
        return format(v, fmt) if isinstance(v, (int, float)) and v == v else "-"

    size = f"{r['ny']} x {r['nx']} x {r['bands']}"
    met = "yes" if r["target_met"] else "NO"
    line = (f"{r['command']:<9} {r['input']:<9} {size:>16} {r['cube_gib']:>7.3f} "
            f"{num(r['seconds'], '>7.2f')} {num(r['numpy_io_s'], '>7.2f')} "
            f"{num(r['x_numpy_io'], '>7.1f')} {num(r['peak_mib'], '>8.0f')} "
            f"{num(r['peak_x_input'], '>7.2f')} "
            f"{num(r['limit_mib'], '>9.0f') if r['limit_mib'] else '-':>9} {met:>8}")
    return line if r["status"] == "ok" else f"{line}  {r['status']}"


def run(*, quick=False, echo=print, write=True, workdir=None):
    """Measure every case at every size, then under the limit; return the rows.

    ``workdir``: where the inputs and outputs go and stay (default: a temporary folder,
    removed, with each size's files removed once measured).
    """
    nb = QUICK_BANDS if quick else N_BANDS
    repeats = QUICK_REPEATS if quick else REPEATS
    keep = workdir is not None
    with contextlib.ExitStack() as stack:
        work = Path(workdir) if keep else Path(stack.enter_context(tempfile.TemporaryDirectory()))
        warm_paths = write_inputs(work / "warm", (*WARM, nb))
        from snapcorr.cli import main

        warm_paths["ff_zarr"] = work / "warm" / "ff_warm.zarr"
        main(cli_args(("flatfield", ".npy"), warm_paths, warm_paths["ff_zarr"]))
        echo(f"snapcorr flatfield and correct --resample from files to .zarr, each in a fresh "
             f"process; time against numpy reading the input and writing the output's bytes; "
             f"target: peak <= {TARGET_BYTES / 1e9:g} GB ({TARGET_BYTES / 2**20:.0f} MiB)")
        echo(_header())
        rows = []
        for ny, nx in QUICK_SIZES if quick else SIZES:
            rows += measure_size((ny, nx, nb), work, warm_paths, repeats=repeats, echo=echo,
                                 keep=keep)
        headroom = QUICK_LIMIT_HEADROOM if quick else LIMIT_HEADROOM
        shape = (*(QUICK_LIMITED if quick else LIMITED), nb)
        echo(f"under an address-space limit (RLIMIT_AS) of the process's baseline after the "
             f"warm-up + {headroom / 2**20:.0f} MiB; the {shape[0]} x {shape[1]} x {nb} cube "
             f"is {shape[0] * shape[1] * nb * 2 / 2**20:.0f} MiB as uint16, "
             f"{shape[0] * shape[1] * nb * 4 / 2**20:.0f} MiB as float32:")
        rows += measure_size(shape, work, warm_paths, headroom=headroom, repeats=repeats,
                             echo=echo, keep=keep)
    missed = [r for r in rows if not r["target_met"]]
    echo(f"peak <= {TARGET_BYTES / 1e9:g} GB: met in {len(rows) - len(missed)} of {len(rows)} "
         "runs" + ("" if not missed else "; missed: " + ", ".join(
             f"{r['command']} {r['input']} {r['ny']}x{r['nx']}" for r in missed)))
    if write:
        write_files(rows)
    return rows


def write_files(rows, folder=HERE):
    """``io_memory.csv`` and ``io_memory.png`` of the rows in ``folder``."""
    folder = Path(folder)
    write_csv(folder / "io_memory.csv", rows)
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(17, 5.4), constrained_layout=True)
    styles = {("flatfield", "ENVI BIL"): ("C0", "o"), ("flatfield", "ENVI BSQ"): ("C1", "s"),
              ("flatfield", ".npy"): ("C2", "^"), ("correct", ".zarr"): ("C3", "D"),
              ("correct", ".npy"): ("C4", "v")}
    ok = [r for r in rows if r["status"] == "ok"]
    keys = ("peak_mib", "seconds", "x_numpy_io")
    for case, (color, marker) in styles.items():
        pts = sorted((r for r in ok if (r["command"], r["input"]) == case),
                     key=lambda r: r["cube_gib"])
        free = [r for r in pts if r["limit_mib"] is None]
        lim = [r for r in pts if r["limit_mib"] is not None]
        for ax, key in zip(axes, keys, strict=True):
            ax.plot([r["cube_gib"] for r in free], [r[key] for r in free], marker + "-",
                    color=color, label=f"{case[0]} from {case[1]}", ms=6)
            ax.plot([r["cube_gib"] for r in lim], [r[key] for r in lim], marker, color=color,
                    mfc="none", ms=10, mew=1.5)
        axes[1].plot([r["cube_gib"] for r in pts], [r["numpy_io_s"] for r in pts], marker + ":",
                     color=color, alpha=0.5, ms=4)
    sizes = sorted({(r["cube_gib"], r["ny"], r["nx"]) for r in rows})
    for ax in axes:
        if ok:
            ax.set_xscale("log")
        ax.set_xticks([g for g, _, _ in sizes],
                      [f"{ny} x {nx}\n{g:.2f} GiB" for g, ny, nx in sizes])
        ax.minorticks_off()
        ax.grid(True, which="both", alpha=0.3)
    ax = axes[0]
    ax.axhline(TARGET_BYTES / 2**20, color="k", ls="--", lw=1)
    ax.annotate("target 1.5 GB", (0.02, TARGET_BYTES / 2**20), xycoords=("axes fraction",
                "data"), textcoords="offset points", xytext=(0, 4), fontsize=8)
    base = [r["base_mib"] for r in ok]
    if base:
        ax.axhspan(min(base), max(base), color="0.85", zorder=0)
        ax.annotate("after the imports, before the run", (0.02, max(base)),
                    xycoords=("axes fraction", "data"), textcoords="offset points",
                    xytext=(0, 3), fontsize=8, color="0.4")
    limited = [r for r in ok if r["limit_mib"] is not None]
    if limited:
        ax.plot([], [], "o", color="0.4", mfc="none", ms=10, label="under RLIMIT_AS (baseline "
                f"+ {limited[0]['limit_mib'] - limited[0]['baseline_vm_mib']:.0f} MiB)")
    ax.set_ylim(0, TARGET_BYTES / 2**20 * 1.1)
    ax.set(xlabel="cube, ny x nx x bands (GiB as float32)", ylabel="peak resident MiB",
           title="peak memory of the process")
    ax.legend(fontsize=8, loc="center left")
    ax = axes[1]
    if ok:
        ax.set_yscale("log")
    ax.plot([], [], "k:", alpha=0.5, label="numpy: read the input, write the output's bytes")
    ax.set(xlabel="cube, ny x nx x bands (GiB as float32)", ylabel="seconds",
           title="wall time (log-log)")
    ax.legend(fontsize=8)
    ax = axes[2]
    ax.set_ylim(bottom=0)
    ax.set(xlabel="cube, ny x nx x bands (GiB as float32)",
           ylabel="time / numpy read + write", title="time as a multiple of numpy's I/O")
    fig.suptitle(f"snapcorr flatfield and correct --resample (f/{F_NUMBER:g}), files to .zarr, "
                 "each run in a fresh process; hollow markers: under an address-space limit")
    fig.savefig(folder / "io_memory.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":  # pragma: no cover
    t0 = time.perf_counter()
    run(quick="--quick" in sys.argv, write="--quick" not in sys.argv)
    print(f"({time.perf_counter() - t0:.0f} s)")
