"""``snapcorr pupil``: the exit pupil distance x (and n_eff) from flat-fielded cubes of a
spectral target, or which target would pin it best (``--predict``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ._frames import _read
from ._options import (
    OVERWRITE_HELP,
    _add_center,
    _add_progress_options,
    _f_number,
    _flat_arg,
    _lens,
    _magnification,
    _one_per_f_number,
    _positive,
    _pupil_magnification,
    _sensor,
    add_command,
)
from ._progress import _StepBar
from ._targets import (
    TARGET_TOLERANCE_HELP,
    _add_pupil_option,
    _add_target_fit_options,
    _check_target_outputs,
    _fitted_sensor,
    _say_precision,
    _target_spectrum,
    _target_tolerance,
)
from ._types import _path

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = ("exit pupil distance x (and n_eff) from flat-fielded cubes of a spectral target (Goossens"
        " et al., OSA Continuum 2019)")

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
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
    """


def add_parser(subparsers):
    p = add_command(subparsers, "pupil", HELP, EXAMPLES)
    p.add_argument("--cube", type=_flat_arg, action="append", default=[],
                   metavar="F_NUMBER=PATH",
                   help="flat-fielded cube of a uniform target with spectral features at an "
                   "f-number (any format snapcorr reads); repeat for each f-number")
    p.add_argument("--sensor", type=str, required=True, metavar="SENSOR",
                   help="sensor description (bundled name or .toml)")
    p.add_argument("--out", type=_path, default=None, help="lens profile to write (.toml)")
    p.add_argument("--lens", type=str, default=None, metavar="LENS",
                   help="lens profile whose vignetting circles (P, h) and magnifications are "
                   "used and copied (bundled name or .toml)")
    _add_target_fit_options(p)
    _add_pupil_option(p)
    _add_center(p, "optical centre in sensor pixels (default: found from the cubes)")
    p.add_argument("--magnification", type=_magnification, default=None,
                   help="linear magnification m (default: the --lens value, else 0, "
                   "focused at infinity, assumed: the target cannot tell it, and the errors "
                   "of x and n_eff then include m / m_P over [0, 0.1]; give 0 if focused at "
                   "infinity)")
    p.add_argument("--pupil-magnification", type=_pupil_magnification, default=None,
                   help="pupil magnification m_P (default: the --lens value, else 1, "
                   "assumed)")
    p.add_argument("--tolerance-nm", type=_positive, default=None, metavar="NM",
                   help=TARGET_TOLERANCE_HELP)
    p.add_argument("--plot", type=_path, default=None, metavar="PNG",
                   help="draw the target over the field and chi-square in x")
    p.add_argument("--name", default=None, help="lens name (default: the output's stem)")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    g = p.add_argument_group("choosing a target (--predict)")
    g.add_argument("--predict", action="store_true",
                   help="print the predicted standard error of x for candidate targets (and "
                   "--target-spectrum) instead of fitting cubes")
    g.add_argument("--f-number", type=_f_number, action="append", default=[],
                   help="an f-number you would measure at (repeat)")
    g.add_argument("--noise-pct", type=_positive, default=None,
                   help="per-pixel noise, %% of the brightest band (default: 1)")
    _add_progress_options(p)
    p.set_defaults(func=run)


