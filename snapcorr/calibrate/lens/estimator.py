"""Which estimator of the vignetting circles a lens calibration uses, and how precise it is.

The joint fit's model or the paper's onsets (Eq. 26), chosen by the rule of ``method``
(:func:`~snapcorr.calibrate.lens.calibration.calibrate_lens`); the standard error of the mean
shift it predicts, in its parts; and the notes that say what sets that error.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from ...optics.lens import Lens
from ...optics.shift import EffectiveIndexWarning
from . import choice, predictive, report, stages
from .joint_fit import N_CIRCLES, ModelFit, param_names

#: Reduced chi-square above which a note says the area model leaves a misfit (the estimator
#: is chosen by prediction, not by this).
MISFIT_CHI2 = 1.5


def _predict(data, fs, fit, ons, base, center_rc, fix_center_rc, h_given, progress):
    """Predictive scores of the joint fit and of the paper's onsets
    (:func:`~snapcorr.calibrate.lens.predictive.compare_estimators`); centres ``(row, col)``."""
    def solver(f):
        others = {g: o for g, o in ons.onsets["ratio"].items() if g != f}
        of = stages.solve_onsets(others, base, h_given)
        return (of.P_mm, of.h_mm) if _sane(of, base.exit_pupil_mm) else None

    return predictive.compare_estimators(data, fs, fit, solver, center_rc,
                                         fix_center_rc=fix_center_rc, fixed_h=h_given,
                                         progress=progress)


def _shift_errors(used, fits, bic, verdicts, model, ons, center_rc, lens, base, fs, max_cra,
                  rivals=None):
    """The shift's standard error per f-number: the fit's part, the model choice's part, and
    both in quadrature (as :class:`LensCalibration` fields)."""
    fit_err = _shift_stderr(used, fits[model], ons.fits, center_rc, base, fs, max_cra)
    noise_err = fit_err
    if used == "joint" and fit_err.size and "noise_covariance" in fits[model].extra:
        fit = fits[model]
        noise = np.asarray(fit.extra["noise_covariance"], float)
        sd = np.sqrt(np.clip(np.diag(noise), 0.0, None))
        stderr = {k: (v if not np.isfinite(fit.stderr[k]) else float(sd[i]))
                  for i, (k, v) in enumerate(fit.stderr.items())}
        noise_err = _shift_stderr(used, dataclasses.replace(fit, covariance=noise,
                                                            stderr=stderr),
                                  ons.fits, center_rc, base, fs, max_cra)
    model_err = (choice.model_choice_stderr(fits, bic, verdicts, model, lens, base, fs,
                                            max_cra, rivals, fit_err=fit_err)
                 if used == "joint" else np.zeros(0))
    return {"shift_stderr_fit_nm": fit_err, "shift_stderr_model_nm": model_err,
            "shift_stderr_noise_nm": noise_err,
            "shift_stderr_nm": _combine(fit_err, model_err)}


def _unless_joint(used, verdicts, model):
    """The model of the profile: the joint fit's choice, or one circle where an onset
    method was used (then the joint fit's choice is marked as not used)."""
    if used == "joint":
        return model
    verdicts[model].chosen = False
    verdicts[model].why = f"the joint fit's choice, not used ({used}): {verdicts[model].why}"
    return "one"


def _precision_notes(verdicts, model, next_best, diff, errs, fs, tolerance_nm,
                     misfit_scale=1.0):
    """Notes where the flats are too noisy to settle the model or to pin the mean shift; the
    advice says which part of the error sets it, and what lowers that part."""
    notes = []
    shift_err = errs["shift_stderr_nm"]
    rival = verdicts.get(next_best) if next_best is not None else None
    if (rival is not None and not rival.problems and N_CIRCLES[next_best] > N_CIRCLES[model]
            and np.nanmax(diff, initial=0.0) > tolerance_nm):
        notes.append(
            f"the flats cannot settle whether {report.CIRCLES[next_best]} are there: that "
            f"model was rejected ({rival.why}), yet it would move the mean shift by up to "
            f"{np.nanmax(diff):.3g} nm; flats with less noise (more frames averaged) would "
            "decide")
    if shift_err.size and np.nanmax(shift_err, initial=0.0) > tolerance_nm:
        worst = int(np.nanargmax(shift_err))
        notes.append(
            f"the flats pin the mean shift only to +- {shift_err[worst]:.3g} nm (one standard "
            f"error, at f/{fs[worst]:g} for a {choice.REFERENCE_CWL_NM:g} nm filter), more "
            f"than the {tolerance_nm:g} nm tolerance: "
            + _what_sets_it(errs, worst, misfit_scale))
    return notes


def _part(errs, key, k):
    v = errs.get(key, np.zeros(0))
    return float(v[k]) if v.size > k and np.isfinite(v[k]) else 0.0


def _what_sets_it(errs, k, misfit_scale):
    """Which part of the shift's error at f-number index ``k`` dominates, and what lowers
    it: the noise's (averaging frames, by sqrt(k) for that part only), the block model's
    approximation (nothing the user does), the choice between models the flats cannot tell
    apart (less noise settles it; it does not shrink as sqrt(k)), or a misfit (the area model
    misses something; more frames do not help)."""
    total = _part(errs, "shift_stderr_nm", k)
    fit = _part(errs, "shift_stderr_fit_nm", k)
    noise = min(_part(errs, "shift_stderr_noise_nm", k), fit)
    model = _part(errs, "shift_stderr_model_nm", k)
    rule = math.sqrt(max(fit * fit - noise * noise, 0.0))
    # the noise alone, without the misfit's scaling where that is a misfit, not chance
    pure = noise / math.sqrt(misfit_scale) if misfit_scale > MISFIT_CHI2 else noise
    misfit = math.sqrt(max(noise * noise - pure * pure, 0.0))
    parts = {"noise": pure, "misfit": misfit, "rule": rule, "model": model}
    lead = max(parts, key=parts.get)
    share = ", ".join(f"{v:.2g} nm {name}" for name, v in (
        ("from the flats' noise", pure), ("from the area model's misfit", misfit),
        ("from the block model's approximation", rule),
        ("from the choice between models", model)) if v > 0.01 * total)
    rest = math.sqrt(max(total * total - pure * pure, 0.0))
    if lead == "noise":
        advice = ("the flats' noise sets it: averaging k frames at every f-number divides that "
                  "part by sqrt(k)" + (f" (the rest, {rest:.2g} nm, does not shrink so)"
                                        if rest > 0.2 * total else ""))
    elif lead == "model":
        advice = ("the choice between models the flats cannot tell apart sets it: flats with "
                  "less noise would settle the choice (it does not shrink as sqrt(k) with k "
                  "frames; it falls away once one model is ruled out)")
    elif lead == "misfit":
        advice = ("the area model's misfit sets it (the errors are scaled by a reduced chi2 of "
                  f"{misfit_scale:.3g}): more frames do not lower it; check the flats for "
                  "what the model lacks (a source that changes with the f-number, aberrations)")
    else:
        advice = ("the block model's approximation sets it: more frames do not lower it")
    return f"{advice} ({share})"


#: How :func:`~snapcorr.calibrate.lens.choice.check_circles` says a circle's onset falls
#: inside the field at too few f-numbers.
_TOO_FEW_ONSETS = "starts cutting the pupil inside the field at"


def _refuse_unpinned_vignetting(fits, verdicts):
    """Refuse flats whose fall-off a circle describes (to within :data:`MISFIT_CHI2`) where
    the rules could not keep it and no circle is left: a profile without vignetting would be
    a confident wrong answer (its shift error 0 where the circle moves it by nm). Only where
    the circle fails on the number of its onsets alone: a stop-like circle that rescales one
    flat, or one the flats leave loose, is no evidence of vignetting."""
    def onsets_only(v):  # pinned otherwise: bounded, moving with the CRA, converged
        return v is not None and v.problems and all(_TOO_FEW_ONSETS in p for p in v.problems)

    better = [m for m, f in fits.items() if m != "none" and f.success
              and f.reduced_chi2 <= MISFIT_CHI2 and onsets_only(verdicts.get(m))]
    if better:
        m = better[0]
        raise ValueError(
            f"the flats show vignetting they cannot pin: without a circle the reduced chi2 is "
            f"{fits['none'].reduced_chi2:.1f}, with {report.CIRCLES[m]} "
            f"{fits[m].reduced_chi2:.2f}, but {verdicts[m].problems[0]}; take flats at more "
            "f-numbers between the fastest and the slowest (each circle's onset must fall "
            "inside the field at two), or of the whole field" + _centre_advice(fits[m]))


def _centre_advice(fit):
    """Where the fit found the optical centre itself, the advice to give it: a crop beside
    the axis places it poorly, and circles fitted about a centre off its place are not
    pinned either."""
    err = [float(fit.stderr.get(k, 0.0)) for k in ("center_row_px", "center_col_px")]
    if not all(np.isfinite(e) and e > 0 for e in err):
        return ""  # the centre was given (held)
    row, col = (float(fit.params[k]) for k in ("center_row_px", "center_col_px"))
    return (f"; the optical centre was found from these flats, at row {row:.1f}, col "
            f"{col:.1f} (+- {err[0]:.2g}, {err[1]:.2g} px): flats beside the axis place it "
            "poorly, so give it where it is known (center_rc=, in the flats' pixels)")


def _decide_method(method, model, fits, verdicts, ons, max_cra, x, predict):
    """The estimator used, why, the circles of the profile, notes, and the predictive scores
    (``{estimator: Prediction}``, empty where none were compared)."""
    chosen = fits[model]
    notes, scores = [], {}
    if model == "none" and fits["none"].reduced_chi2 > MISFIT_CHI2:
        _refuse_unpinned_vignetting(fits, verdicts)
        notes.append(f"no model describes these flats well (reduced chi2 without a circle "
                     f"{fits['none'].reduced_chi2:.1f}); check the optical centre, the "
                     "f-numbers and the files")
    elif model != "none" and chosen.reduced_chi2 > MISFIT_CHI2:
        notes.append(f"the area model leaves a misfit (reduced chi2 {chosen.reduced_chi2:.2f}): "
                     "the standard errors are scaled up by it")
    if method == "auto":
        if model == "none" and len(fits) == 1:
            used = "joint"
            reason = "no vignetting circle tried (max_circles=0): the ideal-aperture model"
        elif model == "none":
            used = "joint"
            reason = (f"no optical vignetting inside the field up to {max_cra:.1f} deg: "
                      f"{verdicts['none'].why}; the ideal-aperture model suffices")
        else:
            used, reason, scores, note = _by_prediction(model, verdicts, ons, x, predict)
            if note:
                notes.append(note)
    else:
        used = method
        reason = f"method {method!r} asked for"
    if used == "joint":
        return used, reason, choice.lens_of(chosen, Lens(x)).vignetting, notes, scores
    det = used.split("-")[1]
    of = ons.fits[det]
    if of is None:
        n_found = sum(o.found for o in ons.onsets[det].values())
        raise ValueError(f"the {used} method needs onsets at two or more f-numbers (found "
                         f"{n_found} inside the field, up to {max_cra:.1f} deg); use the "
                         "joint fit")
    if not _sane(of, x):
        raise ValueError(f"the {used} method gives P = {of.P_mm:.4g} mm, h = "
                         f"{of.h_mm:.4g} mm, which is not a lens; use the joint fit")
    return used, reason, [(of.P_mm, of.h_mm)], notes, scores


def _by_prediction(model, verdicts, ons, x, predict):
    """``auto`` with circles: the joint fit unless the paper's onsets predict left-out flats
    better (:mod:`snapcorr.calibrate.lens.predictive`); (used, reason, scores, note)."""
    why = f"{report.CIRCLES[model]}: {verdicts[model].why}"
    if not _sane(ons.fits["ratio"], x):
        return ("joint", why + "; the paper's onsets give no usable P and h to compare "
                "with", {}, None)
    joint, onsets = predict()
    if not joint.chi2:
        return ("joint", why + "; no flat could be left out and predicted by both "
                "estimators (too few onsets): the joint fit is kept", {}, None)
    scores = {"joint": joint, "onset-ratio": onsets}
    left = ", ".join(f"f/{f:g}" for f in joint.chi2)
    gain = joint.total - onsets.total
    if gain > predictive.MIN_PREDICTIVE_GAIN:
        return ("onset-ratio",
                f"the paper's onsets predict the flats left out ({left}) better than the "
                f"joint fit ({report.CIRCLES[model]}): chi2 {onsets.total:.1f} against "
                f"{joint.total:.1f}, a gain of {gain:.1f} > {predictive.MIN_PREDICTIVE_GAIN:g}; "
                "Eq. (26) over the onsets of the ratio profiles", scores,
                "the joint fit predicts left-out flats worse than the onsets: the area model "
                "misses something in these flats (pupil aberrations, a fall-off that changes "
                "with the f-number)")
    return ("joint",
            f"{why}; it predicts the flats left out ({left}) with chi2 {joint.total:.1f} "
            f"against {onsets.total:.1f} for the paper's onsets", scores, None)


def _combine(fit_err, model_err):
    """The two parts of the shift's standard error in quadrature (either may be empty)."""
    if not model_err.size:
        return fit_err
    if not fit_err.size:
        return model_err
    return np.hypot(fit_err, model_err)


def _x_notes(x, sx, circles):
    """What x given without (or with) an error means for P and h (none without a circle)."""
    if not circles:
        return []
    P, h = circles[0]
    if sx is None:
        return [f"x = {x:g} mm was given without an error, and the flats cannot check it: "
                f"P and h scale with it (dP/dx = {P / x:.4g}, dh/dx = {2 * h / x:.4g}; 1 % "
                "in x is 1 % in P and 2 % in h). Measure x with `snapcorr pupil`, or "
                "calibrate with --target-cube"]
    return [f"x = {x:g} +- {sx:.2g} mm: its error is in the standard errors of P and h "
            f"recorded with it (dP/dx = {P / x:.4g}, dh/dx = {2 * h / x:.4g})"]


def _shift_stderr(used, fit, onset_fits, center_rc, base, fs, max_cra):
    """Standard error of the predicted mean shift for the estimator used, per f-number (an
    onset method's circle about the centre ``(row, col)``)."""
    if used == "joint":
        if fit.model == "none":
            return np.zeros(0)
        return choice.shift_stderr_nm(fit, base, fs, max_cra)
    of = onset_fits[used.split("-")[1]]
    cov = np.zeros((4, 4))
    cov[:2, :2] = of.covariance if of.covariance is not None else np.nan
    names = tuple(param_names("one"))
    params = dict(zip(names, (of.P_mm, of.h_mm, *center_rc), strict=True))
    stderr = dict(zip(names, (*np.sqrt(np.clip(np.diag(cov[:2, :2]), 0, None)), 0.0, 0.0),
                      strict=True))
    if not np.all(np.isfinite(cov)):
        return np.full(len(fs), np.inf)
    as_fit = ModelFit("one", params, stderr, cov, names, math.nan, 0, 0, np.zeros(0), True)
    return choice.shift_stderr_nm(as_fit, base, fs, max_cra)


def _next_best(model, fits, bic, lens, base, fs, max_cra):
    """The best model not chosen (lowest floored BIC) and the mean-shift difference to it."""
    others = [m for m in fits if m != model]
    if not others:
        return None, np.zeros(0)
    other = min(others, key=lambda m: bic[m])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EffectiveIndexWarning)
        diff = choice.shift_difference_nm(lens, choice.lens_of(fits[other], base), fs, max_cra)
    return other, diff


def _sane(of, x):
    """An Eq. (26) solution that describes a lens: P, h > 0, finite, not absurdly large."""
    return (of is not None and np.isfinite([of.P_mm, of.h_mm, of.P_stderr_mm]).all()
            and 0 < of.P_mm < 20 * x and 0 < of.h_mm < 20 * x)
