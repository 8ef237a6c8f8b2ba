"""``snapcorr calibrate``: a lens profile (vignetting circles P, h) from flat fields at several
f-numbers (Goossens Sec. 2.7, 3.2), with x fitted to a spectral target as well when asked."""

from __future__ import annotations

import sys

from .._names import CALIBRATION_METHODS
from ._flats import (
    _band_gains_said,
    _check_crop,
    _check_flat_phase,
    _flat_sensor,
    _flats_provenance,
    _mosaic_of,
    _no_dark_note,
    _pitch_option,
    _read_flats,
)
from ._options import (
    OVERWRITE_HELP,
    _add_center,
    _add_progress_options,
    _distance_mm,
    _flat_arg,
    _lens,
    _magnification,
    _one_per_f_number,
    _positive,
    _pupil_magnification,
    _sensor,
    add_command,
)
from ._output import _check_outputs
from ._progress import _StepBar
from ._targets import (
    TARGET_TOLERANCE_HELP,
    _add_pupil_option,
    _add_target_fit_options,
    _check_target_outputs,
    _fitted_sensor,
    _say_precision,
    _target_cubes,
    _target_spectrum,
    _target_tolerance,
)
from ._types import _path

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = ("lens profile (vignetting circles P, h) from flat fields at several f-numbers (Goossens "
        "Sec. 2.7, 3.2)")

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
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
    """


def add_parser(subparsers):
    p = add_command(subparsers, "calibrate", HELP, EXAMPLES)
    p.add_argument("--flat", type=_flat_arg, action="append", required=True,
                   metavar="F_NUMBER=PATH",
                   help="flat field at an f-number (.npy, .tif, .exr, ENVI .hdr, .nc, .zarr; "
                   "several bands or TIFF pages in a file are averaged); repeat for each "
                   "f-number")
    x = p.add_mutually_exclusive_group()
    x.add_argument("--exit-pupil-mm", type=_distance_mm, metavar="X",
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
                   "divided out, pixels outside its filter area left out; of another layout (a "
                   "Snapscan camera): it gives the pixel pitch and the size a crop lies in")
    _add_target_fit_options(t, "with --target-cube: ", (
        "sensor row and column of the flats' first pixel, for flats that are a crop (raw "
        "mosaic frames or a Snapscan camera's region of interest), recorded in the profile "
        "so the optical centre is placed on the sensor; with --target-cube, of the cubes' "
        "too: flats and cubes must be of the same pixels, and a cube that records its own "
        "must agree"))
    t.add_argument("--target-tolerance-nm", type=_positive, default=None, metavar="NM",
                   help="with --target-cube: " + TARGET_TOLERANCE_HELP)
    _add_pupil_option(t)
    p.add_argument("--pixel-pitch-um", type=_positive, default=None, metavar="UM",
                   help="pixel pitch of the flats, micrometres (default: the --sensor's)")
    p.add_argument("--magnification", type=_magnification, default=None,
                   help="linear magnification m (default: the --lens value, else 0, "
                   "focused at infinity, assumed: the flats cannot tell it, and the errors "
                   "then include m / m_P over [0, 0.1]; give 0 if focused at infinity)")
    p.add_argument("--pupil-magnification", type=_pupil_magnification, default=None,
                   help="pupil magnification m_P (default: the --lens value, else 1, "
                   "assumed; with --magnification > 0 the errors then include m_P over "
                   "[0.5, 2])")
    p.add_argument("--dark", type=_path, default=None, help="dark frame, same size")
    _add_center(p, "optical centre in sensor pixels, as pupil and correct take it (for flats "
                "that are a crop: its first pixel at --sensor-origin-px; default: found from "
                "the flats)")
    p.add_argument("--out", type=_path, required=True, help="lens profile to write (.toml)")
    p.add_argument("--plot", type=_path, default=None, metavar="PNG",
                   help="draw the profiles, onsets and model (the paper's Fig. 8)")
    p.add_argument("--method", default="auto", choices=list(CALIBRATION_METHODS),
                   help="estimator of P and h (default: %(default)s: the joint fit unless "
                   "the paper's onsets predict flats left out of the fit better)")
    p.add_argument("--vignetting-distance-mm", type=_distance_mm, default=None, metavar="H",
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
    p.set_defaults(func=run)


def run(args):
    import dataclasses

    from ..calibrate.lens.calibration import calibrate_lens

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
    _check_outputs({"--out": args.out, "--plot": args.plot}, inputs, args.overwrite,
                   [(".toml",), (".png",)])
    given = _lens(args.lens) if args.lens else None
    _pitch_option(args, sensor)
    mosaic = _mosaic_of(sensor)
    flats, bands, sat, dark = _read_flats(args, mosaic)
    _check_crop(args, sensor, flats)
    _check_flat_phase(args, mosaic, flats, sat, dark, args.sensor_origin_px)
    with _StepBar("calibrating") as bar:
        res = calibrate_lens(
            flats, exit_pupil_mm=args.exit_pupil_mm, lens=given,
            exit_pupil_from=str(args.lens) if given is not None else None,
            pixel_pitch_um=args.pixel_pitch_um, magnification=args.magnification,
            pupil_magnification=args.pupil_magnification,
            dark=dark, center_rc=_flats_center(args, args.sensor_origin_px), saturation=sat,
            vignetting_distance_mm=args.vignetting_distance_mm, method=args.method,
            name=args.name or args.out.stem, inputs={f: str(p) for f, p in args.flat},
            tolerance_nm=args.tolerance_nm, max_circles=args.max_circles, progress=bar.step,
            pupil_radiance=args.pupil, sensor=mosaic, sensor_origin_px=args.sensor_origin_px)
    cal = _flats_provenance(dict(res.lens.calibration), args, bands)
    _band_gains_said(res, cal, args)
    lens = dataclasses.replace(res.lens, calibration=cal)
    lens.save(args.out, overwrite=args.overwrite)
    if args.plot:
        res.save_plot(args.plot)
    print(res.summary())
    _no_dark_note(args)
    print(f"wrote {args.out}" + (f" and {args.plot}" if args.plot else ""))
    return 0


_TARGET_OPTIONS = ("fit_n_eff", "sensor_out", "target_spectrum", "target_tolerance_nm")


def _no_target_options(args):
    """Options that only mean something with --target-cube are refused without it."""
    given = [o for o in _TARGET_OPTIONS if getattr(args, o) not in (None, False)]
    if given:
        raise ValueError(f"--{given[0].replace('_', '-')} goes with --target-cube (fitting x "
                         "from a spectral target); leave it out or add the target's cubes")


def _calibrate_with_target(args):
    """``calibrate --target-cube``: flats and a target's cubes give x, n_eff, P, h and the
    centre in one run (:func:`snapcorr.calibrate.calibrate_with_target`)."""
    import dataclasses

    from ..calibrate import FeaturelessTargetError, calibrate_with_target

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
    cubes, origin = _target_cubes(args, sensor, next(iter(flats.values())).shape)
    _check_flat_phase(args, sensor, flats, sat, dark, origin)
    for f, cube in cubes.items():
        print(f"read target f/{f:g}: {seen[f]} ({cube.sizes['y']} x {cube.sizes['x']} x "
              f"{cube.sizes['band']})", file=sys.stderr)
    try:
        with _StepBar("calibrating the flats, fitting x to the target") as bar:
            res = calibrate_with_target(
                flats, cubes, sensor, pixel_pitch_um=args.pixel_pitch_um,
                fit_n_eff=args.fit_n_eff, magnification=args.magnification,
                pupil_magnification=args.pupil_magnification,
                dark=dark, center_rc=_flats_center(args, origin), saturation=sat,
                method=args.method,
                max_circles=args.max_circles, tolerance_nm=args.tolerance_nm,
                target_spectrum=spectrum, sensor_origin_px=origin,
                name=args.name or args.out.stem, inputs={f: str(p) for f, p in args.flat},
                target_inputs=seen, progress=bar.step, pupil_radiance=args.pupil or "auto",
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



def _flats_center(args, origin):
    """``--center`` (sensor pixels, as ``pupil`` and ``correct`` take it) in the flats' pixels:
    less the crop's ``origin`` (None: the flats are the whole sensor)."""
    if args.center_rc is None or origin is None:
        return args.center_rc
    return (args.center_rc[0] - origin[0], args.center_rc[1] - origin[1])
