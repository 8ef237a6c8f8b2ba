"""Flat fields at several f-numbers in, a lens profile out (Goossens et al. 2019, Sec. 2.7, 3.2).

Two estimators of the vignetting circles are run on the same flats and both are reported:

``onset``
    The paper's: each flat is divided by the flat at the highest f-number, the onset of
    vignetting is located in the radial profile of that ratio (:func:`detect_onset`), and the
    onsets give P and h through the least squares of Eq. (26). It uses only where the fall-off
    starts, so effects the area model leaves out (pupil aberrations, an f-number-dependent
    natural fall-off) barely bias it; but it throws away the shape of the fall-off, and it
    sees one circle.
``joint``
    The vignetted-pupil area model fitted to every ratio image at once, with the optical centre
    (:mod:`snapcorr.calibrate.lens.joint_fit`), for no circle and one to three circles. It uses
    every pixel, so it is several times more precise at a given noise (``benchmarks/``).
    :mod:`snapcorr.calibrate.lens.choice` picks the model: circles that cannot be identified are
    never chosen, the criterion allows for model error, and a further circle must change the
    predicted mean shift by more than a tolerance.

``method="auto"`` keeps the joint fit unless the paper's onsets are shown to predict better:
each flat but the reference is left out in turn, both estimators are fitted without it and
predict it, and the onsets are used only where their summed chi-square is lower by more than
``predictive.MIN_PREDICTIVE_GAIN`` (:mod:`snapcorr.calibrate.lens.predictive`). A chi-square
threshold cannot make this choice: with millions of pixels a harmless misfit is significant.
Whichever is used reports the standard error of the mean shift it predicts. The stages
are in :mod:`snapcorr.calibrate.lens.stages`; the summary and the picture in
:mod:`snapcorr.calibrate.lens.report`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..._coords import accepts_center_rc, called_from_outside, warn_x_first_return
from ..._names import CALIBRATION_METHODS
from ..._validation import (
    check_center,  # noqa: F401 (calibrate.lens_calibration re-exports it)
    check_center_rc,
    check_integers,
    check_pixel_pitch_um,
    check_positive,
    renamed_keywords,
)
from ...optics.chief_ray import cra_map
from ...optics.lens import (
    PUPIL_RADIANCE_MODELS,
    Lens,
    check_length_mm,
    check_magnification,
    check_pupil_magnification,
)
from ...optics.shift import EffectiveIndexWarning
from ..flats.cleaning import check_mosaic_sensor
from . import choice, report, stages
from .estimator import (
    _decide_method,
    _next_best,
    _precision_notes,
    _predict,
    _shift_errors,
    _unless_joint,
    _x_notes,
)
from .joint_fit import CENTER_NAMES
from .table import _calibration_table

__all__ = ["METHODS", "LensCalibration", "calibrate_lens"]

METHODS = CALIBRATION_METHODS


@dataclass
class LensCalibration:
    """Everything a calibration found, and the lens profile it gives.

    Attributes
    ----------
    lens : Lens
        The profile: every circle of the chosen joint-fit model (none if no vignetting was
        found), or the one circle of an onset method where that was used.
    method, model : str
        Estimator used (``"joint"``, ``"onset-ratio"`` or ``"onset-model"``) and vignetting
        model chosen (``"none"``, ``"one"``, ``"two"`` or ``"three"`` circles).
    reason : str
        Why, in a sentence.
    f_numbers : ndarray
    center_rc : (float, float)
        Optical centre used, ``(row, col)`` pixels (``center_px``, x first, is its earlier
        form, deprecated).
    center_source : str
        ``"given"``, ``"contours"``, ``"joint fit"`` or ``"image centre"``.
    onsets : dict
        Detector -> {f-number -> :class:`Onset`}: ``"ratio"``, the discontinuity of the ratio
        profile (the paper's way), and ``"model"``, the area model fitted to each profile.
    onset_fits : dict
        Detector -> :class:`OnsetFit` of Eq. (26) over its onsets (None with fewer than two).
    fits : dict
        Model name -> :class:`ModelFit` of the joint fit.
    bic_floor : dict
        Model name -> information criterion with the systematic floor.
    verdicts : dict
        Model name -> :class:`~snapcorr.calibrate.lens.choice.ModelVerdict`: chosen or why not.
    next_best : str or None
        The best model not chosen, and ``shift_difference_nm`` the largest difference of the
        predicted mean shift between it and the chosen one at each f-number.
    shift_stderr_nm : ndarray
        The standard error of the predicted mean shift, largest over the field, at each
        f-number, for a filter at ``choice.REFERENCE_CWL_NM`` with ``choice.REFERENCE_N_EFF``:
        ``shift_stderr_fit_nm`` (what the uncertainty of P and h leaves, for the estimator
        used, scaled up by the fit's misfit) and ``shift_stderr_model_nm`` (the models the
        rules could not rule out: see
        :func:`~snapcorr.calibrate.lens.choice.model_choice_stderr`) in quadrature. Empty
        where there is neither (no circle, and no other model in question). The fit's part
        is in turn ``shift_stderr_noise_nm`` (the flats' noise, scaled by the misfit: the
        part that averaging frames lowers) and the block model's approximation
        (:func:`~snapcorr.calibrate.lens.joint_fit._rule_bias`), in quadrature.
    rivals : dict
        Name -> ``(ModelFit, floored BIC)`` of models never chosen that count in the model
        choice's error, where two circles were fitted: ``"pixel"``, the first circle plus
        pixel vignetting (``h = x``, :func:`snapcorr.calibrate.lens.stages.pixel_rival`); or
        ``"free"``, the free second circle, where the pixel's had the lower BIC and is the
        two-circle model.
    predictive : dict
        Estimator -> :class:`~snapcorr.calibrate.lens.predictive.Prediction`: how well each
        predicted the flats left out (``auto`` with circles only).
    profiles, ratio_profiles : dict
        f-number -> :class:`RadialProfile` of each flat and of its ratio to the reference.
    mosaic : dict
        Raw flats of a snapshot mosaic: ``sensor``, ``sensor_origin_px`` (None: the whole
        sensor) and ``band_gains`` (f-number -> each band's gain divided out, mean 1). Empty
        for flats without a tile pattern.
    sensor_origin_px : (int, int) or None
        Sensor row and column of the flats' first pixel, for flats that are a crop (of a
        mosaic or not), recorded in the profile as ``sensor_origin_rc`` so that the centre
        is placed on the sensor; None for flats of the whole sensor.
    """

    lens: Lens
    method: str
    model: str
    reason: str
    f_numbers: np.ndarray
    reference_f_number: float | None
    center_rc: tuple
    center_source: str
    max_cra_deg: float
    onsets: dict
    onset_fits: dict
    fits: dict
    profiles: dict
    ratio_profiles: dict
    pixel_pitch_um: float
    shape: tuple
    bic_floor: dict = field(default_factory=dict)
    verdicts: dict = field(default_factory=dict)
    next_best: str | None = None
    shift_difference_nm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    shift_stderr_nm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tolerance_nm: float = choice.TOLERANCE_NM
    notes: list = field(default_factory=list)
    predictive: dict = field(default_factory=dict)
    exit_pupil_stderr_mm: float | None = None
    shift_stderr_fit_nm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    shift_stderr_model_nm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    shift_stderr_noise_nm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rivals: dict = field(default_factory=dict)
    mosaic: dict = field(default_factory=dict)
    sensor_origin_px: tuple | None = None

    @property
    def center_px(self) -> tuple:
        """The optical centre used x first, ``(cx, cy)``: the earlier form of
        :attr:`center_rc`, removed in snapcorr 0.3."""
        if called_from_outside(2):
            warn_x_first_return("LensCalibration.center_px", "LensCalibration.center_rc",
                                stacklevel=3)
        return (self.center_rc[1], self.center_rc[0])

    def model_onsets_deg(self):
        """First onset at each f-number predicted by the chosen circles (NaN past the field)."""
        on = np.asarray(self.lens.onset_cra_deg(self.f_numbers), float)
        return np.where(on <= self.max_cra_deg, on, np.nan)

    def onset_check_deg(self):
        """Largest difference between the paper's onsets (ratio profiles) and the chosen
        model's first onsets, degrees; None where neither finds one inside the field."""
        model_on = self.model_onsets_deg()
        diffs = [abs(o.cra_deg - model_on[j]) for j, f in enumerate(self.f_numbers)
                 if (o := self.onsets["ratio"].get(float(f))) is not None and o.found
                 and np.isfinite(model_on[j])]
        return max(diffs) if diffs else None

    def summary(self) -> str:
        """A few lines for a person (:func:`snapcorr.calibrate.lens.report.summary`)."""
        return report.summary(self)

    def plot(self, ax=None):
        """The paper's Fig. 8 (:func:`snapcorr.calibrate.lens.report.plot`)."""
        return report.plot(self, ax)

    def save_plot(self, path):
        """Write :meth:`plot` to ``path`` (PNG), atomically."""
        report.save_plot(self, path)


def _check_inputs(flats, dark, vignetting_distance_mm):
    """The flats as sorted ``(f_number, image)`` pairs, refused where they cannot be
    calibrated from (:func:`_check_enough_flats`)."""
    if not flats:
        raise ValueError("give at least one flat field")
    items = []
    for f, img in flats.items():
        try:
            fv = float(f)
        except (TypeError, ValueError):
            raise ValueError(f"f-number {f!r} is not a number") from None
        if not math.isfinite(fv) or fv <= 0:
            raise ValueError(f"f-number must be finite and > 0, got {f!r}")
        arr = np.asarray(img)
        if arr.ndim != 2:
            raise ValueError(f"the flat at f/{fv:g} must be a 2-D image, got shape {arr.shape}")
        items.append((fv, arr))
    fs = [f for f, _ in items]
    if len(set(fs)) != len(fs):
        dup = sorted({f for f in fs if fs.count(f) > 1})
        raise ValueError(f"f-number(s) given twice: {', '.join(f'f/{f:g}' for f in dup)}")
    shapes = {a.shape for _, a in items}
    if len(shapes) > 1:
        listing = ", ".join(f"f/{f:g}: {a.shape[0]} x {a.shape[1]}" for f, a in items)
        raise ValueError(f"flat fields differ in size (rows x columns: {listing}); all must "
                         "come from the same sensor area")
    if min(items[0][1].shape) < 16:
        raise ValueError(f"flat fields of {items[0][1].shape[0]} x {items[0][1].shape[1]} "
                         "pixels (rows x columns) are too small to calibrate from (16 x 16 at "
                         "least)")
    if dark is not None and np.shape(dark) != items[0][1].shape:
        raise ValueError(f"the dark frame is {np.shape(dark)}, the flats "
                         f"{items[0][1].shape}")
    _check_enough_flats(items, vignetting_distance_mm)
    return sorted(items)


def _check_args(method, exit_pupil_mm, pixel_pitch_um, vignetting_distance_mm, center_rc,
                exit_pupil_stderr_mm=None, tolerance_nm=choice.TOLERANCE_NM, max_circles=3):
    """Every number checked (:func:`_check_choice_args` too), as floats."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    # the lens's own bounds (a micron to a kilometre), before any flat is read
    exit_pupil_mm = check_length_mm("exit_pupil_mm", check_positive("exit_pupil_mm",
                                                                   exit_pupil_mm))
    pixel_pitch_um = check_pixel_pitch_um("pixel_pitch_um", pixel_pitch_um)
    if vignetting_distance_mm is not None:
        vignetting_distance_mm = check_length_mm(
            "vignetting_distance_mm", check_positive("vignetting_distance_mm",
                                                     vignetting_distance_mm))
    if center_rc is not None:
        center_rc = check_center_rc(center_rc)
    if exit_pupil_stderr_mm is not None:
        exit_pupil_stderr_mm = check_positive("exit_pupil_stderr_mm", exit_pupil_stderr_mm)
    return (exit_pupil_mm, pixel_pitch_um, vignetting_distance_mm, center_rc,
            exit_pupil_stderr_mm, _check_choice_args(tolerance_nm, max_circles))


def _check_choice_args(tolerance_nm, max_circles):
    """``tolerance_nm`` as a float; refuse it unless > 0, and ``max_circles`` unless 0 to 3."""
    tolerance_nm = check_positive("tolerance_nm", tolerance_nm)
    if max_circles not in (0, 1, 2, 3):
        raise ValueError(f"max_circles must be 0, 1, 2 or 3, got {max_circles!r}")
    return tolerance_nm


def _check_enough_flats(items, vignetting_distance_mm):
    """Refuse a single flat without h: one f-number cannot tell P from h."""
    if len(items) == 1 and vignetting_distance_mm is None:
        raise ValueError(
            f"one f-number (f/{items[0][0]:g}) cannot tell the vignetting circle's radius P "
            "from its distance h (Eq. 26 needs two or more onsets): give flats at two or more "
            "f-numbers, or give h (vignetting_distance_mm=)")


@renamed_keywords(pupil="pupil_radiance")
@accepts_center_rc
def calibrate_lens(flats, *, exit_pupil_mm=None, pixel_pitch_um, exit_pupil_stderr_mm=None,
                   magnification=None, pupil_magnification=None, dark=None, center_rc=None,
                   saturation=None, vignetting_distance_mm=None, method="auto", inputs=None,
                   name="calibrated lens", tolerance_nm=choice.TOLERANCE_NM, max_circles=3,
                   progress=None, pupil_radiance=None, sensor=None, sensor_origin_px=None,
                   lens=None, exit_pupil_from=None, center_px=None):
    """Characterise a lens from flat fields at several f-numbers.

    Parameters
    ----------
    flats : mapping
        f-number -> 2-D flat-field image (integrating sphere, or lamp and plaque).
    exit_pupil_mm, pixel_pitch_um : float
        Distance x from the sensor to the exit pupil (mm), unless ``lens`` gives it; pixel
        pitch (um).
    exit_pupil_stderr_mm : float, optional
        Standard error of x, if known (default: the one ``lens`` records, if any): the flats
        fix ``P / x`` and ``h / x^2``, so P and h move with x (``dP/dx = P / x``,
        ``dh/dx = 2 h / x``, in the profile and their errors).
    magnification, pupil_magnification : float, optional
        m and m_P of the working f-number, Eq. (27); default those of ``lens``, else 0 and 1.
    dark : 2-D array, optional
        Dark frame, subtracted from every flat.
    center_rc, center_px : (row, col), optional
        Optical centre, pixels, row first; ``center_px=(cx, cy)`` is the deprecated x-first
        form. Default: found from the flats and refined by the joint fit.
    saturation : float or mapping, optional
        Values at or above are saturated and ignored (one level, or f-number -> level).
    vignetting_distance_mm : float, optional
        h, if known (> 0: at least :data:`~snapcorr._validation.LENGTH_MIN_MM`); then one
        circle is fitted. Required with a single f-number, whose flat cannot tell P from h.
    method : {"auto", "joint", "onset-ratio", "onset-model"}
        ``"joint"``: the area model fitted to every ratio image at once; ``"onset-ratio"``:
        the paper's onsets of the ratio profiles, then Eq. 26; ``"onset-model"``: onsets from
        the area model fitted per profile, then Eq. 26; ``"auto"``: the joint fit, unless
        the onsets predict left-out flats better (:mod:`snapcorr.calibrate.lens.predictive`).
    name : str
    inputs : mapping, optional
        f-number -> file name, recorded in the profile.
    tolerance_nm : float
        A further circle is kept only if it moves the predicted mean shift by more than this
        somewhere in the field (:mod:`snapcorr.calibrate.lens.choice`).
    max_circles : int
        Most vignetting circles tried (0 to 3).
    progress : callable, optional
        ``progress(step)`` before each long step (a model fitted, a flat left out).
    pupil_radiance : {"paper", "lambertian", "paper-lambertian", "auto"}, optional
        The pupil's radiance model (:data:`snapcorr.optics.lens.PUPIL_RADIANCE_MODELS`;
        ``pupil=`` is its earlier name, deprecated; default that of ``lens``, else the
        paper's): its radius sets the onsets, and its ray weight the flats' model (the area
        times the chief ray's ``cos^4``, or for a Lambertian pupil every ray's ``cos^4``
        over the vignetted pupil, :func:`~snapcorr.optics.aperture.relative_irradiance`).
        ``"auto"``: the flats calibrated with each (three times the work), one other than
        the paper's kept only for a BIC lower by more than
        :data:`~snapcorr.calibrate.pupil.locate.PUPIL_CHI2_GAIN`; the choice is in the
        notes and the profile's ``[calibration] pupil_choice``.
    sensor, sensor_origin_px : Sensor, (int, int), optional
        Flats that are raw frames of this snapshot mosaic, whose first pixel is at sensor row
        and column ``sensor_origin_px`` (default: the whole sensor): each flat's band gains are
        fitted and divided out first (:func:`~snapcorr.calibrate.remove_band_gains`). Without
        ``sensor``, ``sensor_origin_px`` is the first pixel of flats that are a crop of a
        sensor without a tile pattern (a Snapscan camera's region of interest). Either way
        it is recorded (``sensor_origin_rc``), and the centre is placed on the sensor by it.
    lens : Lens, optional
        A lens whose exit pupil is known (the profile ``snapcorr pupil`` writes), instead of
        ``exit_pupil_mm``: its x, and its m, m_P, pupil and the standard error of x unless
        given. The profile records where x came from (``exit_pupil_from``) and the lens's
        own record of it (``exit_pupil_stderr_mm``, ``exit_pupil_n_eff``...).
    exit_pupil_from : str or path, optional
        Where ``lens`` came from (its file), recorded; default its name.

    Returns
    -------
    LensCalibration
    """
    magnification, pupil_magnification = checked_magnifications(magnification,
                                                                pupil_magnification)
    given = _from_lens(lens, exit_pupil_mm, exit_pupil_stderr_mm, magnification,
                       pupil_magnification, pupil_radiance)
    run = functools.partial(_calibrate, flats, pixel_pitch_um=pixel_pitch_um, dark=dark,
                            center_rc=center_rc, saturation=saturation,
                            vignetting_distance_mm=vignetting_distance_mm, method=method,
                            inputs=inputs, name=name, tolerance_nm=tolerance_nm,
                            max_circles=max_circles, progress=progress, sensor=sensor,
                            sensor_origin_px=sensor_origin_px)
    if given["pupil_radiance"] == "auto":
        result = _every_pupil(run, given)
    else:
        result = run(**given)
    if lens is not None:
        result.lens = _lens_recorded(result.lens, lens, exit_pupil_from)
    # magnifications not given are assumed: their spread enters the errors, said and recorded
    from . import magnification as _magnification

    return _magnification.account_for_magnifications(result, magnification,
                                                      pupil_magnification, lens, stacklevel=5)


#: A reduced chi-square of the chosen model above which an optical centre the flats put
#: outside them is refused rather than written with errors scaled by the misfit (a 60 px
#: crop 150 px beside the axis put it on the wrong side at 334; crops the joint fit places
#: right fit at about 1).
LOST_CENTRE_CHI2 = 10.0


def _found_outside(center, center_source, shape):
    """The optical centre was found (not given) and lies outside the flats."""
    inside = 0 <= center[0] < shape[0] and 0 <= center[1] < shape[1]
    return center_source != "given" and not inside


def _refuse_a_lost_centre(center, center_source, shape, chi2_red):
    """Refuse a centre the flats put outside them where the model misfits them grossly
    (:data:`LOST_CENTRE_CHI2`): circles fitted about it are not the lens's."""
    if _found_outside(center, center_source, shape) and chi2_red > LOST_CENTRE_CHI2:
        raise ValueError(
            f"the optical centre could not be placed: the flats put it outside them (row "
            f"{center[0]:.1f}, col {center[1]:.1f}), where the model misfits them (reduced "
            f"chi2 {chi2_red:.3g}); flats beside the axis do not show where it is: "
            "give it (center_rc=, in the flats' pixels), or take flats that reach the axis")


def _refuse_a_contradicted_centre(flats, ratios, given, chi2_red):
    """Refuse a given centre that the flats' own contours place elsewhere, inside them,
    where the model misfits them grossly about it (:data:`LOST_CENTRE_CHI2`): a centre 250 px
    off gave two circles of 50 mm at a reduced chi2 of 57, written as the lens's. (A crop
    beside the axis has no contours' centre inside it to contradict the one given.)"""
    if not chi2_red > LOST_CENTRE_CHI2:
        return
    found, how, _ = stages.optical_center_rc(flats, ratios)
    rows, cols = flats.shape
    d = math.hypot(found[0] - given[0], found[1] - given[1])
    if how == "contours" and 0 <= found[0] < rows and 0 <= found[1] < cols \
            and d > GIVEN_CENTRE_DOUBT_PX:
        raise ValueError(
            f"the optical centre given (row {given[0]:g}, col {given[1]:g}) is not the flats': "
            f"their contours place it at row {found[0]:.1f}, col {found[1]:.1f}, {d:.1f} px "
            f"away, and the model misfits them about the one given (reduced chi2 "
            f"{chi2_red:.3g}): check center_rc= (in the flats' pixels), or leave it out to "
            "have it found")


def _misfit_advice(notes, base, center, center_source, shape):
    """The estimator's notes, where the area model leaves a misfit with its likely causes
    that snapcorr can name: an optical centre found outside the flats (a crop beside the
    axis places it poorly), and another pupil than the one fitted (the paper's: every
    ray's cos^4, not the chief ray's)."""
    causes = []
    if _found_outside(center, center_source, shape):
        causes.append(f"the optical centre was found outside the flats (row {center[0]:.1f}, "
                      f"col {center[1]:.1f}), which flats beside the axis place poorly: give "
                      "it where it is known (center_rc=, in the flats' pixels)")
    if base.pupil_radiance == "paper":
        causes.append("flats of a Lambertian pupil (each ray's own cos^4) leave one under "
                      "the paper's pupil: pupil_radiance='auto' (--pupil-radiance auto) fits "
                      "every radiance model and keeps the best")
    else:
        causes.append(f"the pupil is not the {base.pupil_radiance} one (flats of the "
                      "paper's pupil fall off with the chief ray's cos^4 alone): "
                      "pupil_radiance='auto' (--pupil-radiance auto) fits every radiance "
                      "model and keeps the best")
    said = "; it may be that " + "; or that ".join(causes)
    return [n + (said if n.startswith("the area model leaves a misfit") else "")
            for n in notes]


def flats_bic(result):
    """The information criterion of a calibration's chosen joint-fit model (chi-square plus
    ``k ln n``), by which :func:`calibrate_lens` (``pupil_radiance="auto"``) compares
    radiance models fitted to the same flats."""
    return float(result.fits[result.model].bic)


def _every_pupil(run, given):
    """``calibrate_lens(pupil_radiance="auto")``: the flats calibrated with every radiance
    model, the paper's kept unless another lowers the BIC by more than
    :data:`~snapcorr.calibrate.pupil.locate.PUPIL_CHI2_GAIN` (fast flats tell a Lambertian
    pupil, whose every ray falls off with its own cos^4)."""
    from ..pupil.locate import choose_pupil

    runs = {name: run(**{**given, "pupil_radiance": name}) for name in PUPIL_RADIANCE_MODELS}
    return choose_pupil(runs, {k: flats_bic(r) for k, r in runs.items()}, "the flats' BIC",
                        key="bic")


#: What a lens given to :func:`calibrate_lens` records of its exit pupil, and the key each
#: takes in the calibrated profile.
LENS_RECORD_KEYS = {"exit_pupil_stderr_mm": "exit_pupil_stderr_mm",
                    "n_eff": "exit_pupil_n_eff", "n_eff_stderr": "exit_pupil_n_eff_stderr",
                    "n_eff_fitted": "exit_pupil_n_eff_fitted"}


def checked_magnifications(magnification, pupil_magnification):
    """m and m_P as given (None: not given), each refused, naming its keyword, if outside
    physics (:func:`~snapcorr.optics.lens.check_magnification`), before any work."""
    return (None if magnification is None else check_magnification(magnification),
            None if pupil_magnification is None
            else check_pupil_magnification(pupil_magnification))


def _from_lens(lens, exit_pupil_mm, exit_pupil_stderr_mm, magnification,
               pupil_magnification, pupil_radiance):
    """The exit pupil's x, its standard error, m, m_P and the pupil for the calibration: those
    given, else the ``lens``'s, else the defaults (x has none)."""
    if lens is None:
        if exit_pupil_mm is None:
            raise ValueError("give the exit pupil distance: exit_pupil_mm, or a lens whose x "
                             "is known (lens=, the profile snapcorr pupil writes)")
        return {"exit_pupil_mm": exit_pupil_mm, "exit_pupil_stderr_mm": exit_pupil_stderr_mm,
                "magnification": 0.0 if magnification is None else magnification,
                "pupil_magnification": 1.0 if pupil_magnification is None
                else pupil_magnification, "pupil_radiance": pupil_radiance or "paper"}
    if not isinstance(lens, Lens):
        raise TypeError(f"lens must be a Lens (Lens.load(path)), got {type(lens).__name__}")
    if exit_pupil_mm is not None:
        raise ValueError("give exit_pupil_mm or a lens, not both: the lens gives x")
    sx = lens.calibration.get("exit_pupil_stderr_mm")
    sx = sx if isinstance(sx, (int, float)) and not isinstance(sx, bool) and sx > 0 else None
    return {"exit_pupil_mm": lens.exit_pupil_mm,
            "exit_pupil_stderr_mm": sx if exit_pupil_stderr_mm is None else exit_pupil_stderr_mm,
            "magnification": lens.magnification if magnification is None else magnification,
            "pupil_magnification": (lens.pupil_magnification if pupil_magnification is None
                                    else pupil_magnification),
            "pupil_radiance": pupil_radiance or lens.pupil_radiance}


def _lens_recorded(calibrated, lens, source):
    """``calibrated`` with the record of where its x came from: ``source`` (default the
    ``lens``'s name) and what the lens's own record says of x and n_eff."""
    cal = dict(calibrated.calibration)
    cal["exit_pupil_from"] = str(source) if source is not None else (lens.name or "a lens")
    for key, as_key in LENS_RECORD_KEYS.items():
        if key in lens.calibration:
            cal[as_key] = lens.calibration[key]
    return dataclasses.replace(calibrated, calibration=cal)


def _calibrate(flats, *, exit_pupil_mm, pixel_pitch_um, exit_pupil_stderr_mm,
               magnification, pupil_magnification, dark, center_rc, saturation,
               vignetting_distance_mm, method, inputs, name, tolerance_nm, max_circles,
               progress, pupil_radiance, sensor, sensor_origin_px):
    """:func:`calibrate_lens` with x, m, m_P and the pupil settled (its body); every centre
    ``(row, col)``."""
    (exit_pupil_mm, pixel_pitch_um, vignetting_distance_mm, center_rc, exit_pupil_stderr_mm,
     tolerance_nm) = _check_args(method, exit_pupil_mm, pixel_pitch_um, vignetting_distance_mm,
                                 center_rc, exit_pupil_stderr_mm, tolerance_nm, max_circles)
    items = _check_inputs(flats, dark, vignetting_distance_mm)
    origin = _crop_origin(sensor_origin_px)
    items, cleaning, mosaic = _raw_mosaic(items, dark, saturation, sensor, origin)
    base = Lens(exit_pupil_mm, (), magnification, pupil_magnification, name=name,
                pupil_radiance=pupil_radiance)
    fl, ratios, center, center_source, notes = _prepare_flats(items, center_rc, **cleaning)
    ons = _onsets_about(fl, ratios, center, base, pixel_pitch_um, vignetting_distance_mm)
    max_cra, fs = ons.max_cra_deg, fl.f_numbers
    fix_center = center if (center_rc is not None or fl.single) else None
    decide = functools.partial(_choose, base=base, fs=fs, tolerance_nm=tolerance_nm,
                               h_given=vignetting_distance_mm is not None)
    fits, bic, fit_notes, data, rivals = _fit_joint_models(
        fl, ratios, base, pixel_pitch_um, center, fix_center, ons.fits, max_cra,
        vignetting_distance_mm, max_circles, decide, progress)
    model, verdicts = decide(fits, bic, max_cra)
    if model != "none" and fix_center is None:
        center, center_source, model, verdicts, ons, max_cra = _recenter_on_fit(
            fl, ratios, fits, bic, model, verdicts, center, center_source, ons, base,
            pixel_pitch_um, vignetting_distance_mm, decide)
    elif fix_center is None and (lead := _best_circle_model(fits, bic, center)) is not None:
        # no circle kept about the contours' centre may be a field measured about the wrong
        # centre (a crop beside the axis): the choice is made again about the best circle
        # model's own centre, and kept where a circle then stands
        again = _recenter_on_fit(fl, ratios, fits, bic, lead, verdicts, center,
                                 center_source, ons, base, pixel_pitch_um,
                                 vignetting_distance_mm, decide)
        if again[2] != "none":
            center, center_source, model, verdicts, ons, max_cra = again
    if center_source == "joint fit":  # found after all: the contours' fallback is not used
        notes = [n for n in notes if not n.startswith(stages.NO_FALL_OFF)]
    predict = functools.partial(_predict, data, fs, fits[model], ons, base, center, fix_center,
                                vignetting_distance_mm, progress)
    used, reason, circles, method_notes, scores = _decide_method(
        method, model, fits, verdicts, ons, max_cra, base.exit_pupil_mm, predict)
    _refuse_a_lost_centre(center, center_source, fl.shape, fits[model].reduced_chi2)
    if center_source == "given" and not fl.single:
        _refuse_a_contradicted_centre(fl, ratios, center, fits[model].reduced_chi2)
    notes += fit_notes + _misfit_advice(method_notes, base, center, center_source, fl.shape)
    model = _unless_joint(used, verdicts, model)
    lens = dataclasses.replace(base, vignetting=circles)
    next_best, diff = _next_best(model if used == "joint" else None, fits, bic, lens, base,
                                 fs, max_cra)
    errs = _shift_errors(used, fits, bic, verdicts, model, ons, center, lens, base, fs, max_cra,
                         rivals)
    notes += _precision_notes(verdicts, model, next_best, diff, errs, fs, tolerance_nm,
                              fits[model].extra.get("misfit_scale", 1.0) if used == "joint"
                              else 1.0) + _x_notes(exit_pupil_mm, exit_pupil_stderr_mm, circles)
    result = LensCalibration(
        lens=lens, method=used, model=model, reason=reason, f_numbers=fs,
        reference_f_number=None if fl.single else float(fs[-1]), center_rc=center,
        center_source=center_source, max_cra_deg=max_cra, onsets=ons.onsets,
        onset_fits=ons.fits, fits=fits, profiles=ons.profiles,
        ratio_profiles=ons.ratio_profiles, pixel_pitch_um=float(pixel_pitch_um),
        shape=fl.shape, bic_floor=bic, verdicts=verdicts, next_best=next_best,
        shift_difference_nm=diff, tolerance_nm=tolerance_nm, notes=notes, predictive=scores,
        exit_pupil_stderr_mm=exit_pupil_stderr_mm, rivals=rivals, mosaic=mosaic,
        sensor_origin_px=origin, **errs)
    result.lens = dataclasses.replace(lens, calibration=_calibration_table(result, inputs))
    return result


class _Onsets(NamedTuple):
    """The radial profiles, onsets and Eq. (26) fits about one optical centre."""

    profiles: dict
    ratio_profiles: dict
    onsets: dict
    max_cra_deg: float
    fits: dict


def _crop_origin(origin_px):
    """``sensor_origin_px`` as two whole numbers >= 0 (None: flats of the whole sensor)."""
    if origin_px is None:
        return None
    o = check_integers("sensor_origin_px", origin_px)
    if o.shape != (2,) or np.any(o < 0):
        raise ValueError("sensor_origin_px must be a sensor row and column (whole numbers "
                         f">= 0), got {origin_px!r}")
    return int(o[0]), int(o[1])


def _raw_mosaic(items, dark, saturation, sensor, origin_px):
    """Raw flats of a mosaic ``sensor`` with their band gains divided out, what is left of
    cleaning them (keywords of :func:`_prepare_flats`: the dark is subtracted and saturated
    pixels are masked already; each pixel's gain, for its noise), and the record of it (as
    :attr:`LensCalibration.mosaic`); without ``sensor``, the flats as they came and ``{}``
    (``origin_px``, checked by :func:`_crop_origin`, is then only recorded)."""
    if sensor is None:
        return items, {"dark": dark, "saturation": saturation}, {}
    check_mosaic_sensor(sensor)
    items, gains, pixel_gains = stages.without_band_gains(items, dark, saturation, sensor,
                                                          origin_px)
    return items, {"pixel_gains": pixel_gains}, {
        "sensor": sensor, "sensor_origin_px": origin_px, "band_gains": gains}


#: A given centre is doubted in the notes where the flats' contours place the axis more than
#: this many pixels from it (:func:`~snapcorr.calibrate.lens.stages.optical_center_rc`, the
#: median of their circles' centres: to 0.05 px on flats of the paper's lens at 0.5 % noise,
#: the circles scattering by 6 px).
GIVEN_CENTRE_DOUBT_PX = 2.0


def _given_centre_doubted(flats, ratios, given):
    """A note where the flats' own contours place the optical centre far from the one given
    (a centre 5 px off was fitted with three circles where the lens has one, the misfit
    blamed on the light), else none."""
    rows, cols = flats.shape
    if not (0 <= given[0] < rows and 0 <= given[1] < cols):
        return []  # beside the flats their contours cannot place it: nothing to doubt by
    found, how, _ = stages.optical_center_rc(flats, ratios)
    if how != "contours":
        return []
    d = math.hypot(found[0] - given[0], found[1] - given[1])
    if not d > GIVEN_CENTRE_DOUBT_PX:
        return []
    return [f"the flats' contours place the optical centre at row {found[0]:.1f}, col "
            f"{found[1]:.1f}, {d:.1f} px from the one given: a wrong centre shows as extra "
            "circles and a misfit; leave the centre out to have it found, or check it"]


def _prepare_flats(items, center_rc, *, dark=None, saturation=None, pixel_gains=None):
    """Clean the flats, take their ratio images and find the optical centre ``(row, col)``;
    with notes."""
    fl = stages.clean_flats(items, dark, saturation, pixel_gains)
    notes = list(fl.notes)
    ratios = stages.ratio_images(fl)
    center, center_source, note = stages.optical_center_rc(fl, ratios, center_rc)
    if note:
        notes.append(note)
    if center_rc is not None and not fl.single:
        notes += _given_centre_doubted(fl, ratios, center)
    if fl.single:
        notes.append("one flat: nothing cancels the source's non-uniformity or other fall-off "
                     "(cos^4 is divided out); use an integrating sphere, or flats at several "
                     "f-numbers")
    return fl, ratios, center, center_source, notes


def _onsets_about(fl, ratios, center_rc, base, pixel_pitch_um, vignetting_distance_mm):
    """Profiles and onsets about ``center_rc``, and Eq. (26) over each detector's onsets."""
    profiles, ratio_profiles, onsets, max_cra = stages.profiles_and_onsets(
        fl, ratios, center_rc, base, pixel_pitch_um, fixed_h=vignetting_distance_mm)
    onset_fits = {det: stages.solve_onsets(onsets[det], base, vignetting_distance_mm)
                  for det in onsets}
    return _Onsets(profiles, ratio_profiles, onsets, max_cra, onset_fits)


def _choose(fits, bic, max_cra, *, base, fs, tolerance_nm, h_given):
    """The joint-fit model chosen over a field up to ``max_cra``, and every model's verdict."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EffectiveIndexWarning)
        return choice.choose(fits, bic, base, fs, max_cra, tolerance_nm=tolerance_nm,
                             h_given=h_given)


def _fit_joint_models(fl, ratios, base, pixel_pitch_um, center, fix_center, onset_fits,
                      max_cra, vignetting_distance_mm, max_circles, decide, progress=None):
    """The joint fits, one more circle while the last is chosen; their BICs, notes, the
    blocks fitted and the rival models (:func:`~snapcorr.calibrate.lens.stages.joint_fits`);
    centres ``(row, col)``."""
    data = stages.block_data(fl, ratios, base, pixel_pitch_um)
    centers = [center]
    if fix_center is None:  # should the contours have misled: the image centre too
        centers.append(((fl.shape[0] - 1) / 2.0, (fl.shape[1] - 1) / 2.0))

    def keep_going(fits, bic):  # only a chosen model can be the base of a better one
        return decide(fits, bic, max_cra)[0] == list(fits)[-1]

    rivals = {}
    fits, bic = stages.joint_fits(
        data, base, fl.f_numbers, onset_fits.values(), centers, fix_center, max_cra,
        fixed_h=vignetting_distance_mm, max_circles=max_circles, keep_going=keep_going,
        progress=progress, rivals=rivals)
    notes = []
    if vignetting_distance_mm is not None and max_circles > 1:
        notes.append("h given: one circle fitted (a further circle's h would be unknown)")
    notes += [f"the joint fit with {report.CIRCLES[k]} stopped before converging ({v.message})"
              for k, v in fits.items() if not v.success]
    if "free" in rivals:
        notes.append(
            f"two circles: the second is pixel vignetting, held at h = x = {base.exit_pupil_mm:g}"
            " mm (a free h: the BIC with the floor higher by "
            f"{rivals['free'][1] - bic['two']:.4g})")
    return fits, bic, notes, data, rivals


#: A fitted optical centre this far (pixels) from the contours' is taken as the field's
#: centre: the onsets and the choice are made again about it.
RECENTRE_PX = 2.0


def _recenter_on_fit(fl, ratios, fits, bic, model, verdicts, center, center_source, ons, base,
                     pixel_pitch_um, vignetting_distance_mm, decide):
    """Re-centre on the chosen model's centre: the onsets, the choice and the field about it."""
    # The chosen model's centre; where it moved from the contours' centre, the field's
    # extent, the profiles and the paper's onsets are taken again about it, and the
    # choice is made again over that field.
    contour_center, contour_source = center, center_source
    center, center_source = _fitted_center(fits[model]), "joint fit"
    if np.hypot(center[0] - contour_center[0], center[1] - contour_center[1]) > RECENTRE_PX:
        ons = _onsets_about(fl, ratios, center, base, pixel_pitch_um, vignetting_distance_mm)
        model, verdicts = decide(fits, bic, ons.max_cra_deg)
        if model == "none":  # no circle after all: the contours' centre stands
            center, center_source = contour_center, contour_source
        else:
            center = _fitted_center(fits[model])
    max_cra = float(cra_map(fl.shape, pixel_pitch_um, base.exit_pupil_mm,
                            center_rc=center).max())
    return center, center_source, model, verdicts, ons, max_cra


def _best_circle_model(fits, bic, center):
    """The circle model of least BIC among those fitted, where its centre lies more than
    :data:`RECENTRE_PX` from ``center``; else None."""
    ok = [m for m, f in fits.items() if m != "none" and f.success and m in bic]
    if not ok:
        return None
    best = min(ok, key=bic.get)
    c = _fitted_center(fits[best])
    return best if math.hypot(c[0] - center[0], c[1] - center[1]) > RECENTRE_PX else None


def _fitted_center(fit):
    """The fit's optical centre, ``(row, col)``."""
    return tuple(fit.params[k] for k in CENTER_NAMES)


