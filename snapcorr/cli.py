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
    r"""
    examples:
      snapcorr demo                       the paper's lens and experiment, simulated end to end
      snapcorr flatfield scene.hdr --dark dark.hdr --white white.hdr --out scene_ff.nc
                                          flat-field a cube (Goossens Eq. 29)
      snapcorr demo --out /tmp/demo       ... writing the figures elsewhere
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor sensor.toml --f-number 1.4 \
          --out scene_corrected.nc --resample
                                          per-pixel corrected wavelengths (Eq. 23)
      snapcorr calibrate --flat 1.4=f1.4.tif --flat 2=f2.tif --flat 2.8=f2.8.tif \
          --flat 4=f4.tif --flat 8=f8.tif --exit-pupil-mm 21 --pixel-pitch-um 5.5 \
          --magnification 0.06 --pupil-magnification 1.3 --dark dark.tif \
          --out my_lens.toml --plot my_lens.png
                                          lens profile from integrating-sphere flats
      snapcorr shift --f-number 1.4 --cra 0 10 20
                                          mean shift of 700 nm filters behind the bundled lens
      snapcorr shift --lens my_lens.toml --f-number 2.8 --cra 15 --cwl-nm 850 --n-eff 1.9
      snapcorr budget --sensor snapscan_vnir --lens edmund_optics_16mm --f-number 1.4 \
          --source solar --tolerance-pct 0.5 --plot budget.png
                                          which bands and pixels need correcting, and how
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor sensor.toml --f-number 4 \
          --source cube --tolerance-pct 0.5 --out scene_corrected.nc
                                          ... with the model the scene's own spectrum needs
    """
)


def _bundled_or_file(value, load, bundled_path):
    """A profile from a .toml path, or a bundled one by name (``edmund_optics_16mm``)."""
    path = Path(value)
    if path.suffix == ".toml" or path.exists():
        return load(path)
    return load(bundled_path(value))


def _lens(value):
    from .data import lens_path
    from .optics import Lens

    return _bundled_or_file(value, Lens.load, lens_path)


def _sensor(value):
    from .cube import Sensor
    from .data import sensor_path

    return _bundled_or_file(value, Sensor.load, sensor_path)


def _cmd_budget(args):
    import math

    from .budget import parse_source, scene_budget, tolerance_ranges
    from .correct.geometry import cube_cra_deg

    if args.plot is not None:
        if args.plot.suffix.lower() != ".png":
            raise ValueError(f"--plot must name a .png file, got {args.plot}")
        if args.plot.exists() and not args.overwrite:
            raise ValueError(f"{args.plot} exists; use --overwrite to replace it")
    lens = _lens(args.lens)
    sensor = _sensor(args.sensor)
    cube = None
    if args.cube is not None:
        from .cube import read_cube

        cube = read_cube(args.cube, wavelength_nm=sensor.cwl_nm, chunks={})
    if cube is not None and cube.sizes["band"] != sensor.n_bands:
        raise ValueError(f"the cube has {cube.sizes['band']} bands, the sensor {sensor.name!r} "
                         f"{sensor.n_bands}; use the sensor the cube was taken with")
    if cube is not None and not np.allclose(cube["wavelength"].values, sensor.cwl_nm,
                                            rtol=0, atol=0.05):
        raise ValueError(f"the cube's wavelengths differ from the sensor {sensor.name!r}'s; "
                         "use the matching sensor")
    source = parse_source(args.source, cube)
    if args.cra_max is not None:
        cra_max, field = args.cra_max, f"CRA up to {args.cra_max:g} deg (--cra-max)"
    elif cube is not None:
        cra_max = float(cube_cra_deg(cube, lens, sensor, args.center_px)[0].max())
        field = f"the cube's pixels, CRA up to {cra_max:.2f} deg"
    elif sensor.field_radius_mm is not None:
        cra_max = math.degrees(math.atan(sensor.field_radius_mm / lens.exit_pupil_mm))
        field = (f"the sensor's {sensor.size_px[0]} x {sensor.size_px[1]} px field, CRA up "
                 f"to {cra_max:.2f} deg at its corners")
    else:
        raise ValueError(f"the sensor {sensor.name!r} has no size_px: give --cra-max DEG or "
                         "--cube CUBE for the field to cover")
    b = scene_budget(sensor, lens, args.f_number, source, cra_max_deg=cra_max,
                     profile=args.profile, tolerance_pct=args.tolerance_pct)
    model, reason = b.recommend()
    ranges = []
    for c, w, n in zip(sensor.cwl_nm, sensor.fwhm_nm, sensor.n_eff, strict=True):
        try:
            ranges += tolerance_ranges(source, [c], [w], n_eff=n, profile=args.profile)
        except ValueError:  # the source ends within a shift of 5 nm of this band
            ranges.append(["n/a", "n/a"])

    def fmt(r):
        if isinstance(r, str):
            return r
        return "NA" if r is None else f"{r[0]:.1f}-{r[1]:.1f}"

    print(f"scene budget: {source.name}; {lens.name} at f/{args.f_number:g}; {sensor.name} "
          f"({sensor.n_bands} bands, {args.profile} filters); {field}")
    print("worst |signal error| over the field, percent, left by each model; last columns: "
          "centre positions where +-1 nm stays < 0.5 % and +-5 nm < 2 % (Flittner & Slater)")
    table = b.table().splitlines()
    print(f"{table[0]}  {'+-1nm<0.5%':>13} {'+-5nm<2%':>13}")
    for line, rr in zip(table[1:-1], ranges, strict=True):
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
    if args.plot is not None:
        b.plot(args.plot, overwrite=args.overwrite,
               inputs=[args.sensor, args.lens, args.cube, args.source])
        print(f"wrote {args.plot}")
    return 0


