"""Which estimator of the vignetting circles predicts a flat it has not seen.

The joint fit (:mod:`snapcorr.calibrate.lens.joint_fit`) uses every pixel of every flat; the
paper's onsets (Eq. 26) use only where each fall-off starts. Neither is better by decree: the
joint fit is several times more precise where the area model holds, the onsets are immune to
what the model leaves out (pupil aberrations, a fall-off that changes with the f-number). A
chi-square threshold does not decide between them: with millions of pixels a harmless misfit
is "significant", and a joint fit within 0.07 % of the truth was once discarded for onsets
0.44 % off.

So each estimator is asked to predict what it has not seen. For every flat but the reference,
in turn, each estimator is fitted without it (the joint fit on the other flats, started from
its full fit, on every block; Eq. 26 on the other onsets), and the
left-out flat is predicted from the others: each block's gain from the flats kept, the
left-out flat's exposure by least squares (its only free number). The chi-square of that
prediction, summed over the flats left out, is each estimator's predictive score. The paper's
onsets are used only where their score is lower than the joint fit's by more than
``MIN_PREDICTIVE_GAIN`` (a likelihood ratio of e^5): only where the joint fit is shown to
predict worse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..._coords import accepts_center_rc
from .joint_fit import (
    BlockData,
    ModelFit,
    _block_model,
    _profiled,
    fit_model,
)

__all__ = ["MIN_PREDICTIVE_GAIN", "Prediction", "compare_estimators", "predict_left_out"]

#: The onsets must beat the joint fit's predictive chi-square by more than this to be used.
MIN_PREDICTIVE_GAIN = 10.0
#: ``max_nfev`` of a refit without one flat (``fit_model`` gives its first start three times
#: this: 12 evaluations); it starts from the full fit's minimum and runs on every block.
REFIT_NFEV = 4


@dataclass
class Prediction:
    """Predictive chi-square of one estimator: per left-out f-number, and in all."""

    estimator: str
    chi2: dict = field(default_factory=dict)  # f-number -> chi-square of that flat
    n: dict = field(default_factory=dict)  # f-number -> blocks predicted

    @property
    def total(self) -> float:
        return float(sum(self.chi2.values()))

    def as_table(self) -> dict:
        return {"left_out_f_numbers": [float(f) for f in self.chi2],
                "chi2": [round(float(v), 2) for v in self.chi2.values()],
                "blocks": [int(v) for v in self.n.values()],
                "total_chi2": round(self.total, 2)}


def without_flat(data: BlockData, k: int) -> BlockData:
    """``data`` without flat ``k`` (its row)."""
    keep = [i for i in range(data.q.shape[0]) if i != k]

    def rows(a):
        return None if a is None else a[keep]

    return replace(data, q=data.q[keep], sigma=data.sigma[keep], R_mm=data.R_mm[keep],
                   xoff=rows(data.xoff), yoff=rows(data.yoff), xsd=rows(data.xsd),
                   ysd=rows(data.ysd), warm={})


@accepts_center_rc(old="center", new="center_rc")
def predict_left_out(data: BlockData, model: str, p, center_rc, k: int):
    """Chi-square and number of blocks of flat ``k`` predicted from the other flats: their
    gains, the model's area fractions, and the left-out flat's exposure fitted to it.

    Parameters
    ----------
    data : BlockData
        The flats as fitted (with gains).
    model : str
        ``"one"``, ``"two"`` or ``"three"`` circles.
    p : sequence of float
        The model's parameters (:func:`~snapcorr.calibrate.lens.joint_fit.param_names`: the
        centre row first).
    center_rc : (row, col) or None
        Optical centre, pixels; None: the one in ``p``. ``center=(cx, cy)`` is its
        deprecated x-first form.
    k : int
        The flat predicted (its row in ``data``).

    Returns
    -------
    chi2 : float
        NaN where nothing can be predicted.
    n : int
        Blocks predicted.
    """
    A = _block_model(data, model, p, center_rc if center_rc is not None else (p[2], p[3]))
    others = [i for i in range(data.q.shape[0]) if i != k]
    _, _, G = _profiled(data.q[others], data.sigma[others], A[others], return_gains=True)
    seen = np.isfinite(data.sigma[others]).any(axis=0)
    w = 1.0 / data.sigma[k] ** 2
    mu = G * A[k]
    ok = seen & (w > 0) & np.isfinite(mu)
    den = float(np.sum(w[ok] * mu[ok] ** 2))
    if not ok.any() or den <= 0:
        return math.nan, 0
    e = float(np.sum(w[ok] * data.q[k][ok] * mu[ok])) / den
    r = (data.q[k][ok] - e * mu[ok]) * np.sqrt(w[ok])
    return float(r @ r), int(ok.sum())


@accepts_center_rc(old="center", new="center_rc")
@accepts_center_rc(old="fix_center", new="fix_center_rc")
def compare_estimators(data: BlockData, fs, fit: ModelFit, onset_solver, center_rc, *,
                       fix_center_rc=None, fixed_h=None, progress=None):
    """Predictive scores of the joint fit (model of ``fit``) and of the paper's onsets.

    Parameters
    ----------
    data : BlockData
        The flats as fitted (with gains), in the order of ``fs``; the last is the reference.
    fs : array_like
        Their f-numbers.
    fit : ModelFit
        The joint fit chosen (with at least one circle).
    onset_solver : callable
        ``onset_solver(f_left_out)`` -> ``(P, h)`` from Eq. (26) without that f-number's
        onset, or None where the others cannot give one.
    center_rc : (row, col)
        Optical centre at which the onsets' circle is evaluated, pixels (``center=(cx, cy)``
        is its deprecated x-first form).
    fix_center_rc : (row, col), optional
        The joint fit's centre was held here (``fix_center=(cx, cy)``, deprecated, x first).
    fixed_h : float, optional
        The joint fit's h was held at this.
    progress : callable, optional
        ``progress(step)`` before each flat is left out.

    Returns
    -------
    joint, onsets : Prediction
        Over the same left-out flats: those for which both can predict.
    """
    names = list(fit.names)
    p_full = np.array([fit.params[k] for k in names])
    joint, onsets = Prediction("joint"), Prediction("onset-ratio")
    for k in range(len(fs) - 1):
        f = float(fs[k])
        if progress is not None:
            progress(f"predicting f/{f:g} left out")
        circle = onset_solver(f)
        if circle is None:
            continue
        # refitted on every block, from the full fit's minimum (a few Gauss-Newton steps
        # away): not on a subset of them, whose own minimum lies off by the subset's noise and
        # predicted the flat left out worse by tens of chi-square, which handed two-circle
        # lenses to the onsets
        refit = fit_model(without_flat(data, k), fit.model, [p_full], center_rc=fix_center_rc,
                          fixed_h=fixed_h, max_nfev=REFIT_NFEV, keep=1, screen=False,
                          fixed=fit.extra.get("held"))
        p = np.array([refit.params[n] for n in names])
        cj, nj = predict_left_out(data, fit.model, p, fix_center_rc, k)
        po = np.array([circle[0], circle[1], center_rc[0], center_rc[1]])
        co, no = predict_left_out(data, "one", po, center_rc, k)
        if not (math.isfinite(cj) and math.isfinite(co)):
            continue
        joint.chi2[f], joint.n[f] = cj, nj
        onsets.chi2[f], onsets.n[f] = co, no
    return joint, onsets
