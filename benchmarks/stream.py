"""A stream of raw mosaic frames, zarr to zarr, against a warm copy of one output frame.

``snapcorr stream FRAMES.zarr --dark D --white W --sensor S4.toml --demosaic ri --lens
edmund_optics_16mm --f-number 2 --virtual-bands angle-aware --dtype uint16 --out OUT.zarr``:
each frame flat-fielded pixel by pixel, demosaicked by residual interpolation, given its
per-pixel corrected wavelengths (the geometry once for the stream) and its angle-aware virtual
bands, stored uint16-packed. ``S4.toml`` is the bundled 4x4 sensor's tile with measured
responses (the vendor calibration file ``tests/oracles/vendorfiles.py`` writes from the real 4x4 VIS
responses: the angle-aware bands need them; ``mosaic_4x4_vis`` itself has none). The frames:
a scene of ``tests/oracles/msfasim.py`` through those responses, moving a few pixels from frame to
frame, with noise; 2048 x 1088 uint16 (ten distinct frames, repeated in longer streams).

Each run is a fresh process that first streams a tiny film with the same options (imports,
compiled kernels, dask's threads), then times the stream with :func:`benchmarks.cpu_seconds`
around it: wall time, its own CPU seconds and the share of the machine other processes used
(:func:`benchmarks.others_share`), and its resident-set peak (``VmHWM``). Runs of ``m`` = 2,
10 and 100 frames; the time per frame is ``(t(n) - t(m)) / (n - m)``, so the start-up (reading
the references, the geometry and the virtual bands' table on the first frame, opening the
store) cancels. The reference, in the same processes: a warm numpy copy of one float32 output
frame (rows x cols x 16; the least of five).

Where the time goes: in one more process, one warm frame through each stage as the stream runs
it (the least of three each): read a frame from the zarr store, flat-field, RI demosaicking
(the kernel a block runs), the correction (nothing per frame: its geometry is computed once),
the angle-aware virtual bands, the uint16 packing (the clip and the one-pass CF codes of the
reflectance and the virtual bands, as the store writes them), Blosc LZ4 bit-shuffle
compression of the four stored arrays (reflectance, virtual bands, mask, raw copy; as the
store's codec) and writing the compressed bytes.

Targets: time per frame at most 10 x the warm copy; peak memory the same (within 10 %) for 10
and 100 frames. Quick mode: 256 x 512 frames, streams of 2, 3 and 6 (a smoke run; its figures
mean nothing). Writes ``stream.csv`` next to this file unless ``write=False``.
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

from . import cpu_seconds, others_share, write_csv
from .io_memory import _peak

HERE = Path(__file__).parent
SENSOR = "mosaic_4x4_vis"
LENS = "edmund_optics_16mm"
LEVEL_DARK, LEVEL_WHITE = 64.0, 3500.0
BANDS = 16
STAGES = ("read", "flatfield", "demosaic", "correct", "virtual", "pack", "compress", "write")


def _scene(shape, seed=0):
    """Ground-truth band values (rows, cols, 16) of a msfasim scene, larger than the frame by a
    margin the frames move across."""
    sys.path.insert(0, str(HERE.parent / "tests"))
    sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))
    import msfasim as ms
    from vendorfiles import imec_4x4

    fx = imec_4x4()
    responses = fx.curves * np.interp(ms.GRID, fx.components[0][1], fx.components[0][2])
    spectra = ms.colour_spectra()
    rng = np.random.default_rng(seed)
    chosen = spectra[rng.choice(len(spectra), 10, replace=False)]
    return ms.scene_bands(shape, chosen, responses, seed).astype(np.float32)


def write_stream(path, n_frames, shape, seed=0, distinct=None):
    """``n_frames`` raw uint16 frames (frame, y, x) in a plain zarr array, and the dark and
    white ``.npy`` next to it; written a frame at a time. With ``distinct``, frame ``i`` is a
    copy of frame ``i % distinct``."""
    import zarr

    sys.path.insert(0, str(HERE.parent / "tests"))

    sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))
    import msfasim as ms

    rng = np.random.default_rng(seed)
    margin = 16
    truth = _scene((shape[0] + 2 * margin, shape[1] + 2 * margin), seed)
    band_at = np.arange(16).reshape(4, 4)
    arr = zarr.create_array(str(path), shape=(n_frames, *shape), chunks=(1, *shape),
                            dtype=np.uint16)
    for i in range(n_frames):
        if distinct and i >= distinct:
            arr[i] = arr[i % distinct]
            continue
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




def write_sensor(folder):
    """The 4x4 tile with measured responses: a vendor calibration file and its ``.toml``."""
    sys.path.insert(0, str(HERE.parent / "tests"))
    sys.path.insert(0, str(HERE.parent / "tests" / "oracles"))
    from vendorfiles import imec_4x4, write_newer

    write_newer(folder / "s4.xml", imec_4x4())
    path = folder / "s4.toml"
    path.write_text('[sensor]\nvendor_file = "s4.xml"\nname = "mosaic-4x4-vis, measured"\n'
                    "n_eff = 1.7\npixel_pitch_um = 5.5\nbit_depth = 12\n")
    return path


def _stream_args(folder, frames, out, sensor, origin):
    args = ["stream", str(frames), "--dark", str(folder / "dark.npy"), "--white",
            str(folder / "white.npy"), "--sensor", str(sensor), "--demosaic", "ri", "--lens",
            LENS, "--f-number", "2", "--virtual-bands", "angle-aware", "--dtype", "uint16",
            "--quiet", "--out", str(out)]
    return args + (["--sensor-origin-px", f"{origin[0]},{origin[1]}"] if origin else [])


def _timed(f, reps):
    """(least wall seconds, CPU seconds of that run, last result) of ``reps`` calls."""
    best = None
    for _ in range(reps):
        c, t = time.process_time(), time.perf_counter()
        r = f()
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        if best is None or wall < best[0]:
            best = (wall, cpu)
    return (*best, r)


def _copy_seconds(rows, cols):
    """A warm numpy copy of one float32 output frame (rows, cols, 16): the least of five."""
    src = np.random.default_rng(0).random((rows, cols, BANDS), dtype=np.float32)
    dst = np.empty_like(src)
    return _timed(lambda: np.copyto(dst, src), 5)[0]


def _stages(spec):
    """Seconds (wall, CPU) of each stage on one warm frame, as the stream runs it."""
    import numcodecs
    import xarray as xr

    from snapcorr import data
    from snapcorr.correct import correct_cube
    from snapcorr.correct.virtual import apply_virtual
    from snapcorr.cube import Sensor, demosaic, flatfield, read_frames
    from snapcorr.cube.demosaicking import demosaic_array
    from snapcorr.files._packing import pack_uint16
    from snapcorr.optics import Lens

    folder, origin = Path(spec["folder"]), spec.get("origin")
    sensor = Sensor.load(spec["sensor"])
    frames = read_frames(spec["frames"])
    dark = xr.DataArray(np.load(folder / "dark.npy"), dims=("y", "x"))
    white = xr.DataArray(np.load(folder / "white.npy"), dims=("y", "x"))
    out, keep = {}, {}

    def stage(name, f, reps=3):
        out[name] = _timed(f, reps)[:2]
        return _timed(f, 1)[2] if name not in keep else keep[name]

    raw = stage("read", lambda: frames.data[1].compute())
    ff = stage("flatfield", lambda: flatfield(xr.DataArray(raw, dims=("y", "x")), dark, white,
                                              saturation=4095))
    first = demosaic(ff, sensor, "ri", sensor_origin_px=origin)  # the cube, area, phases
    r0, c0, rows, cols = first.attrs["mosaic_area_px"]
    o0 = origin or (0, 0)
    plane = np.ascontiguousarray(ff["reflectance"].values[r0 - o0[0]:r0 - o0[0] + rows,
                                                          c0 - o0[1]:c0 - o0[1] + cols])
    phase = sensor.band_offsets_at((r0, c0))
    n, m = sensor.mosaic_shape
    values = stage("demosaic", lambda: demosaic_array(plane, phase[:, 0] % n, phase[:, 1] % m,
                                                       n, m, "ri"))
    cube = first["reflectance"].copy(data=values)
    lens = Lens.load(data.lens_path(LENS))
    geometry = correct_cube(cube, sensor, 2.0, lens, virtual_bands="angle-aware")
    out["correct"] = (0.0, 0.0)  # per frame nothing: the corrected wavelengths are geometry
    cra = np.asarray(geometry["cra_deg"].transpose("y", "x", ...).values)
    cra = cra.mean(axis=2) if cra.ndim == 3 else cra
    virtual = stage("virtual", lambda: apply_virtual(cube, geometry, cra).values)
    scale, offset = np.float32(4.0 / 65534), np.float32(-0.5)

    def pack():  # as the store does it: the clip stored_as gives, then the one-pass codes
        return [pack_uint16(np.clip(v, -0.5, 3.5), offset, scale, 65534, 65535)
                for v in (values, virtual)]

    packed = stage("pack", pack)
    arrays = [*packed, np.isnan(values), raw[r0 - o0[0]:r0 - o0[0] + rows,
                                             c0 - o0[1]:c0 - o0[1] + cols]]
    codec = numcodecs.Blosc(cname="lz4", clevel=9, shuffle=numcodecs.Blosc.BITSHUFFLE)
    blobs = stage("compress", lambda: [codec.encode(np.ascontiguousarray(a)) for a in arrays])

    def write():
        for i, b in enumerate(blobs):
            with open(folder / f"stage_{i}.bin", "wb") as fh:
                fh.write(b)

    stage("write", write)
    out["stored_bytes"] = sum(len(b) for b in blobs)
    return out


def _child():
    """A measuring process: one JSON argument; prints one JSON line."""
    spec = json.loads(sys.argv[1])
    folder = Path(spec["folder"])
    origin = spec.get("origin")
    from snapcorr.cli import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        wf = Path(spec["warm_frames"])
        warm = _stream_args(wf.parent, wf, folder / "warm.zarr", spec["sensor"], [400, 800])
        if main(warm):
            raise RuntimeError("warm-up failed: snapcorr " + " ".join(warm))
    shutil.rmtree(folder / "warm.zarr", ignore_errors=True)
    if spec["mode"] == "stages":
        print(json.dumps(_stages(spec)))
        return
    out = {"copy_s": _copy_seconds(*spec["out_shape"])}
    os.sync()
    start = cpu_seconds()
    with contextlib.redirect_stdout(io.StringIO()):
        out["rc"] = main(_stream_args(folder, spec["frames"], spec["out"], spec["sensor"],
                                      origin))
    end = cpu_seconds()
    out["others_share"] = others_share(start)
    if start is None:
        out["seconds"], out["cpu_s"] = float("nan"), float("nan")
    else:
        out["seconds"], out["cpu_s"] = end[2] - start[2], end[1] - start[1]
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
        return {"rc": res.returncode, "seconds": float("nan"), "cpu_s": float("nan"),
                "peak_bytes": float("nan"), "copy_s": float("nan"),
                "others_share": float("nan"), "error": tail[0]}


def _copy_frames(src, n, dst):
    """The first ``n`` frames of the zarr stream ``src`` as a stream of their own."""
    import zarr

    a = zarr.open_array(str(src), mode="r")
    b = zarr.create_array(str(dst), shape=(n, *a.shape[1:]), chunks=(1, *a.shape[1:]),
                          dtype=a.dtype)
    for i in range(n):
        b[i] = a[i]
    return dst


def _row(n, r, base, shape, cores):
    """One CSV row: the stream of ``n`` frames against the start-up run ``base``."""
    per = (r["seconds"] - base["seconds"]) / (n - base["frames"])
    cpu = (r["cpu_s"] - base["cpu_s"]) / (n - base["frames"])
    return {"frames": n, "less_frames": base["frames"], "rows": shape[0], "cols": shape[1],
            "seconds": round(r["seconds"], 3), "seconds_per_frame": round(per, 4),
            "cpu_s_per_frame": round(cpu, 4), "copy_s": round(r["copy_s"], 5),
            "x_copy": round(per / r["copy_s"], 1),
            "cores_used": round(cpu / per / cores, 3) if per > 0 else float("nan"),
            "others_share": round(r["others_share"], 3),
            "peak_mib": round(r["peak_bytes"] / 2**20, 1), "rc": r.get("rc"),
            "error": r.get("error", "")}


def _echo_stages(echo, st, per):
    total = sum(st[k][0] for k in STAGES)
    echo(f"  stages of one warm frame (wall s, CPU s; {os.cpu_count()} cores): "
         + ", ".join(f"{k} {st[k][0]:.3f} ({st[k][1]:.3f})" for k in STAGES)
         + f"; sum {total:.3f} s against {per:.3f} s per frame in the stream")


def run(*, quick=False, echo=print, write=True, workdir=None):
    """Rows of (frames, seconds per frame, ratio to the warm copy, cores' share, peak MiB)."""
    shape = (256, 512) if quick else (1088, 2048)
    origin = [400, 800] if quick else None
    base_n, lengths = (2, (3, 6)) if quick else (2, (10, 100))
    cores = os.cpu_count() or 1
    rows = []
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        folder = Path(tmp)
        (folder / "warm").mkdir()
        sensor = write_sensor(folder)
        write_stream(folder / "warm" / "frames.zarr", 2, (64, 96), seed=1)
        longest = write_stream(folder / f"frames_{lengths[-1]}.zarr", lengths[-1], shape,
                               distinct=10)
        common = {"folder": tmp, "sensor": str(sensor), "origin": origin,
                  "warm_frames": str(folder / "warm" / "frames.zarr"),
                  "out_shape": [shape[0], shape[1]]}
        runs = {}
        for n in (base_n, *lengths):
            frames = folder / f"frames_{n}.zarr"
            if not frames.exists():
                _copy_frames(longest, n, frames)
            r = _measure({**common, "mode": "stream", "frames": str(frames),
                          "out": str(folder / f"out_{n}.zarr")})
            shutil.rmtree(folder / f"out_{n}.zarr", ignore_errors=True)
            runs[n] = {**r, "frames": n}
        st = _measure({**common, "mode": "stages", "frames": str(longest)})
    base = runs[base_n]
    echo(f"stream, {shape[0]} x {shape[1]} raw frames, 4x4 sensor, ri, corrected at f/2, "
         "angle-aware virtual bands, uint16, zarr to zarr:")
    for n in lengths:
        row = _row(n, runs[n], base, shape, cores)
        rows.append(row)
        echo(f"  {n:4d} frames less {base_n}: {row['seconds_per_frame']:.3f} s/frame "
             f"({row['cpu_s_per_frame']:.3f} CPU s), {row['x_copy']:.1f} x the warm copy of "
             f"one output frame ({row['copy_s']:.4f} s; target <= 10); the run used "
             f"{100 * row['cores_used']:.0f} % of the {cores} cores, others "
             f"{100 * row['others_share']:.0f} %; peak {row['peak_mib']:.0f} MiB"
             + (f"  FAILED: {row['error']}" if row["rc"] else ""))
    start_up = base["seconds"] - base_n * rows[0]["seconds_per_frame"]
    echo(f"  start-up (imports excluded: reading the references, the geometry and the "
         f"virtual bands' table on the first frame): {start_up:.1f} s")
    if "error" in st:
        echo(f"  stages FAILED: {st['error']}")
    else:
        _echo_stages(echo, st, rows[0]["seconds_per_frame"])
        for row in rows:
            row.update({f"{k}_s": round(st[k][0], 4) for k in STAGES})
            row.update({f"{k}_cpu_s": round(st[k][1], 4) for k in STAGES})
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
