"""An unknown lens in one run: flats and target cubes together give x, n_eff, P, h and the centre.

Flat fields alone fix the vignetting circles only relative to the exit pupil distance: the
overlap of the pupil (radius ``x tan theta_cone``, Goossens et al. 2019, Eq. 28) and the
projected circle (radius ``P``, offset ``h tan CRA = h d / x``, Eq. 9) scales as a whole with
``x`` when ``P / x`` and ``h / x^2`` are held, so every flat is fitted equally well at any ``x``.
Cubes of a target with spectral features fix ``x`` (and ``n_eff``) through the chief-ray
angles (Goossens et al., OSA Continuum 2019), but need the circles where the fastest cube is
vignetted.

The two data sets are independent and the likelihood factorises: the flats determine
``u = P / x``, ``v = h / x^2`` and the optical centre; the target determines ``x`` (and the
index) with the circles held at ``(u x, v x^2)`` for every trial ``x``
(:func:`~snapcorr.calibrate.locate_pupil` with ``scale_circles``). So
:func:`calibrate_with_target` runs

1. :func:`~snapcorr.calibrate.calibrate_lens` at a provisional ``x`` (any value: only ``u``,
   ``v`` and the centre are kept),
2. :func:`~snapcorr.calibrate.locate_pupil` with those circles scaled at every trial ``x`` and
   the flats' centre,
3. :func:`~snapcorr.calibrate.calibrate_lens` again at the ``x`` found, with its error, so that
   every angle, onset and shift error in the profile belongs to that ``x``.

The joint covariance of ``x``, the index, every ``P`` and ``h`` and the centre follows from the
two fits' covariances by the chain rule (``P = u x``, ``h = v x^2``). It leaves out how an error
of the circles moves the fitted ``x`` (second order: the target's x depends on the circles only
where the fastest cube is vignetted); the evidence over seeds in the tests checks that the
errors cover all the same.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from .._coords import accepts_center_rc
from .._validation import renamed_keywords
from ..optics.lens import PUPIL_RADIANCE_MODELS, Lens
from .lens import choice
from .lens.calibration import (
    LensCalibration,
    calibrate_lens,
    checked_magnifications,
    flats_bic,
)
from .lens.joint_fit import CENTER_NAMES
from .lens.magnification import ASSUMED_MAGNIFICATION, ASSUMED_PUPIL_MAGNIFICATION, ratio_range
from .pupil.centre_error import account_for_the_centre, fastest_positions
from .pupil.locate import PupilFit, choose_pupil, locate_pupil
from .unknown_magnification import account_for_target_magnifications

__all__ = ["LensAndPupil", "calibrate_with_target"]

#: The two calibrations (at the provisional and at the fitted x) must agree on ``P / x`` and
#: ``h / x^2`` to this relative difference; they differ only by rounding when they do.
SCALE_CONSISTENCY = 1e-4
#: Chief-ray positions at which the shift's dependence on x is evaluated, per f-number.
_N_FIELD = 48


@dataclass
class LensAndPupil:
    """What :func:`calibrate_with_target` found.

    Attributes
    ----------
    lens : Lens
        The profile: ``x`` from the target, the circles at that ``x``, the calibration tables
        of both fits and the joint covariance (``[calibration.joint]``).
    calibration : LensCalibration
        The flats' calibration at the ``x`` found (with its error).
    pupil : PupilFit
        The target's fit, with the circles scaled at every trial ``x``.
    names : tuple of str
        Parameters of :attr:`covariance`: ``exit_pupil_mm``, ``n_eff`` (or ``n_eff_factor``,
        the factor on the sensor's design values) when one index was fitted, ``P_mm``,
        ``h_mm`` (``P2_mm``, ``h2_mm``, ... for further circles) and ``cx_px``, ``cy_px``
        (the flats' pixels) when the joint fit gave them.
    values, stderr : ndarray
    covariance : ndarray
    shift_stderr_nm : ndarray
        The predicted mean shift's standard error per f-number, largest over the field, for a
        filter at ``choice.REFERENCE_CWL_NM`` with ``choice.REFERENCE_N_EFF``: the flats' part
        (fit and model choice) and ``shift_stderr_exit_pupil_nm`` (x's error: every pixel's
        chief-ray angle and the scaled circles move with it) in quadrature.
    notes : list of str
    """

    lens: Lens
    calibration: LensCalibration
    pupil: PupilFit
    names: tuple
    values: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray
    shift_stderr_nm: np.ndarray
    shift_stderr_exit_pupil_nm: np.ndarray
    provisional_x_mm: float
    notes: list = field(default_factory=list)

    def correlation(self) -> np.ndarray:
        """The correlation matrix of :attr:`names`."""
        s = np.where(self.stderr > 0, self.stderr, np.inf)
        return self.covariance / np.outer(s, s)

    def summary(self) -> str:
        """A few lines for a person: the flats' summary, the target's, and the joint result."""
        lines = [self.calibration.summary(), "", self.pupil.summary(), "",
                 f"jointly (flats + target, provisional x {self.provisional_x_mm:.4g} mm):"]
        for name, v, e in zip(self.names, self.values, self.stderr, strict=True):
            lines.append(f"  {name:14s} {v:12.6g} +- {e:.2g}")
        rho = self.correlation()
        i = self.names.index("exit_pupil_mm")
        big = [f"{n} {rho[i, j]:+.2f}" for j, n in enumerate(self.names)
               if j != i and abs(rho[i, j]) > 0.5]
        if big:
            lines.append("  correlated with x: " + ", ".join(big))
        fs = self.calibration.f_numbers
        if self.shift_stderr_nm.size:
            lines.append("  mean-shift standard error with x's (largest over the field, "
                         f"{choice.REFERENCE_CWL_NM:g} nm filter, n_eff "
                         f"{choice.REFERENCE_N_EFF:g}): " + ", ".join(
                             f"f/{f:g} {e:.2g} nm" for f, e in
                             zip(fs, self.shift_stderr_nm, strict=True)))
        lines.extend(f"note: {t}" for t in self.notes)
        return "\n".join(lines)


@renamed_keywords(pupil="pupil_radiance")
@accepts_center_rc
def calibrate_with_target(flats, cubes, sensor, *, pixel_pitch_um, fit_n_eff=False,
                          provisional_x_mm=None, magnification=None, pupil_magnification=None,
                          dark=None, center_rc=None, center_px=None, saturation=None,
                          method="auto",
                          max_circles=3, tolerance_nm=choice.TOLERANCE_NM,
                          target_spectrum=None, sensor_origin_px=None, profile="gaussian",
                          name="calibrated lens", inputs=None, target_inputs=None,
                          progress=None, pupil_radiance="paper", target_tolerance_nm=None,
                          report=None) -> LensAndPupil:
    """Characterise a lens whose exit pupil distance is unknown: flats plus target cubes.

    Parameters
    ----------
    flats : mapping
        f-number -> 2-D flat field (as :func:`~snapcorr.calibrate.calibrate_lens`).
    cubes : mapping
        f-number -> flat-fielded cube of a uniform target with spectral features (as
        :func:`~snapcorr.calibrate.locate_pupil`); two f-numbers far apart to fit ``n_eff``.
    sensor : Sensor
        The cubes' camera; flats of a mosaic's size are its raw frames (band gains divided out).
    pixel_pitch_um : float
        Pixel pitch of the flats.
    fit_n_eff : bool
        Fit the effective index too.
    provisional_x_mm : float, optional
        Any positive x for the first calibration; only ``P / x``, ``h / x^2`` and the centre are
        kept from it. Default: the x at which the flats' corner sits at 20 degrees.
    magnification, pupil_magnification : float, optional
        m and m_P of the working f-number, Eq. (27); None: not given. Those not given are
        assumed (m = 0, m_P = 1) and judged over a plausible range as in
        :func:`~snapcorr.calibrate.calibrate_lens`: the target is fitted again at its nodes
        and the spread is in every joint error and the shift's
        (:mod:`~snapcorr.calibrate.unknown_magnification`), with a
        :class:`~snapcorr.calibrate.lens.magnification.MagnificationWarning`. Given values
        (m = 0 alone included) are exact.
    dark, center_rc, center_px, saturation, method, max_circles, tolerance_nm
        As :func:`~snapcorr.calibrate.calibrate_lens` (the optical centre ``center_rc=(row,
        col)`` in the flats' pixels; ``center_px=(cx, cy)`` is its deprecated x-first form).
    target_spectrum, sensor_origin_px, profile
        As :func:`~snapcorr.calibrate.locate_pupil`.
    name : str
    inputs, target_inputs : mapping, optional
        f-number -> path of each flat and cube, recorded in the profile.
    progress : callable, optional
        ``progress(step)`` before each long step.
    pupil_radiance : {"paper", "lambertian", "paper-lambertian", "auto"}
        How the light fills the pupil (:data:`snapcorr.optics.lens.PUPIL_RADIANCE_MODELS`),
        for the flats and the target alike. ``"auto"``: the whole calibration is run with
        each, and one other than the paper's is kept only where the target's chi-square plus
        the flats' BIC falls by more than
        :data:`~snapcorr.calibrate.pupil.locate.PUPIL_CHI2_GAIN` (fast flats tell a
        Lambertian pupil by every ray's cos^4; the target's spectral structure tells the
        radii). Earlier name: ``pupil``.
    target_tolerance_nm, report
        The shift precision the target must be able to give, and where its prediction is
        said: ``tolerance_nm`` and ``report`` of :func:`~snapcorr.calibrate.locate_pupil`
        (checked before any flat is fitted only as far as the target's own fit goes: the
        prediction needs the flats' circles).

    Returns
    -------
    LensAndPupil

    Raises
    ------
    FeaturelessTargetError
        The target carries no information about x.
    """
    args = dict(locals())
    del args["center_px"]  # turned into center_rc by accepts_center_rc
    m, mp = checked_magnifications(magnification, pupil_magnification)  # before any work
    given, _, rng = ratio_range(m, mp)
    args.update(magnification=ASSUMED_MAGNIFICATION if m is None else m,
                pupil_magnification=ASSUMED_PUPIL_MAGNIFICATION if mp is None else mp)
    res = _either_pupil(args) if pupil_radiance == "auto" else _one_pupil(**args)
    if rng[1] > rng[0]:  # m / m_P assumed: its spread in the errors, said and recorded
        res = account_for_target_magnifications(res, given, rng, res._refit, stacklevel=5)
    return res


def _one_pupil(flats, cubes, sensor, *, pixel_pitch_um, fit_n_eff, provisional_x_mm,
               magnification, pupil_magnification, dark, center_rc, saturation, method,
               max_circles, tolerance_nm, target_spectrum, sensor_origin_px, profile, name,
               inputs, target_inputs, progress, pupil_radiance, target_tolerance_nm,
               report) -> LensAndPupil:
    """:func:`calibrate_with_target` for one pupil and m, m_P settled (its body); every
    centre ``(row, col)``."""
    flats = dict(flats)
    if not flats or not cubes:
        raise ValueError("give flat fields and target cubes (one of each at least)")
    shape = np.shape(next(iter(flats.values())))
    _same_pixels(shape, cubes, sensor, sensor_origin_px)
    if provisional_x_mm is None:
        half_diag_mm = 0.5 * math.hypot(*shape[:2]) * float(pixel_pitch_um) * 1e-3
        provisional_x_mm = half_diag_mm / math.tan(math.radians(20.0))
    common = dict(pixel_pitch_um=pixel_pitch_um, magnification=magnification,
                  pupil_magnification=pupil_magnification, dark=dark, center_rc=center_rc,
                  saturation=saturation, method=method, max_circles=max_circles,
                  tolerance_nm=tolerance_nm, name=name, inputs=inputs, progress=progress,
                  pupil_radiance=pupil_radiance,
                  **_raw_mosaic_of(sensor, shape, sensor_origin_px))
    first = calibrate_lens(flats, exit_pupil_mm=provisional_x_mm, **common)
    notes = []
    centre = (None if first.center_source == "image centre"  # assumed there, not found
              else _target_center(cubes, sensor, _origin_kept(first.lens, sensor_origin_px),
                                sensor_origin_px, notes))
    # a refusal of the centre names the flats' where the flats found it; every fit about it
    # (again with other circles, at other magnifications) shares one check of it
    whose = "given" if first.center_source == "given" else "flats"
    checks = {}
    flats_err = _flats_centre_err(first) if centre is not None and whose == "flats" else None

    def fit_x(lens, centre=centre, again=False):  # these circles scaled to every trial x
        fit = locate_pupil(cubes, sensor, lens=lens, fit_n_eff=fit_n_eff, center_rc=centre,
                           target_spectrum=target_spectrum, sensor_origin_px=sensor_origin_px,
                           profile=profile, inputs=target_inputs, name=name,
                           progress=progress, scale_circles=True,
                           tolerance_nm=None if again else target_tolerance_nm,
                           report=None if again else report, center_from=whose,
                           center_checks=checks)
        if whose == "flats":
            fit = _centre_named_the_flats(fit, first.center_source, flats_err)
        if again or flats_err is None:
            return fit
        # the flats' centre is a measurement too: its error in x's and n_eff's
        return account_for_the_centre(
            fit, flats_err, *fastest_positions(cubes, sensor, lens, sensor_origin_px),
            lambda c: fit_x(lens, centre=c, again=True), whose="the flats' optical centre")

    pupil = fit_x(first.lens)
    x, sx = pupil.exit_pupil_mm, pupil.exit_pupil_stderr_mm
    final = calibrate_lens(flats, exit_pupil_mm=x, exit_pupil_stderr_mm=sx, **common)
    differ = _consistency(first, final, provisional_x_mm, x)
    if final.model != first.model:  # x was fitted with other circles: fit it with these
        notes += differ
        pupil = fit_x(final.lens)
        x, sx = pupil.exit_pupil_mm, pupil.exit_pupil_stderr_mm
        final = calibrate_lens(flats, exit_pupil_mm=x, exit_pupil_stderr_mm=sx, **common)
        notes.append(f"x was fitted again with the {final.model!r} circles: {x:.4g} mm")
    elif differ and final.lens.ray_weight == "cos4":  # expected: their flats depend on x
        pupil, final, x, sx = _settled_x(fit_x, final, pupil, flats, common, notes)
    else:
        notes += differ
    names, values, cov = _joint_covariance(final, pupil, sensor)
    x_part = _shift_stderr_from_x(final, x, sx)
    own = final.shift_stderr_nm if final.shift_stderr_nm.size else np.zeros_like(x_part)
    total = np.hypot(own, x_part) if x_part.size else own
    lens = _profile(final, pupil, names, values, cov, total, x_part, provisional_x_mm)
    if final.center_source == "image centre":
        lens = _target_centre_kept(lens, pupil, sensor, sensor_origin_px, pixel_pitch_um, notes)
    lens = _origin_kept(lens, sensor_origin_px)
    out = LensAndPupil(lens, final, pupil, names, values,
                       np.sqrt(np.clip(np.diag(cov), 0, None)), cov, total, x_part,
                       float(provisional_x_mm), notes)
    # the target fitted again with other circles, as this one was (the assumed magnifications'
    # spread), the centre held where this fit found it
    out._refit = functools.partial(fit_x, centre=pupil.center_rc, again=True)
    return out


def flats_areas(shape, sensor, sensor_origin_px=None):
    """The sensor areas ``(row, col, rows, cols)`` a cube of the same pixels as raw mosaic
    flats of ``shape`` at ``sensor_origin_px`` records: the frame's own, or (a tile or
    demosaicked cube, ``mosaic_area_px``) its whole tiles inside the filter area."""
    from ..cube.mosaic import frame_area

    r0, c0 = (int(v) for v in (sensor_origin_px or (0, 0)))
    areas = {(r0, c0, int(shape[0]), int(shape[1]))}
    try:
        (lo_r, lo_c), (rows, cols), _ = frame_area(tuple(shape[:2]), sensor,
                                                   sensor_origin_px)
    except ValueError:  # no whole tile: refused where the cubes are made
        return areas
    tr, tc = sensor.mosaic_shape
    return areas | {(int(lo_r), int(lo_c), rows // tr * tr, cols // tc * tc)}


def _same_pixels(shape, cubes, sensor, sensor_origin_px):
    """Raw flats of a mosaic and its cubes must be of the same sensor pixels: a cube that
    records its area (``mosaic_area_px``) elsewhere than the flats' (their ``shape`` at
    ``sensor_origin_px``, the whole sensor without it) is refused, naming both."""
    if getattr(sensor, "layout", None) != "mosaic":
        return
    whole = sensor.size_px is not None and tuple(shape[:2]) == tuple(sensor.size_px)
    if sensor_origin_px is None and not whole:
        return  # flats of another grid than the sensor's: nothing to compare
    r0, c0 = (int(v) for v in (sensor_origin_px or (0, 0)))
    flats = (r0, c0, int(shape[0]), int(shape[1]))
    areas = flats_areas(shape, sensor, sensor_origin_px)
    for f, cube in cubes.items():
        area = getattr(cube, "attrs", {}).get("mosaic_area_px")
        if area is not None and tuple(int(v) for v in area) not in areas:
            a = [int(v) for v in area]
            raise ValueError(
                f"the flats ({flats[2]} x {flats[3]} px at sensor row {r0}, col {c0}) and the "
                f"target cube at f/{float(f):g} ({a[2]} x {a[3]} px at sensor row {a[0]}, col "
                f"{a[1]}) are not of the same pixels: take both of one sensor area "
                "(sensor_origin_px= its first pixel)")


def _raw_mosaic_of(sensor, shape, sensor_origin_px=None):
    """The keywords of :func:`calibrate_lens` for flats of ``shape`` that are raw frames of a
    mosaic ``sensor``: the whole sensor's, or a crop's at ``sensor_origin_px`` (the target
    cubes' origin: the flats and the cubes are taken of the same pixels); else none."""
    if getattr(sensor, "layout", None) != "mosaic":
        return {"sensor": None}
    if sensor.size_px is not None and tuple(shape) == tuple(sensor.size_px):
        return {"sensor": sensor}
    if sensor_origin_px is not None:
        return {"sensor": sensor, "sensor_origin_px": sensor_origin_px}
    return {"sensor": None}


def _either_pupil(args):
    """``calibrate_with_target(pupil_radiance="auto")``: the paper's pupil unless another fits
    the target clearly better (:data:`~snapcorr.calibrate.pupil.locate.PUPIL_CHI2_GAIN`)."""
    args = {k: v for k, v in args.items() if k != "pupil_radiance"}
    runs = {name: _one_pupil(**args, pupil_radiance=name) for name in PUPIL_RADIANCE_MODELS}
    # the flats tell the pupils apart too where they are fast (every ray's cos^4 against the
    # chief ray's): their information criterion joins the target's chi-square
    return choose_pupil(runs, {k: r.pupil.chi2_red * r.pupil.dof + flats_bic(r.calibration)
                               for k, r in runs.items()},
                        "the target's chi-square plus the flats' BIC",
                        key="chi2_plus_flats_bic")


def _centre_named_the_flats(fit, how, err):
    """The target's fit about the flats' centre, saying so (not ``"given"``: the user gave
    none), with how the flats found it and its errors where known."""
    import dataclasses

    said = f"the flats' ({how}" + ("" if err is None else
                                   f", +- {err[0]:.2g} px in the row, {err[1]:.2g} px in "
                                   "the column") + ")"
    cal = {**fit.lens.calibration, "center_source": said}
    return dataclasses.replace(fit, center_source=said,
                               lens=dataclasses.replace(fit.lens, calibration=cal))


def _flats_centre_err(first):
    """The standard errors ``(row, col)`` of the optical centre the flats' joint fit found
    (the chosen model's), or None where the centre came otherwise (their contours: no
    error)."""
    fit = first.fits.get(first.model)
    if first.center_source != "joint fit" or fit is None:
        return None
    err = tuple(float(fit.stderr.get(k, np.nan)) for k in CENTER_NAMES)
    return err if all(np.isfinite(e) and e > 0 for e in err) else None


def _target_center(cubes, sensor, lens, sensor_origin_px, notes):
    """The flats' optical centre ``(row, col)`` in the cubes' sensor pixels, or None (found
    from the cubes)."""
    from ..correct.geometry import PlacementError, optical_center_rc

    try:
        centre, _ = optical_center_rc(next(iter(cubes.values())), sensor, lens)
    except PlacementError as err:
        notes.append(f"the flats' optical centre could not be carried to the cubes ({err}); "
                     "the target's fit found its own")
        return None
    return centre


def _origin_kept(lens, sensor_origin_px):
    """The profile of flats that are a crop, their first pixel at ``sensor_origin_px``
    (row, col) on the sensor: recorded (``sensor_origin_rc``), as raw mosaic flats' is, so the
    optical centre, in the flats' pixels, is carried to the sensor's (without it, a crop's
    centre was read as sensor pixels: the axis 32 rows and 40 columns off)."""
    import dataclasses

    if sensor_origin_px is None or "sensor_origin_rc" in lens.calibration:
        return lens
    table = dict(lens.calibration)
    table["sensor_origin_rc"] = [int(sensor_origin_px[0]), int(sensor_origin_px[1])]
    return dataclasses.replace(lens, calibration=table)


def _target_centre_kept(lens, pupil, sensor, sensor_origin_px, pixel_pitch_um, notes):
    """The profile of flats that show no fall-off to find the optical centre from (their image
    centre was only assumed): the centre the target's fit found instead, in the flats' pixels
    (less the crop's origin) where they are the sensor's own; else the image centre, recorded
    as assumed."""
    import dataclasses

    table = dict(lens.calibration)
    p = getattr(sensor, "pixel_pitch_um", None)
    if p and abs(float(pixel_pitch_um) - float(p)) <= 1e-9 * float(p):
        r0, c0 = sensor_origin_px if sensor_origin_px is not None else (0, 0)
        row, col = pupil.center_rc[0] - r0, pupil.center_rc[1] - c0
        table["center_rc"] = [float(row), float(col)]
        table["center_px"] = [float(col), float(row)]  # x first, for earlier readers
        table["center_source"] = f"the target cubes: {pupil.center_source}"
        notes.append("the flats show no fall-off to find the optical centre from: the target "
                     f"cubes' centre (sensor row {pupil.center_rc[0]:.1f}, col "
                     f"{pupil.center_rc[1]:.1f}) is the profile's")
    else:
        notes.append("the flats show no fall-off to find the optical centre from: the profile "
                     "records their image centre, assumed; give --center where it matters")
    return dataclasses.replace(lens, calibration=table)


#: Most rounds of :func:`_settled_x`; x moves by less than a tenth of its error after two
#: where the flats change with x only through every ray's cos^4.
SETTLE_ROUNDS = 4


def _settled_x(fit_x, final, pupil, flats, common, notes):
    """x fitted again with the circles the flats give at the x found, until it stays within a
    tenth of its error: a Lambertian pupil's flats weight every ray by its cos^4, which
    depends on x itself, so they fix ``P / x`` and ``h / x^2`` only approximately and the
    circles from the provisional x, scaled, are not those at the x found (15 % off from
    12.4 mm to 20.8 mm)."""
    x, sx = pupil.exit_pupil_mm, pupil.exit_pupil_stderr_mm
    for k in range(SETTLE_ROUNDS):
        again = fit_x(final.lens)
        moved = again.exit_pupil_mm - x
        pupil, x, sx = again, again.exit_pupil_mm, again.exit_pupil_stderr_mm
        final = calibrate_lens(flats, exit_pupil_mm=x, exit_pupil_stderr_mm=sx, **common)
        if abs(moved) <= 0.1 * sx:
            notes.append(f"x fitted again with the circles the flats give at it, {k + 1} "
                         f"time(s), until it moved by less than a tenth of its error: "
                         f"{x:.5g} mm")
            return pupil, final, x, sx
    notes.append(f"x fitted again with the circles the flats give at it {SETTLE_ROUNDS} "
                 f"times and still moving ({moved:+.2g} mm the last time, against an error "
                 f"of {sx:.2g} mm): its error does not cover that")
    return pupil, final, x, sx


def _consistency(first, final, x0, x):
    """Both calibrations must give the same ``P / x`` and ``h / x^2``, circle for circle:
    matched by ``h / x^2``, as the two fits may list them in either order (compared by
    index, two right circles were said to differ by 110 %)."""
    a = sorted(first.lens.vignetting, key=lambda c: c[1] / x0**2)
    b = sorted(final.lens.vignetting, key=lambda c: c[1] / x**2)
    if first.model != final.model or len(a) != len(b):
        return [f"the flats chose {first.model!r} circles at the provisional x = {x0:.4g} mm "
                f"and {final.model!r} at x = {x:.4g} mm; the second is used"]
    worst = max((max(abs(P1 / x - P0 / x0) / (P0 / x0), abs(h1 / x**2 - h0 / x0**2)
                     / max(abs(h0) / x0**2, 1e-12))
                 for (P0, h0), (P1, h1) in zip(a, b, strict=True)), default=0.0)
    if worst > SCALE_CONSISTENCY:
        return [f"P / x and h / x^2 differ by {100 * worst:.2g} % between the calibration at the "
                f"provisional x = {x0:.4g} mm and at x = {x:.4g} mm (expected: equal)"]
    return []


def _flat_block(cal: LensCalibration):
    """Names, values and covariance of the circles (and centre) the flats gave at their x,
    rescaled to the standard errors the calibration reports (the covariance's own diagonal:
    the noise's part scaled by the misfit, plus the block model's approximation). Refused if
    the flats' fit has no finite one."""
    if cal.method == "joint":
        fit = cal.fits[cal.model]  # without a circle: the centre alone, if it was fitted
        names = list(fit.names)
        if not names or fit.covariance is None:
            return [], np.zeros(0), np.zeros((0, 0))
        values = np.array([fit.params[k] for k in names], float)
        cov = np.asarray(fit.covariance, float)
        raw = np.sqrt(np.clip(np.diag(cov), 0, None))
        want = np.array([fit.stderr[k] for k in names], float)
        if not (np.all(np.isfinite(cov)) and np.all(np.isfinite(want))):
            raise ValueError("the flats' joint fit has no finite covariance (P, h or the "
                             "centre undetermined): no joint errors can be given; add flats at "
                             "more f-numbers or give center_rc= (row, col)")
        d = np.divide(want, raw, out=np.ones_like(want), where=raw > 0)
        return names, values, cov * np.outer(d, d)
    of = cal.onset_fits[cal.method.split("-")[1]]
    cov = (np.asarray(of.covariance, float) if of.covariance is not None else
           np.diag([of.P_stderr_mm ** 2, of.h_stderr_mm ** 2]))
    return ["P_mm", "h_mm"], np.array([of.P_mm, of.h_mm], float), cov


def _joint_covariance(cal: LensCalibration, pupil: PupilFit, sensor):
    """``(names, values, covariance)`` of x, the index, the circles and the centre.

    The flats' circles at the fitted ``x`` are ``P = u x``, ``h = v x^2`` with ``u``, ``v``
    known from the flats alone: their covariance there, plus ``dP/dx = P / x`` and
    ``dh/dx = 2 h / x`` times x's variance (and its covariance with the index)."""
    x = pupil.exit_pupil_mm
    pnames = ["exit_pupil_mm"]
    pvals = [x]
    pcov = np.array([[pupil.exit_pupil_stderr_mm ** 2]])
    if pupil.n_eff_fitted == "one":
        from .pupil.target import N_EFF_START

        # a vendor file gives no index: the fit's scale is of its start value
        design = np.asarray(sensor.n_eff if sensor.n_eff is not None
                            else np.full(sensor.n_bands, N_EFF_START), float)
        k_cov = np.asarray(pupil.covariance, float)[:2, :2]
        if np.ptp(design) == 0:
            pnames.append("n_eff")
            pvals.append(float(pupil.n_eff[0]))
            scale = np.diag([1.0, float(design[0])])
        else:
            pnames.append("n_eff_factor")
            pvals.append(float(pupil.n_eff[0] / design[0]))
            scale = np.eye(2)
        pcov = scale @ k_cov @ scale
        pcov[0, 0] = pupil.exit_pupil_stderr_mm ** 2  # as reported (any index model)
    fnames, fvals, fcov = _flat_block(cal)
    names = pnames + fnames
    n, m = len(pnames), len(fnames)
    # the Jacobian of (x, index, flats' params at fixed x) -> the same at the fitted x
    J = np.zeros((n + m, n + m))
    J[:n, :n] = np.eye(n)
    J[n:, n:] = np.eye(m)
    for j, name in enumerate(fnames):
        if name.startswith("P"):
            J[n + j, 0] = fvals[j] / x
        elif name.startswith("h"):
            J[n + j, 0] = 2.0 * fvals[j] / x
    block = np.zeros((n + m, n + m))
    block[:n, :n] = pcov
    block[n:, n:] = fcov
    return tuple(names), np.array(pvals + list(fvals), float), J @ block @ J.T


def _shift_stderr_from_x(cal: LensCalibration, x, sx):
    """Largest change over the field of the predicted mean shift when x moves by its error,
    with the circles scaled as the flats fix them and every pixel's chief-ray angle moving."""
    from ..optics.mean import mean_shift
    from .pupil.target_model import scaled_circles

    lens = cal.lens
    if not sx or not math.isfinite(sx):
        return np.zeros(0)
    d = np.linspace(0.0, x * math.tan(math.radians(cal.max_cra_deg)), _N_FIELD)
    out = []
    for f in cal.f_numbers:
        shifts = []
        for xi in (x - sx, x + sx):
            li = Lens(xi, scaled_circles(lens.vignetting, x, xi), lens.magnification,
                      lens.pupil_magnification, pupil_radiance=lens.pupil_radiance)
            cra = np.degrees(np.arctan(d / xi))
            cut = float(li.cutoff_cra_deg(f)) if li.has_vignetting else 90.0
            cra = np.where(cra < cut, cra, np.nan)
            shifts.append(mean_shift(choice.REFERENCE_CWL_NM, choice.REFERENCE_N_EFF, f, cra,
                                     li, method="vignetted"))
        diff = np.abs(shifts[1] - shifts[0]) / 2.0
        out.append(float(np.nanmax(diff)) if np.any(np.isfinite(diff)) else 0.0)
    return np.array(out)


def _profile(cal, pupil, names, values, cov, total, x_part, x0):
    """The lens profile: the flats' calibration at the fitted x, the target's fit, the joint
    covariance."""
    def r(v, d=6):
        return float(f"{float(v):.{d}g}")

    table = dict(cal.lens.calibration)
    pc = pupil.lens.calibration
    for key in ("n_eff", "n_eff_stderr", "n_eff_fitted", "n_eff_source"):
        if key in pc:
            table[key] = pc[key]
    table["exit_pupil_from"] = "the target cubes, fitted with the flats' circles scaled"
    table["exit_pupil_fit"] = {k: v for k, v in pc.items()
                               if k not in ("vignetting_scaled", "snapcorr_version", "date")}
    if total.size:
        table["shift_stderr_nm"] = [r(v, 4) for v in total]
        table["shift_stderr_exit_pupil_nm"] = [r(v, 4) for v in x_part]
    stderr = np.sqrt(np.clip(np.diag(cov), 0, None))
    table["joint"] = {
        "rule": ("the flats fix P / x, h / x^2 and the centre, the target x (and n_eff) with "
                 "the circles scaled at every trial x; covariance by the chain rule, the two "
                 "data sets independent"),
        "provisional_x_mm": r(x0),
        "names": list(names),
        "values": [r(v, 8) for v in values],
        "stderr": [r(v, 4) for v in stderr],
        "covariance": [[r(v, 6) for v in row] for row in cov],
    }
    lens = cal.lens
    return Lens(lens.exit_pupil_mm, lens.vignetting, lens.magnification,
                lens.pupil_magnification, name=lens.name, calibration=table,
                pupil_radiance=lens.pupil_radiance)
