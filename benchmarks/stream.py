"""A stream of raw mosaic frames, zarr to zarr: time per frame and peak memory against length.

``snapcorr stream FRAMES.zarr --dark D --white W --sensor mosaic_4x4_vis --demosaic ri --lens
edmund_optics_16mm --f-number 2 --out OUT.zarr`` (each frame flat-fielded pixel by pixel,
demosaicked by residual interpolation and given its per-pixel corrected wavelengths; the
geometry once for the stream) runs in a fresh process on streams of 10 and of 100 raw
2048 x 1088 uint16 frames (a scene of ``tests/msfasim.py`` through the 4x4 sensor's measured
responses, moving a few pixels from frame to frame, with noise), after a warm-up on a tiny
stream (imports, compiled kernels, dask's threads). Reported: the wall time per frame and
the process's resident-set peak (``VmHWM``, as in :mod:`benchmarks.io_memory`).

The reference, in the same kind of process: the single-frame in-memory path -- the frame, the
dark and the white as numpy arrays, :func:`~snapcorr.cube.flatfield`,
:func:`~snapcorr.cube.demosaic` and :func:`~snapcorr.correct.correct_cube` with its corrected
wavelengths computed -- the least of three.

Targets: time per frame at most 2 x the single-frame path; peak memory the same (within 10 %)
for 10 and 100 frames. Quick mode: 256 x 512 frames, streams of 3 and 6, one run each (a
smoke run; its figures mean nothing). Writes ``stream.csv`` next to this file unless
``write=False``.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from . import write_csv
from .io_memory import _peak, _status

HERE = Path(__file__).parent
SENSOR = "mosaic_4x4_vis"
LENS = "edmund_optics_16mm"
LEVEL_DARK, LEVEL_WHITE = 64.0, 3500.0


def _scene(shape, seed=0):
    """Ground-truth band values (rows, cols, 16) of a msfasim scene, larger than the frame by a
    margin the frames move across."""
    sys.path.insert(0, str(HERE.parent / "tests"))
    import msfasim as ms
    from vendorfiles import imec_4x4

    fx = imec_4x4()
    responses = fx.curves * np.interp(ms.GRID, fx.components[0][1], fx.components[0][2])
    spectra = ms.colour_spectra()
    rng = np.random.default_rng(seed)
    chosen = spectra[rng.choice(len(spectra), 10, replace=False)]
    return ms.scene_bands(shape, chosen, responses, seed).astype(np.float32)


def write_stream(path, n_frames, shape, seed=0):
    """``n_frames`` raw uint16 frames (frame, y, x) in a plain zarr array, and the dark and
    white ``.npy`` next to it; written a frame at a time."""
    import zarr

    sys.path.insert(0, str(HERE.parent / "tests"))
    import msfasim as ms

    rng = np.random.default_rng(seed)
    margin = 16
    truth = _scene((shape[0] + 2 * margin, shape[1] + 2 * margin), seed)
    band_at = np.arange(16).reshape(4, 4)
    arr = zarr.create_array(str(path), shape=(n_frames, *shape), chunks=(1, *shape),
                            dtype=np.uint16)
    for i in range(n_frames):
        dy, dx = rng.integers(0, 2 * margin, 2)
        dy, dx = dy - dy % 4, dx - dx % 4
        refl = ms.mosaic(truth[dy:dy + shape[0], dx:dx + shape[1]], band_at)
        dn = LEVEL_DARK + refl * (LEVEL_WHITE - LEVEL_DARK) + rng.normal(0, 4, shape)
        arr[i] = np.clip(np.round(dn), 0, 4095).astype(np.uint16)
    dark = (LEVEL_DARK + rng.normal(0, 1, shape)).astype(np.float32)
    white = (LEVEL_WHITE + rng.normal(0, 8, shape)).astype(np.float32)
    np.save(Path(path).parent / "dark.npy", dark)
    np.save(Path(path).parent / "white.npy", white)
    return path


def _stream_args(folder, frames, out, origin):
    args = ["stream", str(frames), "--dark", str(folder / "dark.npy"), "--white",
            str(folder / "white.npy"), "--sensor", SENSOR, "--demosaic", "ri", "--lens", LENS,
            "--f-number", "2", "--out", str(out)]
    return args + (["--sensor-origin-px", f"{origin[0]},{origin[1]}"] if origin else [])


def _child():
    """A measuring process: one JSON argument; prints one JSON line."""
    spec = json.loads(sys.argv[1])
    folder = Path(spec["folder"])
    origin = spec.get("origin")
    out = {}
    if spec["mode"] == "single":
        import xarray as xr

        from snapcorr import data
        from snapcorr.correct import correct_cube
        from snapcorr.cube import Sensor, demosaic, flatfield, read_frames
        from snapcorr.optics import Lens

        sensor = Sensor.load(data.sensor_path(SENSOR))
        lens = Lens.load(data.lens_path(LENS))
        frame = xr.DataArray(read_frames(spec["frames"]).data[0].compute(), dims=("y", "x"))
        dark = xr.DataArray(np.load(folder / "dark.npy"), dims=("y", "x"))
        white = xr.DataArray(np.load(folder / "white.npy"), dims=("y", "x"))
        times = []
        for _ in range(4):  # the first warms up
            t = time.perf_counter()
            ds = demosaic(flatfield(frame, dark, white), sensor, "ri", origin_px=origin)
            res = correct_cube(ds["reflectance"], sensor, 2.0, lens, mask=ds["mask"])
            res["wavelength_corrected"].values  # noqa: B018 - computed, as a user would
            times.append(time.perf_counter() - t)
        out["seconds"] = min(times[1:])
        out["peak_bytes"] = _peak()
        print(json.dumps(out))
        return
    from snapcorr.cli import main

    with contextlib.redirect_stdout(io.StringIO()):
        wf = Path(spec["warm_frames"])
        warm = _stream_args(wf.parent, wf, folder / "warm.zarr", [400, 800])
        if main(warm):
            raise RuntimeError("warm-up failed: snapcorr " + " ".join(warm))
    shutil.rmtree(folder / "warm.zarr", ignore_errors=True)
    out["base_bytes"] = _status("VmRSS") or _peak()
    os.sync()
    t = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        out["rc"] = main(_stream_args(folder, spec["frames"], spec["out"], origin))
    out["seconds"] = time.perf_counter() - t
    out["peak_bytes"] = _peak()
    print(json.dumps(out))


def _measure(spec):
    res = subprocess.run(
        [sys.executable, "-c", "from benchmarks.stream import _child; _child()",
         json.dumps(spec)], cwd=HERE.parent, capture_output=True, text=True, timeout=7200)
    try:
        return json.loads(res.stdout.strip().splitlines()[-1])
    except (IndexError, ValueError):
        tail = res.stderr.strip().splitlines()[-1:] or ["no output"]
        return {"rc": res.returncode, "seconds": float("nan"), "peak_bytes": float("nan"),
                "error": tail[0]}


def run(*, quick=False, echo=print, write=True, workdir=None):
    """Rows of (frames, seconds per frame, ratio to the single frame, peak MiB)."""
    shape = (256, 512) if quick else (1088, 2048)
    origin = [400, 800] if quick else None
    lengths = (3, 6) if quick else (10, 100)
    rows = []
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        folder = Path(tmp)
        (folder / "warm").mkdir()
        write_stream(folder / "warm" / "frames.zarr", 2, (64, 96), seed=1)
        single_frames = write_stream(folder / f"frames_{lengths[0]}.zarr", lengths[0], shape)
        single = _measure({"mode": "single", "folder": tmp, "frames": str(single_frames),
                           "origin": origin})
        echo(f"stream, {shape[0]} x {shape[1]} raw frames, {SENSOR}, ri, corrected at f/2:")
        echo(f"  single frame in memory: {single['seconds']:.2f} s, peak "
             f"{single['peak_bytes'] / 2**20:.0f} MiB")
        for n in lengths:
            frames = folder / f"frames_{n}.zarr"
            if not frames.exists():
                write_stream(frames, n, shape)
            spec = {"mode": "stream", "folder": tmp, "frames": str(frames),
                    "warm_frames": str(folder / "warm" / "frames.zarr"),
                    "out": str(folder / f"out_{n}.zarr"), "origin": origin}
            r = _measure(spec)
            shutil.rmtree(folder / f"out_{n}.zarr", ignore_errors=True)
            per = r["seconds"] / n
            rows.append({"frames": n, "rows": shape[0], "cols": shape[1],
                         "seconds": round(r["seconds"], 3), "seconds_per_frame": round(per, 3),
                         "single_frame_s": round(single["seconds"], 3),
                         "x_single_frame": round(per / single["seconds"], 2),
                         "peak_mib": round(r["peak_bytes"] / 2**20, 1),
                         "rc": r.get("rc"), "error": r.get("error", "")})
            echo(f"  {n:4d} frames: {per:.2f} s/frame ({per / single['seconds']:.2f} x the "
                 f"single frame; target <= 2), peak {r['peak_bytes'] / 2**20:.0f} MiB"
                 + (f"  FAILED: {r.get('error')}" if r.get("rc") else ""))
    if len(rows) == 2:
        growth = rows[1]["peak_mib"] / rows[0]["peak_mib"]
        echo(f"  peak memory, {lengths[1]} over {lengths[0]} frames: {growth:.2f} (target: "
             f"within 10 %{', met' if abs(growth - 1) <= 0.10 else ', NOT met'})")
    if write:
        write_csv(HERE / "stream.csv", rows)
    return rows


if __name__ == "__main__":  # pragma: no cover
    import argparse

    parser = argparse.ArgumentParser(prog="python -m benchmarks.stream", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small frames: a smoke run")
    args = parser.parse_args()
    run(quick=args.quick, write=not args.quick)
