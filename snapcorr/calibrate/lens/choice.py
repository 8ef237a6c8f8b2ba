"""Which vignetting model the flats support: rules a spurious circle cannot pass.

Flat fields with millions of pixels make any tiny mismatch between the flats and the area
model "significant" against pixel noise, so an information criterion on pixels alone will add
circles that fit the mismatch: a stop (``h ~ 0``) with ``P`` equal to the fastest exit pupil,
say, which only rescales one flat. The choice here therefore has three parts.

1. **Identifiability** (:func:`check_circles`). A circle counts only if

   - its onset (Eq. 24-25) lies inside the field at two or more f-numbers of the flats:
     Eq. (26) needs two onsets to tell ``P`` from ``h``, and so do the flats; and it cuts the
     light the pupil and the other circles leave somewhere in the field
     (:func:`effective_onsets_deg`). A circle partly hidden behind another may still be
     pinned by the events it leaves (where it starts to cut, where another takes over); the
     next rule says whether it is;
   - its ``P`` and ``h`` have finite standard errors below ``MAX_REL_ERROR`` (half) of their
     values: bounded, though not necessarily small (P and h of a circle that cuts only the
     field's edge are strongly correlated, yet the shift they predict may be well pinned:
     rule 3 judges that);
   - its ``h`` is more than ``MIN_H_SIGMAS`` standard errors from 0: a circle that does not
     move with the chief-ray angle changes the aperture, which the flats' exposure scales
     absorb (and which the f-number already sets).

   A model with any circle that fails is never chosen.
2. **A criterion that allows for model error**
   (:func:`~snapcorr.calibrate.lens.joint_fit.floor_chi2`).
   The Bayesian information criterion is computed with each block's variance raised by a
   systematic floor, ``(FLOOR_REL * q)^2``: a relative 0.1 % that no area model describes
   (source, pupil aberrations, the block model's approximations). A model with more circles
   must lower that criterion by more than ``MIN_BIC_GAIN``.
3. **Function, not parameters** (:func:`shift_difference_nm`). The profile serves the
   wavelength correction, so a further circle is kept only where it moves the predicted mean
   shift, somewhere in the field at some f-number of the flats, by more than the tolerance
   (0.005 nm by default, for a filter at ``REFERENCE_CWL_NM`` with ``REFERENCE_N_EFF``, a
   long wavelength and a low index: the largest shifts such cameras show), and by more than
   ``MIN_SHIFT_SIGMAS`` times the standard error of the shift the richer model predicts
   (:func:`shift_stderr_nm`, at the same f-number). Otherwise the simpler model is as good
   for correcting, or the flats cannot tell the two apart where it matters, and the simpler
   one is chosen.

   A circle is judged by what it does, not by the relative error of its parameters: a pixel
   vignetting circle that removes 0.2 nm of shift at the field's edge is kept at 10 % noise
   per pixel even though its P and h are only known to 5-8 % there; dropping it would be the
   confident wrong answer.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ...optics.goossens2019 import PupilCutOffError
from ...optics.lens import Lens
from ...optics.mean import mean_shift
from ...optics.shift import EffectiveIndexWarning
from .joint_fit import N_CIRCLES, ModelFit, circles_of

__all__ = [
    "FLOOR_REL",
    "MAX_REL_ERROR",
    "MIN_BIC_GAIN",
    "MIN_H_SIGMAS",
    "MIN_MODEL_WEIGHT",
    "MIN_SHIFT_SIGMAS",
    "ModelVerdict",
    "check_circles",
    "choose",
    "effective_onsets_deg",
    "model_choice_stderr",
    "shift_difference_nm",
    "shift_stderr_nm",
]

#: Relative systematic floor of the ratio images in the model criterion.
FLOOR_REL = 1e-3
#: A model with more circles must lower the floored BIC by more than this ("very strong").
MIN_BIC_GAIN = 10.0
#: A circle's P and h must have standard errors below this fraction of their values.
MAX_REL_ERROR = 0.5
#: A further circle must move the mean shift by more than this many of its standard errors.
MIN_SHIFT_SIGMAS = 3.0
#: A circle's |h| must exceed this many standard errors (else it is a change of aperture).
MIN_H_SIGMAS = 5.0
#: The filter the functional differences are stated for (nm, effective index).
REFERENCE_CWL_NM = 1000.0
REFERENCE_N_EFF = 1.5
#: Default tolerance of the functional test, nm of mean shift.
TOLERANCE_NM = 0.005
_CRA_SAMPLES = 97
_ONSET_SAMPLES = 400


@dataclass
class ModelVerdict:
    """What became of one model: chosen or rejected, and why."""

    model: str
    chosen: bool
    why: str
    bic_floor: float
    reduced_chi2: float
    problems: list = field(default_factory=list)

    def as_table(self) -> dict:
        return {"chosen": self.chosen, "why": self.why,
                "bic_with_floor": _finite(self.bic_floor),
                "reduced_chi2": _finite(self.reduced_chi2)}


def _finite(v):
    v = float(v)
    return v if math.isfinite(v) else ("nan" if math.isnan(v) else "inf")


def lens_of(fit: ModelFit, base: Lens) -> Lens:
    """``base`` (exit pupil, magnifications) with the fit's circles."""
    p = [fit.params[k] for k in fit.names]
    return replace(base, vignetting=circles_of(fit.model, p), calibration={})