def run(args):
    if args.predict:
        return _pupil_predict(args)
    from ..calibrate import FeaturelessTargetError, locate_pupil

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
                               center_rc=args.center_rc, target_spectrum=spectrum,
                               sensor_origin_px=args.sensor_origin_px,
                               magnification=args.magnification,
                               pupil_magnification=args.pupil_magnification,
                               inputs=seen, name=args.name or args.out.stem,
                               progress=bar.step, pupil_radiance=args.pupil or (
                                   lens.pupil_radiance if lens is not None and lens.has_vignetting
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


#: Options of a fit that --predict would not use: refused with it, not ignored.
_FIT_ONLY = (("out", "--out"), ("sensor_out", "--sensor-out"), ("plot", "--plot"),
             ("name", "--name"), ("overwrite", "--overwrite"),
             ("sensor_origin_px", "--sensor-origin-px"), ("pupil", "--pupil-radiance"),
             ("center", "--center"), ("center_px", "--center-px"),
             ("magnification", "--magnification"),
             ("pupil_magnification", "--pupil-magnification"),
             ("tolerance_nm", "--tolerance-nm"))


def _pupil_predict(args):
    from ..calibrate import CANDIDATE_TARGETS, pupil_precision

    if args.cube:
        raise ValueError("--predict compares targets before measuring; leave out --cube")
    given = [opt for dest, opt in _FIT_ONLY if getattr(args, dest) not in (None, False)]
    if given:
        raise ValueError(f"{', '.join(given)} go{'es' if len(given) == 1 else ''} with a fit "
                         "to cubes (--cube), not --predict, which writes nothing and takes "
                         "the lens from --lens")
    if not args.f_number:
        raise ValueError("give the f-numbers you would measure at: --f-number F (repeat)")
    sensor = _sensor(args.sensor)
    if sensor.size_px is None:
        raise ValueError(f"--predict needs the sensor's size: {args.sensor} gives no size_px "
                         "(add size_px = [ROWS, COLS] to a sensor TOML)")
    lens = _lens(args.lens or "edmund_optics_16mm")
    targets = dict(CANDIDATE_TARGETS)
    if args.target_spectrum is not None:  # checked as a fit checks it: not held at its ends
        from ..calibrate import FeaturelessTargetError
        from ..calibrate.pupil.target import check_target_spectrum

        wl, val = _target_spectrum(args.target_spectrum)
        try:
            check_target_spectrum(wl, val, sensor)
        except FeaturelessTargetError:  # constant: its row says it gives nothing
            pass
        except ValueError as err:
            raise ValueError(f"--target-spectrum {args.target_spectrum}: {err}") from None
        targets[Path(args.target_spectrum).name] = lambda lam: np.interp(lam, wl, val)
    args.noise_pct = 1.0 if args.noise_pct is None else args.noise_pct
    noise = args.noise_pct / 100.0
    fs = sorted(set(args.f_number))
    lens.working_f_number(fs)  # an f-number below the lens's limit is refused before any output
    fit_n = args.fit_n_eff
    table = [  # printed once every bound is computed: a refusal mid-way prints no part of it
        f"predicted standard error of the exit pupil distance x = {lens.exit_pupil_mm:g} mm "
        f"(Cramer-Rao bound), sensor {sensor.name}, lens {lens.name or args.lens}, "
        f"f/{', f/'.join(f'{f:g}' for f in fs)}, noise {args.noise_pct:g} % of the brightest "
        "band per pixel" + (", n_eff fitted too" if fit_n else "")
        + (" (one f-number: x's bound is with n_eff free; where that leaves n_eff known to "
           "worse than 1 %, the fit holds the sensor's index, and x's error is then x's at "
           "that index)" if fit_n and len(fs) < 2 else ""),
        f"{'target':34s} {'x, spectrum unknown':>22s} {'x, spectrum known':>20s}"
        + (f" {'n_eff':>12s}" if args.fit_n_eff else "")]

    def line(name, row):
        cells = [_precision_cell(p) for p in row]
        extra = ""
        if args.fit_n_eff:
            extra = (f" {row[0].n_eff_stderr:12.2g}" if row[0].informative
                     else f" {'-':>12s}")
        table.append(f"{name[:34]:34s} {cells[0]:>22s} {cells[1]:>20s}{extra}")

    from ..spectra import COLOUR_CHECKER_PATCHES

    with _StepBar("bounds for each target",
                  total=2 * len(targets) + len(COLOUR_CHECKER_PATCHES) + 1) as bar:
        for name, S in targets.items():
            row = []
            for known in (False, True):
                bar.step(f"{name[:24]}, spectrum {'known' if known else 'unknown'}")
                row.append(pupil_precision(S, sensor, fs, lens, noise=noise, fit_n_eff=fit_n,
                                           spectrum_known=known))
            line(name, row)
        chart = _chart_line(sensor, fs, lens, noise, fit_n, bar)
        if isinstance(chart, str):
            table.append(chart)
        else:
            best, rest = chart
            line(f"ColorChecker {best[0]}", best[1])
            table.append(rest)
    print("\n".join(table))
    print("noise only: a target that is not uniform, or filters of another shape than the "
          "sensor file says, add errors of their own")
    return 0


def _chart_line(sensor, fs, lens, noise, fit_n, bar):
    """The colour chart's best patch (its bounds, spectrum unknown and known) and a line on
    the others; or why the chart cannot be judged on this sensor."""
    from ..calibrate.pupil.precision import (
        OutsideChartError,
        colour_chart_precision,
        pupil_precision,
    )
    from ..spectra import COLOUR_CHECKER_PATCHES, colour_checker

    try:
        ranked = colour_chart_precision(sensor, fs, lens, noise=noise, fit_n_eff=fit_n,
                                        on_patch=lambda p: bar.step(f"ColorChecker {p[:14]}"))
    except OutsideChartError as exc:  # said before any bound is computed
        bar.skip(len(COLOUR_CHECKER_PATCHES) + 1)
        return f"{'ColorChecker (24 patches)':34s} not judged: {exc}"
    name, unknown = ranked[0]
    bar.step(f"ColorChecker {name[:14]}, spectrum known")
    sp = colour_checker(name)  # held at its ends, where no band responds
    known = pupil_precision(lambda lam: np.interp(lam, sp.wavelength_nm, sp.values), sensor,
                            fs, lens, noise=noise, fit_n_eff=fit_n, spectrum_known=True)
    nxt = ", ".join(f"{n} {p.x_stderr_mm:.2g}" for n, p in ranked[1:4] if p.informative)
    worst = ranked[-1]
    rest = (f"  (the best of the chart's 24 patches, published spectra; next, x in mm with the "
            f"spectrum unknown: {nxt or 'none informative'}; the least, {worst[0]}: "
            + (f"{worst[1].x_stderr_mm:.2g} mm" if worst[1].informative else "no information")
            + ")")
    return (name, [unknown, known]), rest


def _precision_cell(p):
    if not p.informative:
        return "no information"
    return f"{p.x_stderr_mm:.2g} mm ({100 * p.x_stderr_mm / p.exit_pupil_mm:.2g} %)"

