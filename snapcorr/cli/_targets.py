"""A fit to a target's cubes, shared by ``pupil`` and ``calibrate --target-cube``: its
options, its outputs and the sensor with the fitted index."""

from __future__ import annotations

from ._frames import _read
from ._options import _origin_arg
from ._output import _check_outputs
from ._types import _path

TARGET_TOLERANCE_HELP = (
    "the shift precision x and n_eff must give (nm, one standard deviation, the chief ray at "
    "the sensor's corner in the longest band): before the fit the precision the cubes can "
    "give is predicted and printed, and a target that cannot reach it is refused (default: "
    "0.05)")


def _add_target_fit_options(group, when="", origin_help="sensor row and column of the "
                            "cubes' first pixel (crops)"):
    """The options of a fit to a target's cubes, shared by ``pupil`` and ``calibrate
    --target-cube`` (``when`` says which option they go with; ``origin_help``, what
    ``--sensor-origin-px`` places)."""
    group.add_argument("--fit-n-eff", action="store_true",
                       help=f"{when}fit the effective index too (two f-numbers far apart "
                       "separate it from x; one does where the field is wide and the cone "
                       "fast, and otherwise gives x * n_eff with x at the sensor's index)")
    group.add_argument("--sensor-out", type=_path, default=None, metavar="SENSOR.toml",
                       help="with --fit-n-eff and two or more f-numbers: also write the "
                       "sensor description with the fitted n_eff, for the correction "
                       "(correct --sensor)")
    group.add_argument("--target-spectrum", type=_path, default=None, metavar="PATH",
                       help=f"{when}the target's spectrum, two columns (wavelength nm, "
                       "value); default: unknown, solved for")
    group.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                       help=origin_help)


def _add_pupil_option(group):
    """``--pupil-radiance``: how the light fills the exit pupil
    (``snapcorr.optics.lens.PUPIL_RADIANCE_MODELS``, ``Lens.pupil_radiance``); ``--pupil``, its
    earlier name, still taken."""
    group.add_argument("--pupil-radiance", "--pupil", dest="pupil", default=None,
                       choices=["paper", "lambertian", "paper-lambertian", "auto"],
                       help="how the light fills the exit pupil (--pupil, the earlier name, "
                       "is still taken): paper (Goossens 2019 Eq. 28, "
                       "uniform per area), lambertian (sine condition, uniform in direction "
                       "cosines), paper-lambertian (Eq. 28's disc, each ray weighted by its "
                       "cos^4: a flat pupil of uniform radiance) or auto (all fitted, another "
                       "than the paper's kept only where it lowers the criterion by more than "
                       "10: the chi-square of target cubes, the BIC of flats, their sum for "
                       "both). "
                       "Default: auto with "
                       "target cubes (the --lens profile's when it has circles, which belong to "
                       "its pupil), else the --lens profile's, else paper")


def _check_target_outputs(args, seen, inputs, cubes):
    """The outputs of a target fit (``--out``, ``--plot``, ``--sensor-out``), before any work
    (:func:`~snapcorr.files.outputs.check_outputs` refuses two of them at one path)."""
    if args.sensor_out is not None and not (args.fit_n_eff and len(seen) >= 2):
        raise ValueError(f"--sensor-out needs --fit-n-eff and {cubes} at two or more "
                         "f-numbers (one f-number may not pin n_eff)")
    _check_outputs({"--out": args.out, "--plot": args.plot, "--sensor-out": args.sensor_out},
                   inputs, args.overwrite,
                   [(".toml",), (".png",), (".toml",)])


def _target_tolerance(value):
    """``--tolerance-nm`` / ``--target-tolerance-nm``, or the default."""
    from ..calibrate.pupil.precision import DEFAULT_TOLERANCE_NM

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
    from ..calibrate.pupil.target import N_EFF_START

    design = ({"n_eff_design": list(sensor.n_eff)} if sensor.n_eff is not None
              else {"n_eff_start": N_EFF_START})  # a vendor file gives none
    record = {"n_eff_from": str(args.out), **design, **{k: cal[k] for k in keep if k in cal}}
    record["source"] = "snapcorr pupil: " + cal["source"]
    return dataclasses.replace(sensor, name=f"{sensor.name} (n_eff fitted)",
                               n_eff=tuple(float(v) for v in fit.n_eff), calibration=record)


def _target_spectrum(path):
    if path is None:
        return None
    from ..spectra import read_spectrum

    sp = read_spectrum(path)
    return sp.wavelength_nm, sp.values