def effective_onsets_deg(lens: Lens, f_numbers, max_cra_deg, samples=_ONSET_SAMPLES):
    """Where each circle starts to cut the light the pupil *and the other circles* leave.

    Shape ``(n_circles, n_f)``, degrees on a grid of ``samples`` CRAs from 0 to
    ``max_cra_deg`` (``inf``: not inside the field). A circle hidden behind another until a
    CRA that does not depend on the f-number (two circles touching inside each other) tells
    nothing about its own P and h there, unlike its onset against the bare pupil (Eq. 24-25).

    Parameters
    ----------
    lens : Lens
        Exit pupil and vignetting circles.
    f_numbers : array_like
        Nominal f-numbers (1-D).
    max_cra_deg : float
        Largest chief-ray angle of the field, degrees.
    samples : int
        Number of CRAs on the grid.

    Returns
    -------
    ndarray
        ``(n_circles, n_f)``: the last grid CRA before the circle cuts, degrees; ``inf`` where
        it cuts nothing up to ``max_cra_deg``.
    """
    fs = np.asarray(f_numbers, float)
    cra = np.linspace(0.0, max_cra_deg, samples)
    out = np.full((len(lens.vignetting), fs.size), np.inf)
    for j, f in enumerate(fs):
        with_all = lens.relative_illumination(f, cra)
        for i in range(len(lens.vignetting)):
            others = replace(lens, vignetting=lens.vignetting[:i] + lens.vignetting[i + 1:])
            without = others.relative_illumination(f, cra)
            cut = np.flatnonzero(without - with_all > 1e-9 * np.maximum(without, 1e-300))
            if cut.size:
                out[i, j] = cra[max(cut[0] - 1, 0)]
    return out


def check_circles(fit: ModelFit, base: Lens, f_numbers, max_cra_deg, *, h_given=False):
    """Reasons (a list of sentences) why the fit's circles are not identifiable (rule 1 of the
    module's description); empty: all are.

    Parameters
    ----------
    fit : ModelFit
        The fit of one model (:func:`~snapcorr.calibrate.lens.joint_fit.fit_model`).
    base : Lens
        Exit pupil and magnifications; its circles are replaced by the fit's.
    f_numbers : array_like
        Nominal f-numbers of the flats (1-D).
    max_cra_deg : float
        Largest chief-ray angle of the field, degrees.
    h_given : bool
        ``h`` was given rather than fitted (one circle): one onset inside the field suffices.

    Returns
    -------
    list of str
    """
    problems = []
    p = [fit.params[k] for k in fit.names]
    err = [fit.stderr[k] for k in fit.names]
    names = list(fit.names)
    lens = lens_of(fit, base)
    fs = np.asarray(f_numbers, float)
    bare = lens.circle_onsets_cra_deg(fs)
    effective = effective_onsets_deg(lens, fs, max_cra_deg)
    for i, (P, h) in enumerate(circles_of(fit.model, p)):
        label = "P_mm" if i == 0 else f"P{i + 1}_mm"
        sP = err[names.index(label)]
        sh = err[names.index(label.replace("P", "h"))]
        tag = f"circle {i + 1} (P {P:.4g} mm, h {h:.4g} mm)"
        inside = int(np.sum(bare[i] < max_cra_deg))
        need = 1 if h_given else 2
        if inside < need:
            problems.append(f"{tag} starts cutting the pupil inside the field at {inside} "
                            "f-number(s); " + ("one is needed" if h_given else
                                               "two are needed to tell P from h"))
        elif not np.any(np.isfinite(effective[i])):
            problems.append(f"{tag} cuts no light inside the field: the other circles hide it")
        if not (math.isfinite(sP) and math.isfinite(sh)):
            problems.append(f"{tag} has no finite standard error: the flats do not pin it")
        elif sP > MAX_REL_ERROR * P or sh > MAX_REL_ERROR * abs(h):
            problems.append(f"{tag} is loose: +- {sP:.2g} mm in P, +- {sh:.2g} mm in h")
        if math.isfinite(sh) and abs(h) <= MIN_H_SIGMAS * sh:
            problems.append(f"{tag} hardly moves (h within {MIN_H_SIGMAS:g} standard errors "
                            "of 0): a change of aperture, not a vignetting circle")
    if not fit.success:
        problems.append(f"the fit did not converge ({fit.message})")
    return problems


