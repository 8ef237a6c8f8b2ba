"""``snapcorr budget``: which bands and pixels a scene needs corrected, and with which model
(the signal error of the filter shift)."""

from __future__ import annotations

import math

import numpy as np

from ._frames import _read
from ._options import (
    ORIGIN_HELP,
    SENSOR_HELP,
    _add_center,
    _f_number,
    _lens,
    _origin_arg,
    _positive,
    _sensor,
    _source,
    add_command,
)
from ._output import _check_outputs
from ._types import _path

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = ("which bands and pixels a scene needs corrected, and with which model (signal error of "
        "the filter shift)")

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
      snapcorr budget --sensor snapscan_vnir --lens edmund_optics_16mm --f-number 1.4 \
          --source solar --tolerance-pct 0.5 --plot budget.png
                                          which bands and pixels need correcting, and how
      snapcorr budget --sensor sensor.toml --lens my_lens.toml --f-number 2.8 \
          --source cube --cube scene_ff.nc
                                          ... for a scene's own spectrum
    """


def add_parser(subparsers):
    p = add_command(subparsers, "budget", HELP, EXAMPLES)
    p.add_argument("--sensor", required=True, help=SENSOR_HELP)
    p.add_argument("--lens", required=True,
                   help="lens profile (.toml) or a bundled one (edmund_optics_16mm)")
    p.add_argument("--f-number", type=_f_number, required=True, metavar="F",
                   help="f-number of the lens")
    p.add_argument("--source", required=True, metavar="SOURCE",
                   help="solar (Kurucz, 0.5 nm), solar:astm-g173 (at the ground, with O2 and "
                   "H2O), tungsten:TEMPERATURE_K, cube or cube:Y,X (with --cube: its mean "
                   "spectrum or one pixel's) or a two-column file (wavelength nm, value)")
    p.add_argument("--tolerance-pct", type=_positive, default=0.5, metavar="PCT",
                   help="radiometric tolerance, percent (default: %(default)s)")
    p.add_argument("--plot", type=_path, default=None, metavar="PNG",
                   help="error against band and against image radius")
    p.add_argument("--cube", type=_path, default=None,
                   help="a cube: its pixels set the field, and --source cube its spectrum")
    _add_center(p, "optical centre in the cube's sensor pixels, for --cube (default: "
                   "from the lens calibration, else the sensor's centre)")
    p.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                   help="with --cube: " + ORIGIN_HELP)
    p.add_argument("--cra-max", type=_positive, default=None, metavar="DEG",
                   help="the field to cover (default: the sensor's size_px, or the cube)")
    p.add_argument("--profile", default=None, choices=["gaussian", "multi_lorentzian", "pi"],
                   help="filter shape (default: the sensor's; Flittner & Slater's "
                   "multi-Lorentzian or Mishev & Bakalova's Pi-shaped to compare)")
    p.add_argument("--all-bands", action="store_true",
                   help="print every band (default: the ten the uncorrected model leaves worst)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --plot")
    p.set_defaults(func=run)


def run(args):
    from ..budget import scene_budget, tolerance_ranges
    _check_outputs({"--plot": args.plot}, [args.cube, args.sensor, args.lens], args.overwrite,
                   [(".png",)])
    if args.source.split(":")[0].strip().lower() == "cube" and args.cube is None:
        raise ValueError(f"--source {args.source} is the spectrum of a cube: give --cube CUBE")
    if args.sensor_origin_px is not None and args.cube is None:
        raise ValueError("--sensor-origin-px places --cube on the sensor: give --cube CUBE")
    lens = _lens(args.lens)
    sensor = _sensor(args.sensor)
    sensor.require("n_eff", "the budget")  # before anything is computed with an unknown index
    cube = None
    if args.cube is not None:
        cube = _read(args.cube, sensor, args.sensor_origin_px)
        sensor.check_cube(cube, f"--cube {args.cube}")
    source = _source(args.source, cube)
    cra_max, field = _budget_field(args, lens, sensor, cube)
    cutoff = float(lens.cutoff_cra_deg(args.f_number))
    if args.cra_max is None and not cra_max < cutoff:  # the field, not an option given
        raise ValueError(f"{field}: beyond the lens's full cut-off at f/{args.f_number:g} "
                         f"({cutoff:.2f} deg), where no light arrives; check --center (sensor "
                         "pixels), or give --cra-max DEG below the cut-off")
    from ..budget.scene import profile_of

    args.profile = profile_of(sensor, args.profile)
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


def _budget_field(args, lens, sensor, cube):
    """The largest CRA the budget covers, and a phrase saying where it comes from."""
    from ..correct.geometry import cube_cra

    if args.cra_max is not None:
        return args.cra_max, f"CRA up to {args.cra_max:g} deg (--cra-max)"
    if cube is not None:
        cra_max = float(cube_cra(cube, sensor, lens, center_rc=args.center_rc,
                                 sensor_origin_px=args.sensor_origin_px).cra_deg.max())
        return cra_max, f"the cube's pixels, CRA up to {cra_max:.2f} deg"
    if args.center_rc is not None and sensor.size_px is not None:  # the axis off the middle
        (rows, cols), (row, col) = sensor.size_px, args.center_rc
        pitch_mm = sensor.require("pixel_pitch_um", "the field about --center") * 1e-3
        far = max(math.hypot(r - row, c - col) for r in (-0.5, rows - 0.5)
                  for c in (-0.5, cols - 0.5))
        cra_max = math.degrees(math.atan(far * pitch_mm / lens.exit_pupil_mm))
        return cra_max, (f"the sensor's {rows} x {cols} px field about --center {row:g},{col:g}, "
                         f"CRA up to {cra_max:.2f} deg at its farthest corner")
    if args.center_rc is not None:
        raise ValueError(f"--center places the optical axis on the sensor {sensor.name!r}, "
                         "which has no size_px: give --cube CUBE or --cra-max DEG")
    if sensor.field_radius_mm is not None:
        cra_max = math.degrees(math.atan(sensor.field_radius_mm / lens.exit_pupil_mm))
        return cra_max, (f"the sensor's {sensor.size_px[0]} x {sensor.size_px[1]} px field, "
                         f"CRA up to {cra_max:.2f} deg at its corners")
    raise ValueError(f"the sensor {sensor.name!r} has no size_px: give --cra-max DEG or "
                     "--cube CUBE for the field to cover")


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

