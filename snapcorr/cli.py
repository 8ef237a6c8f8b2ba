"""Command-line interface: a thin shell around the library.

Every expected failure becomes one line on stderr and a non-zero exit status; inputs are never
written over, outputs appear whole or not at all (also on Ctrl-C and SIGTERM).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np

from ._io import check_replaceable
from ._names import CALIBRATION_METHODS, CORRECTION_MODELS, SHIFT_METHODS
from ._validation import check_pack_range, check_positive

#: Each subcommand's examples (its --help shows its own; ``snapcorr --help`` shows all).
EXAMPLES = {
    "demo": r"""
      snapcorr demo                       the paper's lens and experiment, simulated end to end
      snapcorr demo --out /tmp/demo       ... writing the figures elsewhere
    """,
    "flatfield": r"""
      snapcorr flatfield scene.hdr --dark dark.hdr --white white.hdr --out scene_ff.nc
                                          flat-field a cube (Goossens Eq. 29)
      snapcorr flatfield frame.npy --dark dark.npy --white white.npy \
          --sensor mosaic_4x4_vis --out scene_ff.zarr --plot scene_ff.png
                                          ... a raw mosaic frame, split into its 16 bands
      snapcorr flatfield frame.npy --dark dark.npy --white white.npy \
          --sensor imec_5x5_nir --demosaic ri --out scene_full.nc
                                          ... flat-fielded pixel by pixel, then every band at
                                          every pixel (full resolution; or nearest, bilinear,
                                          ppid)
      snapcorr flatfield crop.hdr --dark dark.hdr --white white.hdr --sensor snapscan_vnir \
          --sensor-origin-px 512,768 --out crop_ff.nc
                                          ... a crop whose first pixel is sensor row 512, col 768
    """,
    "stream": r"""
      snapcorr stream frames.zarr --dark dark.npy --white white.npy --sensor imec_5x5_nir \
          --demosaic ri --lens my_lens.toml --f-number 2 --out stream.zarr
                                          a film of raw frames (a .zarr, a multi-page .tif or
                                          a folder of frames), each flat-fielded, demosaicked
                                          and corrected, frame by frame
      snapcorr stream frames.zarr --dark dark.npy --white white.npy --sensor imec_5x5_nir \
          --lens my_lens.toml --f-number 2.8 --virtual-bands angle-aware --out film.zarr
                                          ... with every frame's virtual bands, for each
                                          pixel's angle behind the lens
      snapcorr stream frames/ --dark dark.npy --white white.npy --sensor mosaic_4x4_vis \
          --out stream.zarr               ... flat-fielded and demosaicked only
    """,
    "correct": r"""
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor snapscan_vnir --f-number 1.4 \
          --out scene_corrected.nc --resample --plot scene_corrected.png
                                          per-pixel corrected wavelengths (Eq. 23)
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor sensor.toml --f-number 4 \
          --source cube --tolerance-pct 0.5 --out scene_corrected.nc
                                          ... with the model the scene's own spectrum needs
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor snapscan_vnir --f-number 1.4 \
          --harmonise --out scene_harmonised.nc
                                          ... and spectra with one response per band, the
                                          same for a material anywhere in the field
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor snapscan_vnir --f-number 2 \
          --resample --no-input --out scene.hdr
                                          ... as ENVI pairs for other tools (scene.hdr,
                                          scene_wavelength_corrected.hdr, scene_resampled.hdr,
                                          ...), without a copy of the input
      snapcorr correct mosaic_ff.nc --lens my_lens.toml --sensor imec_5x5_nir --f-number 2 \
          --virtual-bands angle-aware --out mosaic_corrected.nc
                                          ... and virtual bands recomputed for each pixel's
                                          angle behind the lens (or: vendor, fitted)
    """,
    "sensor": r"""
      snapcorr sensor CMV2K-SSM5x5-600_875-5.5.9.2.xml --plot filters.png
                                          what a vendor calibration file holds, and its curves
      snapcorr sensor camera.xml --toml my_camera.toml
                                          ... and a sensor TOML naming it, to add n_eff
      snapcorr sensor camera.xml --phase-from white.npy --dark dark.npy
                                          where a crop's first pixel sits on the mosaic's
                                          tile grid, read from its white reference
      snapcorr sensor camera.xml --phase-from white.npy --sensor-origin-px 512,768
                                          ... and whether the stated origin agrees
    """,
    "calibrate": r"""
      snapcorr calibrate --flat 1.4=f1.4.tif --flat 2=f2.tif --flat 2.8=f2.8.tif \
          --flat 4=f4.tif --flat 8=f8.tif --exit-pupil-mm 21 --pixel-pitch-um 5.5 \
          --magnification 0.06 --pupil-magnification 1.3 --dark dark.tif \
          --out my_lens.toml --plot my_lens.png
                                          lens profile from integrating-sphere flats
      snapcorr calibrate --flat 2=f2.tif --flat 4=f4.tif --flat 11=f11.tif \
          --exit-pupil-mm 21 --pixel-pitch-um 5.5 --max-circles 2 --tolerance-nm 0.01 \
          --out my_lens.toml
                                          at most two circles; keep a second only if it
                                          moves the mean shift by more than 0.01 nm
      snapcorr calibrate --flat 2=f2.tif --flat 8=f8.tif --dark dark.tif --lens lens_x.toml \
          --pixel-pitch-um 5.5 --out my_lens.toml
                                          x (and m, m_P) from the profile snapcorr pupil wrote
      snapcorr calibrate --flat 2=f2.tif --flat 4=f4.tif --flat 8=f8.tif --flat 11=f11.tif \
          --target-cube 2=target_f2_ff.nc --target-cube 8=target_f8_ff.nc \
          --sensor snapscan_vnir --fit-n-eff --pixel-pitch-um 5.5 \
          --magnification 0.06 --pupil-magnification 1.3 --out my_lens.toml
                                          x unknown: x, n_eff, P, h and the centre in one run,
                                          with their covariance, from flats and a target
      snapcorr calibrate --flat 2=raw_f2.npy --flat 4=raw_f4.npy --flat 11=raw_f11.npy \
          --sensor mosaic_4x4_vis --dark raw_dark.npy --exit-pupil-mm 21 \
          --pixel-pitch-um 5.5 --out my_lens.toml
                                          raw frames of a snapshot mosaic: each flat's band
                                          gains (the tile pattern) fitted and divided out
      snapcorr calibrate --flat 2=crop_f2.tif --flat 8=crop_f8.tif --sensor mosaic_4x4_vis \
          --sensor-origin-px 512,768 --exit-pupil-mm 21 --pixel-pitch-um 5.5 --out my_lens.toml
                                          ... a crop whose first pixel is sensor row 512, col 768
    """,
    "pupil": r"""
      snapcorr pupil --cube 2=target_f2_ff.nc --cube 8=target_f8_ff.nc --sensor snapscan_vnir \
          --lens my_lens.toml --fit-n-eff --out my_lens_x.toml --plot my_lens_x.png \
          --sensor-out my_sensor.toml
                                          exit pupil x and n_eff from cubes of a spectral
                                          target at two f-numbers (P, h kept from my_lens.toml);
                                          my_sensor.toml: the sensor with the fitted n_eff
      snapcorr pupil --cube 2.8=target_ff.hdr --sensor sensor.toml --target-spectrum filter.csv \
          --out lens_x.toml
                                          ... one f-number and a target of known spectrum
      snapcorr pupil --predict --sensor snapscan_vnir --lens edmund_optics_16mm \
          --f-number 2 --f-number 8 --noise-pct 1
                                          which target pins x best (Cramer-Rao bound)
      with --lens from snapcorr calibrate (x guessed), the circles are scaled to the x found
    """,
    "shift": r"""
      snapcorr shift --f-number 1.4 --cra 0 10 20
                                          mean shift of 700 nm filters behind the bundled lens
      snapcorr shift --lens my_lens.toml --f-number 2.8 --cra 15 --cwl-nm 850 --n-eff 1.9
    """,
    "budget": r"""
      snapcorr budget --sensor snapscan_vnir --lens edmund_optics_16mm --f-number 1.4 \
          --source solar --tolerance-pct 0.5 --plot budget.png
                                          which bands and pixels need correcting, and how
      snapcorr budget --sensor sensor.toml --lens my_lens.toml --f-number 2.8 \
          --source cube --cube scene_ff.nc
                                          ... for a scene's own spectrum
    """,
}

#: ``snapcorr --help``: the everyday path in four commands (each command's --help has more).
WORKFLOW = r"""
  snapcorr demo                           the paper's experiment, simulated end to end
  snapcorr flatfield scene.hdr --dark dark.hdr --white white.hdr --sensor snapscan_vnir \
      --out scene_ff.nc                   (DN - dark) / (white - dark)
  snapcorr calibrate --flat 2=f2.tif --flat 8=f8.tif --target-cube 2=t2_ff.nc \
      --target-cube 8=t8_ff.nc --sensor snapscan_vnir --pixel-pitch-um 5.5 --out my_lens.toml
                                          the lens, once: flats and a spectral target
  snapcorr correct scene_ff.nc --lens my_lens.toml --sensor snapscan_vnir --f-number 2 \
      --out scene_corrected.nc --plot scene_corrected.png
                                          every pixel's wavelengths
"""

#: Library parameter names as the command line spells them, for error messages.
_CLI_TERMS = {
    "pass wavelength_nm": "give --sensor SENSOR.toml (its cwl_nm are the wavelengths)",
    "virtual_wavelengths_nm": "--virtual-wavelengths",
    "virtual_fwhm_nm": "--virtual-fwhm-nm",
    "overwrite=True": "--overwrite",
    "but wavelength_nm gives": "but the --sensor has",
    "(read a 2-D frame with read_frame)": "(a 2-D raw frame of a mosaic camera is read with "
                                          "that camera's --sensor, whose layout is mosaic)",
}


def _examples(*commands):
    text = "".join(textwrap.dedent(EXAMPLES[c]).strip("\n") + "\n" for c in commands)
    return "examples:\n" + textwrap.indent(text, "  ")


# -- shared pieces -----------------------------------------------------------------------------


def _bundled_or_file(value, load, bundled_path, suffixes=(".toml",)):
    """A profile from a file (``suffixes``), or a bundled one by name
    (``edmund_optics_16mm``)."""
    path = Path(value)
    if path.suffix.lower() in suffixes or path.exists():
        return load(path)
    return load(bundled_path(str(value)))


def _lens(value):
    from .data import lens_path
    from .optics import Lens

    return _bundled_or_file(value, Lens.load, lens_path)


def _sensor(value):
    from .cube import Sensor
    from .data import sensor_path

    return _bundled_or_file(value, Sensor.load, sensor_path, (".toml", ".xml"))


#: Pixel positions further out than this are a typo: no sensor is this wide.
_MAX_PX = 1_000_000
#: The most wavelengths a list may give (a step of 0.01 nm over 100 nm-10 um).
_MAX_WAVELENGTHS = 1_000_000


def _pair_arg(what, names, *, integer=False):
    def parse(value):
        try:
            a, b = (float(v) for v in value.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {names} in pixels, got {value!r}") \
                from None
        if not (math.isfinite(a) and math.isfinite(b)):
            raise argparse.ArgumentTypeError(f"the {what} must be finite, got {value!r}")
        if max(abs(a), abs(b)) > _MAX_PX:
            raise argparse.ArgumentTypeError(f"the {what} lies {max(abs(a), abs(b)):.3g} "
                                             f"pixels out; no sensor is wider than {_MAX_PX:,} "
                                             f"pixels, got {value!r}")
        if integer:
            if a != round(a) or b != round(b) or a < 0 or b < 0:
                raise argparse.ArgumentTypeError(f"the {what} is whole pixels >= 0, got "
                                                 f"{value!r}")
            return int(a), int(b)
        return a, b
    return parse


_center_arg = _pair_arg("centre", "CX,CY")
_center_rc_arg = _pair_arg("centre", "ROW,COL")
_origin_arg = _pair_arg("origin", "ROW,COL", integer=True)


def _pack_range_arg(value):
    """``--pack-range LO,HI``: two finite numbers, LO < HI."""
    try:
        lo, hi = (float(v) for v in value.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO,HI (two numbers), got {value!r}") \
            from None
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise argparse.ArgumentTypeError(f"expected finite LO < HI, got {value!r}")
    try:  # what the float32 CF packing can hold
        return check_pack_range("--pack-range", lo, hi)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err).removeprefix("--pack-range ")) from None


def _number(text):
    """A command-line string as a float (NaN for text that is not one, refused after)."""
    try:
        return float(text)
    except (TypeError, ValueError, OverflowError):
        return float("nan")


def _positive(value):
    try:
        return check_positive("value", _number(value))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {value!r}") \
            from None


def _check_outputs(outputs, inputs, overwrite, suffixes):
    """Refuse, before any long work, outputs that are, contain or lie in an input, that exist
    (without ``--overwrite``), have the wrong suffix or no folder to go in."""
    # realpath, unlike Path.resolve, does not raise on a symlink loop (the reader reports it)
    srcs = [Path(os.path.realpath(_input_path(i))) for i in inputs if i is not None]
    bundled = _bundled_folder()
    seen = []
    for out, allowed in zip(outputs, suffixes, strict=True):
        if out is None:
            continue
        out = Path(out)
        res = Path(os.path.realpath(out))
        if bundled is not None and res.is_relative_to(bundled) and os.path.lexists(res):
            raise ValueError(f"output {out} is one of snapcorr's bundled files ({bundled}), "
                             "never replaced; give your own a new name")
        for other, given in seen:  # two outputs of one command: neither in the other
            if res == other or res.is_relative_to(other) or other.is_relative_to(res):
                raise ValueError(f"outputs {given} and {out} are the same or one lies in the "
                                 "other; give each its own path")
        seen.append((res, out))
        for src in srcs:
            if res == src:
                raise ValueError(f"output {out} is also an input; choose another output path")
            if src.is_relative_to(res) or res.is_relative_to(src):
                raise ValueError(f"output {out} holds or lies in the input {src}; choose "
                                 "another output path")
        if out.suffix.lower() not in allowed:
            raise ValueError(f"{out}: the output must end in {' or '.join(allowed)}")
        folder = out.suffix.lower() == ".zarr"  # a zarr store is a folder, the rest files
        if out.exists() and out.is_dir() != folder:
            raise ValueError(f"{out} exists and is a {'folder' if out.is_dir() else 'file'}; "
                             "it is never replaced: choose another output path")
        if os.path.lexists(out) and not overwrite:
            raise FileExistsError(f"{out} exists; choose another name or pass --overwrite")
        check_replaceable(out)  # notes what is there now (nothing, too): only that is replaced
        if not res.parent.is_dir():
            raise ValueError(f"{out.parent} is not a folder; create it first")


def _input_path(value):
    """An input as the file it names: a bundled lens or sensor by name is its profile."""
    path = Path(value)
    if path.exists() or path.suffix:
        return path
    from .data import lens_path, sensor_path

    for find in (lens_path, sensor_path):
        try:
            found = find(str(value))
        except (FileNotFoundError, ValueError):
            continue
        if found.exists():
            return found
    return path


def _bundled_folder():
    """The bundled profiles' folder (None when not installed from a checkout)."""
    from .data import calibration_dir

    try:
        return Path(os.path.realpath(calibration_dir()))
    except FileNotFoundError:
        return None