def shift_difference_nm(lens_a: Lens, lens_b: Lens, f_numbers, max_cra_deg, *,
                        cwl_nm=REFERENCE_CWL_NM, n_eff=REFERENCE_N_EFF):
    """Largest difference of the predicted mean shift (nm) between two lenses over the field
    (CRA 0 to ``max_cra_deg``), for each f-number; CRAs past either lens's full cut-off are
    left out (no light, no shift).

    Parameters
    ----------
    lens_a, lens_b : Lens
        The two lenses (usually the same pupil with different circles).
    f_numbers : array_like
        Nominal f-numbers (1-D).
    max_cra_deg : float
        Largest chief-ray angle of the field, degrees (97 CRAs are compared).
    cwl_nm : float
        Central wavelength of the reference filter, nm.
    n_eff : float
        Its effective index.

    Returns
    -------
    ndarray
        One difference per f-number, nm (``"vignetted"`` mean shift); NaN where no CRA is left
        or the pupil is cut off.
    """
    out = []
    for f in np.asarray(f_numbers, float):
        top = min(max_cra_deg, 0.999 * float(lens_a.cutoff_cra_deg(f)),
                  0.999 * float(lens_b.cutoff_cra_deg(f)))
        if not top > 0:
            out.append(float("nan"))
            continue
        cra = np.linspace(0.0, top, _CRA_SAMPLES)
        try:
            a = mean_shift(cwl_nm, n_eff, f, cra, lens_a, method="vignetted")
            b = mean_shift(cwl_nm, n_eff, f, cra, lens_b, method="vignetted")
        except PupilCutOffError:
            out.append(float("nan"))
            continue
        out.append(float(np.max(np.abs(a - b))))
    return np.array(out)


