"""``snapcorr flatfield``: (DN - dark) / (white - dark) (Goossens Eq. 29), of a cube or a
raw mosaic frame (then demosaicked with ``--demosaic``)."""

from __future__ import annotations

import sys

from ._errors import name_references
from ._frames import (
    _check_phase,
    _default_saturation,
    _flatfield_demosaic,
    _read,
)
from ._options import (
    DTYPE_HELP,
    ORIGIN_HELP,
    OVERWRITE_HELP,
    SENSOR_HELP,
    STORAGE_CHOICES,
    _add_output_options,
    _add_progress_options,
    _check_storage_option,
    _origin_arg,
    _positive,
    _sensor,
    add_command,
)
from ._output import RAW_COPIES, _check_outputs, _quicklook, _stored_type, _write_result
from ._progress import _StageBar
from ._types import _path

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = "flat-field a cube: (DN - dark) / (white - dark) (Eq. 29)"

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
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
    """


def add_parser(subparsers):
    p = add_command(subparsers, "flatfield", HELP, EXAMPLES)
    p.add_argument("raw", type=_path, help="the cube to correct (.hdr, .tif (one band per page "
                   "or channel), .exr, .nc, .zarr, .npy), or a raw 2-D mosaic frame with a "
                   "mosaic --sensor")
    p.add_argument("--dark", type=_path, action="append", required=True,
                   help="dark frame (repeat to average several)")
    p.add_argument("--white", type=_path, action="append", required=True,
                   help="white reference (repeat to average several; a strip of fewer rows "
                   "than the cube is broadcast along the scan axis)")
    p.add_argument("--filter-white", type=_path, default=None,
                   help="the white target seen through a filter: adds the filter's "
                   "transmittance (Goossens Sec. 3.1) to the output")
    p.add_argument("--out", type=_path, required=True, help="result, .nc or .zarr")
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
    p.add_argument("--plot", type=_path, default=None, metavar="PNG",
                   help="quick look: a band image, the mask and a few pixels' spectra")
    _add_output_options(p, input_name="the raw data (raw, filter_white_raw)")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    _add_progress_options(p)
    p.set_defaults(func=run)


def run(args):
    from ..cube import flatfield
    from ..cube.flatfield import check_masked

    inputs = [p for p in (args.raw, *args.dark, *args.white, args.filter_white) if p]
    _check_outputs({"--out": args.out, "--plot": args.plot}, inputs, args.overwrite,
                   [(".nc", ".zarr"), (".png",)])
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
    snapshot = sensor is not None and sensor.layout == "mosaic"
    said = _default_saturation(args, sensor, whites)
    try:  # the library checks every reference frame against the cube; its words, our options
        ds = flatfield(raw, darks, whites, saturation=args.saturation, dtype=args.dtype,
                       snapshot=snapshot)
    except ValueError as err:
        raise ValueError(name_references(str(err), {"dark": args.dark, "white": args.white})) \
            from None
    if args.filter_white:
        fw = read(args.filter_white)
        if fw.shape != raw.shape:
            sizes = [" x ".join(map(str, c.shape)) for c in (fw, raw)]
            raise ValueError(f"--filter-white {args.filter_white} is {sizes[0]} but {args.raw} "
                             f"is {sizes[1]}: the white seen through the filter is a cube of "
                             "the same size and place")
        tr = flatfield(fw, darks, whites, saturation=args.saturation, name="transmittance",
                       dtype=args.dtype, snapshot=snapshot)
        from ..pipeline import with_transmittance

        with_transmittance(ds, tr, args.filter_white)
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
    if said:
        print(said, file=sys.stderr)
    _quicklook(args, "plot_flatfield", ds)
    return 0