def _cmd_demo(args):
    from .demo import run_demo

    run_demo(args.out)
    return 0


def _dataset_output(out, inputs, overwrite):
    """The output path of a Dataset, checked before any (possibly long) reading.

    ``write_dataset`` checks again when it writes.
    """
    out = Path(out)
    for src in inputs:
        if Path(src).resolve() == out.resolve():
            raise ValueError(f"output {out} is also an input; choose another output path")
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out} exists; choose another name or pass --overwrite")
    if out.suffix.lower() not in (".nc", ".zarr"):
        raise ValueError(f"--out must end in .nc or .zarr, got {out.name}")
    return out


def _cmd_flatfield(args):
    from .cube import flatfield, read_cube
    from .cube.io import write_dataset

    inputs = [args.raw, *args.dark, *args.white]
    if args.filter_white is not None:
        inputs.append(args.filter_white)
    out = _dataset_output(args.out, inputs, args.overwrite)
    wl = _sensor(args.sensor).cwl_nm if args.sensor else None

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




def _cmd_correct(args):
    from .correct import correct_cube
    from .cube import read_cube, row_blocks
    from .cube.io import write_dataset

    inputs = [args.cube, args.lens, args.sensor]
    out = _dataset_output(args.out, inputs, args.overwrite)
    lens = _lens(args.lens)
    sensor = _sensor(args.sensor)
    # lazily, as stored, then in blocks of whole rows: memory stays bounded at any size
    cube = row_blocks(read_cube(args.cube, wavelength_nm=sensor.cwl_nm, chunks={}))
    if args.source is not None and args.method != "auto":
        raise ValueError("--source chooses the model: use it with --method auto")
    if args.tolerance_pct is not None and args.source is None:
        raise ValueError("--tolerance-pct applies to the scene budget: give --source too")
    ds = correct_cube(cube, lens, sensor, args.f_number, center_px=args.center_px,
                      method=args.method, tolerance_nm=args.tolerance_nm,
                      resample=args.resample, source=args.source,
                      tolerance_pct=0.5 if args.tolerance_pct is None else args.tolerance_pct)
    ds.attrs.update({"cube_file": str(args.cube), "lens_file": str(args.lens),
                     "sensor_file": str(args.sensor)})
    if args.scheduler:
        from distributed import Client

        try:
            client = Client(args.scheduler, timeout="10s")
        except OSError as err:
            raise ValueError(f"cannot reach the dask scheduler at {args.scheduler}: {err}") \
                from None
        with client:  # progress: the cluster's dashboard
            write_dataset(ds, out, overwrite=args.overwrite, inputs=inputs)
    else:
        from dask.diagnostics import ProgressBar

        with ProgressBar(minimum=1.0, out=sys.stderr):
            write_dataset(ds, out, overwrite=args.overwrite, inputs=inputs)
    print(f"wrote {out}: {cube.shape[0]} x {cube.shape[1]} x {cube.shape[2]} cube, f/"
          f"{args.f_number:g}, method {ds.attrs['method']} ({ds.attrs['method_reason']}); "
          f"CRA up to {ds.attrs['cra_max_deg']:.2f} deg, optical centre "
          f"{tuple(round(c, 1) for c in ds.attrs['optical_center_px'])} px "
          f"({ds.attrs['optical_center_source']})"
          + ("; resampled onto the nominal wavelengths" if args.resample else ""))
    return 0


