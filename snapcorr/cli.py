"""Command-line interface: a thin shell around the library.

Every expected failure becomes one line on stderr and a non-zero exit status.
"""

from __future__ import annotations

import argparse
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np

from . import __version__

EXAMPLES = textwrap.dedent(
    """
    examples:
      snapcorr demo                       run the optics on the bundled 16 mm lens
      snapcorr flatfield scene.hdr --dark dark.hdr --white white.hdr --out scene_ff.nc
                                          flat-field a cube (Goossens Eq. 29)
      snapcorr demo --out /tmp/demo       ... writing the figures elsewhere
      snapcorr shift --f-number 1.4 --cra 0 10 20
                                          mean shift of 700 nm filters behind the bundled lens
      snapcorr shift --lens my_lens.toml --f-number 2.8 --cra 15 --cwl-nm 850 --n-eff 1.9
    """
)


def _lens(value):
    from .data import lens_path
    from .optics import Lens

    path = Path(value)
    if path.suffix == ".toml" or path.exists():
        return Lens.load(path)
    return Lens.load(lens_path(value))


def _cmd_demo(args):
    from .demo import run_demo

    run_demo(args.out)
    return 0


def _cmd_flatfield(args):
    from .cube import Sensor, flatfield, read_cube
    from .cube.io import write_dataset

    inputs = [args.raw, *args.dark, *args.white]
    if args.filter_white is not None:
        inputs.append(args.filter_white)
    out = Path(args.out)
    # Checked again by write_dataset, but here before any (possibly long) reading.
    for src in inputs:
        if Path(src).resolve() == out.resolve():
            raise ValueError(f"output {out} is also an input; choose another output path")
    if out.exists() and not args.overwrite:
        raise FileExistsError(f"{out} exists; choose another name or pass --overwrite")
    if out.suffix.lower() not in (".nc", ".zarr"):
        raise ValueError(f"--out must end in .nc or .zarr, got {out.name}")
    wl = Sensor.load(args.sensor).cwl_nm if args.sensor else None

    def read(path):  # chunked: cubes larger than memory stream through dask
        return read_cube(path, wavelength_nm=wl, chunks={"y": 512})

    raw = read(args.raw)
    darks = [read(p) for p in args.dark]
    whites = [read(p) for p in args.white]
    for label, cubes in (("dark", darks), ("white", whites)):
        for c, p in zip(cubes, args.dark if label == "dark" else args.white, strict=True):
            if c.sizes["band"] != raw.sizes["band"] or c.sizes["x"] != raw.sizes["x"]:
                raise ValueError(f"{p} is {c.shape[0]} x {c.shape[1]} x {c.shape[2]} but "
                                 f"{args.raw} is {raw.shape[0]} x {raw.shape[1]} x "
                                 f"{raw.shape[2]}: x and band must match")
    ds = flatfield(raw, darks, whites, saturation=args.saturation)
    if args.filter_white:
        tr = flatfield(read(args.filter_white), darks, whites, saturation=args.saturation,
                       name="transmittance")
        ds["transmittance"] = tr["transmittance"]
        ds["filter_white_raw"] = tr["raw"]
        ds["transmittance_mask"] = tr["mask"]
    ds.attrs.update({"raw_file": str(args.raw), "dark_files": ", ".join(map(str, args.dark)),
                     "white_files": ", ".join(map(str, args.white))})
    if args.filter_white:
        ds.attrs["filter_white_file"] = str(args.filter_white)
    from dask.diagnostics import ProgressBar

    # A progress bar on stderr for work that takes over a second (the inputs stream by blocks).
    with ProgressBar(minimum=1.0, out=sys.stderr):
        n_masked, total = int(ds["n_masked"]), int(ds["mask"].size)
        write_dataset(ds, out, overwrite=args.overwrite, inputs=inputs)
    print(f"wrote {out}: reflectance of {args.raw} ({raw.shape[0]} x {raw.shape[1]} x "
          f"{raw.shape[2]}), {len(darks)} dark and {len(whites)} white frame(s) averaged; "
          f"{n_masked} of {total} values masked ({100 * n_masked / total:.2f} %)")
    return 0


