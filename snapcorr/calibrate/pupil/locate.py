"""The exit pupil distance and the filters' effective index from cubes of a spectral target.

Goossens, Geelen, Lambrechts and Van Hoof (OSA Continuum 2, 2217, 2019) find the exit pupil
distance ``x`` from the spectral shift the camera itself sees on a spatially uniform target
with spectral features: a pixel at ``d`` mm from the optical axis has ``tan CRA = d / x``
(Goossens et al. 2019, Eq. 8), its filters move to the blue by Eq. (3), and a target whose
spectrum changes within the bands turns that shift into a change of signal over the field.

:func:`locate_pupil` fits the binned cubes (:mod:`~snapcorr.calibrate.pupil.target_model`: the whole
filter behind the lens, Eq. 13) by least squares in ``x`` (and ``n_eff``), the target's
spectrum either given or solved for with the field centre as reference. What the data can
tell apart:

* At small angles the field's shift depends on ``sin^2(CRA) / n_eff^2 ~ d^2 / (x n_eff)^2``:
  the field alone gives the product ``x * n_eff``.
* The cone term separates ``n_eff``: the centre's spectrum moves between f-numbers by
  ``~ cwl tan^2(theta_cone) / (4 n_eff^2)`` whatever ``x`` is. One f-number with ``n_eff``
  unknown gives ``x * n_eff`` (and says so); two or more give both.

:func:`pupil_precision` predicts, before any measurement, the standard error of ``x`` a target
would give (the Cramer-Rao bound of the same model), so a target can be chosen;
:data:`CANDIDATE_TARGETS` holds the usual ones.

The fit runs in stages, each in its own module; this one is the entry point: it strings them
together, assembles the result and re-exports every name callers import from here.

* :mod:`~snapcorr.calibrate.pupil.target`: the input: the cubes and the target's spectrum
  checked, the optical centre (:func:`estimate_target_center_rc`) and the annuli about it;
* :mod:`~snapcorr.calibrate.pupil.distance`: the search for ``x`` and the test that the target
  shows a shift at all (in sample and held out, :class:`FeaturelessTargetError`);
* :mod:`~snapcorr.calibrate.pupil.index`: the ladder of effective-index models;
* here: :func:`locate_pupil`, the choice of pupil (:func:`choose_pupil`) and the result
  (:class:`PupilFit` and its lens profile);
* :mod:`~snapcorr.calibrate.pupil.precision`: choosing a target, :func:`pupil_precision` and
  the named spectra of :data:`CANDIDATE_TARGETS`.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import functools
import math
from dataclasses import dataclass, field

import numpy as np

# ``name as name``: re-exported (the stages' constants and the named targets) for the callers
# that import it from here
from ... import __version__
from ..._coords import accepts_center_rc, called_from_outside, warn_x_first_return
from ..._validation import renamed_keywords
from ...optics.lens import (
    PUPIL_RADIANCE_MODELS,
    Lens,
    check_magnification,
    check_pupil_magnification,
)
from ...spectra import colour_filter as colour_filter
from ..lens.magnification import ratio_range
from . import magnification as _magnification
from .centre_error import (
    account_for_a_disagreeing_centre,
    account_for_the_centre,
    fastest_positions,
)
from .distance import EDGE_CRA_DEG as EDGE_CRA_DEG
from .distance import HELDOUT_SKIP as HELDOUT_SKIP
from .distance import MAX_REL_STDERR as MAX_REL_STDERR
from .distance import MIN_DELTA_CHI2 as MIN_DELTA_CHI2
from .distance import MIN_HELDOUT_SIGMA as MIN_HELDOUT_SIGMA
from .distance import (
    _check_shift_seen,
    _circles_at,
    _field_radius,
    _fit_x,
    _heldout,
    _index_at_one_f_number,
    _max_shift_rel,
    _one_blas_thread,
    _target_models,
    _trial_range,
)
from .index import N_EFF_P as N_EFF_P
from .index import N_EFF_REL_STDERR as N_EFF_REL_STDERR
from .index import _index_ladder
from .precision import (
    CANDIDATE_TARGETS,
    Precision,
    edge_mm,
    errors_not_below_the_prediction,
    precision_check,
    pupil_precision,
    target_precision,
    x_times_n_eff,
)
from .precision import DEFAULT_TOLERANCE_NM as DEFAULT_TOLERANCE_NM
from .precision import LAMP_LINES_NM as LAMP_LINES_NM
from .precision import RARE_EARTH_BANDS as RARE_EARTH_BANDS
from .precision import TargetPrecision as TargetPrecision
from .precision import line_lamp as line_lamp
from .precision import rare_earth_glass as rare_earth_glass
from .precision import white_tile as white_tile
from .solver import _Problem
from .target import (
    CENTER_FROM,
    FeaturelessTargetError,
    ImpreciseTargetError,
    _annuli,
    _check_cubes,
    _spectrum,
    check_center_from,
    check_given_center,
    check_modelled,
    check_n_bins,
    cubes_center_rc,
    estimate_target_center,
    estimate_target_center_rc,
    spectrum_short_of_the_edge,
)
from .target import IN_MEMORY_BYTES as IN_MEMORY_BYTES
from .target_model import TargetModel, scaled_circles

__all__ = [
    "CANDIDATE_TARGETS",
    "FeaturelessTargetError",
    "ImpreciseTargetError",
    "Precision",
    "PupilFit",
    "estimate_target_center",
    "estimate_target_center_rc",
    "locate_pupil",
    "pupil_precision",
]

#: The effective-index law is validated up to about this angle (Goossens 2019, Sec. 2.2).
AOI_VALIDITY_DEG = 40.0


@dataclass
class PupilFit:
    """What :func:`locate_pupil` found.

    Attributes
    ----------
    exit_pupil_mm, exit_pupil_stderr_mm : float
    n_eff : ndarray, shape (n_bands,)
        The index used: fitted (``n_eff_fitted``) or the sensor's.
    n_eff_stderr : ndarray or None
    n_eff_fitted : {"no", "one", "linear", "per band", "product"}
        ``"linear"``: the sensor's values times a factor linear in wavelength.
        ``"product"``: one f-number, index unknown; only ``x * n_eff`` is determined and
        ``exit_pupil_mm`` assumes the sensor's index.
    x_n_eff_mm, x_n_eff_stderr_mm : float
        The product ``x * mean(n_eff)`` and its standard error (what the field alone fixes).
    chi2_red : float
    center_rc : (float, float)
        The optical centre used, ``(row, col)`` sensor pixels (``center_px``, x first, is its
        earlier form, deprecated).
    center_source : str
        ``"given"``, or where it was found and its standard errors.
    center_stderr_px : (float, float) or None
        The standard errors of a centre found from the cubes (row, col); None: given. They are
        in x's and n_eff's errors (:mod:`~snapcorr.calibrate.pupil.centre_error`).
    lens : Lens
        The profile to write: ``x``, the circles and magnifications of the lens given.
    notes : list of str
    """

    exit_pupil_mm: float
    exit_pupil_stderr_mm: float
    n_eff: np.ndarray
    n_eff_stderr: np.ndarray | None
    n_eff_fitted: str
    x_n_eff_mm: float
    x_n_eff_stderr_mm: float
    chi2_red: float
    dof: int
    center_rc: tuple
    center_source: str
    spectrum: str
    lens: Lens
    model: TargetModel = field(repr=False)
    coefficients: np.ndarray = field(repr=False)
    notes: list = field(default_factory=list)
    covariance: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((1, 1)))
    """Covariance of ``x`` (mm) and, when fitted as one value, the index scale."""
    predicted: object = None
    """The precision predicted before the least squares (:class:`TargetPrecision`)."""
    center_stderr_px: tuple | None = None

    @property
    def center_px(self) -> tuple:
        """The optical centre used x first, ``(cx, cy)``: the earlier form of
        :attr:`center_rc`, removed in snapcorr 0.3."""
        if called_from_outside(2):
            warn_x_first_return("PupilFit.center_px", "PupilFit.center_rc", stacklevel=3)
        return (self.center_rc[1], self.center_rc[0])

    def summary(self) -> str:
        lines = [f"exit pupil x = {self.exit_pupil_mm:.4g} +- {self.exit_pupil_stderr_mm:.2g} mm"
                 f" (reduced chi-square {self.chi2_red:.3g}, {self.dof} degrees of freedom)"]
        n = self.n_eff
        if self.n_eff_fitted == "one":
            lines.append(f"n_eff = {n[0]:.4g} +- {self.n_eff_stderr[0]:.2g} (one value, fitted)")
        elif self.n_eff_fitted in ("linear", "per band"):
            how = "linear in wavelength" if self.n_eff_fitted == "linear" else "per band"
            lines.append(f"n_eff {how} {n.min():.4g}-{n.max():.4g}, standard errors "
                         f"{self.n_eff_stderr.min():.2g}-{self.n_eff_stderr.max():.2g}")
        elif self.n_eff_fitted == "product":
            lines.append(f"x * n_eff = {self.x_n_eff_mm:.4g} +- {self.x_n_eff_stderr_mm:.2g} mm "
                         f"(x assumes the sensor's n_eff = {np.mean(n):.4g})")
        lines.append(f"optical centre row {self.center_rc[0]:.2f}, col {self.center_rc[1]:.2f} "
                     f"({self.center_source}); target spectrum {self.spectrum}")
        lines.extend(f"note: {t}" for t in self.notes)
        return "\n".join(lines)

    def plot(self, *, bands=4):
        """The data and the model over the field for the most informative bands, and the
        chi-square against ``x``. Returns a matplotlib Figure."""
        from .report import plot_pupil_fit

        return plot_pupil_fit(self, bands=bands)

    def save_plot(self, path):
        """Write :meth:`plot` to ``path`` (PNG), atomically."""
        import matplotlib.pyplot as plt

        from ...files.png import save_png

        fig = self.plot()
        try:
            save_png(fig, path, dpi=120)
        finally:
            plt.close(fig)


@renamed_keywords(pupil="pupil_radiance")
@accepts_center_rc
@_one_blas_thread
def locate_pupil(cubes, sensor, *, lens: Lens | None = None, fit_n_eff=False, center_rc=None,
                 center_px=None, target_spectrum=None, sensor_origin_px=None, magnification=None,
                 pupil_magnification=None, profile="gaussian", n_bins=96, inputs=None,
                 name=None, progress=None, scale_circles=None, pupil_radiance=None,
                 tolerance_nm=None, report=None, center_from="given",
                 center_checks=None) -> PupilFit:
    """The exit pupil distance ``x`` (and ``n_eff``) from flat-fielded cubes of a target.

    Parameters
    ----------
    cubes : dict of float -> xarray.DataArray
        Flat-fielded cubes (``(y, x, band)``, the sensor's bands) of one uniform target with
        spectral features, by f-number.
    sensor : Sensor
    lens : Lens, optional
        Its vignetting circles (P, h), magnification and pupil magnification are used and
        copied to the result; its ``x`` is not (the search scans the field edge's chief-ray
        angles, :data:`EDGE_CRA_DEG`). Give the circles wherever the fastest f-number is
        vignetted inside the field: without them that cube misleads.
    fit_n_eff : bool
        Fit the effective index too: one value (the sensor's values times one factor), or,
        where the data ask for it and constrain it (``N_EFF_P``, ``N_EFF_REL_STDERR``), the
        sensor's values times a factor linear in wavelength, or one per band. With one
        f-number only ``x * n_eff`` is determined: the result says so.
    center_rc, center_px : (row, col), optional
        Optical centre in sensor pixels (default: found from the cubes); ``center_px``: its
        deprecated x-first form.
    target_spectrum : callable or (wavelength_nm, value), optional
        The target's spectrum, known up to a scale per cube (default: unknown, solved for).
    sensor_origin_px : (row, col), optional
        The sensor row and column of the cubes' first pixel (crops without positions).
    magnification, pupil_magnification : float, optional
        m and m_P of the working f-number, Eq. (27), in place of the lens's; None: not given
        (the lens's, if it states them). Those not given are assumed (m = 0, m_P = 1) and
        judged over a plausible range (:func:`~snapcorr.calibrate.lens.magnification.
        ratio_range`), their spread in the errors of x and n_eff, with a ``MagnificationWarning``
        (:mod:`~snapcorr.calibrate.pupil.magnification`); a lens whose circles came from flats
        at an assumed ratio has them rescaled to the ratio given.
    profile : str
        The filters' shape (a name in :data:`snapcorr.optics.PROFILES`); not used for a
        sensor with measured responses, whose whole curves are the filters
        (:class:`~snapcorr.calibrate.pupil.measured_target.MeasuredTargetModel`).
    n_bins : int
        Annuli per cube.
    progress : callable, optional
        ``progress(step)`` before every evaluation of the model (a progress bar).
    scale_circles : bool, optional
        The lens's circles came from flats at its ``x`` (``calibrate_lens``), which fix ``P /
        x`` and ``h / x^2``: they are scaled to every trial ``x``, and written at the ``x``
        found. Default: where the lens's calibration says so (``exit_pupil_scaling``).
    pupil_radiance : {None, "paper", "lambertian", "paper-lambertian", "auto"}
        How the light fills the pupil (:data:`snapcorr.optics.lens.PUPIL_RADIANCE_MODELS`;
        ``pupil=``: its deprecated name). None: the lens's (the paper's without a lens).
        ``"auto"``: every one is fitted, and one other than the paper's is
        kept only if it lowers chi-square by more than :data:`PUPIL_CHI2_GAIN` (they have the
        same parameters); the choice and the chi-squares are in the notes and the profile.
        A lens with circles keeps its own pupil (they were found with its radius).
    tolerance_nm : float, optional
        The shift precision needed (nm, one standard deviation). Before the least squares the
        precision the cubes can give is predicted (:func:`~snapcorr.calibrate.pupil.precision.
        target_precision`: the Fisher information at the search's start, with the annuli's
        noise), as the chief ray's shift at the sensor's (or the cubes') corner in the longest
        band; a target that cannot reach it is refused (:class:`ImpreciseTargetError`). None:
        not checked (the prediction is in ``PupilFit.predicted`` all the same).
    report : callable, optional
        ``report(text)`` with the prediction, before the least squares.
    center_from : {"given", "flats"}
        Where ``center_rc`` came from, as a refusal of it says (:data:`~snapcorr.calibrate.
        pupil.target.CENTER_FROM`): the caller's, or the flats' (``calibrate_with_target``).
    center_checks : dict, optional
        The given centre's checks against these cubes (seconds each), kept by centre: one dict
        for every fit of the same cubes about the same centre checks it once.

    Returns
    -------
    PupilFit

    Raises
    ------
    FeaturelessTargetError
        The target's signal does not change over the field above the noise.
    ImpreciseTargetError
        (a ``FeaturelessTargetError``) The target cannot give the shift to ``tolerance_nm``.
    """
    if magnification is not None:  # refused before any work, naming the keyword
        magnification = check_magnification(magnification)
    if pupil_magnification is not None:
        pupil_magnification = check_pupil_magnification(pupil_magnification)
    check_center_from(center_from)
    args = dict(locals())
    for k in ("center_px", "center_from", "center_checks"):  # center_px: now center_rc
        del args[k]
    given, _, rng = ratio_range(magnification, pupil_magnification, lens)
    if lens is not None:  # m, m_P given override the lens's (circles from flats rescaled)
        args["lens"] = _magnification.with_given(lens, magnification, pupil_magnification)
    fit = _fit_checking_the_centre(args, center_from, center_checks)
    if rng[1] > rng[0]:  # m / m_P assumed: its spread in x's and n_eff's errors, said
        fit = _magnification.account_for_pupil_magnifications(
            fit, given, rng, functools.partial(_refit, args, fit), stacklevel=6)
    return fit


def _fit_checking_the_centre(args, center_from, checks):
    """:func:`_checked_locate` of ``args``, a given centre checked against the cubes once (the
    refits for assumed magnifications hold their own centre), a found one's error carried into
    x's and n_eff's (:func:`~snapcorr.calibrate.pupil.centre_error.account_for_the_centre`)."""
    center_rc = args["center_rc"]
    doubt = (None if center_rc is None else
             _center_doubt(args["cubes"], args["sensor"], args["lens"],
                           args["sensor_origin_px"], center_rc, center_from, checks))
    fit = _checked_locate(**args)
    if center_rc is None:
        _refuse_a_lost_centre(fit, min(args["cubes"]))
    if doubt is not None:
        return _given_center_doubted(fit, doubt, center_from)
    if center_rc is not None:
        fit = _compared_with_found_centre(args, fit, center_from)
    if fit.center_stderr_px is not None:  # found: its error in x's and n_eff's
        rows, cols = fastest_positions(args["cubes"], args["sensor"], args["lens"],
                                       args["sensor_origin_px"])
        fit = account_for_the_centre(fit, fit.center_stderr_px, rows, cols,
                                     functools.partial(_refit_about, args, fit))
    return fit


#: Above this reduced chi-square a fit about the centre the cubes found is refused: its x
#: is not a measurement (an axis near a corner of 128 x 160 cubes, 0.5 % noise: the centre
#: found 24-1500 px astray, x 132-148 mm for 21, reduced chi-square 80-325); the centre
#: given gives x to 0.0001 %. The lens calibration refuses such a centre alike.
LOST_CENTRE_CHI2_RED = 10.0


def _refuse_a_lost_centre(fit, f0):
    """Refuse a fit about a found centre that misses the data grossly
    (:data:`LOST_CENTRE_CHI2_RED`), naming the centre and the way out."""
    if fit.chi2_red > LOST_CENTRE_CHI2_RED:
        raise ValueError(
            f"the fit about the optical centre the f/{f0:g} cube places (row "
            f"{fit.center_rc[0]:.1f}, col {fit.center_rc[1]:.1f}) misses the data (reduced "
            f"chi-square {fit.chi2_red:.3g} over {fit.dof} degrees of freedom), so x and n_eff "
            "would not be measurements: the centre is likely misplaced (an axis near the "
            "cubes' edge or outside them); give the centre (center_rc=), from the lens's "
            "flats, or check that the cubes are of one uniform target and this lens")


#: A given centre the cubes place far from it by their errors (more than
#: :data:`CENTER_COMPARED_SIGMAS` of the fit's own and :data:`CENTER_COMPARED_PX`) is fitted
#: about theirs too. Refused where that lowers chi-square by more than this plus
#: :data:`CENTER_CHI2_SIGMAS` times chi-square's spread, ``sqrt(2 dof)`` (the annuli about
#: another centre are other data): 10 px off on a 128 x 160 sensor, 7.3 against 0.97 over
#: 478 degrees of freedom. Else the difference of the two fits is in the errors
#: (:func:`~snapcorr.calibrate.pupil.centre_error.account_for_a_disagreeing_centre`):
#: chi-square's level hardly tells centres 2-10 px off, whose x was 11-37 of its errors off.
CENTER_CHI2_GAIN = 25.0
CENTER_CHI2_SIGMAS = 5.0
CENTER_COMPARED_SIGMAS = 5.0
CENTER_COMPARED_PX = 0.5


def _compared_with_found_centre(args, fit, center_from):
    """The fit about a given centre, compared with one about the centre the cubes place
    where that lies far from it by its errors: refused where theirs fits clearly better,
    left as it is where theirs fits clearly worse (an axis near the cubes' corner, whose
    estimate went 1500 px astray and fitted at a reduced chi-square of 80-325, had widened
    x's error 0.0031 mm to 127 mm), else widened by the difference. A centre the cubes
    cannot place (a crop far from the axis whose estimate fails) leaves the fit as it is."""
    placed = cubes_center_rc(args["cubes"], args["sensor"], args["lens"],
                             args["sensor_origin_px"])
    if placed is None:
        return fit
    found, err = placed
    given = args["center_rc"]
    d = (given[0] - found[0], given[1] - found[1])
    if math.hypot(*d) < CENTER_COMPARED_PX or not math.hypot(
            d[0] / max(err[0], 1e-9), d[1] / max(err[1], 1e-9)) > CENTER_COMPARED_SIGMAS:
        return fit
    try:
        other = _checked_locate(**{**args, "center_rc": found, "report": None,
                                   "tolerance_nm": None})
    except ValueError:  # the cubes' centre cannot be fitted about: no evidence against
        return fit
    gain = fit.chi2_red * fit.dof - other.chi2_red * other.dof
    if -gain > CENTER_CHI2_GAIN + CENTER_CHI2_SIGMAS * math.sqrt(2 * fit.dof):
        return fit  # theirs fits clearly worse: no evidence against the centre given
    if gain > CENTER_CHI2_GAIN + CENTER_CHI2_SIGMAS * math.sqrt(2 * fit.dof):
        raise ValueError(
            f"{CENTER_FROM[center_from]} (row {given[0]:g}, col {given[1]:g}) fits the cubes "
            f"clearly worse than the centre the f/{min(args['cubes']):g} cube places (row "
            f"{found[0]:.1f}, col {found[1]:.1f}): chi-square higher by {gain:.0f} (reduced "
            f"{fit.chi2_red:.3g} against {other.chi2_red:.3g} over {fit.dof} degrees of "
            f"freedom), and x rests on the centre: {_CENTER_ADVICE[center_from]}")
    return account_for_a_disagreeing_centre(fit, other, found, CENTER_FROM[center_from])


def _center_doubt(cubes, sensor, lens, sensor_origin_px, center_rc, center_from, checks):
    """:func:`check_given_center`, looked up in ``checks`` (a dict, or None) and kept there."""
    if checks is None:
        return check_given_center(cubes, sensor, lens, sensor_origin_px, center_rc,
                                  center_from)
    key = (tuple(float(v) for v in center_rc), center_from,
           None if sensor_origin_px is None else tuple(float(v) for v in sensor_origin_px))
    if key not in checks:
        checks[key] = check_given_center(cubes, sensor, lens, sensor_origin_px, center_rc,
                                         center_from)
    return checks[key]


#: What a refusal of a given centre advises, by where it came from (``center_from``).
_CENTER_ADVICE = {
    "given": "give the centre in sensor pixels of the lens these cubes were taken with, or "
             "leave it out to use the one found",
    "flats": "the flats and the target cubes do not agree on the axis: take both with the "
             "same lens, focus and sensor area, or give the centre in sensor pixels "
             "(center_rc=) where it is known"}


def _given_center_doubted(fit, doubt, center_from="given"):
    """A fit about a given centre its cubes place elsewhere (``doubt``): refused where the
    fit also misses the data beyond the noise (a wrong centre: 5000,5000 on a 1088 x 2048
    sensor fitted x = 86 +- 0.25 mm for 21, at a reduced chi-square of 1.49 over 2601
    degrees of freedom); else kept, the doubt in its notes and its profile (a crop far from
    the axis can place the centre wrongly itself). The advice is the one true where the
    centre came from (``center_from``)."""
    if _misfits(fit.chi2_red, fit.dof):
        raise ValueError(f"{doubt}, and the fit about it misses the data (reduced chi-square "
                         f"{fit.chi2_red:.3g} over {fit.dof} degrees of freedom): "
                         f"{_CENTER_ADVICE[center_from]}")
    whose = "the given centre" if center_from == "given" else "the flats' centre"
    said = f"{doubt}; the fit about {whose} matches the data, so it is kept"
    fit.notes.append(said)
    cal = dict(fit.lens.calibration)
    cal["center_doubt"] = said
    fit.lens = dataclasses.replace(fit.lens, calibration=cal)
    return fit


def _misfits(chi2_red, dof):
    """Whether a reduced chi-square over ``dof`` is more than the noise explains
    (:data:`MISFIT_CHI2_RED`, :data:`MISFIT_P`)."""
    from scipy import stats

    return chi2_red > 2.0 or (chi2_red > MISFIT_CHI2_RED
                              and float(stats.chi2.sf(chi2_red * dof, dof)) < MISFIT_P)


def _refit_about(args, fit, center_rc):
    """The fit of ``args`` made again about ``center_rc``, its pupil held at ``fit``'s."""
    return _locate(**{**args, "center_rc": center_rc, "pupil_radiance": fit.lens.pupil_radiance,
                      "tolerance_nm": None, "report": None})


def _refit(args, fit, ratio):
    """The fit of ``args`` made again at ``m / m_P = ratio`` (the lens's circles rescaled as
    flats would give them there), the centre and pupil held at those of ``fit``."""
    lens = args["lens"]
    again = {**args, "center_rc": fit.center_rc, "pupil_radiance": fit.lens.pupil_radiance,
             "tolerance_nm": None, "report": None, "magnification": ratio,
             "pupil_magnification": 1.0}
    if lens is not None:
        again["lens"] = _magnification.at_ratio(lens, ratio)
        if again["scale_circles"] is None:
            again["scale_circles"] = "exit_pupil_scaling" in lens.calibration
    return _locate(**again)


def _checked_locate(cubes, sensor, *, lens, fit_n_eff, center_rc, target_spectrum,
                    sensor_origin_px, magnification, pupil_magnification, profile, n_bins,
                    inputs, name, progress, scale_circles, pupil_radiance, tolerance_nm,
                    report):
    """:func:`locate_pupil` with m and m_P settled, the assumption's spread left out."""
    if (lens is not None and lens.has_vignetting
            and pupil_radiance not in (None, lens.pupil_radiance)):
        raise ValueError(f"the lens's vignetting circles belong to the {lens.pupil_radiance} "
                         "pupil (its radius sets their onsets); the "
                         f"{pupil_radiance} pupil would need them found again: fit flats and "
                         "target together, which chooses the pupil (calibrate_with_target "
                         "with pupil_radiance 'auto'; on the command line snapcorr calibrate "
                         "--target-cube --pupil-radiance auto)")
    if pupil_radiance == "auto":
        return _either_pupil(locals())
    return _locate(**locals())


def _locate(cubes, sensor, *, lens, fit_n_eff, center_rc, target_spectrum, sensor_origin_px,
            magnification, pupil_magnification, profile, n_bins, inputs, name, progress,
            scale_circles, pupil_radiance, tolerance_nm, report):
    """:func:`locate_pupil` for one pupil (its body); the centre ``(row, col)``."""
    n_design = check_modelled(sensor, "the exit-pupil fit (snapcorr pupil)",
                              fit_n_eff=bool(fit_n_eff))
    if sensor.responses is not None:  # each band's whole measured curve, not a profile
        profile = "measured"
    cubes = _check_cubes(cubes, sensor, **({} if center_rc is None else {"min_side": 1}))
    n_bins = check_n_bins(n_bins)
    base = lens or Lens(30.0, (), magnification or 0.0,
                        pupil_magnification if pupil_magnification is not None else 1.0)
    if pupil_radiance is not None:
        base = dataclasses.replace(base, pupil_radiance=pupil_radiance)
    spectrum, spectrum_desc = _spectrum(target_spectrum, sensor)
    nb = sensor.n_bands
    bins, center, center_source, center_err = _annuli(cubes, sensor, lens, sensor_origin_px,
                                                      center_rc, n_bins)
    r_max = _field_radius(bins)
    x_lo, x_hi = _trial_range(r_max)
    cone = math.radians(float(base.cone_angle_deg(min(cubes))))  # the fastest cube's cone
    max_rel = _max_shift_rel(r_max, x_lo, n_design, cone)
    circles_at = _circles_at(lens, base, scale_circles)
    model, coarse = _target_models(bins, sensor, base, n_design, spectrum, profile, max_rel,
                                   circles_at)
    problem = _Problem(model, n_design, progress)
    several = len(cubes) >= 2
    fit_k = bool(fit_n_eff)
    predicted, edge, cwl_max = [], edge_mm(sensor, center, r_max), float(np.max(sensor.cwl_nm))
    before = precision_check(problem, fit_k, edge, cwl_max, tolerance_nm, report, predicted)
    p, cov, r, s, rank = fit = _fit_x(problem, coarse, sensor, r_max, x_lo, x_hi, fit_k, before)
    one_f = None
    if fit_k and not several:
        pred_n = predicted[0].n_eff_stderr
        (p, cov, r, s, rank), one_f = _index_at_one_f_number(
            problem, fit, x_lo, x_hi, model.n_rows,
            pred_n / float(np.mean(n_design)) if pred_n is not None else math.inf)
        if one_f is not None:
            _one_f_number_needs_an_index(sensor, one_f, min(cubes))
            fit_k = False
            predicted[0] = target_precision(problem, float(p[0]), False, edge, cwl_max)
    x, k = float(p[0]), float(p[1]) if fit_k else 1.0
    chi2 = float(r @ r)
    dof = max(round(model.n_rows - rank - len(p)), 1)
    chi2_red = chi2 / dof
    scale = max(1.0, chi2_red)
    err = np.sqrt(np.clip(np.diag(cov), 0, None) * scale)
    _check_shift_seen(problem, x, k, chi2, rank, len(p), scale, err[0], _heldout(
        bins, sensor, base, n_design, spectrum, profile, max_rel, circles_at,
        (r_max, x_lo, x_hi), n_design * k))
    n = n_design * k
    n_err = n_design * err[1] if fit_k else None
    mode = "one" if fit_k else ("product" if fit_n_eff else "no")
    notes = _one_f_number_notes(one_f, fit_n_eff and not several, err, k)
    if fit_k and nb >= 2:
        mode, x, x_err, n, n_err, chi2, red = _index_ladder(problem, x, n, float(err[0]),
                                                            n_err, chi2, scale, notes)
        if mode != "one":
            err, cov, chi2_red = np.array([x_err]), np.array([[x_err**2 / scale]]), red
    xn, xn_err = x_times_n_eff(x, n, err, cov * scale, k, n_design, fit_k and mode == "one")
    if one_f is not None:  # with the index free: its error includes the index's
        xn, xn_err = one_f.x_n_eff_mm, one_f.x_n_eff_stderr_mm
    err[0], n_err, xn_err, cov = errors_not_below_the_prediction(
        x, float(err[0]), n_err, xn_err, predicted[0], notes, cov)
    notes += _validity_notes(r_max, x, cone, chi2_red, dof)
    short = spectrum_short_of_the_edge(spectrum, sensor, r_max, x, n, cone, min(cubes))
    notes += [short] if short else []
    notes += _scaled_lambertian_circles(base, circles_at, x, err[0])
    out_lens = _result_lens(base, lens, x, err[0], n, n_err, mode, xn, xn_err, chi2_red, dof,
                            center, center_source, sensor, cubes, spectrum_desc, profile,
                            inputs, name, circles_at)
    pred = predicted[0]
    out_lens.calibration["predicted_before_fit"] = {
        "x_stderr_mm": float(f"{pred.x_stderr_mm:.3g}"),
        **({} if pred.n_eff_stderr is None else
           {"n_eff_stderr": float(f"{pred.n_eff_stderr:.3g}")}),
        "shift_stderr_nm": float(f"{pred.shift_stderr_nm:.3g}"),
        **({} if pred.n_eff_band_stderr is None else {"n_eff_per_band_stderr_range": [
            float(f"{np.min(pred.n_eff_band_stderr):.3g}"),
            float(f"{np.max(pred.n_eff_band_stderr):.3g}")]}),
        "at_mm": float(f"{pred.edge_mm:.4g}"), "cwl_nm": float(f"{pred.cwl_nm:.5g}"),
        **({} if tolerance_nm is None else {"tolerance_nm": float(tolerance_nm)})}
    return PupilFit(x, float(err[0]), np.asarray(n, float),
                    None if n_err is None else np.asarray(n_err, float), mode, xn, xn_err,
                    chi2_red, dof, center, center_source, spectrum_desc, out_lens, model, s,
                    notes, cov * scale, pred,
                    None if center_err is None else tuple(float(e) for e in center_err))


def _one_f_number_needs_an_index(sensor, said, f_number):
    """Refuse a sensor without an index (a vendor file) where one f-number does not pin it."""
    if sensor.n_eff is None:
        raise ValueError(
            f"one f-number (f/{f_number:g}) does not pin the effective index here (to "
            f"{100 * said.rel_stderr:.2g} % from the field alone, where "
            f"{100 * N_EFF_REL_STDERR:g} % is needed) and the sensor {sensor.name!r} gives "
            "none: add cubes at a second f-number far from this one (e.g. f/2 and f/8), or "
            "give n_eff in a sensor TOML naming the vendor file (vendor_file = ..., n_eff = "
            "...)")


def _one_f_number_notes(said, one_f_number, err, k):
    """What one f-number told of the index, for the fit's notes."""
    if not one_f_number:
        return []
    if said is None:
        return [f"one f-number: the field alone (the curvature of sin^2 against tan^2 of the "
                f"chief-ray angle, the cone's tilt off axis) pins the index to "
                f"{100 * err[1] / k:.2g} %"]
    return [f"one f-number: the field alone pins the index to {100 * said.rel_stderr:.2g} % "
            f"only (not {100 * N_EFF_REL_STDERR:g} %), so x assumes the sensor's n_eff and "
            "its error is given that index; x * n_eff is from the fit with the index free, "
            "its error including the index's. A cube at a second f-number (far apart, e.g. "
            "f/2 and f/8) separates them through the cone term"]


#: ``pupil_radiance="auto"`` keeps the Lambertian pupil only if it lowers chi-square by more
#: than this (the two models have the same parameters: a likelihood ratio of exp(5), as the lens
#: calibration's :data:`~snapcorr.calibrate.lens.choice.MIN_BIC_GAIN`).
PUPIL_CHI2_GAIN = 10.0


def _either_pupil(args):
    """``locate_pupil(pupil_radiance="auto")``: every pupil fitted, the paper's kept unless
    another fits clearly better."""
    args = {k: v for k, v in args.items() if k != "pupil_radiance"}
    fits = {}
    for name in PUPIL_RADIANCE_MODELS:
        try:
            fits[name] = _checked_locate(**args, pupil_radiance=name)
            args["report"] = None  # the precision said once, for the first pupil fitted
        except FeaturelessTargetError:
            raise
        except ValueError as err:  # e.g. a numerical aperture of 1 for one of them
            fits[name] = err
    ok = {k: v for k, v in fits.items() if isinstance(v, PupilFit)}
    if not ok:
        raise fits["paper"]
    failed = [f"the {k} pupil could not be fitted ({v})" for k, v in fits.items() if k not in ok]
    chosen = choose_pupil(ok, {k: v.chi2_red * v.dof for k, v in ok.items()}, "chi-square")
    chosen.notes.extend(failed)
    return chosen


def choose_pupil(results, chi2, what, *, key="chi2"):
    """The result to keep of ``results`` (pupil -> a result with ``notes`` and ``lens``):
    the paper's pupil unless the best of the others lowers ``chi2`` (pupil -> chi-square, or
    another criterion ``what`` names: a BIC) by more than :data:`PUPIL_CHI2_GAIN`; the
    choice and every value go into its notes and its lens's ``[calibration] pupil_choice``,
    under ``key``."""
    others = {k: v for k, v in chi2.items() if k != "paper" and k in results}
    best = min(others, key=others.get) if others else "paper"
    gain = chi2.get("paper", np.inf) - chi2.get(best, np.inf)
    name = best if "paper" not in results or gain > PUPIL_CHI2_GAIN else "paper"
    got = results[name]
    said = ", ".join(f"{k} {v:.6g}" for k, v in chi2.items())
    note = (f"pupil: {name} ({what} {said}; a pupil other than the paper's is kept only for "
            f"a gain above {PUPIL_CHI2_GAIN:g})")
    got.notes.append(note)
    cal = dict(got.lens.calibration)
    if "notes" in cal:  # a profile that keeps its notes (the flats' calibration) keeps this
        cal["notes"] = [*cal["notes"], note]
    cal["pupil_choice"] = {"chosen": name, "rule": f"{what}: a gain > {PUPIL_CHI2_GAIN:g}",
                           key: {k: float(f"{v:.6g}") for k, v in chi2.items()}}
    got.lens = dataclasses.replace(got.lens, calibration=cal)
    return got


#: A fit's reduced chi-square is said to be more than the noise explains above this, where
#: the chance of so large a one from noise alone is below :data:`MISFIT_P` (a wrong optical
#: centre gave 1.49 over 2601 degrees of freedom, x = 86 mm for 21); fits of cubes from
#: physical rays behind the right lens give 1.00.
MISFIT_CHI2_RED = 1.1
MISFIT_P = 1e-6


#: Relative distance between the x a Lambertian pupil's circles were found at and the x
#: fitted beyond which :func:`_scaled_lambertian_circles` says their scaling is in doubt.
LAMBERTIAN_SCALING_REL = 0.01


def _scaled_lambertian_circles(base, circles_at, x, x_err):
    """Where a Lambertian pupil's circles, found by flats at another x, were scaled to the
    trial x: its flats fix ``P / x`` and ``h / x^2`` only approximately (every ray's cos^4
    depends on x), so x leans towards where they were found (12.4 mm circles scaled to
    20.8 mm were 15 % off, x 24 of its errors low)."""
    if circles_at is None or base.ray_weight != "cos4":
        return []
    if abs(x - circles_at) <= max(LAMBERTIAN_SCALING_REL * x, 0.1 * x_err):
        return []
    return [f"the circles were found by flats at x = {circles_at:.4g} mm and scaled to "
            f"{x:.4g} mm; for a Lambertian pupil that scaling is only approximate: calibrate "
            "the flats again at this x (calibrate --lens with this profile) and fit x again, "
            "or give flats and target together (calibrate --target-cube)"]


def _validity_notes(r_max, x, cone_rad, chi2_red, dof):
    """Notes where rays pass the index law's validated angle, or the model misfits."""
    notes = []
    aoi = math.degrees(math.atan(r_max / x + math.tan(cone_rad)))  # from the pupil's far rim
    if aoi > AOI_VALIDITY_DEG:
        notes.append(f"rays reach the filters at up to {aoi:.1f} deg; the effective-index law "
                     f"is validated up to about {AOI_VALIDITY_DEG:g} deg (Goossens 2019, Sec. "
                     "2.2): x rests on its extrapolation")
    if _misfits(chi2_red, dof):
        notes.append(f"reduced chi-square {chi2_red:.3g} over {dof} degrees of freedom is more "
                     "than the noise explains: the model misses something (an optical centre "
                     "or a lens that is not these cubes', a target that is not uniform, stray "
                     "light, another filter shape); the errors are scaled by it, which does "
                     "not cover such a misfit")
    return notes


def _result_lens(base, lens, x, x_err, n, n_err, mode, xn, xn_err, chi2_red, dof, center_rc,
                 center_source, sensor, cubes, spectrum_desc, profile, inputs, name,
                 circles_at=None):
    def r(v, d=6):
        return float(f"{float(v):.{d}g}")

    uniform = bool(np.ptp(n) == 0)
    cal = {
        "source": "flat-fielded cubes of a spatially uniform spectral target",
        "method": ("least squares of the binned cubes: whole filter behind the lens (Goossens "
                   "et al. 2019, Eq. 13; exit pupil as in Goossens et al., OSA Continuum 2019)"),
        "f_numbers": [float(f) for f in cubes],
        "exit_pupil_stderr_mm": r(x_err, 3),
        "reduced_chi2": r(chi2_red, 4),
        "degrees_of_freedom": int(dof),
        "n_eff_fitted": mode,
        "x_times_n_eff_mm": r(xn),
        "x_times_n_eff_stderr_mm": r(xn_err, 3),
        "target_spectrum": spectrum_desc,
        "filter_profile": profile,
        "sensor": sensor.name,
        "center_rc": [r(center_rc[0], 8), r(center_rc[1], 8)],
        "center_px": [r(center_rc[1], 8), r(center_rc[0], 8)],  # x first, for earlier readers
        "center_source": center_source,
        "pixel_pitch_um": float(sensor.pixel_pitch_um),
        "snapcorr_version": __version__,
        "date": _dt.date.today().isoformat(),
    }
    if mode in ("one", "linear", "per band"):
        cal["n_eff"] = r(n[0]) if uniform else [r(v) for v in n]
        cal["n_eff_stderr"] = (r(n_err[0], 3) if mode == "one" and uniform
                               else [r(v, 3) for v in n_err])
    else:
        cal["n_eff"] = r(n[0]) if uniform else [r(v) for v in n]
        cal["n_eff_source"] = "the sensor's (not fitted)"
    if sensor.size_px is not None:
        cal["image_size_px"] = [int(sensor.size_px[1]), int(sensor.size_px[0])]
    if inputs:
        cal["inputs"] = {f"f{float(f):g}": str(p) for f, p in inputs.items()}
    circles = base.vignetting
    if lens is not None:
        cal["vignetting_from"] = lens.name or "the lens given"
        if lens.calibration.get("method"):
            cal["vignetting_method"] = str(lens.calibration["method"])
    if circles_at is not None:
        circles = scaled_circles(base.vignetting, circles_at, x)
        cal["vignetting_scaled"] = {
            "from_x_mm": float(circles_at),
            "circles_at_that_x_mm": [[float(P), float(h)] for P, h in base.vignetting],
            "rule": "the flats fix P / x and h / x^2: P scaled as x, h as x^2, to the x found"}
    return Lens(x, circles, base.magnification, base.pupil_magnification,
                name=name or (lens.name if lens is not None else "lens (exit pupil from a target)"),
                calibration=cal, pupil_radiance=base.pupil_radiance)
