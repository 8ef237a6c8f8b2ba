"""The size of a stream's output by the type its values are stored as, and the codecs behind
the default compression.

``snapcorr stream FRAMES.zarr --dark D --white W --sensor mosaic_4x4_vis --demosaic ri --lens
edmund_optics_16mm --f-number 2 --dtype DTYPE --compression C --out OUT`` on one stream of 100
raw uint16 frames (a scene of ``tests/oracles/msfasim.py`` through the 4x4 sensor's measured
responses, moving from frame to frame, noise of 4 DN over a white 3436 DN above the dark: the stream
of :mod:`benchmarks.stream`), 256 x 512 pixels of the sensor each, in one process after a warm-up
(imports, compiled kernels). Every output holds what the command writes: the reflectance
(frame, y, x, band), its mask, the raw frames, the chief-ray angles and the compact corrected
wavelengths. Reported, for Zarr and netCDF: the bytes on disk as a ratio to the same stream
stored as uncompressed float32 (``--dtype float32 --compression none``, the same format),
measured in the same run; the writing time as a ratio to that one's; the share of the CPUs
other processes used meanwhile (Linux's ``/proc/stat``); and, for the packed types, the
largest difference between the values read back (by xarray directly) and the float32 ones,
against the ``packing_error`` the file states.

The codec table: the first 4 frames' reflectance (float32, and packed to uint16 over -0.5 to
3.5), each Blosc compressor and shuffle, and DEFLATE with a byte shuffle (netCDF's), on one
thread: the share of the bytes it keeps and its speed. Speeds are on a shared machine: the
ratios between them, not their values, are the figure.

Target: the uint16 stream at most 0.3 x the bytes of uncompressed float32. Quick mode: 6
frames of 64 x 96 (a smoke run; its figures mean nothing). Writes ``output_size.csv`` and
``output_codecs.csv`` next to this file unless ``write=False``.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np

from . import cpu_seconds, others_share, write_csv
from .stream import LENS, SENSOR, write_stream

HERE = Path(__file__).parent
ORIGIN = (400, 800)
#: (format, --dtype, --compression); the first of each format is the reference.
RUNS = [(".zarr", "float32", "none"), (".zarr", "float32", "auto"), (".zarr", "float16", "auto"),
        (".zarr", "uint16", "auto"), (".nc", "float32", "none"), (".nc", "float32", "auto"),
        (".nc", "uint16", "auto")]


def _bytes(path):
    """Bytes of a file, or of every file in a folder."""
    path = Path(path)
    if path.is_file():
        return path.stat().st_size
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def _args(folder, frames, out, dtype, compression):
    return ["stream", str(frames), "--dark", str(folder / "dark.npy"), "--white",
            str(folder / "white.npy"), "--sensor", SENSOR, "--demosaic", "ri", "--lens", LENS,
            "--f-number", "2", "--sensor-origin-px", f"{ORIGIN[0]},{ORIGIN[1]}",
            "--dtype", dtype, "--compression", compression, "--out", str(out)]


def _run(args):
    from snapcorr.cli import main

    start = cpu_seconds()
    t = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        rc = main(args)
    seconds = time.perf_counter() - t
    if rc:
        raise RuntimeError("snapcorr " + " ".join(args) + f" returned {rc}")
    return seconds, others_share(start)


def _reflectance(path):
    import xarray as xr

    engine = "zarr" if path.suffix == ".zarr" else "h5netcdf"
    with xr.open_dataset(path, engine=engine) as ds:
        var = ds["reflectance"]
        return var.values.astype(np.float64), var.attrs.get("packing_error")


def sizes(folder, frames, echo=print):
    """Rows of (format, dtype, compression, bytes, ratios, seconds, packing error)."""
    rows, ref = [], {}
    for ext, dtype, comp in RUNS:
        out = folder / f"out_{dtype}_{comp}{ext}"
        seconds, others = _run(_args(folder, frames, out, dtype, comp))
        size = _bytes(out)
        values, stated = _reflectance(out)
        if ext not in ref:
            ref[ext] = (size, seconds, values)
        size0, seconds0, values0 = ref[ext]
        err = float(np.nanmax(np.abs(values - np.clip(values0, -0.5, 3.5))))
        rows.append({"format": ext, "dtype": dtype, "compression": comp, "bytes": size,
                     "x_float32_plain": round(size / size0, 3),
                     "seconds": round(seconds, 2), "x_time": round(seconds / seconds0, 2),
                     "others_cpu_share": round(others, 2), "max_error": f"{err:.3g}",
                     "stated_error": stated if stated is not None else ""})
        echo(f"  {ext:5s} {dtype:7s} {comp:4s}: {size / 2**20:8.1f} MiB, "
             f"{size / size0:.3f} x plain float32, written in {seconds:.1f} s "
             f"({seconds / seconds0:.2f} x; others used {100 * others:.0f} % of the CPUs); "
             f"largest error {err:.3g}" + (f" (stated {stated})" if stated else ""))
        if comp != "none":  # the references stay for the others (the folder goes after)
            shutil.rmtree(out) if out.is_dir() else out.unlink()
    return rows


def _shuffled(a):
    b = np.ascontiguousarray(a).reshape(-1).view(np.uint8).reshape(-1, a.dtype.itemsize)
    return np.ascontiguousarray(b.T).tobytes()


def codecs(values, echo=print):
    """Rows of (data, codec, share of bytes kept, MB/s) on one thread."""
    from numcodecs import Blosc

    packed = np.round((np.clip(values, -0.5, 3.5) + 0.5) / (4 / 65534)).astype(np.uint16)
    Blosc.use_threads = False
    rows = []
    for label, data in (("float32", values.astype(np.float32)), ("uint16", packed)):
        tries = [(f"blosc {c} {s} {lv}",
                  Blosc(cname=c, clevel=lv, shuffle=getattr(Blosc, s.upper())).encode)
                 for c in ("lz4", "zstd") for s in ("noshuffle", "shuffle", "bitshuffle")
                 for lv in (1, 5, 9) if not (c == "zstd" and lv == 9)]
        tries += [(f"deflate shuffle {lv}", lambda x, lv=lv: zlib.compress(_shuffled(x), lv))
                  for lv in (1, 3, 6)]
        for name, encode in tries:
            best = np.inf
            for _ in range(2):
                t = time.perf_counter()
                kept = len(encode(data))
                best = min(best, time.perf_counter() - t)
            rows.append({"data": label, "codec": name, "kept": round(kept / data.nbytes, 3),
                         "kept_of_float32": round(kept / values.astype(np.float32).nbytes, 3),
                         "mb_per_s": round(data.nbytes / best / 1e6)})
            echo(f"  {label:7s} {name:22s}: keeps {kept / data.nbytes:.3f} "
                 f"({rows[-1]['kept_of_float32']:.3f} of float32), "
                 f"{rows[-1]['mb_per_s']:5d} MB/s")
    return rows


def run(*, quick=False, echo=print, write=True, workdir=None):
    shape = (64, 96) if quick else (256, 512)
    n = 6 if quick else 100
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        folder = Path(tmp)
        (folder / "warm").mkdir()
        warm = write_stream(folder / "warm" / "frames.zarr", 2, (64, 96), seed=1)
        _run(_args(folder / "warm", warm, folder / "warm" / "out.zarr", "uint16", "auto"))
        frames = write_stream(folder / "frames.zarr", n, shape)
        echo(f"output size: a stream of {n} frames of {shape[0]} x {shape[1]} px, {SENSOR}, "
             f"ri, corrected at f/2; {os.cpu_count()} cores")
        rows = sizes(folder, frames, echo)
        if write:
            write_csv(HERE / "output_size.csv", rows)
        import xarray as xr

        with xr.open_dataset(folder / "out_float32_none.zarr", engine="zarr") as ds:
            values = ds["reflectance"][:4].values
    echo("codecs on the first 4 frames' reflectance (one thread):")
    crows = codecs(values, echo)
    if write:
        write_csv(HERE / "output_codecs.csv", crows)
    return rows, crows


if __name__ == "__main__":  # pragma: no cover
    import argparse

    parser = argparse.ArgumentParser(prog="python -m benchmarks.output_size",
                                     description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small frames: a smoke run")
    args = parser.parse_args()
    run(quick=args.quick, write=not args.quick)