def _cmd_shift(args):
    from .optics import mean_shift, select_method

    lens = _lens(args.lens)
    cra = np.asarray(args.cra, float)
    shift = mean_shift(
        args.cwl_nm,
        args.n_eff,
        args.f_number,
        cra,
        lens,
        method=args.method,
        tolerance_nm=args.tolerance_nm,
    )
    if args.method == "auto":
        used = select_method(
            args.n_eff,
            args.f_number,
            cra,
            lens,
            cwl_nm=args.cwl_nm,
            tolerance_nm=args.tolerance_nm,
        )
    else:
        used = np.full(cra.shape, args.method)
    print(f"# {lens.name}, f/{args.f_number:g}, cwl {args.cwl_nm:g} nm, n_eff {args.n_eff:g}")
    print(f"{'cra_deg':>8} {'shift_nm':>10} {'corrected_nm':>13}  method")
    for c, s, m in zip(cra, np.atleast_1d(shift), np.atleast_1d(used), strict=True):
        print(f"{c:>8.3f} {s:>10.4f} {args.cwl_nm + s:>13.4f}  {m}")
    return 0


def build_parser():
    parser = argparse.ArgumentParser(
        prog="snapcorr",
        description="Wavelength correction for spectral cameras with thin-film "
        "Fabry-Perot filters (Goossens et al. 2019).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"snapcorr {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    def command(name, help_):
        return sub.add_parser(name, help=help_, epilog=EXAMPLES,
                              formatter_class=argparse.RawDescriptionHelpFormatter)

    demo = command("demo", "run the main job on the bundled default lens and write figures")
    demo.add_argument(
        "--out", default="snapcorr-demo", type=Path, help="output folder (default: %(default)s)"
    )
    demo.set_defaults(func=_cmd_demo)

    ff = command("flatfield", "flat-field a cube: (DN - dark) / (white - dark) (Eq. 29)")
    ff.add_argument("raw", type=Path, help="the cube to correct (.hdr, .tif, .exr, .nc, "
                    ".zarr, .npy)")
    ff.add_argument("--dark", type=Path, action="append", required=True,
                    help="dark frame (repeat to average several)")
    ff.add_argument("--white", type=Path, action="append", required=True,
                    help="white reference (repeat to average several; a strip narrower than "
                    "the cube is broadcast along the scan axis)")
    ff.add_argument("--filter-white", type=Path, default=None,
                    help="the white target seen through a filter: adds the filter's "
                    "transmittance (Goossens Sec. 3.1) to the output")
    ff.add_argument("--out", type=Path, required=True, help="result, .nc or .zarr")
    ff.add_argument("--sensor", type=Path, default=None,
                    help="sensor description giving the wavelengths of files that have none")
    ff.add_argument("--saturation", type=float, default=None,
                    help="digital number at or above which a pixel is saturated")
    ff.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    ff.set_defaults(func=_cmd_flatfield)

    shift = command("shift", "mean central-wavelength shift at chief-ray angles (Eq. 22-23)")
    shift.add_argument(
        "--lens",
        default="edmund_optics_16mm",
        help="lens profile (.toml) or a bundled lens name (default: %(default)s)",
    )
    shift.add_argument("--f-number", type=float, required=True)
    shift.add_argument("--cra", type=float, nargs="+", required=True, metavar="DEG")
    shift.add_argument("--cwl-nm", type=float, default=700.0)
    shift.add_argument("--n-eff", type=float, default=1.7)
    from .optics import METHODS

    shift.add_argument("--method", default="auto", choices=list(METHODS))
    shift.add_argument("--tolerance-nm", type=float, default=0.001)
    shift.set_defaults(func=_cmd_shift)
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 0
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.showwarning = _one_line_warning
            return args.func(args)
    except (ValueError, TypeError, OSError) as err:
        message = " ".join(str(err).split())  # libraries' messages may span lines
        print(f"snapcorr {args.command}: error: {message}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("snapcorr: interrupted", file=sys.stderr)
        return 130


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"snapcorr: warning: {message}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