def _area(origin, shape):
    """A sensor area for a message, rows first."""
    return f"{shape[0]} x {shape[1]} px at sensor row {origin[0]}, col {origin[1]}"


def _cube_area(cube):
    """``(row, col, rows, cols)`` of the sensor area a mosaic cube records it covers (its
    ``mosaic_area_px``, else its ``sensor_row`` / ``sensor_col``), or None."""
    import numpy as np

    area = cube.attrs.get("mosaic_area_px")
    if area is not None:
        return tuple(int(v) for v in area)
    if "sensor_row" in cube.coords and "sensor_col" in cube.coords:
        r, c = np.asarray(cube["sensor_row"].values), np.asarray(cube["sensor_col"].values)
        return (int(r.min()), int(c.min()), int(r.max() - r.min()) + 1,
                int(c.max() - c.min()) + 1)
    return None


def _crop_without_origin(shape, sensor, f, path, area):
    """The refusal of flats smaller than the sensor whose place on it is not given."""
    return (f"the flats are {shape[0]} x {shape[1]} px, a crop of the sensor {sensor.name!r} "
            f"({sensor.size_px[0]} x {sensor.size_px[1]} px): give --sensor-origin-px ROW,COL, "
            "the sensor row and column of their first pixel" + (
                f" (the target cube f/{f:g} {path} records row {area[0]}, col {area[1]})"
                if area is not None else ""))


def _target_cubes(args, sensor, shape):
    """The target's cubes, and the sensor origin of the flats and the cubes alike (None: the
    whole sensor). Of a mosaic, the flats (raw frames) and the cubes must be of the same
    pixels: a cube that records its sensor area is read as it records it and refused, in one
    line naming both, where that area is not the flats' (``--sensor-origin-px`` and their
    size); flats that are a crop need ``--sensor-origin-px``."""
    cubes = {}
    whole = sensor.size_px is not None and tuple(shape) == tuple(sensor.size_px)
    origin = args.sensor_origin_px
    if sensor.size_px is not None and any(
            n > m for n, m in zip(shape[:2], sensor.size_px, strict=True)):
        raise ValueError(f"the flats are {shape[0]} x {shape[1]} px, larger than the sensor "
                         f"{sensor.name!r} ({sensor.size_px[0]} x {sensor.size_px[1]} px): "
                         "frames of another camera? check --sensor")
    if sensor.layout != "mosaic":
        for f, path in sorted(args.target_cube):
            cubes[f] = _read(path, sensor, origin)
            area = _cube_area(cubes[f])
            size = (cubes[f].sizes["y"], cubes[f].sizes["x"])
            if size != tuple(shape[:2]):
                raise ValueError(
                    f"the flats ({shape[0]} x {shape[1]} px) and the target cube f/{f:g} "
                    f"{path} ({size[0]} x {size[1]} px) are not of the same pixels: take the "
                    "flats and the target's cubes of one sensor area")
            if origin is None and not whole and sensor.size_px is not None:
                # before any work: flats of unknown place cannot be put about the axis
                raise ValueError(_crop_without_origin(shape, sensor, f, path, area))
        return cubes, origin
    from ..calibrate.unknown_lens import flats_areas

    areas = flats_areas(shape, sensor, origin)
    for f, path in sorted(args.target_cube):
        try:  # a cube read as it records its place; a raw frame has none: at the origin
            cube = _read(path, sensor, None)
        except ValueError:
            cube = _read(path, sensor, origin)
        area = _cube_area(cube)
        if area is None:  # it records nowhere: placed where the flats are
            cube = _read(path, sensor, origin)
            area = _cube_area(cube)
        if origin is None and sensor.size_px is None and area is not None:
            origin = area[:2]  # a sensor of no known size: the flats sit where the cube does
            areas = flats_areas(shape, sensor, origin)
        if origin is None and not whole and sensor.size_px is not None:
            raise ValueError(_crop_without_origin(shape, sensor, f, path, area))
        if area is not None and area not in areas:
            raise ValueError(
                f"the flats ({_area(origin or (0, 0), shape)}) and the target cube f/{f:g} "
                f"{path} ({_area(area[:2], area[2:])}) are not of the same pixels: take the "
                "flats and the target's cubes of one sensor area, and give its origin "
                "(--sensor-origin-px ROW,COL)")
        cubes[f] = cube
    return cubes, origin