#: Progress bars: None on a terminal only (the default), False never (``--quiet``), True
#: always, from the start (``--progress``); set by :func:`main` for the command it runs.
_SHOW_PROGRESS = None


def _progress_bar(desc, unit, total, **options):
    """A tqdm bar on stderr as ``--quiet`` and ``--progress`` say: by default shown after a
    second of work, on a terminal only (not in logs or pipes)."""
    from tqdm import tqdm

    asked = _SHOW_PROGRESS is True
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr,
                delay=0 if asked else _StageBar.DELAY_S, leave=asked, dynamic_ncols=True,
                disable=None if _SHOW_PROGRESS is None else not _SHOW_PROGRESS,
                mininterval=0.1 if sys.stderr.isatty() else 1.0, **options)


class _Ticking:
    """Redraws a bar every second while a long step gives it nothing to count, so its
    elapsed time shows that the work goes on (after the bar's delay, as tqdm would)."""

    def __init__(self, bar, every_s=1.0):
        import threading

        self.bar, self.every_s = bar, every_s
        self.stop = threading.Event()
        self.thread = None
        if not bar.disable:
            self.thread = threading.Thread(target=self._run, name="snapcorr-progress",
                                           daemon=True)
            self.thread.start()

    def _run(self):
        import time

        while not self.stop.wait(self.every_s):
            if time.time() - self.bar.start_t >= self.bar.delay:
                self.bar.refresh()

    def close(self):
        self.stop.set()
        if self.thread is not None:
            self.thread.join()