def shift_stderr_nm(fit: ModelFit, base: Lens, f_numbers, max_cra_deg, *,
                    cwl_nm=REFERENCE_CWL_NM, n_eff=REFERENCE_N_EFF):
    """Standard error of the predicted mean shift that the fit's uncertainty in P and h leaves,
    largest over the field, for each f-number (nm; NaN where it cannot be propagated).

    The covariance of the circles' parameters is the fit's: the noise's, scaled by the
    misfit, plus the block model's approximation as one correlated direction
    (:func:`~snapcorr.calibrate.lens.joint_fit._rule_bias`), so the reported standard errors are
    the square roots of its diagonal. Where a reported error is larger than that (a fit made
    elsewhere, with its own errors), the covariance is scaled up as a whole by the largest
    ratio: scaling each variance by its own would upset the cancellation between strongly
    correlated P and h. It is carried through the mean shift by finite differences:
    ``sqrt(diag(J C J^T))`` on a grid of CRAs.

    Parameters
    ----------
    fit : ModelFit
        The fit of one model, with its covariance and standard errors.
    base : Lens
        Exit pupil and magnifications; its circles are replaced by the fit's.
    f_numbers : array_like
        Nominal f-numbers (1-D).
    max_cra_deg : float
        Largest chief-ray angle of the field, degrees (49 CRAs up to it or the cut-off).
    cwl_nm : float
        Central wavelength of the reference filter, nm.
    n_eff : float
        Its effective index.

    Returns
    -------
    ndarray
        One standard error per f-number, nm: NaN for all without circles or covariance, or
        where the shift cannot be computed; ``inf`` for all when a reported standard error is
        not finite.
    """
    names = [k for k in fit.names if k.endswith("_mm")]
    fs = np.asarray(f_numbers, float)
    if not names or fit.covariance is None:
        return np.full(fs.size, np.nan)
    idx = [fit.names.index(k) for k in names]
    cov = np.asarray(fit.covariance)[np.ix_(idx, idx)]
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    err = np.array([fit.stderr[k] for k in names])
    if not np.all(np.isfinite(err)):
        return np.full(fs.size, np.inf)
    free = sd > 0
    cov = cov * float(np.max(np.where(free, err / np.where(free, sd, 1.0), 1.0), initial=1.0)) ** 2
    p0 = {k: fit.params[k] for k in fit.names}
    lens = lens_of(fit, base)
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EffectiveIndexWarning)
        for f in fs:
            top = min(max_cra_deg, 0.999 * float(lens.cutoff_cra_deg(f)))
            cra = np.linspace(0.0, top, 49)
            try:
                ref = mean_shift(cwl_nm, n_eff, f, cra, lens, method="vignetted")
                J = []
                for k in names:
                    step = 1e-5 * max(abs(p0[k]), 1.0)
                    moved = replace(fit, params={**p0, k: p0[k] + step})
                    J.append((mean_shift(cwl_nm, n_eff, f, cra, lens_of(moved, base),
                                         method="vignetted") - ref) / step)
            except (PupilCutOffError, ValueError):
                out.append(float("nan"))
                continue
            J = np.asarray(J).T  # (cra, params)
            out.append(float(np.sqrt(np.max(np.einsum("ij,jk,ik->i", J, cov, J)))))
    return np.array(out)


def _significance(diff, sd):
    """Largest ratio, over f-numbers, of a shift difference to its standard error (``inf``
    where the error is 0 and the difference is not, ``nan`` if none can be formed)."""
    diff, sd = np.asarray(diff, float), np.asarray(sd, float)
    ok = np.isfinite(diff) & (diff > 0) & ~np.isnan(sd)
    if not ok.any():
        return float("nan")
    with np.errstate(divide="ignore"):
        return float(np.max(np.where(sd[ok] > 0, diff[ok] / np.where(sd[ok] > 0, sd[ok], 1.0),
                                     np.inf)))


