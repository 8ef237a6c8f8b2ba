"""``snapcorr stream``: raw mosaic frames flat-fielded, demosaicked and corrected, frame by
frame."""

from __future__ import annotations

import sys

from ._frames import _default_saturation, _read_frame_checked
from ._options import (
    DTYPE_HELP,
    ORIGIN_HELP,
    OVERWRITE_HELP,
    SENSOR_HELP,
    STORAGE_CHOICES,
    _add_center,
    _add_output_options,
    _add_progress_options,
    _add_virtual_options,
    _check_storage_option,
    _check_virtual_options,
    _f_number,
    _lens,
    _origin_arg,
    _positive,
    _sensor,
    add_command,
)
from ._output import RAW_COPIES, _check_outputs, _masked_in, _print_virtual, _write_result
from ._progress import _StageBar
from ._types import _path

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = "a stream of raw mosaic frames: flat-field, demosaic and correct each frame"

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
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
    """


def add_parser(subparsers):
    p = add_command(subparsers, "stream", HELP, EXAMPLES)
    p.add_argument("frames", type=_path, help="frames (frame, y, x): a .zarr or .nc holding one "
                   "3-D variable, a 3-D .npy, a multi-page .tif (a frame per page) or a folder "
                   "of frame files (.npy, .tif, .exr, .hdr; in the order of their names, "
                   "numbers in them read as numbers: t0.25, t0.5, t1)")
    p.add_argument("--dark", type=_path, action="append", required=True,
                   help="dark frame (repeat to average several)")
    p.add_argument("--white", type=_path, action="append", required=True,
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
    p.add_argument("--f-number", type=_f_number, default=None, metavar="F",
                   help="the f-number the frames were taken at")
    _add_center(p, "with --lens: optical centre in sensor pixels (default: the lens "
                   "profile's, converted to this pixel pitch, else the sensor's centre)")
    p.add_argument("--resample", action="store_true",
                   help="also every frame's spectra on the nominal wavelengths")
    _add_virtual_options(p)
    p.add_argument("--saturation", type=_positive, default=None, metavar="DN",
                   help="digital number at or above which a pixel is saturated (default: the "
                   "sensor's largest code, from its bit_depth, where it gives one)")
    p.add_argument("--dtype", default="float32", choices=["float64", *STORAGE_CHOICES],
                   help=DTYPE_HELP + "; float64 computes and stores in double precision "
                   "(default: %(default)s)")
    p.add_argument("--out", type=_path, required=True, help="result, .zarr (or .nc)")
    _add_output_options(p, input_name="the raw frames (raw)", derived=True)
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    _add_progress_options(p)
    p.set_defaults(func=run)


def run(args):
    from ..cube import read_frames
    from ..pipeline import process_stream

    inputs = [args.frames, *args.dark, *args.white]
    _check_outputs({"--out": args.out}, inputs, args.overwrite, [(".zarr", ".nc")])
    _check_storage_option(args)
    sensor = _sensor(args.sensor)
    if sensor.layout != "mosaic":
        raise ValueError(f"stream takes raw mosaic frames: --sensor {args.sensor} is not a "
                         f"mosaic (layout {sensor.layout!r})")
    if (args.lens is None) != (args.f_number is None):
        raise ValueError("correcting a stream needs both --lens and --f-number")
    if args.center_rc is not None and args.lens is None:
        raise ValueError("--center places the lens's optical centre: give --lens and "
                         "--f-number too")
    if args.resample and args.lens is None:
        raise ValueError("--resample needs --lens and --f-number")
    if args.store_derived and args.lens is None:  # nothing derived is stored without a lens
        raise ValueError("--store-derived stores the corrected wavelengths: it needs --lens "
                         "and --f-number")
    _check_virtual_options(args, sensor)
    if args.virtual_bands is not None and args.lens is None:
        raise ValueError("--virtual-bands needs --lens and --f-number (the stream is corrected "
                         "first)")
    lens = _lens(args.lens) if args.lens is not None else None
    frames = read_frames(args.frames)
    darks = [_read_frame_checked(p, sensor, "--dark", frames.shape[1:]) for p in args.dark]
    whites = [_read_frame_checked(p, sensor, "--white", frames.shape[1:]) for p in args.white]
    said = _default_saturation(args, sensor, whites)
    ds = process_stream(frames, darks, whites, sensor, demosaic_method=args.demosaic, lens=lens,
                        f_number=args.f_number, sensor_origin_px=args.sensor_origin_px,
                        center_rc=args.center_rc,
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
    if said:
        print(said, file=sys.stderr)
    if n_masked == cube.size:  # flatfield refuses this before its one pass; a stream would
        from ..cube.flatfield import masked_causes  # need two, and keeps what it wrote

        raise ValueError(f"every value of the {cube.sizes['frame']} frames is masked: "
                         f"{masked_causes(args.saturation, '--saturation')} ({args.out} "
                         "holds them, with the raw frames)")
    return 0

