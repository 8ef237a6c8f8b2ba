"""``snapcorr sensor``: what a sensor file holds, and where a crop sits on the mosaic's tile
grid."""

from __future__ import annotations

from ._frames import _read_frame_checked
from ._options import OVERWRITE_HELP, _origin_arg, _sensor, add_command
from ._output import _check_outputs, _quicklook
from ._types import _path

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = "what a sensor file holds: bands, layout, active area, filter responses, correction matrices"

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
      snapcorr sensor CMV2K-SSM5x5-600_875-5.5.9.2.xml --plot filters.png
                                          what a vendor calibration file holds, and its curves
      snapcorr sensor camera.xml --toml my_camera.toml
                                          ... and a sensor TOML naming it, to add n_eff
      snapcorr sensor camera.xml --phase-from white.npy --dark dark.npy
                                          where a crop's first pixel sits on the mosaic's
                                          tile grid, read from its white reference
      snapcorr sensor camera.xml --phase-from white.npy --sensor-origin-px 512,768
                                          ... and whether the stated origin agrees
    """


def add_parser(subparsers):
    p = add_command(subparsers, "sensor", HELP, EXAMPLES)
    p.add_argument("file", help="a vendor calibration file (.xml), a sensor TOML or a bundled "
                   "sensor's name")
    p.add_argument("--toml", type=_path, default=None, metavar="OUT.toml",
                   help="write the equivalent sensor TOML (naming the vendor file, where there "
                   "is one), to add n_eff or the pixel pitch")
    p.add_argument("--plot", type=_path, default=None, metavar="PNG",
                   help="draw the bands' responses and what each correction matrix makes of "
                   "them")
    p.add_argument("--phase-from", type=_path, default=None, metavar="WHITE",
                   help="a raw white frame of a mosaic sensor with measured responses: print "
                   "where its first pixel sits on the tile grid (the band gains under a smooth "
                   "lamp are the tile's fingerprint)")
    p.add_argument("--dark", type=_path, default=None, metavar="DARK",
                   help="with --phase-from: a dark frame, subtracted from the white")
    p.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                   help="with --phase-from: the stated sensor row and column of the white's "
                   "first pixel, checked against what the white shows (a whole-sensor frame "
                   "needs none); exit status 1 where it disagrees, or no phase fits")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.set_defaults(func=run)


def run(args):
    inputs = [args.file]
    _check_outputs({"--toml": args.toml, "--plot": args.plot}, inputs, args.overwrite,
                   [(".toml",), (".png",)])
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
    from ..cube.phase import FLIP_ADVICE, flip_shown, mosaic_phase

    if args.toml or args.plot:
        raise ValueError("--phase-from reads a white frame: give --toml and --plot in a run "
                         "of their own")
    if sensor.layout != "mosaic" or sensor.responses is None:
        what = "not a mosaic" if sensor.layout != "mosaic" else "a mosaic without them"
        raise ValueError(f"--phase-from reads a white through a mosaic's measured responses: "
                         f"{args.file} is {what} (a vendor calibration file gives them)")
    white = _read_frame_checked(args.phase_from, sensor, "--phase-from")
    dark = (None if args.dark is None else
            _read_frame_checked(args.dark, sensor, "--dark", white.shape))
    try:
        found = mosaic_phase(white, sensor, dark=dark, sensor_origin_px=args.sensor_origin_px)
        flipped = flip_shown(white, sensor, dark=dark, sensor_origin_px=args.sensor_origin_px,
                             found=found)
    except ValueError as err:
        raise ValueError(f"--phase-from {args.phase_from}: {err}") from None
    print(f"{args.phase_from} ({white.shape[0]} x {white.shape[1]} px): {found.describe()}")
    if flipped is not None:
        raise ValueError(f"--phase-from {args.phase_from} {flipped}: {FLIP_ADVICE}")
    if found.agrees is not None:
        stated = ("the whole-sensor frame" if args.sensor_origin_px is None else
                  "--sensor-origin-px {},{}".format(*args.sensor_origin_px))
        print(f"{stated}: {'agrees' if found.agrees else 'DISAGREES'}"
              + ("" if found.agrees else
                 " (an origin that agrees: {},{})".format(
                     *found.origin_px(args.sensor_origin_px or (0, 0)))))
    return 0 if found.phase_px is not None and found.agrees is not False else 1