class _StageBar:
    """One labelled progress bar (tqdm, on stderr) over every dask computation of a stage.

    With ``frames``, a stream's: frames done (each computation's share of its tasks done, in
    frames), frames per second and the time left, bar by bar for each writing pass."""

    #: Seconds of work before the bar shows (short stages print nothing).
    DELAY_S = 1.0

    def __init__(self, desc, frames=None, count=True):
        self.desc, self.frames, self.count = desc, frames, count

    def __enter__(self):
        from dask.callbacks import Callback

        frames, desc = self.frames, self.desc
        # work that gives nothing to count shows the time it has taken
        self.bar = bar = _progress_bar(desc, "frame" if frames else "block", frames or 0,
                                       **({} if self.count else
                                          {"bar_format": "{desc} ({elapsed})"}))
        counts = {"passes": 0, "done": 0, "tasks": 0}
        stage = self

        class _Count(Callback):
            def _start_state(self, dsk, state):
                if not stage.count:
                    return
                tasks = len(state["ready"]) + len(state["waiting"])
                counts["passes"] += 1
                if frames is None:
                    bar.total += tasks
                    return
                counts.update(done=0, tasks=max(tasks, 1))
                if counts["passes"] > 1:  # each writing pass goes through every frame
                    bar.reset(total=frames)
                    bar.set_description(f"{desc} (pass {counts['passes']})", refresh=False)

            def _posttask(self, key, result, dsk, state, worker_id):
                if not stage.count:
                    return
                if frames is None:
                    bar.update(1)
                    return
                counts["done"] += 1
                bar.update(frames * counts["done"] // counts["tasks"] - bar.n)

            def _finish(self, dsk, state, errored):
                bar.refresh()  # each pass's end is seen (a log keeps it)

        self.callback = _Count()
        self.callback.__enter__()
        self.ticking = _Ticking(bar)
        return self

    def __exit__(self, *exc):
        self.ticking.close()
        self.callback.__exit__(*exc)
        self.bar.close()


class _StepBar:
    """A progress bar (tqdm, on stderr, on a terminal only) over the named steps of a long
    computation: ``step(description)`` is called before each one."""

    def __init__(self, desc, total=None):
        self.desc, self.total = desc, total

    def __enter__(self):
        self.bar = _progress_bar(self.desc, "step", self.total)
        self.started = False
        self.ticking = _Ticking(self.bar)
        return self

    def step(self, what=""):
        if self.started:
            self.bar.update(1)
        self.started = True
        self.bar.set_postfix_str(what, refresh=True)

    def __exit__(self, *exc):
        self.ticking.close()
        self.bar.close()


def _read(path, sensor=None, origin=None):
    """A cube (or a raw mosaic frame split into bands) from any format, in row blocks.

    Row blocks of about 16 MiB keep memory bounded whatever the file's size (ENVI and .npy are
    memory-mapped, never copied whole).
    """
    return _read_with_mask(path, sensor, origin)[0]


def _read_with_mask(path, sensor=None, origin=None):
    """:func:`_read`'s cube and a flat-field result's ``mask`` (or None), from one opening."""
    from .cube.io import read_cube_and_mask

    wl = sensor.cwl_nm if sensor is not None else None
    frame_error = None
    if sensor is not None and sensor.layout == "mosaic":
        try:
            frame = _read_frame_rows(path, sensor)
        except ValueError as err:  # not a single-band frame: read it as a cube below
            frame_error = err
        else:
            from .cube import mosaic_to_cube

            try:
                return mosaic_to_cube(frame.data, sensor, origin_px=origin,
                                      attrs={**frame.attrs, "source": str(path)}), None
            except ValueError as err:
                raise ValueError(f"{path}: {err}") from None
    try:  # opened once, read in blocks
        cube, mask = read_cube_and_mask(path, wavelength_nm=wl, chunks="rows")
    except ValueError as err:
        if frame_error is not None and "2-D" in str(err):
            raise frame_error from None
        raise
    if origin is not None:
        from .cube import sensor_positions
        from .cube.model import with_positions

        rows, cols = sensor_positions(sensor, cube.sizes["y"], cube.sizes["x"], origin)
        if "sensor_row" not in cube.coords:
            cube = with_positions(cube, rows, cols)
        else:
            _check_origin(path, cube, rows, cols, origin)
    return cube, mask


def _check_origin(path, cube, rows, cols, origin):
    """A --sensor-origin-px must agree with the positions the file records (which are used)."""
    for coord, dim, want in (("sensor_row", "y", rows), ("sensor_col", "x", cols)):
        if coord not in cube.coords:
            continue
        have = np.asarray(cube[coord].transpose(dim, ...).values)
        have = have if have.ndim == 2 else have[:, None]
        if have.shape[0] != want.shape[0] or not np.array_equal(
                np.broadcast_to(have, want.shape) if have.shape[1] == 1 else have, want):
            raise ValueError(f"--sensor-origin-px {origin[0]},{origin[1]} disagrees with the "
                             f"sensor positions {path} records (its first pixel at row "
                             f"{int(np.min(cube['sensor_row']))}, col "
                             f"{int(np.min(cube['sensor_col']))}); leave the option out: the "
                             "file's positions are used")


def _frame_rows(frame, sensor):
    """Rows per block of a 2-D mosaic frame: whole tiles, about 16 MiB."""
    from .cube.io import BLOCK_BYTES

    tr = sensor.mosaic_shape[0]
    return max(tr, (BLOCK_BYTES // max(1, frame.sizes["x"] * 4)) // tr * tr)


# -- subcommands -------------------------------------------------------------------------------


def _stored_type(args, computed):
    """The type the values are written in, as a summary line says it (``--dtype`` float16 or
    uint16 compute in float32)."""
    stored = getattr(args, "storage", None)
    if stored is None or stored == str(computed):
        return str(computed)
    return f"stored as {stored}{', CF-packed' if stored == 'uint16' else ''}, computed in " \
        f"{computed}"


def _check_storage_option(args):
    """``--dtype`` and ``--pack-range`` for ``--out``'s format, before any work; ``--dtype``
    float16 or uint16 computes in float32 and stores as asked (``args.storage``)."""
    from .cube.datasets import check_storage

    dtype = getattr(args, "dtype", None)
    args.storage = dtype if dtype in ("float32", "float16", "uint16") else None
    if dtype in ("float16", "uint16"):
        args.dtype = "float32"
    suffix = args.out.suffix.lower()
    fmt = {".nc": "netcdf", ".zarr": "zarr", ".hdr": "envi"}.get(suffix)
    if args.pack_range is not None and args.storage != "uint16":
        raise ValueError(f"--pack-range goes with --dtype uint16"
                         f"{'' if args.storage is None else f', not {args.storage}'}")
    check_storage(args.storage, args.pack_range, fmt, what="--dtype")


def _cmd_demo(args):
    from .demo import run_demo

    run_demo(args.out, overwrite=args.overwrite)
    return 0


def _cmd_flatfield(args):
    from .cube import flatfield
    from .cube.flatfield import check_masked

    inputs = [p for p in (args.raw, *args.dark, *args.white, args.filter_white) if p]
    _check_outputs([args.out, args.plot], inputs, args.overwrite, [(".nc", ".zarr"), (".png",)])
    _check_storage_option(args)
    sensor = _sensor(args.sensor) if args.sensor else None
    if args.sensor_origin_px is not None and sensor is None:
        raise ValueError("--sensor-origin-px needs --sensor (the layout places the pixels)")

    def read(path):
        return _read(path, sensor, args.sensor_origin_px)

    _check_phase(args, sensor)
    if args.demosaic is not None:
        return _flatfield_demosaic(args, sensor, inputs)
    raw = read(args.raw)
    darks = [read(p) for p in args.dark]
    whites = [read(p) for p in args.white]
    for label, cubes, paths in (("--dark", darks, args.dark), ("--white", whites, args.white)):
        for c, p in zip(cubes, paths, strict=True):
            if c.sizes["band"] != raw.sizes["band"] or c.sizes["x"] != raw.sizes["x"]:
                raise ValueError(f"{label} {p} is {c.shape[0]} x {c.shape[1]} x {c.shape[2]} "
                                 f"but {args.raw} is {raw.shape[0]} x {raw.shape[1]} x "
                                 f"{raw.shape[2]}: x and band must match")
    snapshot = sensor is not None and sensor.layout == "mosaic"
    _default_saturation(args, sensor, whites)
    ds = flatfield(raw, darks, whites, saturation=args.saturation, dtype=args.dtype,
                   snapshot=snapshot)
    if args.filter_white:
        fw = read(args.filter_white)
        if fw.shape != raw.shape:
            sizes = [" x ".join(map(str, c.shape)) for c in (fw, raw)]
            raise ValueError(f"--filter-white {args.filter_white} is {sizes[0]} but {args.raw} "
                             f"is {sizes[1]}: the white seen through the filter is a cube of "
                             "the same size and place")
        tr = flatfield(fw, darks, whites, saturation=args.saturation, name="transmittance",
                       dtype=args.dtype, snapshot=snapshot)
        _with_transmittance(ds, tr, args.filter_white)
    ds.attrs.update({"raw_file": str(args.raw), "dark_files": [str(p) for p in args.dark],
                     "white_files": [str(p) for p in args.white]})
    with _StageBar("flat-fielding (checking the mask)"):
        n_masked, total = check_masked(ds)
    with _StageBar(f"writing {args.out.name}"):
        _write_result(args, ds, inputs, RAW_COPIES, args.raw)
    print(f"wrote {args.out}: {ds.attrs.get('name', 'reflectance')} of {args.raw} "
          f"({raw.shape[0]} x {raw.shape[1]} x {raw.shape[2]}, "
          f"{_stored_type(args, ds['reflectance'].dtype)}), "
          f"{len(darks)} dark and {len(whites)} white frame(s) averaged; {n_masked} of {total} "
          f"values masked ({100 * n_masked / total:.2f} %)")
    _quicklook(args, "plot_flatfield", ds)
    return 0


def _default_saturation(args, sensor, whites):
    """``--saturation`` defaults to the sensor's largest code (its bit depth), said on stderr."""
    from .cube.mosaic import frame_saturation

    if args.saturation is None:
        args.saturation = frame_saturation(sensor, whites, what=f"--white {args.white[0]}")
        if args.saturation is not None:
            print(f"saturation: {args.saturation:g} DN, the largest {sensor.bit_depth}-bit code "
                  "of the sensor (--saturation DN to change)", file=sys.stderr)


def _check_phase(args, sensor):
    """The stated origin (or a whole-sensor frame) against the phase the first white frame
    shows, before any work (a white cube records where it was taken: it is not re-checked)."""
    from .cube.phase import check_mosaic_phase

    if sensor is None or sensor.layout != "mosaic" or sensor.responses is None:
        return
    try:
        white = _read_frame_rows(args.white[0], sensor)
        dark = _read_frame_rows(args.dark[0], sensor) if args.dark else None
    except ValueError:  # a cube, not a raw frame
        return
    check_mosaic_phase(white, sensor, args.sensor_origin_px,
                       dark=dark if dark is not None and dark.shape == white.shape else None,
                       saturation=args.saturation, what=f"--white {args.white[0]}")


def _read_frame_rows(path, sensor):
    """A raw 2-D mosaic frame, opened once, lazily in whole-tile row blocks."""
    from .cube import read_frame

    frame = read_frame(path, chunks="rows")
    return frame.chunk({"y": _frame_rows(frame, sensor), "x": -1})


def _read_frame_checked(path, sensor, what, shape=None):
    """A raw 2-D mosaic frame, lazily in whole-tile row blocks; of ``shape`` when given."""
    frame = _read_frame_rows(path, sensor)
    if shape is not None and frame.shape != shape:
        raise ValueError(f"{what} {path} is {frame.shape[0]} x {frame.shape[1]} px but the raw "
                         f"frame {shape[0]} x {shape[1]}: a snapshot's references are frames "
                         "of the same size and place")
    return frame


def _with_transmittance(ds, tr, path):
    """The filter's transmittance (``--filter-white``) added to a flat-field result."""
    ds["transmittance"] = tr["transmittance"]
    ds["filter_white_raw"] = tr["raw"]
    ds["transmittance_mask"] = tr["mask"].assign_attrs(
        long_name="transmittance value not meaningful")
    ds.attrs["filter_white_file"] = str(path)


def _quicklook(args, draw, what):
    """``--plot``: the quick look ``snapcorr.quicklook.<draw>`` of ``what``, if asked for."""
    if args.plot:
        from . import quicklook

        getattr(quicklook, draw)(what, args.plot, overwrite=args.overwrite)
        print(f"wrote {args.plot}")


def _masked_in(path):
    """``n_masked`` of a result just written (counted in the writing pass)."""
    from .cube import read_dataset

    with read_dataset(path, chunks={}) as ds:
        return int(ds["n_masked"])


def _flatfield_demosaic(args, sensor, inputs):
    """``flatfield --demosaic``: the raw frame flat-fielded pixel by pixel, then demosaicked."""
    from .cube import demosaic, flatfield
    from .cube.flatfield import check_masked

    if sensor is None or sensor.layout != "mosaic":
        raise ValueError("--demosaic needs a mosaic --sensor (its layout places the bands)")
    origin = args.sensor_origin_px
    raw = _read_frame_checked(args.raw, sensor, "the raw frame")
    darks = [_read_frame_checked(p, sensor, "--dark", raw.shape) for p in args.dark]
    whites = [_read_frame_checked(p, sensor, "--white", raw.shape) for p in args.white]
    _default_saturation(args, sensor, whites)
    ff = flatfield(raw, darks, whites, saturation=args.saturation, dtype=args.dtype)
    with _StageBar("flat-fielding (checking the mask)"):
        check_masked(ff)
    ds = demosaic(ff, sensor, args.demosaic, origin_px=origin)
    if args.filter_white:
        fw = _read_frame_checked(args.filter_white, sensor, "--filter-white", raw.shape)
        tr = demosaic(flatfield(fw, darks, whites, saturation=args.saturation,
                                name="transmittance", dtype=args.dtype),
                      sensor, args.demosaic, origin_px=origin)
        _with_transmittance(ds, tr, args.filter_white)
    ds.attrs.update({"raw_file": str(args.raw), "dark_files": [str(p) for p in args.dark],
                     "white_files": [str(p) for p in args.white]})
    cube = ds["reflectance"]
    with _StageBar(f"demosaicking ({args.demosaic}) and writing {args.out.name}"):
        _write_result(args, ds, inputs, RAW_COPIES, args.raw)
    n_masked, total = _masked_in(args.out), cube.size
    print(f"wrote {args.out}: reflectance of {args.raw}, demosaicked ({args.demosaic}) to "
          f"{cube.shape[0]} x {cube.shape[1]} x {cube.shape[2]} "
          f"({_stored_type(args, cube.dtype)}), sensor rows "
          f"and columns {ds.attrs['mosaic_area_px']} (first row, first column, rows, columns); "
          f"{len(darks)} dark and {len(whites)} white frame(s) averaged; {n_masked} of {total} "
          f"values masked ({100 * n_masked / total:.2f} %)")
    _quicklook(args, "plot_flatfield", ds)
    return 0


def _cmd_stream(args):
    from .cube import read_frames
    from .stream import process_stream

    inputs = [args.frames, *args.dark, *args.white]
    _check_outputs([args.out], inputs, args.overwrite, [(".zarr", ".nc")])
    _check_storage_option(args)
    sensor = _sensor(args.sensor)
    if sensor.layout != "mosaic":
        raise ValueError(f"stream takes raw mosaic frames: --sensor {args.sensor} is not a "
                         f"mosaic (layout {sensor.layout!r})")
    if (args.lens is None) != (args.f_number is None):
        raise ValueError("correcting a stream needs both --lens and --f-number")
    if args.resample and args.lens is None:
        raise ValueError("--resample needs --lens and --f-number")
    _check_virtual_options(args, sensor)
    if args.virtual_bands is not None and args.lens is None:
        raise ValueError("--virtual-bands needs --lens and --f-number (the stream is corrected "
                         "first)")
    lens = _lens(args.lens) if args.lens is not None else None
    frames = read_frames(args.frames)
    darks = [_read_frame_checked(p, sensor, "--dark", frames.shape[1:]) for p in args.dark]
    whites = [_read_frame_checked(p, sensor, "--white", frames.shape[1:]) for p in args.white]
    ds = process_stream(frames, darks, whites, sensor, demosaic_method=args.demosaic, lens=lens,
                        f_number=args.f_number, origin_px=args.sensor_origin_px,
                        saturation=args.saturation, dtype=args.dtype, resample=args.resample,
                        virtual_bands=args.virtual_bands, virtual_matrix=args.virtual_matrix,
                        virtual_wavelengths_nm=args.virtual_wavelengths,
                        virtual_fwhm_nm=args.virtual_fwhm_nm)
    ds.attrs.update({"frames_file": str(args.frames), "dark_files": [str(p) for p in args.dark],
                     "white_files": [str(p) for p in args.white]}
                    | ({"lens_file": str(args.lens)} if args.lens else {})
                    | {"sensor_file": str(args.sensor)})
    cube = ds["reflectance"]
    with _StageBar(f"flat-fielding, demosaicking ({args.demosaic})"
                   f"{', correcting' if lens else ''}, writing {args.out.name}",
                   frames=cube.sizes["frame"]):
        _write_result(args, ds, inputs, RAW_COPIES, args.frames)
    n_masked = _masked_in(args.out)
    print(f"wrote {args.out}: {cube.sizes['frame']} frames of {args.frames}, each "
          f"{cube.shape[1]} x {cube.shape[2]} x {cube.shape[3]} ({args.demosaic}); "
          f"{n_masked} of {cube.size} values masked ({100 * n_masked / cube.size:.2f} %)"
          + (f", f/{args.f_number:g}, method {ds.attrs['method']} (CRA up to "
             f"{ds.attrs['cra_max_deg']:.2f} deg)" if lens else ", not corrected (no --lens)")
          + ("; resampled onto the nominal wavelengths" if args.resample else ""))
    _print_virtual(args, ds)
    if args.saturation is None and sensor.full_scale_dn is not None:
        print(f"saturation: {sensor.full_scale_dn} DN, the largest {sensor.bit_depth}-bit code "
              "of the sensor (--saturation DN to change)", file=sys.stderr)
    return 0


def _correct_input(args, sensor):
    """The cube to correct and, from a flat-field result, its mask (the file opened once)."""
    return _read_with_mask(args.cube, sensor, args.sensor_origin_px)


def _write_correction(args, ds, inputs, cube_name):
    """``correct``'s result as ``--out`` asks: a .nc or .zarr, or ENVI pairs; the paths."""
    if args.out.suffix.lower() == ".hdr":
        from .cube.datasets import _stored_as
        from .cube.envi_result import write_envi_result

        if args.no_input:
            ds.attrs["input_left_out"] = f"{cube_name} (--no-input); the input is {args.cube}"
        ds = _stored_as(ds, args.storage, None, "envi")
        return write_envi_result(ds, args.out, overwrite=args.overwrite, inputs=inputs,
                                 include_input=not args.no_input, input_name=cube_name)
    return [_write_result(args, ds, inputs, [cube_name, *RAW_COPIES], args.cube)]


#: What a flat-field result says of how it was made, kept (as ``input_<name>``) in the
#: correction of it.
FLATFIELD_RECORD = ("raw_file", "dark_files", "white_files", "dark_frames", "white_frames",
                    "filter_white_files", "demosaic_method", "mosaic_area_px", "sensor",
                    "created", "snapcorr_version")


def _keep_flatfield_record(path, ds):
    """A correction of a flat-field result (.nc or .zarr) keeps its raw counts (lazily, as
    stored) and its record of the raw, dark and white files: the corrected values sit next to
    the camera's numbers they came from."""
    if path.suffix.lower() not in (".nc", ".zarr"):
        return
    from .cube import read_dataset

    src = read_dataset(path, chunks={})
    for name in RAW_COPIES:
        raw = src.variables.get(name)
        if raw is not None and name not in ds.variables and all(
                ds.sizes.get(d) == n for d, n in raw.sizes.items()):
            ds[name] = src[name].reset_coords(drop=True)
    for key in FLATFIELD_RECORD:
        if key in src.attrs:
            ds.attrs.setdefault(f"input_{key}", src.attrs[key])


def _check_virtual_options(args, sensor):
    """The virtual-band options make sense together, and for the sensor, before any work."""
    if args.virtual_bands is None and any(v is not None for v in (
            args.virtual_matrix, args.virtual_wavelengths, args.virtual_fwhm_nm)):
        raise ValueError("--virtual-matrix, --virtual-wavelengths and --virtual-fwhm-nm choose "
                         "the virtual bands: give --virtual-bands too")
    if args.virtual_matrix is not None and args.virtual_bands != "vendor":
        raise ValueError("--virtual-matrix names the vendor matrix to apply: use it with "
                         "--virtual-bands vendor")
    if args.virtual_bands == "vendor" and (args.virtual_wavelengths is not None
                                           or args.virtual_fwhm_nm is not None):
        raise ValueError("the vendor's virtual bands are the file's; --virtual-wavelengths and "
                         "--virtual-fwhm-nm set fitted or angle-aware ones")
    if args.virtual_bands in ("fitted", "angle-aware") and sensor.responses is not None:
        from .correct.virtual import virtual_targets

        virtual_targets(sensor, args.virtual_wavelengths, args.virtual_fwhm_nm)


def _print_virtual(args, ds):
    """One line on the virtual bands of a result, if it has them."""
    if "virtual" in ds:
        wl = ds["virtual_wavelength"].values
        err = (f"; expected error up to {float(ds['virtual_stderr'].max()):.2g} (virtual_stderr)"
               if "virtual_stderr" in ds else "")
        print(f"virtual bands: {wl.size} from {wl.min():.1f} to {wl.max():.1f} nm, "
              f"{args.virtual_bands}{err}")


def _cmd_correct(args):
    from .correct import correct_cube
    from .cube.derived import with_fwhm_table

    inputs = [args.cube, args.lens, args.sensor]
    _check_outputs([args.out, args.plot], inputs, args.overwrite,
                   [(".nc", ".zarr", ".hdr"), (".png",)])
    if args.out.suffix.lower() == ".hdr" and (args.compression != "auto" or args.store_derived):
        raise ValueError("an ENVI result is written plainly and whole: --compression and "
                         "--store-derived go with .nc or .zarr")
    _check_storage_option(args)
    if args.source is not None and args.method != "auto":
        raise ValueError("--source chooses the model: use it with --method auto")
    if args.tolerance_pct is not None and args.source is None:
        raise ValueError("--tolerance-pct applies to the scene budget: give --source too")
    if args.target_fwhm_nm is not None and not (args.harmonise or args.method == "harmonised"):
        raise ValueError("--target-fwhm-nm sets the common response of --harmonise: give "
                         "--harmonise (or --method harmonised) too")
    lens = _lens(args.lens)
    sensor = _sensor(args.sensor)
    cube, mask = _correct_input(args, sensor)
    method, provenance = args.method, {}
    if args.source is not None:  # the scene budget chooses the model
        from .budget import recommend_model

        method, _, provenance = recommend_model(
            cube, sensor, args.f_number, lens, args.source,
            tolerance_pct=0.5 if args.tolerance_pct is None else args.tolerance_pct,
            center_px=args.center_px, sensor_origin_px=args.sensor_origin_px)
    _check_virtual_options(args, sensor)
    with _StageBar("correcting: chief-ray angles, models and tables", count=False):
        ds = correct_cube(cube, sensor, args.f_number, lens, method=method,
                          tolerance_nm=args.tolerance_nm, center_px=args.center_px,
                          sensor_origin_px=args.sensor_origin_px, resample=args.resample,
                          harmonise=args.harmonise, target_fwhm_nm=args.target_fwhm_nm,
                          mask=mask, virtual_bands=args.virtual_bands,
                          virtual_matrix=args.virtual_matrix,
                          virtual_wavelengths_nm=args.virtual_wavelengths,
                          virtual_fwhm_nm=args.virtual_fwhm_nm)
    ds.attrs.update({**provenance, "cube_file": str(args.cube), "lens_file": str(args.lens),
                     "sensor_file": str(args.sensor)})
    _keep_flatfield_record(args.cube, ds)
    if args.scheduler:
        from distributed import Client

        try:
            client = Client(args.scheduler, timeout="10s")
        except OSError as err:
            raise ValueError(f"cannot reach the dask scheduler at {args.scheduler}: {err}") \
                from None
        with client:  # progress: the cluster's dashboard
            written = _write_correction(args, ds, inputs, cube.name)
    else:
        with _StageBar(f"correcting, writing {args.out.name}"):
            written = _write_correction(args, ds, inputs, cube.name)
    if len(written) > 1:
        print("ENVI pairs (header and .raw) in " + f"{args.out.parent}: "
              + ", ".join(p.name for p in written))
    print(f"wrote {args.out}: {cube.shape[0]} x {cube.shape[1]} x {cube.shape[2]} cube, f/"
          f"{args.f_number:g}, method {ds.attrs['method']} ({ds.attrs['method_reason']}); "
          f"CRA up to {ds.attrs['cra_max_deg']:.2f} deg, optical centre row "
          f"{ds.attrs['optical_center_rc'][0]:g}, col {ds.attrs['optical_center_rc'][1]:g} "
          f"({ds.attrs['optical_center_source']})"
          + ("; resampled onto the nominal wavelengths" if args.resample else ""))
    ds = with_fwhm_table(ds)  # built by the write already
    if "fwhm_table" in ds:
        table = ds["fwhm_table"].values
        print(f"each pixel's band FWHM: {np.nanmin(table):.3g}-{np.nanmax(table):.3g} nm over "
              f"the field ({sensor.profile} filters of {np.min(sensor.fwhm_nm):.3g}-"
              f"{np.max(sensor.fwhm_nm):.3g} nm)")
    _print_virtual(args, ds)
    if "harmonised" in ds:  # asked for, or chosen by the scene budget
        w = ds["fwhm_harmonised"].values
        print(f"harmonised: one response per band, FWHM {np.nanmin(w):.3g}-{np.nanmax(w):.3g} "
              f"nm ({ds['fwhm_harmonised'].attrs['source']})")
        left_out = ds["harmonised"].attrs.get("not_harmonised", "none")
        if not left_out.startswith("none"):  # measured responses: the bands left NaN, and why
            print(f"harmonised: not harmonised (NaN): {left_out}")
    _quicklook(args, "plot_correction", ds)
    return 0


def _wavelength_list(value):
    """``NM,NM,...`` or ``START:STOP:STEP`` (inclusive of STOP when it falls on a step)."""
    try:
        if ":" in value:
            start, stop, step = (float(v) for v in value.split(":"))
            if not step > 0 or not stop >= start:
                raise ValueError
            count = (stop - start) / step + 1
            if not count <= _MAX_WAVELENGTHS:
                raise argparse.ArgumentTypeError(
                    f"{value!r} gives {count:.3g} wavelengths; at most {_MAX_WAVELENGTHS:,} "
                    "(is the step in nm?)")
            values = np.arange(start, stop + 0.5 * step, step)
        else:
            values = np.array([float(v) for v in value.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NM,NM,... or START:STOP:STEP in nm, got "
                                         f"{value!r}") from None
    if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise argparse.ArgumentTypeError(f"wavelengths must be finite and > 0 nm, got {value!r}")
    return values


def _cmd_sensor(args):
    inputs = [args.file]
    _check_outputs([args.toml, args.plot], inputs, args.overwrite, [(".toml",), (".png",)])
    sensor = _sensor(args.file)
    if args.phase_from is not None:
        return _print_phase(args, sensor)
    if args.dark is not None or args.sensor_origin_px is not None:
        given = "--dark" if args.dark is not None else "--sensor-origin-px"
        raise ValueError(f"{given} goes with --phase-from WHITE")
    print(sensor.describe())
    if args.toml:
        sensor.save(args.toml, overwrite=args.overwrite)
        note = ("" if sensor.n_eff is not None else
                "; its n_eff line is commented out: snapcorr pupil --fit-n-eff --sensor-out "
                "measures it and writes it")
        print(f"wrote {args.toml}{note}")
    _quicklook(args, "plot_sensor", sensor)
    return 0


def _print_phase(args, sensor):
    """``sensor --phase-from WHITE``: where the white's first pixel sits on the tile grid."""
    from .cube.phase import mosaic_phase

    if args.toml or args.plot:
        raise ValueError("--phase-from reads a white frame: give --toml and --plot in a run "
                         "of their own")
    white = _read_frame_checked(args.phase_from, sensor, "--phase-from")
    dark = (None if args.dark is None else
            _read_frame_checked(args.dark, sensor, "--dark", white.shape))
    try:
        found = mosaic_phase(white, sensor, dark=dark, origin_px=args.sensor_origin_px)
    except ValueError as err:
        raise ValueError(f"--phase-from {args.phase_from}: {err}") from None
    print(f"{args.phase_from} ({white.shape[0]} x {white.shape[1]} px): {found.describe()}")
    if found.agrees is not None:
        stated = ("the whole-sensor frame" if args.sensor_origin_px is None else
                  "--sensor-origin-px {},{}".format(*args.sensor_origin_px))
        print(f"{stated}: {'agrees' if found.agrees else 'DISAGREES'}"
              + ("" if found.agrees else
                 " (an origin that agrees: {},{})".format(
                     *found.origin_px(args.sensor_origin_px or (0, 0)))))
    return 0 if found.phase_px is not None else 1


def _flat_arg(value):
    """``F_NUMBER=PATH`` (F_NUMBER may be written 2.8, f2.8 or f/2.8)."""
    if "=" not in value:
        raise argparse.ArgumentTypeError(f"expected F_NUMBER=PATH, got {value!r}")
    f, path = value.split("=", 1)
    f = f.strip().lower().removeprefix("f").removeprefix("/")
    try:
        fv = check_positive("the f-number", _number(f))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{value!r}: {f!r} is not an f-number > 0") from None
    if not path:
        raise argparse.ArgumentTypeError(f"{value!r}: no file after '='")
    return fv, Path(path)


def _one_per_f_number(pairs, what):
    """``{f_number: path}`` from ``F_NUMBER=PATH`` arguments; an f-number given twice is an
    error."""
    seen = {}
    for f, path in pairs:
        if f in seen:
            raise ValueError(f"f/{f:g} given twice ({seen[f]} and {path}); give one {what} per "
                             "f-number")
        seen[f] = path
    return seen


def _pitch_option(args, sensor):
    """``--pixel-pitch-um``, else the ``--sensor``'s pitch; refused where neither gives one."""
    if args.pixel_pitch_um is not None:
        return
    pitch = getattr(sensor, "pixel_pitch_um", None)
    if not pitch or not pitch > 0:
        raise ValueError("give the flats' pixel pitch: --pixel-pitch-um UM"
                         + ("" if sensor is None else f" (the sensor {args.sensor} gives none)"))
    args.pixel_pitch_um = float(pitch)
    print(f"pixel pitch: {pitch:g} um, the sensor's ({args.sensor})", file=sys.stderr)


def _cmd_calibrate(args):
    import dataclasses

    from .calibrate import calibrate_lens

    _one_per_f_number(args.flat, "flat")
    if args.target_cube:
        return _calibrate_with_target(args)
    _no_target_options(args)
    sensor = _flat_sensor(args)
    if args.exit_pupil_mm is None and args.lens is None:
        raise ValueError("give the exit pupil distance: --exit-pupil-mm X, --lens LENS.toml "
                         "(from snapcorr pupil), or --target-cube F_NUMBER=PATH (repeat) with "
                         "--sensor to fit it from a spectral target in the same run")
    inputs = [p for _, p in args.flat] + [args.dark, args.lens, args.sensor]
    _check_outputs([args.out, args.plot], inputs, args.overwrite, [(".toml",), (".png",)])
    given = _lens(args.lens) if args.lens else None
    x = given.exit_pupil_mm if given else args.exit_pupil_mm
    sx = given.calibration.get("exit_pupil_stderr_mm") if given else None
    sx = sx if isinstance(sx, (int, float)) and not isinstance(sx, bool) and sx > 0 else None
    m = args.magnification if args.magnification is not None else (
        given.magnification if given else 0.0)
    mp = args.pupil_magnification if args.pupil_magnification is not None else (
        given.pupil_magnification if given else 1.0)
    if args.pupil == "auto":
        raise ValueError("--pupil auto chooses by a spectral target's fit, which flats alone "
                         "cannot make: give --target-cube, or --pupil paper or lambertian")
    pupil = args.pupil or (given.pupil if given else "paper")
    _pitch_option(args, sensor)
    flats, bands, sat, dark = _read_flats(args, sensor)
    with _StepBar("calibrating") as bar:
        res = calibrate_lens(
            flats, exit_pupil_mm=x, pixel_pitch_um=args.pixel_pitch_um,
            exit_pupil_stderr_mm=sx, magnification=m, pupil_magnification=mp,
            dark=dark, center_px=args.center_px, saturation=sat,
            vignetting_distance_mm=args.vignetting_distance_mm, method=args.method,
            name=args.name or args.out.stem, inputs={f: str(p) for f, p in args.flat},
            tolerance_nm=args.tolerance_nm, max_circles=args.max_circles, progress=bar.step,
            pupil=pupil, sensor=sensor, sensor_origin_px=args.sensor_origin_px)
    cal = _flats_provenance(dict(res.lens.calibration), args, bands)
    _band_gains_said(res, cal, args)
    if given is not None:
        cal["exit_pupil_from"] = str(args.lens)
        for key in ("exit_pupil_stderr_mm", "n_eff", "n_eff_stderr", "n_eff_fitted"):
            if key in given.calibration:
                cal[f"exit_pupil_{key}" if key.startswith("n_eff") else key] = \
                    given.calibration[key]
    lens = dataclasses.replace(res.lens, calibration=cal)
    lens.save(args.out, overwrite=args.overwrite)
    if args.plot:
        res.save_plot(args.plot)
    print(res.summary())
    _no_dark_note(args)
    print(f"wrote {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0


_TARGET_OPTIONS = ("fit_n_eff", "sensor_out", "target_spectrum", "target_tolerance_nm")


def _flat_sensor(args):
    """``--sensor`` without --target-cube: the mosaic whose raw frames the flats are (its band
    gains are divided out); a sensor of another layout is refused."""
    if args.sensor is None:
        if args.sensor_origin_px is not None:
            raise ValueError("--sensor-origin-px needs --sensor (the mosaic whose raw frames "
                             "the flats are)")
        return None
    sensor = _sensor(args.sensor)
    if sensor.layout != "mosaic":
        raise ValueError(f"--sensor {args.sensor} is not a mosaic (layout {sensor.layout!r}): "
                         "its flats carry no tile pattern to remove; leave --sensor out (it "
                         "goes with raw mosaic flats, or with --target-cube)")
    return sensor


def _band_gains_said(res, cal, args):
    """Say which band gains were divided out, and record the sensor file."""
    if not res.mosaic:
        return
    cal["band_gains"] = {**cal["band_gains"], "sensor_file": str(args.sensor)}
    spread = [f"f/{f:g} {g.min():.2f}-{g.max():.2f}"
              for f, g in sorted(res.mosaic["band_gains"].items())]
    print(f"divided out the band gains of {res.mosaic['sensor'].name} (relative to their mean: "
          + ", ".join(spread) + ")", file=sys.stderr)


def _no_target_options(args):
    """Options that only mean something with --target-cube are refused without it."""
    given = [o for o in _TARGET_OPTIONS if getattr(args, o) not in (None, False)]
    if given:
        raise ValueError(f"--{given[0].replace('_', '-')} goes with --target-cube (fitting x "
                         "from a spectral target); leave it out or add the target's cubes")


def _read_flats(args, sensor=None):
    """Every flat (mean of its bands), the saturation levels and the dark. Raw flats of a
    mosaic ``sensor`` that gives its bit depth saturate at its largest code by default."""
    from .calibrate import read_flat
    from .cube.mosaic import frame_saturation

    flats, bands, sat = {}, set(), {}
    for f, path in sorted(args.flat):
        image, info = read_flat(path)
        flats[f] = image
        bands.add(info["bands"])
        sat[f] = (args.saturation if args.saturation is not None
                  else frame_saturation(sensor, [image], what=f"--flat {f:g}={path}")
                  or info["saturation"])
        print(f"read f/{f:g}: {path} ({image.shape[1]} x {image.shape[0]}"
              + (f", mean of {info['bands']} bands" if info["bands"] > 1 else "") + ")",
              file=sys.stderr)
    dark = read_flat(args.dark)[0] if args.dark else None
    return flats, bands, sat, dark


def _flats_provenance(cal, args, bands):
    cal["bands"] = ("mean of the bands in each file" if max(bands) > 1
                    else "single-band flats")
    cal["dark"] = (str(args.dark) if args.dark else
                   "none given: the flats were taken as already dark-subtracted")
    return cal


def _no_dark_note(args):
    if not args.dark:
        print("note: no --dark: the flats were taken as already dark-subtracted; an offset left "
              "in them is read as light and biases P and h (it can even add a circle)")


def _calibrate_with_target(args):
    """``calibrate --target-cube``: flats and a target's cubes give x, n_eff, P, h and the
    centre in one run (:func:`snapcorr.calibrate.calibrate_with_target`)."""
    import dataclasses

    from .calibrate import FeaturelessTargetError, calibrate_with_target

    if args.exit_pupil_mm is not None or args.lens is not None:
        raise ValueError("--target-cube fits x: leave out --exit-pupil-mm and --lens (give "
                         "--magnification and --pupil-magnification directly)")
    if args.sensor is None:
        raise ValueError("--target-cube needs --sensor SENSOR (the camera of the cubes: its "
                         "bands, filters and pixel pitch)")
    seen = _one_per_f_number(args.target_cube, "target cube")
    _check_target_outputs(args, seen, [p for _, p in args.flat] + [p for _, p in args.target_cube]
                          + [args.dark, args.sensor, args.target_spectrum], "target cubes")
    sensor = _sensor(args.sensor)
    _pitch_option(args, sensor)
    spectrum = _target_spectrum(args.target_spectrum)
    # raw flats of a mosaic saturate at its largest code (calibrate_with_target divides out
    # the band gains of whole-sensor raw flats)
    flats, bands, sat, dark = _read_flats(args, sensor if sensor.layout == "mosaic" else None)
    cubes = {f: _read(path, sensor, args.sensor_origin_px)
             for f, path in sorted(args.target_cube)}
    for f, cube in cubes.items():
        print(f"read target f/{f:g}: {seen[f]} ({cube.sizes['y']} x {cube.sizes['x']} x "
              f"{cube.sizes['band']})", file=sys.stderr)
    try:
        with _StepBar("calibrating the flats, fitting x to the target") as bar:
            res = calibrate_with_target(
                flats, cubes, sensor, pixel_pitch_um=args.pixel_pitch_um,
                fit_n_eff=args.fit_n_eff, magnification=args.magnification or 0.0,
                pupil_magnification=(args.pupil_magnification
                                     if args.pupil_magnification is not None else 1.0),
                dark=dark, center_px=args.center_px, saturation=sat, method=args.method,
                max_circles=args.max_circles, tolerance_nm=args.tolerance_nm,
                target_spectrum=spectrum, sensor_origin_px=args.sensor_origin_px,
                name=args.name or args.out.stem, inputs={f: str(p) for f, p in args.flat},
                target_inputs=seen, progress=bar.step, pupil=args.pupil or "auto",
                target_tolerance_nm=_target_tolerance(args.target_tolerance_nm),
                report=_say_precision)
    except FeaturelessTargetError as err:
        raise ValueError(f"nothing written: {err}") from None
    cal = _flats_provenance(dict(res.lens.calibration), args, bands)
    lens = dataclasses.replace(res.lens, calibration=cal)
    lens.save(args.out, overwrite=args.overwrite)
    written = [args.out]
    if args.sensor_out is not None:
        _fitted_sensor(sensor, res.pupil, args).save(args.sensor_out,
                                                     overwrite=args.overwrite)
        written.append(args.sensor_out)
    if args.plot:
        res.calibration.save_plot(args.plot)
        written.append(args.plot)
    print(res.summary())
    _no_dark_note(args)
    print("wrote " + ", ".join(str(w) for w in written))
    return 0


def _check_target_outputs(args, seen, inputs, cubes):
    """The outputs of a target fit (``--out``, ``--plot``, ``--sensor-out``), before any work."""
    if args.sensor_out is not None and not (args.fit_n_eff and len(seen) >= 2):
        raise ValueError(f"--sensor-out needs --fit-n-eff and {cubes} at two or more "
                         "f-numbers (one f-number fixes only x * n_eff)")
    _check_outputs([args.out, args.plot, args.sensor_out], inputs, args.overwrite,
                   [(".toml",), (".png",), (".toml",)])
    if args.sensor_out is not None and os.path.realpath(args.sensor_out) == os.path.realpath(
            args.out):
        raise ValueError("--sensor-out and --out are the same file; choose two paths")


def _cmd_pupil(args):
    if args.predict:
        return _pupil_predict(args)
    from .calibrate import FeaturelessTargetError, locate_pupil

    if args.f_number or args.noise_pct is not None:
        raise ValueError("--f-number and --noise-pct describe a measurement to plan with "
                         "--predict; a fit takes its f-numbers from --cube F_NUMBER=PATH and "
                         "measures the noise in the cubes")
    if not args.cube or args.out is None:
        raise ValueError("give --cube F_NUMBER=PATH (one per f-number) and --out LENS.toml, or "
                         "--predict to compare targets before measuring")
    seen = _one_per_f_number(args.cube, "cube")
    _check_target_outputs(args, seen, [p for _, p in args.cube]
                          + [args.sensor, args.lens, args.target_spectrum], "cubes")
    sensor = _sensor(args.sensor)
    lens = _lens(args.lens) if args.lens else None
    spectrum = _target_spectrum(args.target_spectrum)
    cubes = {f: _read(path, sensor, args.sensor_origin_px) for f, path in sorted(args.cube)}
    for f, cube in cubes.items():
        print(f"read f/{f:g}: {seen[f]} ({cube.sizes['y']} x {cube.sizes['x']} x "
              f"{cube.sizes['band']})", file=sys.stderr)
    try:
        with _StepBar("fitting the exit pupil") as bar:
            fit = locate_pupil(cubes, sensor, lens=lens, fit_n_eff=args.fit_n_eff,
                               center_px=args.center_px, target_spectrum=spectrum,
                               sensor_origin_px=args.sensor_origin_px,
                               magnification=args.magnification,
                               pupil_magnification=args.pupil_magnification,
                               inputs=seen, name=args.name or args.out.stem,
                               progress=bar.step, pupil=args.pupil or (
                                   lens.pupil if lens is not None and lens.has_vignetting
                                   else "auto"),
                               tolerance_nm=_target_tolerance(args.tolerance_nm),
                               report=_say_precision)
    except FeaturelessTargetError as err:
        raise ValueError(f"nothing written: {err}") from None
    fit.lens.save(args.out, overwrite=args.overwrite)
    written = [args.out]
    if args.sensor_out is not None:
        _fitted_sensor(sensor, fit, args).save(args.sensor_out, overwrite=args.overwrite)
        written.append(args.sensor_out)
    if args.plot:
        fit.save_plot(args.plot)
        written.append(args.plot)
    print(fit.summary())
    print("wrote " + ", ".join(str(w) for w in written))
    return 0


def _target_tolerance(value):
    """``--tolerance-nm`` / ``--target-tolerance-nm``, or the default."""
    from .calibrate.pupil_precision import DEFAULT_TOLERANCE_NM

    return DEFAULT_TOLERANCE_NM if value is None else value


def _say_precision(text):
    """The precision a target's cubes can give, said before the fit."""
    print(text, flush=True)


def _fitted_sensor(sensor, fit, args):
    """The sensor with the fitted effective index, and where it came from."""
    import dataclasses

    cal = fit.lens.calibration
    keep = ("n_eff_fitted", "n_eff_stderr", "f_numbers", "target_spectrum", "inputs",
            "snapcorr_version", "date")
    from .calibrate.pupil_target import N_EFF_START

    design = ({"n_eff_design": list(sensor.n_eff)} if sensor.n_eff is not None
              else {"n_eff_start": N_EFF_START})  # a vendor file gives none
    record = {"n_eff_from": str(args.out), **design, **{k: cal[k] for k in keep if k in cal}}
    record["source"] = "snapcorr pupil: " + cal["source"]
    return dataclasses.replace(sensor, name=f"{sensor.name} (n_eff fitted)",
                               n_eff=tuple(float(v) for v in fit.n_eff), calibration=record)


def _target_spectrum(path):
    if path is None:
        return None
    from .spectra import read_spectrum

    sp = read_spectrum(path)
    return sp.wavelength_nm, sp.values


def _pupil_predict(args):
    from .calibrate import CANDIDATE_TARGETS, pupil_precision

    if args.cube:
        raise ValueError("--predict compares targets before measuring; leave out --cube")
    if not args.f_number:
        raise ValueError("give the f-numbers you would measure at: --f-number F (repeat)")
    sensor = _sensor(args.sensor)
    if sensor.size_px is None:
        raise ValueError(f"--predict needs the sensor's size: {args.sensor} gives no size_px "
                         "(add size_px = [ROWS, COLS] to a sensor TOML)")
    lens = _lens(args.lens or "edmund_optics_16mm")
    targets = dict(CANDIDATE_TARGETS)
    if args.target_spectrum is not None:
        wl, val = _target_spectrum(args.target_spectrum)
        targets[Path(args.target_spectrum).name] = lambda lam: np.interp(lam, wl, val)
    args.noise_pct = 1.0 if args.noise_pct is None else args.noise_pct
    noise = args.noise_pct / 100.0
    fs = sorted(set(args.f_number))
    print(f"predicted standard error of the exit pupil distance x = {lens.exit_pupil_mm:g} mm "
          f"(Cramer-Rao bound), sensor {sensor.name}, lens {lens.name or args.lens}, "
          f"f/{', f/'.join(f'{f:g}' for f in fs)}, noise {args.noise_pct:g} % of the brightest "
          "band per pixel" + (", n_eff fitted too" if args.fit_n_eff else ""))
    print(f"{'target':34s} {'x, spectrum unknown':>22s} {'x, spectrum known':>20s}"
          + (f" {'n_eff':>12s}" if args.fit_n_eff else ""))
    with _StepBar("bounds for each target", total=2 * len(targets)) as bar:
        for name, S in targets.items():
            row = []
            for known in (False, True):
                bar.step(f"{name[:24]}, spectrum {'known' if known else 'unknown'}")
                p = pupil_precision(S, sensor, fs, lens, noise=noise,
                                    fit_n_eff=args.fit_n_eff and len(fs) > 1,
                                    spectrum_known=known)
                row.append(p)
            cells = [_precision_cell(p) for p in row]
            extra = ""
            if args.fit_n_eff:
                extra = (f" {'x * n_eff only':>12s}" if len(fs) < 2 else
                         f" {row[0].n_eff_stderr:12.2g}" if row[0].informative else
                         f" {'-':>12s}")
            print(f"{name[:34]:34s} {cells[0]:>22s} {cells[1]:>20s}{extra}")
    print("noise only: a target that is not uniform, or filters of another shape than the "
          "sensor file says, add errors of their own")
    return 0


def _precision_cell(p):
    if not p.informative:
        return "no information"
    return f"{p.x_stderr_mm:.2g} mm ({100 * p.x_stderr_mm / p.exit_pupil_mm:.2g} %)"


def _cmd_shift(args):
    from ._validation import check_wavelengths_nm
    from .optics import mean_shift, select_method

    lens = _lens(args.lens)
    check_wavelengths_nm("--cwl-nm", [args.cwl_nm])
    if not args.n_eff > 1:
        raise ValueError(f"--n-eff must be > 1 (a filter's effective index), got {args.n_eff:g}")
    cra = np.asarray(args.cra, float)
    cutoff = float(lens.cutoff_cra_deg(args.f_number))
    past = np.abs(cra) >= cutoff
    if np.any(past):
        raise ValueError(f"CRA {float(np.abs(cra[past]).max()):g} deg is past the full cut-off "
                         f"at {cutoff:.2f} deg for f/{args.f_number:g} (the lens's vignetting "
                         "circles leave no light); give smaller --cra values")
    shift = mean_shift(args.cwl_nm, args.n_eff, args.f_number, cra, lens, method=args.method,
                       tolerance_nm=args.tolerance_nm)
    if args.method == "auto":
        used = select_method(args.n_eff, args.f_number, cra, lens, cwl_nm=args.cwl_nm,
                             tolerance_nm=args.tolerance_nm)
    else:
        used = np.full(cra.shape, args.method)
    print(f"# {lens.name}, f/{args.f_number:g}, cwl {args.cwl_nm:g} nm, n_eff {args.n_eff:g}")
    print(f"{'cra_deg':>8} {'shift_nm':>10} {'corrected_nm':>13}  method")
    for c, s, m in zip(cra, np.atleast_1d(shift), np.atleast_1d(used), strict=True):
        print(f"{c:>8.3f} {s:>10.4f} {args.cwl_nm + s:>13.4f}  {m}")
    return 0


def _budget_field(args, lens, sensor, cube):
    """The largest CRA the budget covers, and a phrase saying where it comes from."""
    from .correct.geometry import cube_cra_deg

    if args.cra_max is not None:
        return args.cra_max, f"CRA up to {args.cra_max:g} deg (--cra-max)"
    if cube is not None:
        cra_max = float(cube_cra_deg(cube, sensor, lens, args.center_px)[0].max())
        return cra_max, f"the cube's pixels, CRA up to {cra_max:.2f} deg"
    if sensor.field_radius_mm is not None:
        cra_max = math.degrees(math.atan(sensor.field_radius_mm / lens.exit_pupil_mm))
        return cra_max, (f"the sensor's {sensor.size_px[0]} x {sensor.size_px[1]} px field, "
                         f"CRA up to {cra_max:.2f} deg at its corners")
    raise ValueError(f"the sensor {sensor.name!r} has no size_px: give --cra-max DEG or "
                     "--cube CUBE for the field to cover")


def _cmd_budget(args):
    from .budget import scene_budget, tolerance_ranges
    from .spectra import parse_source

    _check_outputs([args.plot], [args.cube, args.sensor, args.lens], args.overwrite,
                   [(".png",)])
    if args.source.split(":")[0].strip().lower() == "cube" and args.cube is None:
        raise ValueError(f"--source {args.source} is the spectrum of a cube: give --cube CUBE")
    lens = _lens(args.lens)
    sensor = _sensor(args.sensor)
    cube = None
    if args.cube is not None:
        cube = _read(args.cube, sensor)
        sensor.check_cube(cube, f"--cube {args.cube}")
    source = parse_source(args.source, cube)
    cra_max, field = _budget_field(args, lens, sensor, cube)
    from .budget.scene import _profile_of

    args.profile = _profile_of(sensor, args.profile)
    b = scene_budget(source, sensor, args.f_number, lens, cra_max_deg=cra_max,
                     profile=args.profile, tolerance_pct=args.tolerance_pct)
    ranges = []
    for c, w, n in zip(sensor.cwl_nm, sensor.fwhm_nm, sensor.n_eff, strict=True):
        try:
            ranges += tolerance_ranges(source, [c], [w], n_eff=n, profile=args.profile)
        except ValueError:  # the source ends within a shift of 5 nm of this band
            ranges.append(["n/a", "n/a"])
    _print_budget(args, b, sensor, lens, source, field, ranges)
    if args.plot is not None:
        b.plot(args.plot, overwrite=args.overwrite,
               inputs=[args.sensor, args.lens, args.cube, args.source])
        print(f"wrote {args.plot}")
    return 0


#: Bands ``budget`` prints unless --all-bands.
_BUDGET_ROWS = 10


def _print_budget(args, b, sensor, lens, source, field, ranges):
    def fmt(r):
        if isinstance(r, str):
            return r
        return "NA" if r is None else f"{r[0]:.1f}-{r[1]:.1f}"

    model, reason = b.recommend()
    print(f"scene budget: {source.name}; {lens.name} at f/{args.f_number:g}; {sensor.name} "
          f"({sensor.n_bands} bands, {args.profile} filters); {field}")
    print("worst |signal error| over the field, percent, left by each model; last columns: "
          "centre positions where +-1 nm stays < 0.5 % and +-5 nm < 2 % (Flittner & Slater)")
    table = b.table().splitlines()
    rows = list(zip(table[1:-1], ranges, strict=True))
    shown = range(len(rows))
    if not args.all_bands and len(rows) > _BUDGET_ROWS:
        worst = np.abs(b.data["residual"]).max("cra").sel(model=b.models[0]).values
        shown = sorted(np.argsort(-worst, kind="stable")[:_BUDGET_ROWS])
        print(f"the {_BUDGET_ROWS} of {len(rows)} bands the {b.models[0]!r} model leaves worst "
              "(--all-bands for every one):")
    print(f"{table[0]}  {'+-1nm<0.5%':>13} {'+-5nm<2%':>13}")
    for i in shown:
        line, rr = rows[i]
        print(f"{line}  {fmt(rr[0]):>13} {fmt(rr[1]):>13}")
    print(table[-1])
    radius = b.radius_mm()
    if math.isinf(radius):
        print(f"uncorrected within {args.tolerance_pct:g} % over the whole field "
              "(Mishev & Bakalova's radius is beyond it)")
    elif radius > 0:
        print(f"uncorrected within {args.tolerance_pct:g} %: image radius < {radius:.2f} mm "
              f"({radius / sensor.pixel_pitch_mm:.0f} px) (Mishev & Bakalova)")
    else:
        print(f"uncorrected, the signal is off by more than {args.tolerance_pct:g} % even on "
              f"the axis (the cone of f/{args.f_number:g} alone shifts the bands)")
    print(f"recommended: {model}: {reason}")


# -- the parser --------------------------------------------------------------------------------

#: What ``--dtype`` may store a result's values as.
STORAGE_CHOICES = ("float32", "float16", "uint16")
DTYPE_HELP = ("type the values are stored as: float32; float16 (.zarr only, relative error "
              "4.9e-4); uint16 (.nc, .zarr: packed by CF scale_factor/add_offset that readers "
              "apply, reflectance at most 3.2e-5 from the value); raw counts are kept as they "
              "are")
SENSOR_HELP = ("sensor description (.toml), the vendor's calibration file (.xml) or a bundled "
               "sensor (snapscan_vnir, mosaic_4x4_vis, imec_5x5_nir, ...)")
OVERWRITE_HELP = "replace an existing --out (or --plot) that snapcorr wrote; never an input"
ORIGIN_HELP = ("sensor row and column of the cube's first pixel (of its tile, for a mosaic), "
               "for a crop that does not record where it sits")


def _add_output_options(p, *, input_name, derived=False, dtype=False):
    """``--compression``, ``--pack-range`` and ``--no-input`` (and ``--store-derived``,
    ``--dtype``) for a result."""
    g = p.add_argument_group("output")
    if dtype:
        g.add_argument("--dtype", default=None, choices=list(STORAGE_CHOICES),
                       help=DTYPE_HELP + " (default: the input's own type)")
    g.add_argument("--compression", default="auto", choices=["auto", "all", "none"],
                   help="auto (default): every numeric variable (.zarr: Blosc LZ4 with bit "
                   "shuffle; .nc: DEFLATE level 1 with byte shuffle), except a copy its "
                   "source compressed already; all; none")
    g.add_argument("--pack-range", type=_pack_range_arg, default=None, metavar="LO,HI",
                   help="with --dtype uint16: the values packed (default for reflectance and "
                   "transmittance: -0.5,3.5); values outside are stored as LO or HI")
    g.add_argument("--no-input", action="store_true",
                   help=f"leave out the copy of {input_name} (by default kept next to the "
                   "result); its path stays in the attributes")
    if derived:
        g.add_argument("--store-derived", action="store_true",
                       help="store wavelength_corrected and fwhm_corrected whole (about one "
                       "cube each), for readers without snapcorr; by default they are "
                       "rebuilt on reading from a compact form")


def _without_input(ds, names, source):
    """``--no-input``: ``ds`` without the input's copy, saying where the input is."""
    present = [n for n in names if n in ds.variables]
    ds = ds.drop_vars(present)
    ds.attrs["input_left_out"] = f"{', '.join(present)} (--no-input); the input is {source}"
    return ds


#: The copies of the input a flat-field result keeps (``--no-input`` leaves them out).
RAW_COPIES = ("raw", "filter_white_raw")


def _write_result(args, ds, inputs, input_names, source):
    """Write ``ds`` to ``--out`` as the output options say; ``input_names`` are the input's
    copy, left out with ``--no-input``."""
    from .cube import write_dataset

    if args.no_input:
        ds = _without_input(ds, input_names, source)
    return write_dataset(ds, args.out, overwrite=args.overwrite, inputs=inputs,
                         compression=args.compression,
                         store_derived=getattr(args, "store_derived", False),
                         dtype=getattr(args, "storage", None),
                         pack_range=getattr(args, "pack_range", None))


def _add_progress_options(p):
    """``--quiet`` and ``--progress``: the progress bars of a long command."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--quiet", action="store_true",
                   help="no progress bars (by default they show on stderr after a second of "
                   "work, when stderr is a terminal)")
    g.add_argument("--progress", action="store_true",
                   help="progress bars on stderr from the start, also when stderr is not a "
                   "terminal (a log file)")


def _add_center(p, help_text):
    """``--center ROW,COL`` and its deprecated x-first form ``--center-px CX,CY``."""
    p.add_argument("--center", type=_center_rc_arg, default=None, metavar="ROW,COL",
                   help=help_text.replace("optical centre", "optical centre (row, column)", 1))
    p.add_argument("--center-px", type=_center_arg, default=None, metavar="CX,CY",
                   help="deprecated: the optical centre x first; use --center ROW,COL")


def _center_option(args):
    """``args.center_px``, the internal (cx, cy), from ``--center ROW,COL`` or the deprecated
    ``--center-px CX,CY`` (said on stderr; giving both is an error)."""
    if getattr(args, "center_px", None) is not None:
        if args.center is not None:
            raise ValueError("give the optical centre once: --center ROW,COL (--center-px "
                             "CX,CY is its old x-first form)")
        cx, cy = args.center_px
        print(f"snapcorr {args.command}: --center-px CX,CY is deprecated and will be removed; "
              f"give --center ROW,COL (here --center {cy:g},{cx:g})", file=sys.stderr)
    elif getattr(args, "center", None) is not None:
        row, col = args.center
        args.center_px = (col, row)


def _add_demo(command):
    p = command("demo", "the main job on a bundled default: calibrate the paper's lens, "
                "correct a simulated cube, write figures")
    p.add_argument("--out", default="snapcorr-demo", type=Path,
                   help="output folder (default: %(default)s); a folder holding other files "
                   "is refused")
    p.add_argument("--overwrite", action="store_true",
                   help="write into a folder holding other files, replacing those of the "
                   "same names")
    p.set_defaults(func=_cmd_demo)


def _add_flatfield(command):
    p = command("flatfield", "flat-field a cube: (DN - dark) / (white - dark) (Eq. 29)")
    p.add_argument("raw", type=Path, help="the cube to correct (.hdr, .tif (one band per page "
                   "or channel), .exr, .nc, .zarr, .npy), or a raw 2-D mosaic frame with a "
                   "mosaic --sensor")
    p.add_argument("--dark", type=Path, action="append", required=True,
                   help="dark frame (repeat to average several)")
    p.add_argument("--white", type=Path, action="append", required=True,
                   help="white reference (repeat to average several; a strip of fewer rows "
                   "than the cube is broadcast along the scan axis)")
    p.add_argument("--filter-white", type=Path, default=None,
                   help="the white target seen through a filter: adds the filter's "
                   "transmittance (Goossens Sec. 3.1) to the output")
    p.add_argument("--out", type=Path, required=True, help="result, .nc or .zarr")
    p.add_argument("--sensor", default=None,
                   help=SENSOR_HELP + ": the wavelengths of files that have none, and the "
                   "band layout of raw mosaic frames")
    p.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                   help=ORIGIN_HELP + " (needs --sensor)")
    p.add_argument("--saturation", type=_positive, default=None, metavar="DN",
                   help="digital number at or above which a pixel is saturated (default: the "
                   "sensor's largest code, from its bit_depth, where it gives one)")
    p.add_argument("--dtype", default="float32", choices=["float64", *STORAGE_CHOICES],
                   help=DTYPE_HELP + "; float64 computes and stores in double precision "
                   "(default: %(default)s)")
    p.add_argument("--demosaic", default=None, metavar="METHOD",
                   choices=["nearest", "bilinear", "ppid", "ri"],
                   help="a raw mosaic frame (with a mosaic --sensor): flat-field it pixel by "
                   "pixel, then estimate every band at every pixel by METHOD: nearest (tile "
                   "replication), bilinear (weighted bilinear), ppid (pseudo-panchromatic "
                   "difference) or ri (residual interpolation, the most accurate); without "
                   "it, one spectrum per tile")
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="quick look: a band image, the mask and a few pixels' spectra")
    _add_output_options(p, input_name="the raw data (raw, filter_white_raw)")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    _add_progress_options(p)
    p.set_defaults(func=_cmd_flatfield)


def _add_calibrate(command):
    p = command("calibrate", "lens profile (vignetting circles P, h) from flat fields at "
                "several f-numbers (Goossens Sec. 2.7, 3.2)")
    p.add_argument("--flat", type=_flat_arg, action="append", required=True,
                   metavar="F_NUMBER=PATH",
                   help="flat field at an f-number (.npy, .tif, .exr, ENVI .hdr, .nc, .zarr; "
                   "several bands or TIFF pages in a file are averaged); repeat for each "
                   "f-number")
    x = p.add_mutually_exclusive_group()
    x.add_argument("--exit-pupil-mm", type=_positive, metavar="X",
                   help="distance x from the sensor to the exit pupil, mm, when known")
    x.add_argument("--lens", default=None, metavar="LENS.toml",
                   help="take x (and m, m_P unless given) from this lens profile, e.g. the "
                   "output of snapcorr pupil; its provenance is recorded")
    t = p.add_argument_group("x unknown: fit it from a spectral target as well (one run)")
    t.add_argument("--target-cube", type=_flat_arg, action="append", default=[],
                   metavar="F_NUMBER=PATH",
                   help="flat-fielded cube of a uniform target with spectral features at an "
                   "f-number; repeat (two far apart, e.g. f/2 and f/8, with --fit-n-eff). x, "
                   "n_eff, P, h and the centre are then fitted together, with their "
                   "covariance; instead of --exit-pupil-mm / --lens")
    t.add_argument("--sensor", default=None, metavar="SENSOR",
                   help="with --target-cube: the camera of the cubes (bundled name, .toml or "
                   "vendor .xml); without it: a snapshot mosaic whose raw frames the flats "
                   "are, whose band gains (the tile pattern) are fitted in each flat and "
                   "divided out, pixels outside its filter area left out (a sensor of "
                   "another layout is refused: its flats have no tile pattern)")
    _add_target_fit_options(t, "with --target-cube: ")
    t.add_argument("--target-tolerance-nm", type=_positive, default=None, metavar="NM",
                   help="with --target-cube: " + TARGET_TOLERANCE_HELP)
    _add_pupil_option(t)
    p.add_argument("--pixel-pitch-um", type=_positive, default=None, metavar="UM",
                   help="pixel pitch of the flats, micrometres (default: the --sensor's)")
    p.add_argument("--magnification", type=float, default=None,
                   help="linear magnification m (default 0: focused at infinity, or the "
                   "--lens value)")
    p.add_argument("--pupil-magnification", type=_positive, default=None,
                   help="pupil magnification m_P (default 1, or the --lens value)")
    p.add_argument("--dark", type=Path, default=None, help="dark frame, same size")
    _add_center(p, "optical centre in pixels (default: found from the flats)")
    p.add_argument("--out", type=Path, required=True, help="lens profile to write (.toml)")
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="draw the profiles, onsets and model (the paper's Fig. 8)")
    p.add_argument("--method", default="auto", choices=list(CALIBRATION_METHODS),
                   help="estimator of P and h (default: %(default)s: the joint fit unless "
                   "the paper's onsets predict flats left out of the fit better)")
    p.add_argument("--vignetting-distance-mm", type=float, default=None, metavar="H",
                   help="h, when known (needed with a single f-number)")
    p.add_argument("--saturation", type=_positive, default=None, metavar="DN",
                   help="value at or above which a pixel is saturated (default: the "
                   "largest value of the file's integer type)")
    p.add_argument("--max-circles", type=int, default=3, choices=(0, 1, 2, 3),
                   help="most vignetting circles to try (default: %(default)s)")
    p.add_argument("--tolerance-nm", type=_positive, default=0.005, metavar="NM",
                   help="a further circle is kept only if it moves the predicted mean shift "
                   "(1000 nm filter, n_eff 1.5) by more than this (default: %(default)s)")
    p.add_argument("--name", default=None, help="lens name (default: the output's stem)")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    _add_progress_options(p)
    p.set_defaults(func=_cmd_calibrate)


def _add_correct(command):
    p = command("correct", "corrected central wavelength of every pixel and band (Eq. 23)")
    p.add_argument("cube", type=Path, help="the cube (.hdr, .tif, .exr, .nc, .zarr, .npy), "
                   "ideally flat-fielded; or a 2-D mosaic frame with a mosaic --sensor")
    p.add_argument("--lens", required=True,
                   help="lens profile (.toml) or a bundled one (edmund_optics_16mm)")
    p.add_argument("--sensor", required=True, help=SENSOR_HELP)
    p.add_argument("--f-number", type=_positive, required=True, metavar="F",
                   help="the f-number the cube was taken at")
    p.add_argument("--out", type=Path, required=True,
                   help="result: .nc or .zarr (everything, provenance in the attributes), or "
                   "STEM.hdr for ENVI pairs (STEM.hdr the input's values, "
                   "STEM_wavelength_corrected.hdr, STEM_resampled.hdr, ...)")
    _add_center(p, "optical centre in sensor pixels (default: the lens profile's, "
                   "converted to this pixel pitch, else the sensor's centre)")
    p.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                   help=ORIGIN_HELP)
    p.add_argument("--method", default="auto", choices=["auto", *CORRECTION_MODELS],
                   help="the model, cheapest first (default: %(default)s, the cheapest "
                   "meeting the tolerance; harmonised = vignetted and --harmonise)")
    p.add_argument("--tolerance-nm", type=_positive, default=0.01, metavar="NM",
                   help="largest wavelength error allowed, nm (default: %(default)s)")
    p.add_argument("--source", default=None, metavar="SOURCE",
                   help="the scene's spectrum: solar, solar:astm-g173, "
                   "tungsten:TEMPERATURE_K, cube (the cube's mean spectrum) or a two-column "
                   "file; --method auto then takes the cheapest model whose signal error "
                   "stays below --tolerance-pct")
    p.add_argument("--tolerance-pct", type=_positive, default=None, metavar="PCT",
                   help="radiometric tolerance with --source, percent (default: 0.5)")
    p.add_argument("--resample", action="store_true",
                   help="also interpolate each spectrum onto the nominal wavelengths")
    p.add_argument("--harmonise", action="store_true",
                   help="also give every pixel one common response per band (the widest in "
                   "the field, or --target-fwhm-nm) on the nominal wavelengths: the same "
                   "material gives the same spectrum anywhere")
    p.add_argument("--target-fwhm-nm", type=_positive, default=None, metavar="NM",
                   help="with --harmonise: the common response's FWHM for every band (at "
                   "least the widest in the field)")
    _add_virtual_options(p)
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="quick look: a band image, the CRA and shift maps, a few pixels' "
                   "spectra at nominal and corrected wavelengths")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="dask.distributed scheduler to run on, e.g. tcp://host:8786 "
                   "(default: in-process threads)")
    _add_output_options(p, input_name="the input cube", derived=True, dtype=True)
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    _add_progress_options(p)
    p.set_defaults(func=_cmd_correct)


def _add_shift(command):
    p = command("shift", "mean central-wavelength shift at chief-ray angles (Eq. 22-23)")
    p.add_argument("--lens", default="edmund_optics_16mm",
                   help="lens profile (.toml) or a bundled lens name (default: %(default)s)")
    p.add_argument("--f-number", type=_positive, required=True, metavar="F",
                   help="f-number of the lens")
    p.add_argument("--cra", type=float, nargs="+", required=True, metavar="DEG",
                   help="chief-ray angles, degrees (one or more)")
    p.add_argument("--cwl-nm", type=float, default=700.0, metavar="NM",
                   help="the filter's central wavelength at normal incidence, nm (default: "
                   "%(default)s)")
    p.add_argument("--n-eff", type=float, default=1.7,
                   help="the filter's effective refractive index (default: %(default)s)")
    p.add_argument("--method", default="auto", choices=list(SHIFT_METHODS),
                   help="how to compute the mean shift (default: %(default)s, the cheapest "
                   "within --tolerance-nm)")
    p.add_argument("--tolerance-nm", type=_positive, default=0.001, metavar="NM",
                   help="largest error allowed with --method auto, nm (default: %(default)s)")
    p.set_defaults(func=_cmd_shift)


def _add_pupil_option(group):
    """``--pupil``: how the light fills the exit pupil (``snapcorr.optics.lens.PUPILS``)."""
    group.add_argument("--pupil", default=None, choices=["paper", "lambertian", "auto"],
                       help="how the light fills the exit pupil: paper (Goossens 2019 Eq. 28, "
                       "uniform per area), lambertian (sine condition, uniform in direction "
                       "cosines) or auto (both fitted to the target, the Lambertian kept only "
                       "for a chi-square gain above 10; twice the time). Default: auto with "
                       "target cubes (the --lens profile's when it has circles, which belong to "
                       "its pupil), else the --lens profile's, else paper")


def _add_target_fit_options(group, when=""):
    """The options of a fit to a target's cubes, shared by ``pupil`` and ``calibrate
    --target-cube`` (``when`` says which option they go with)."""
    group.add_argument("--fit-n-eff", action="store_true",
                       help=f"{when}fit the effective index too (needs two f-numbers to "
                       "separate it from x; one gives x * n_eff)")
    group.add_argument("--sensor-out", type=Path, default=None, metavar="SENSOR.toml",
                       help="with --fit-n-eff and two or more f-numbers: also write the "
                       "sensor description with the fitted n_eff, for the correction "
                       "(correct --sensor)")
    group.add_argument("--target-spectrum", type=Path, default=None, metavar="PATH",
                       help=f"{when}the target's spectrum, two columns (wavelength nm, "
                       "value); default: unknown, solved for")
    group.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                       help=f"{when}sensor row and column of the cubes' first pixel (crops)"
                       + ("; without it, of the raw mosaic flats' (with --sensor)" if when
                          else ""))


TARGET_TOLERANCE_HELP = (
    "the shift precision x and n_eff must give (nm, one standard deviation, the chief ray at "
    "the sensor's corner in the longest band): before the fit the precision the cubes can "
    "give is predicted and printed, and a target that cannot reach it is refused (default: "
    "0.05)")


def _add_pupil(command):
    p = command("pupil", "exit pupil distance x (and n_eff) from flat-fielded cubes of a "
                "spectral target (Goossens et al., OSA Continuum 2019)")
    p.add_argument("--cube", type=_flat_arg, action="append", default=[],
                   metavar="F_NUMBER=PATH",
                   help="flat-fielded cube of a uniform target with spectral features at an "
                   "f-number (any format snapcorr reads); repeat for each f-number")
    p.add_argument("--sensor", type=str, required=True, metavar="SENSOR",
                   help="sensor description (bundled name or .toml)")
    p.add_argument("--out", type=Path, default=None, help="lens profile to write (.toml)")
    p.add_argument("--lens", type=str, default=None, metavar="LENS",
                   help="lens profile whose vignetting circles (P, h) and magnifications are "
                   "used and copied (bundled name or .toml)")
    _add_target_fit_options(p)
    _add_pupil_option(p)
    _add_center(p, "optical centre in sensor pixels (default: found from the cubes)")
    p.add_argument("--magnification", type=float, default=None,
                   help="linear magnification m without --lens (default 0)")
    p.add_argument("--pupil-magnification", type=_positive, default=None,
                   help="pupil magnification m_P without --lens (default 1)")
    p.add_argument("--tolerance-nm", type=_positive, default=None, metavar="NM",
                   help=TARGET_TOLERANCE_HELP)
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="draw the target over the field and chi-square in x")
    p.add_argument("--name", default=None, help="lens name (default: the output's stem)")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    g = p.add_argument_group("choosing a target (--predict)")
    g.add_argument("--predict", action="store_true",
                   help="print the predicted standard error of x for candidate targets (and "
                   "--target-spectrum) instead of fitting cubes")
    g.add_argument("--f-number", type=_positive, action="append", default=[],
                   help="an f-number you would measure at (repeat)")
    g.add_argument("--noise-pct", type=_positive, default=None,
                   help="per-pixel noise, %% of the brightest band (default: 1)")
    _add_progress_options(p)
    p.set_defaults(func=_cmd_pupil)


def _add_stream(command):
    p = command("stream", "a stream of raw mosaic frames: flat-field, demosaic and correct "
                "each frame")
    p.add_argument("frames", type=Path, help="frames (frame, y, x): a .zarr or .nc holding one "
                   "3-D variable, a 3-D .npy, a multi-page .tif (a frame per page) or a folder "
                   "of frame files (.npy, .tif, .exr, .hdr; in the order of their names, "
                   "numbers in them read as numbers: t0.25, t0.5, t1)")
    p.add_argument("--dark", type=Path, action="append", required=True,
                   help="dark frame (repeat to average several)")
    p.add_argument("--white", type=Path, action="append", required=True,
                   help="white reference frame (repeat to average several)")
    p.add_argument("--sensor", required=True, help=SENSOR_HELP + " (a mosaic)")
    p.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                   help=ORIGIN_HELP)
    p.add_argument("--demosaic", default="ri", metavar="METHOD",
                   choices=["nearest", "bilinear", "ppid", "ri"],
                   help="nearest, bilinear, ppid or ri (default: %(default)s, the most "
                   "accurate)")
    p.add_argument("--lens", default=None,
                   help="lens profile (.toml) or a bundled one: also the corrected "
                   "wavelengths (with --f-number)")
    p.add_argument("--f-number", type=_positive, default=None, metavar="F",
                   help="the f-number the frames were taken at")
    p.add_argument("--resample", action="store_true",
                   help="also every frame's spectra on the nominal wavelengths")
    _add_virtual_options(p)
    p.add_argument("--saturation", type=_positive, default=None, metavar="DN",
                   help="digital number at or above which a pixel is saturated (default: the "
                   "sensor's largest code, from its bit_depth, where it gives one)")
    p.add_argument("--dtype", default="float32", choices=["float64", *STORAGE_CHOICES],
                   help=DTYPE_HELP + "; float64 computes and stores in double precision "
                   "(default: %(default)s)")
    p.add_argument("--out", type=Path, required=True, help="result, .zarr (or .nc)")
    _add_output_options(p, input_name="the raw frames (raw)", derived=True)
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    _add_progress_options(p)
    p.set_defaults(func=_cmd_stream)


def _add_virtual_options(p):
    g = p.add_argument_group("virtual bands (mosaic sensors with a vendor calibration file)")
    g.add_argument("--virtual-bands", default=None, choices=["vendor", "fitted", "angle-aware"],
                   help="also give virtual bands: the vendor's matrix, one fitted to the "
                   "measured responses, or one for each pixel's responses behind the lens")
    g.add_argument("--virtual-matrix", default=None, metavar="NAME",
                   help="the vendor matrix to apply (default: the one for flat-fielded values)")
    g.add_argument("--virtual-wavelengths", type=_wavelength_list, default=None,
                   metavar="NM,NM,...|START:STOP:STEP",
                   help="centres of fitted virtual bands (default: the vendor's)")
    g.add_argument("--virtual-fwhm-nm", type=_positive, default=None, metavar="NM",
                   help="width of fitted virtual bands (default: the vendor's)")


def _add_sensor(command):
    p = command("sensor", "what a sensor file holds: bands, layout, active area, filter "
                "responses, correction matrices")
    p.add_argument("file", help="a vendor calibration file (.xml), a sensor TOML or a bundled "
                   "sensor's name")
    p.add_argument("--toml", type=Path, default=None, metavar="OUT.toml",
                   help="write the equivalent sensor TOML (naming the vendor file, where there "
                   "is one), to add n_eff or the pixel pitch")
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="draw the bands' responses and what each correction matrix makes of "
                   "them")
    p.add_argument("--phase-from", type=Path, default=None, metavar="WHITE",
                   help="a raw white frame of a mosaic sensor with measured responses: print "
                   "where its first pixel sits on the tile grid (the band gains under a smooth "
                   "lamp are the tile's fingerprint)")
    p.add_argument("--dark", type=Path, default=None, metavar="DARK",
                   help="with --phase-from: a dark frame, subtracted from the white")
    p.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                   help="with --phase-from: the stated sensor row and column of the white's "
                   "first pixel, checked against what the white shows (a whole-sensor frame "
                   "needs none)")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.set_defaults(func=_cmd_sensor)


def _add_budget(command):
    p = command("budget", "which bands and pixels a scene needs corrected, and with which "
                "model (signal error of the filter shift)")
    p.add_argument("--sensor", required=True, help=SENSOR_HELP)
    p.add_argument("--lens", required=True,
                   help="lens profile (.toml) or a bundled one (edmund_optics_16mm)")
    p.add_argument("--f-number", type=_positive, required=True, metavar="F",
                   help="f-number of the lens")
    p.add_argument("--source", required=True, metavar="SOURCE",
                   help="solar (Kurucz, 0.5 nm), solar:astm-g173 (at the ground, with O2 and "
                   "H2O), tungsten:TEMPERATURE_K, cube or cube:Y,X (with --cube: its mean "
                   "spectrum or one pixel's) or a two-column file (wavelength nm, value)")
    p.add_argument("--tolerance-pct", type=_positive, default=0.5, metavar="PCT",
                   help="radiometric tolerance, percent (default: %(default)s)")
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="error against band and against image radius")
    p.add_argument("--cube", type=Path, default=None,
                   help="a cube: its pixels set the field, and --source cube its spectrum")
    _add_center(p, "optical centre in the cube's sensor pixels, for --cube (default: "
                   "from the lens calibration, else the sensor's centre)")
    p.add_argument("--cra-max", type=_positive, default=None, metavar="DEG",
                   help="the field to cover (default: the sensor's size_px, or the cube)")
    p.add_argument("--profile", default=None, choices=["gaussian", "multi_lorentzian", "pi"],
                   help="filter shape (default: the sensor's; Flittner & Slater's "
                   "multi-Lorentzian or Mishev & Bakalova's Pi-shaped to compare)")
    p.add_argument("--all-bands", action="store_true",
                   help="print every band (default: the ten the uncorrected model leaves worst)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --plot")
    p.set_defaults(func=_cmd_budget)


class _Version(argparse.Action):
    """``--version``: the installed version, looked up only when asked (the lookup costs as
    much as importing numpy)."""

    def __call__(self, parser, namespace, values, option_string=None):
        from . import __version__

        parser._print_message(f"snapcorr {__version__}\n", sys.stdout)
        parser.exit()


class _Parser(argparse.ArgumentParser):
    """Usage errors as one line, like every other error, with where to read more."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser():
    parser = _Parser(
        prog="snapcorr",
        description="Wavelength correction for spectral cameras with thin-film "
        "Fabry-Perot filters (Goossens et al. 2019).",
        epilog="a session (snapcorr COMMAND --help shows each command's options and "
        "examples):\n" + textwrap.indent(textwrap.dedent(WORKFLOW).strip("\n"), "  "),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action=_Version, nargs=0,
                        help="show the version number and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    def command(name, help_):
        return sub.add_parser(name, help=help_, description=help_, epilog=_examples(name),
                              formatter_class=argparse.RawDescriptionHelpFormatter)

    for add in (_add_demo, _add_sensor, _add_flatfield, _add_stream, _add_calibrate,
                _add_pupil, _add_correct, _add_shift, _add_budget):
        add(command)
    return parser


def _message(err):
    """The exception as one line, in command-line terms."""
    message = " ".join(str(err).split())  # libraries' messages may span lines
    for term, cli in _CLI_TERMS.items():
        message = message.replace(term, cli)
    return message


def _negative_pairs(argv):
    """``--pack-range -0.5,3.5`` as ``--pack-range=-0.5,3.5``: argparse takes a value that
    starts with ``-`` and is not a plain number for an option, and the default range starts
    with one."""
    out, rest = [], iter(argv)
    for arg in rest:
        if arg == "--pack-range":
            value = next(rest, None)
            if value is not None and value.startswith("-") and not value.startswith("--"):
                out.append(f"--pack-range={value}")
                continue
            out.extend([arg] if value is None else [arg, value])
            continue
        out.append(arg)
    return out


def main(argv=None):
    from ._io import cleanup_on_signals

    parser = build_parser()
    argv = _negative_pairs(sys.argv[1:] if argv is None else list(argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # usage errors and --help: argparse has printed them
        return exit_.code
    if not getattr(args, "command", None):
        parser.print_help()
        return 0
    global _SHOW_PROGRESS
    _SHOW_PROGRESS = (False if getattr(args, "quiet", False) else
                      True if getattr(args, "progress", False) else None)
    try:
        with cleanup_on_signals(), warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.showwarning = _one_line_warning
            _center_option(args)
            return args.func(args)
    except (ValueError, TypeError, OverflowError, OSError, KeyError) as err:
        print(f"snapcorr {args.command}: error: {_message(err)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        # Libraries interrupted mid-write (h5netcdf, zarr's threads) may fail again when their
        # half-closed objects are collected; Python would print those as "Exception ignored"
        # tracebacks. The outputs are already removed: say it once, quietly.
        import signal

        # finishing: a second Ctrl-C waits (for the command line; a caller of main(argv) in a
        # Python session gets its handlers back)
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        hook, sys.unraisablehook = sys.unraisablehook, _quiet_unraisable
        print(f"snapcorr {args.command}: interrupted; unfinished outputs were removed",
              file=sys.stderr)
        if argv is not None:
            signal.signal(signal.SIGINT, previous)
            sys.unraisablehook = hook
        return 130
    finally:
        _SHOW_PROGRESS = None


def _quiet_unraisable(unraisable):
    """Drop errors raised while collecting objects left behind by an interruption."""


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"snapcorr: warning: {_message(message)}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