def choose(fits: dict, bic_floor: dict, base: Lens, f_numbers, max_cra_deg, *,
           tolerance_nm=TOLERANCE_NM, h_given=False):
    """The model the flats support, and a verdict on every model tried.

    Models are taken in order of their number of circles; each step up must pass all three
    rules of the module's description against the model chosen so far.

    Parameters
    ----------
    fits : dict
        Model name (``"none"``, ``"one"``, ``"two"``, ``"three"``) -> its :class:`ModelFit`.
    bic_floor : dict
        Model name -> its BIC with the systematic floor
        (:func:`~snapcorr.calibrate.lens.joint_fit.floor_chi2`).
    base : Lens
        Exit pupil and magnifications; its circles are replaced by each fit's.
    f_numbers : array_like
        Nominal f-numbers of the flats (1-D).
    max_cra_deg : float
        Largest chief-ray angle of the field, degrees.
    tolerance_nm : float
        Rule 3: a further circle must move the mean shift by more than this, nm.
    h_given : bool
        ``h`` was given rather than fitted (see :func:`check_circles`).

    Returns
    -------
    chosen : str
        The model chosen.
    verdicts : dict
        Model name -> :class:`ModelVerdict`, for every model in ``fits``.
    """
    order = sorted(fits, key=lambda m: N_CIRCLES[m])
    chosen = order[0]
    verdicts = {chosen: ModelVerdict(chosen, True, "", bic_floor[chosen],
                                     fits[chosen].reduced_chi2)}
    for model in order[1:]:
        fit = fits[model]
        v = ModelVerdict(model, False, "", bic_floor[model], fit.reduced_chi2)
        verdicts[model] = v
        problems = check_circles(fit, base, f_numbers, max_cra_deg, h_given=h_given)
        if problems:
            v.problems = problems
            v.why = "not identifiable: " + "; ".join(problems)
            continue
        gain = bic_floor[chosen] - bic_floor[model]
        if gain <= MIN_BIC_GAIN:
            v.why = (f"no better than {chosen} once a {100 * FLOOR_REL:g} % systematic floor is "
                     f"allowed for (BIC gain {gain:.4g} <= {MIN_BIC_GAIN:g})")
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", EffectiveIndexWarning)
            diff = shift_difference_nm(lens_of(fit, base), lens_of(fits[chosen], base),
                                       f_numbers, max_cra_deg)
        if not np.nanmax(diff, initial=0.0) > tolerance_nm:
            v.why = (f"changes the predicted mean shift by at most {np.nanmax(diff):.4g} nm "
                     f"(<= {tolerance_nm:g} nm) from {chosen}: {chosen} suffices")
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", EffectiveIndexWarning)
            sd = shift_stderr_nm(fit, base, f_numbers, max_cra_deg)
        z = _significance(diff, sd)
        if not z > MIN_SHIFT_SIGMAS:
            v.why = (f"changes the predicted mean shift by up to {np.nanmax(diff):.4g} nm from "
                     f"{chosen}, but that is only {z:.3g} of its own standard errors "
                     f"(<= {MIN_SHIFT_SIGMAS:g}): the flats cannot tell them apart")
            continue
        verdicts[chosen].chosen = False
        verdicts[chosen].why = f"{model} describes the flats better and it matters (below)"
        v.chosen = True
        v.why = (f"every circle identifiable; BIC gain {gain:.4g} over {chosen} with the "
                 f"floor; moves the mean shift by up to {np.nanmax(diff):.4g} nm ({z:.3g} "
                 "standard errors)")
        chosen = model
    if not verdicts[chosen].why:
        verdicts[chosen].why = ("no model with more circles passed the rules" if len(order) > 1
                                else "the only model tried")
    return chosen, verdicts


#: Models whose weight (from the floored BIC) is below this add nothing to the error bar.
MIN_MODEL_WEIGHT = 1e-4


