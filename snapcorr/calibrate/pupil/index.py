"""The exit-pupil fit's index stage: the ladder of effective-index models after ``x``.

With ``x`` and one scale of the sensor's index fitted (:mod:`~snapcorr.calibrate.pupil.distance`),
:func:`_index_ladder` tries richer models of ``n_eff``, the sensor's values times a factor
linear in wavelength and then one value per band, each by damped Gauss-Newton in ``x`` and the
index together (:func:`_index_fit`, the Jacobian of :func:`_per_band_jacobian`), and keeps the
cheapest one the data need and pin (:data:`N_EFF_P`, :data:`N_EFF_REL_STDERR`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy import stats

from .solver import _prediction_derivatives, _project_off, _row_bands, _solve, _whiten

#: A richer model of the effective index (linear in wavelength, one per band) is taken when it
#: improves the fit at this significance and pins every band's index to this relative
#: standard error.
N_EFF_P = 1e-3
N_EFF_REL_STDERR = 0.01


def _per_band_jacobian(model, x, n, *, central=False):
    """Whitened residuals and their Jacobian in ``(x, n_1..n_B)`` at fixed target
    coefficients, projected off the target's columns (variable projection). The index
    columns are the model's analytic derivative (:func:`_prediction_derivatives`); ``x``'s
    is a forward difference, or a central one with ``central``."""
    n = np.asarray(n, float)
    A = model.design(x, n)
    s, r, _ = _solve(model, A)
    dx, dn = _prediction_derivatives(model, x, n, A, s, central=central)
    # every band's rows depend on its own index only: each row fills its band's column
    Jn = np.zeros((model.n_rows, n.size))
    Jn[np.arange(model.n_rows), _row_bands(model)] = dn
    return r, _project_off(_whiten(model, A), np.column_stack([dx, Jn]))


class _IndexFit(NamedTuple):
    status: str  # "fitted", "unconstrained" or "not needed"
    x: float
    n: np.ndarray
    n_err: np.ndarray  # unscaled standard errors
    x_err: float
    chi2: float = math.nan  # for "not needed": the gain one step predicts
    rank: float | None = None


def _index_fit(problem, x, n, basis, *, needed_gain=0.0, jacobians=None):
    """``x`` and the index ``n = n_design * (basis @ c)`` by damped Gauss-Newton from ``(x, n)``.

    Stops at the start (status ``"unconstrained"``) when even noise alone leaves some band's
    index unknown to more than ``N_EFF_REL_STDERR``, or (``"not needed"``) when the first
    step's predicted chi-square gain is below ``needed_gain``. ``jacobians`` (a dict) keeps
    the first Jacobian for the next rung, which starts from the same point when this one is
    not taken."""
    model = problem.model
    B = problem.n_design[:, None] * basis
    c = np.linalg.lstsq(B, n, rcond=None)[0]  # the start lies in every richer model's span
    xb = float(x)
    for it in range(30):
        n = n if it == 0 else B @ c
        key = (xb, n.tobytes())
        if jacobians is not None and key in jacobians:
            r, Jp = jacobians[key]
        else:
            r, Jp = _per_band_jacobian(model, xb, n)
            if jacobians is not None and it == 0:
                jacobians[key] = (r, Jp)
        J = np.column_stack([Jp[:, 0], Jp[:, 1:] @ B])
        try:
            cov = np.linalg.inv(J.T @ J)
        except np.linalg.LinAlgError:
            return _IndexFit("unconstrained", xb, n, np.full(n.size, np.inf), math.inf)
        n_err = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", B, cov[1:, 1:], B), 0, None))
        x_err = math.sqrt(max(cov[0, 0], 0.0))
        step = cov @ (J.T @ r)
        if it == 0 and not np.all(n_err < N_EFF_REL_STDERR * n):
            return _IndexFit("unconstrained", xb, n, n_err, x_err)
        if it == 0 and step @ (J.T @ r) < needed_gain:
            return _IndexFit("not needed", xb, n, n_err, x_err, float(step @ (J.T @ r)))
        limit = max(1.0, float(np.max(np.abs(B @ step[1:]) / (0.05 * n))),
                    abs(step[0]) / (0.05 * xb))
        xb, c = xb + step[0] / limit, c + step[1:] / limit
        if limit == 1.0 and np.all(np.abs(step) < 0.02 * np.sqrt(np.diag(cov))):
            break
    n = B @ c
    _, r, rank = _solve(model, model.design(xb, n), rank=True)
    return _IndexFit("fitted", xb, n, n_err, x_err, float(r @ r), rank)


def _index_ladder(problem, x, n, x_err, n_err, chi2, scale, notes):
    """The cheapest index model the data need, from one value (fitted) up: linear in
    wavelength, then one per band. A richer model is taken when it lowers chi-square at
    significance ``N_EFF_P`` (scaled by its own reduced chi-square) and pins every band's index
    to ``N_EFF_REL_STDERR``; it is not fitted when one Gauss-Newton step from the current model
    predicts a gain ten times less significant than that.

    Returns ``(mode, x, x_err, n, n_err, chi2, chi2_red)``, errors scaled; ``chi2_red`` is None
    when one value stays."""
    model = problem.model
    nb = n.size
    t = (model.cwl - model.cwl.mean()) / max(float(np.ptp(model.cwl)) / 2, 1e-9)
    ladder = [("linear in wavelength", np.column_stack([np.ones(nb), t]))] if nb >= 3 else []
    ladder.append(("one per band", np.eye(nb)))
    best = ("one", x, x_err, n, n_err, chi2, None)
    q_best, limit, jacobians = 1, 100 * N_EFF_REL_STDERR, {}
    for name, basis in ladder:
        q = basis.shape[1]
        needed = float(stats.chi2.isf(10 * N_EFF_P, q - q_best)) * scale
        fit = _index_fit(problem, best[1], best[3], basis, needed_gain=needed,
                         jacobians=jacobians)
        if fit.status == "unconstrained":
            worst = float(np.max(fit.n_err / fit.n))
            notes.append(f"n_eff not {name}: the data would pin it only to "
                         + (f"{100 * worst:.2g} %" if worst < 1 else "nothing (a band without a "
                            "feature of the target)") + f" at worst (limit {limit:g} %)")
            continue
        if fit.status == "not needed":
            notes.append(f"n_eff not {name}: it would lower chi-square by about {fit.chi2:.3g} "
                         f"for {q - q_best} more parameter{'s' if q - q_best > 1 else ''}")
            continue
        dof = max(round(model.n_rows - fit.rank - 1 - q), 1)
        s = max(1.0, fit.chi2 / dof)
        ne, xe = fit.n_err * math.sqrt(s), fit.x_err * math.sqrt(s)
        gain = best[5] - fit.chi2
        pval = float(stats.chi2.sf(max(gain, 0.0) / s, q - q_best))
        worst = float(np.max(ne / fit.n))
        told = (f"chi-square lower by {gain:.3g} for {q - q_best} more parameter"
                f"{'s' if q - q_best > 1 else ''} (p = {pval:.2g}), every index known to "
                f"{100 * worst:.2g} % or better")
        if pval < N_EFF_P and worst < N_EFF_REL_STDERR:
            best = ("linear" if q == 2 else "per band", fit.x, xe, fit.n, ne, fit.chi2,
                    fit.chi2 / dof)
            q_best, scale = q, s
            notes.append(f"n_eff {name}: {told}")
        else:
            notes.append(f"n_eff not {name}: {told} (needs p < {N_EFF_P:g} and {limit:g} %)")
    return best
