"""A fit to a target's cubes, shared by ``pupil`` and ``calibrate --target-cube``: its
options, its outputs and the sensor with the fitted index."""

from __future__ import annotations

from pathlib import Path

from ._options import _origin_arg
from ._output import _check_outputs

TARGET_TOLERANCE_HELP = (
    "the shift precision x and n_eff must give (nm, one standard deviation, the chief ray at "
    "the sensor's corner in the longest band): before the fit the precision the cubes can "
    "give is predicted and printed, and a target that cannot reach it is refused (default: "
    "0.05)")


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
                       help=("sensor row and column of the raw mosaic flats' first pixel "
                             "(crops, with --sensor; with --target-cube, of the cubes' too: "
                             "flats and cubes must be of the same pixels, and a cube that "
                             "records its own must agree)" if when else
                             "sensor row and column of the cubes' first pixel (crops)"))


def _add_pupil_option(group):
    """``--pupil-radiance``: how the light fills the exit pupil
    (``snapcorr.optics.lens.PUPIL_RADIANCE_MODELS``, ``Lens.pupil_radiance``); ``--pupil``, its
    earlier name, still taken."""
    group.add_argument("--pupil-radiance", "--pupil", dest="pupil", default=None,
                       choices=["paper", "lambertian", "auto"],
                       help="how the light fills the exit pupil (--pupil, the earlier name, "
                       "is still taken): paper (Goossens 2019 Eq. 28, "
                       "uniform per area), lambertian (sine condition, uniform in direction "
                       "cosines) or auto (both fitted to the target, the Lambertian kept only "
                       "for a chi-square gain above 10; twice the time). Default: auto with "
                       "target cubes (the --lens profile's when it has circles, which belong to "
                       "its pupil), else the --lens profile's, else paper")


def _check_target_outputs(args, seen, inputs, cubes):
    """The outputs of a target fit (``--out``, ``--plot``, ``--sensor-out``), before any work
    (:func:`~snapcorr.files.outputs.check_outputs` refuses two of them at one path)."""
    if args.sensor_out is not None and not (args.fit_n_eff and len(seen) >= 2):
        raise ValueError(f"--sensor-out needs --fit-n-eff and {cubes} at two or more "
                         "f-numbers (one f-number fixes only x * n_eff)")
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