def model_choice_stderr(fits, bic, verdicts, model, lens, base, fs, max_cra, rivals=None,
                        fit_err=None):
    """The error of the predicted mean shift that the choice of model leaves, per f-number.

    The rules choose a richer model only on strong evidence; where the flats cannot decide
    (a circle's effect near the noise), the model chosen may lack a circle that is there, and
    its own standard error knows nothing of it: at 5 % noise per pixel a missed pixel-
    vignetting circle left errors of 0.2 nm under error bars of 0.011 nm. So every other
    model that is a lens (its circles identifiable) contributes ``p * d^2``: ``d`` the
    largest difference of the mean shift it predicts from the chosen one's, ``p`` its
    weight ``1 / (1 + exp(delta / 2))`` from its criterion ``delta`` above the chosen one's.
    A model far worse weighs nothing; one the flats cannot tell from the chosen one weighs
    about half. Empty when no model counts.

    A model with more circles than the chosen one (a circle the choice may have dropped)
    weighs at least its Akaike weight against the chosen one, ``1 / (1 + exp((2 dk - G) /
    2))`` for ``dk`` more parameters and a fall ``G`` of the floored chi-square (Burnham &
    Anderson 2002, Model Selection and Multimodel Inference, section 2.9): the AIC prices a
    parameter at 2, not the BIC's ``ln n`` (11.5 for 1e5 blocks). The BIC's price is right
    for choosing, a strong claim that a circle is there; as the weight of "a circle may be
    there" it made the term vanish where the flats cannot tell the two lenses apart. And it
    contributes ``d^2`` less the noise of ``d`` itself, ``s_rich^2 - s_chosen^2`` (the two
    fits' own standard errors of the shift: for nested fits of the same data the variance of
    their difference is the difference of their variances, Hausman 1978), at least 0: a
    circle fitted to noise moves the shift by about its own error and adds nothing.

    On counted-ray flats at 2 % noise (``benchmarks/calibration_coverage.py``) the paper's
    lens plus a pixel-vignetting circle (seed 8) and the paper's lens alone (seed 2) both
    drop the pixel circle, whose fit lowers the chi-square by 0.79 and 1.61 and moves the
    shift by 0.134 and 0.178 nm (its own error 0.060 and 0.048 nm): the flats see the same in
    both, yet the first is 0.209 nm off. The BIC's weight (0.005) reported that as 0.019 nm
    (z 11), and so did an earlier floor of ``1 - 2 dk / G``, zero below the AIC's price. The
    lens without the pixel circle pays for flats that cannot rule it out. At 0.5 % noise a
    pixel circle fitted to noise (``G`` 0.34) moves the shift by 0.021 nm, under its own
    error of 0.042 nm: without the noise's share it would have widened the error 2.8 times.
    Where the weights add up to more than 1 (two forms of the same dropped circle), they are
    scaled to 1: the error is then at most the largest difference.

    The rivals (``{name: (fit, floored BIC)}``, :func:`~snapcorr.calibrate.lens.stages.joint_fits`)
    count the same way where their circles are identifiable: the first circle plus pixel
    vignetting (``h = x``, one parameter) carries a pixel circle at the detection limit,
    which a free second circle (two parameters, and a valley of P and h) often cannot.

    Parameters
    ----------
    fits, bic, verdicts : dict
        Model name -> :class:`ModelFit`, its floored BIC and its :class:`ModelVerdict`.
    model : str
        The model chosen.
    lens, base : Lens
        The profile of the chosen model; the exit pupil and magnifications alone.
    fs : array_like
        Nominal f-numbers (1-D).
    max_cra : float
        Largest chief-ray angle of the field, degrees.
    rivals : dict, optional
        Name -> (fit, floored BIC) of further models.
    fit_err : array_like, optional
        The chosen model's own standard error of the shift per f-number
        (:func:`shift_stderr_nm`); None: computed here.

    Returns
    -------
    ndarray
        nm per f-number; empty when no model counts.
    """
    var, total = np.zeros(len(fs)), 0.0
    used = False
    candidates = [(fit, bic[m]) for m, fit in fits.items()
                  if m != model and (v := verdicts.get(m)) is not None and not v.problems]
    candidates += [(fit, b) for fit, b in (rivals or {}).values()
                   if not check_circles(fit, base, fs, max_cra)]
    own = None
    for fit, b in candidates:
        if not fit.success:
            continue
        weight = _choice_weight(fit, b, fits[model], bic[model])
        if weight < MIN_MODEL_WEIGHT:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", EffectiveIndexWarning)
            d2 = np.nan_to_num(shift_difference_nm(lens, lens_of(fit, base), fs, max_cra)) ** 2
            if N_CIRCLES[fit.model] > N_CIRCLES[fits[model].model]:
                if own is None:
                    own = _own_stderr(fits[model], base, fs, max_cra, fit_err)
                rich = np.nan_to_num(shift_stderr_nm(fit, base, fs, max_cra), posinf=0.0)
                d2 = np.clip(d2 - np.clip(rich**2 - own**2, 0.0, None), 0.0, None)
        var += weight * d2
        total += weight
        used = True
    # the rivals are alternatives to one another (a pixel circle held at h = x or free):
    # their weights share at most the whole
    return np.sqrt(var / max(total, 1.0)) if used else np.zeros(0)


def _own_stderr(fit, base, fs, max_cra, fit_err):
    """The chosen model's standard error of the shift per f-number (0 without circles)."""
    if fit_err is None:
        fit_err = shift_stderr_nm(fit, base, fs, max_cra) if fit.model != "none" else []
    err = np.nan_to_num(np.asarray(fit_err, float), posinf=0.0)
    return err if err.size == len(fs) else np.zeros(len(fs))


def _choice_weight(fit, b, chosen, b_chosen):
    """A model's weight against the chosen one (:func:`model_choice_stderr`): from the
    floored BIC, and for a model with more circles at least its Akaike weight."""
    delta = float(b - b_chosen)
    weight = 1.0 / (1.0 + math.exp(min(delta / 2.0, 700.0)))
    dk = fit.k - chosen.k
    if N_CIRCLES[fit.model] > N_CIRCLES[chosen.model] and dk > 0 and fit.n > 1:
        gain = dk * math.log(fit.n) - delta  # how much lower its floored chi-square is
        weight = max(weight, 1.0 / (1.0 + math.exp(min((2 * dk - gain) / 2.0, 700.0))))
    return weight