def _flat_arg(value):
    """``F_NUMBER=PATH`` (F_NUMBER may be written 2.8, f2.8 or f/2.8)."""
    if "=" not in value:
        raise argparse.ArgumentTypeError(f"expected F_NUMBER=PATH, got {value!r}")
    f, path = value.split("=", 1)
    f = f.strip().lower().removeprefix("f").removeprefix("/")
    try:
        fv = float(f)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{value!r}: {f!r} is not an f-number") from None
    if not np.isfinite(fv) or fv <= 0:
        raise argparse.ArgumentTypeError(f"{value!r}: the f-number must be > 0")
    if not path:
        raise argparse.ArgumentTypeError(f"{value!r}: no file after '='")
    return fv, Path(path)


def _center_arg(value):
    try:
        cx, cy = (float(v) for v in value.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected CX,CY in pixels, got {value!r}") from None
    if not (np.isfinite(cx) and np.isfinite(cy)):
        raise argparse.ArgumentTypeError(f"the centre must be finite, got {value!r}")
    return cx, cy


def _cmd_calibrate(args):
    from .calibrate import calibrate_lens, read_flat

    out = Path(args.out)
    if out.suffix.lower() != ".toml":
        raise ValueError(f"--out {out}: a lens profile is a .toml file")
    seen = {}
    for f, path in args.flat:
        if f in seen:
            raise ValueError(f"f/{f:g} given twice ({seen[f]} and {path}); give one flat per "
                             "f-number")
        seen[f] = path
    inputs = [p for _, p in args.flat] + ([args.dark] if args.dark else [])
    outputs = [out] + ([Path(args.plot)] if args.plot else [])
    for o in outputs:
        if any(Path(i).resolve() == o.resolve() for i in inputs):
            raise ValueError(f"output {o} is also an input; choose another path")
        if o.exists() and not args.overwrite:
            raise ValueError(f"{o} exists; choose another path or pass --overwrite")
        if not o.parent.is_dir():
            raise ValueError(f"{o.parent} is not a folder; create it first")
    if args.plot and Path(args.plot).suffix.lower() != ".png":
        raise ValueError(f"--plot {args.plot}: the figure is written as .png")
    flats, bands, sat = {}, set(), {}
    for f, path in sorted(args.flat):
        image, info = read_flat(path)
        flats[f] = image
        bands.add(info["bands"])
        sat[f] = args.saturation if args.saturation is not None else info["saturation"]
        print(f"read f/{f:g}: {path} ({image.shape[1]} x {image.shape[0]}"
              + (f", mean of {info['bands']} bands" if info["bands"] > 1 else "") + ")",
              file=sys.stderr)
    dark = read_flat(args.dark)[0] if args.dark else None
    res = calibrate_lens(
        flats, exit_pupil_mm=args.exit_pupil_mm, pixel_pitch_um=args.pixel_pitch_um,
        magnification=args.magnification, pupil_magnification=args.pupil_magnification,
        dark=dark, center_px=args.center_px, saturation=sat,
        vignetting_distance_mm=args.vignetting_distance_mm, method=args.method,
        name=args.name or out.stem, inputs={f: str(p) for f, p in args.flat})
    lens = res.lens
    cal = dict(lens.calibration)
    cal["bands"] = ("mean of the bands in each file" if max(bands) > 1
                    else "single-band flats")
    if args.dark:
        cal["dark"] = str(args.dark)
    lens = type(lens)(lens.name, lens.exit_pupil_mm, lens.vignetting_radius_mm,
                      lens.vignetting_distance_mm, lens.magnification, lens.pupil_magnification,
                      calibration=cal)
    lens.save(out, overwrite=args.overwrite)
    if args.plot:
        res.save_plot(args.plot)
    print(res.summary())
    print(f"wrote {out}" + (f" and {args.plot}" if args.plot else ""))
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

    demo = command("demo", "the main job on a bundled default: calibrate the paper's lens, "
                   "correct a simulated cube, write figures")
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

    cal = command("calibrate", "lens profile (P, h) from flat fields at several f-numbers "
                  "(Goossens Sec. 2.7, 3.2)")
    cal.add_argument("--flat", type=_flat_arg, action="append", required=True,
                     metavar="F_NUMBER=PATH",
                     help="flat field at an f-number (.npy, .tif, .exr, ENVI .hdr, .nc, .zarr; "
                     "several bands in a file are averaged); repeat for each f-number")
    cal.add_argument("--exit-pupil-mm", type=float, required=True,
                     help="distance x from the sensor to the exit pupil")
    cal.add_argument("--pixel-pitch-um", type=float, required=True)
    cal.add_argument("--magnification", type=float, default=0.0,
                     help="linear magnification m (default 0: focused at infinity)")
    cal.add_argument("--pupil-magnification", type=float, default=1.0,
                     help="pupil magnification m_P (default 1)")
    cal.add_argument("--dark", type=Path, default=None, help="dark frame, same size")
    cal.add_argument("--center-px", type=_center_arg, default=None, metavar="CX,CY",
                     help="optical centre in pixels (default: found from the flats)")
    cal.add_argument("--out", type=Path, required=True, help="lens profile to write (.toml)")
    cal.add_argument("--plot", type=Path, default=None, metavar="PNG",
                     help="draw the profiles, onsets and model (the paper's Fig. 8)")
    from .calibrate import METHODS as CAL_METHODS

    cal.add_argument("--method", default="auto", choices=list(CAL_METHODS),
                     help="estimator of P and h (default: %(default)s: the joint fit unless "
                     "its area model misfits)")
    cal.add_argument("--vignetting-distance-mm", type=float, default=None, metavar="H",
                     help="h, when known (needed with a single f-number)")
    cal.add_argument("--saturation", type=float, default=None,
                     help="value at or above which a pixel is saturated (default: the "
                     "largest value of the file's integer type)")
    cal.add_argument("--name", default=None, help="lens name (default: the output's stem)")
    cal.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    cal.set_defaults(func=_cmd_calibrate)

    cor = command("correct", "corrected central wavelength of every pixel and band (Eq. 23)")
    cor.add_argument("cube", type=Path, help="the cube (.hdr, .tif, .exr, .nc, .zarr, .npy), "
                     "ideally flat-fielded")
    cor.add_argument("--lens", type=Path, required=True, help="lens profile (.toml)")
    cor.add_argument("--sensor", type=Path, required=True, help="sensor description (.toml)")
    cor.add_argument("--f-number", type=float, required=True)
    cor.add_argument("--out", type=Path, required=True, help="result, .nc or .zarr")
    cor.add_argument("--center-px", type=_center_arg, default=None, metavar="CX,CY",
                     help="optical centre in sensor pixels (default: the lens profile's, "
                     "else the image centre)")
    from .correct import METHODS as COR_METHODS

    cor.add_argument("--method", default="auto", choices=list(COR_METHODS),
                     help="shift model (default: %(default)s, the cheapest meeting the "
                     "tolerance)")
    cor.add_argument("--tolerance-nm", type=float, default=0.01)
    cor.add_argument("--source", default=None, metavar="SOURCE",
                     help="the scene's spectrum: solar, solar:astm-g173, "
                     "tungsten:TEMPERATURE_K, cube (the "
                     "cube's mean spectrum) or a two-column file; --method auto then takes "
                     "the cheapest model whose signal error stays below --tolerance-pct")
    cor.add_argument("--tolerance-pct", type=float, default=None,
                     help="radiometric tolerance with --source, percent (default: 0.5)")
    cor.add_argument("--resample", action="store_true",
                     help="also interpolate each spectrum onto the nominal wavelengths")
    cor.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="dask.distributed scheduler to run on, e.g. tcp://host:8786 "
                     "(default: in-process threads)")
    cor.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    cor.set_defaults(func=_cmd_correct)

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

    bud = command("budget", "which bands and pixels a scene needs corrected, and with which "
                  "model (signal error of the filter shift)")
    bud.add_argument("--sensor", required=True,
                     help="sensor description (.toml) or a bundled one (snapscan_vnir, ...)")
    bud.add_argument("--lens", required=True,
                     help="lens profile (.toml) or a bundled one (edmund_optics_16mm)")
    bud.add_argument("--f-number", type=float, required=True)
    bud.add_argument("--source", required=True, metavar="SOURCE",
                     help="solar (Kurucz, 0.5 nm), solar:astm-g173 (at the ground, with O2 and "
                     "H2O), tungsten:TEMPERATURE_K, cube or cube:Y,X "
                     "(with --cube: its mean spectrum or one pixel's) or a two-column file "
                     "(wavelength nm, value)")
    bud.add_argument("--tolerance-pct", type=float, default=0.5,
                     help="radiometric tolerance, percent (default: %(default)s)")
    bud.add_argument("--plot", type=Path, default=None, metavar="PNG",
                     help="error against band and against image radius")
    bud.add_argument("--cube", type=Path, default=None,
                     help="a cube: its pixels set the field, and --source cube its spectrum")
    bud.add_argument("--center-px", type=_center_arg, default=None, metavar="CX,CY",
                     help="optical centre in the cube's sensor pixels, for --cube (default: "
                     "from the lens calibration, else the centre of the cube)")
    bud.add_argument("--cra-max", type=float, default=None, metavar="DEG",
                     help="the field to cover (default: the sensor's size_px, or the cube)")
    bud.add_argument("--profile", default="multi_lorentzian",
                     choices=["multi_lorentzian", "pi"],
                     help="filter shape (default: Flittner & Slater's multi-Lorentzian)")
    bud.add_argument("--overwrite", action="store_true", help="replace an existing --plot")
    bud.set_defaults(func=_cmd_budget)
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
