"""The exit-pupil fit's index stage: the ladder of effective-index models after ``x``.

With ``x`` and one scale of the sensor's index fitted (:mod:`~snapcorr.calibrate.pupil.distance`),
:func:`_index_ladder` tries richer models of ``n_eff``, the sensor's values times a factor
linear in wavelength and then one value per band, each by damped Gauss-Newton in ``x`` and the
index together (:func:`_index_fit`, the Jacobian of :func:`_per_band_jacobian`), and keeps the
cheapest one the data need (:data:`N_EFF_P`). A shared model must pin every index to
:data:`N_EFF_REL_STDERR`. One index per band is fitted where the data ask for it, for every band
they know at all (:data:`N_EFF_BAND_MAX_STDERR`; the others keep the cheaper model together,
:func:`_pinned_basis`), each with its own standard error: where the target's features pin some
bands and not others (a wavelength standard's absorption bands fall in a few of a mosaic's
bands) the notes name the bands pinned (:data:`N_EFF_BAND_STDERR`) and those that are not. A
band known to 1 % keeps its own index; a band known less well keeps the shared model's, with an
error widened by how far the other bands' own indices fall from it (:func:`_per_band_said`):
a band between two of the target's features is not given an index as if it were measured.
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
#: A band's index is said to be pinned where its standard error is below this fraction: within
#: N_EFF_REL_STDERR (1 %) at 2.5 standard errors.
N_EFF_BAND_STDERR = N_EFF_REL_STDERR / 2.5
#: One index per band is fitted for every band the data know to this fraction or better (pinned
#: or not: its standard error says how well); a band they know less well (a band without a
#: feature of the target) keeps the cheaper model with the others of its kind.
N_EFF_BAND_MAX_STDERR = 0.25


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


def _index_fit(problem, x, n, basis, *, needed_gain=0.0, jacobians=None, rel_limit=None):
    """``x`` and the index ``n = n_design * (basis @ c)`` by damped Gauss-Newton from ``(x, n)``.

    Stops at the start (status ``"unconstrained"``) when even noise alone leaves some band's
    index unknown to more than its ``rel_limit`` (relative; default ``N_EFF_REL_STDERR``
    for every band), or (``"not needed"``) when the first
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
        if it == 0 and not np.all(n_err < (N_EFF_REL_STDERR if rel_limit is None
                                           else rel_limit) * n):
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


def _pinned_basis(prev, n_err, n):
    """The basis of "one per band" for the bands the data know (``n_err`` below
    :data:`N_EFF_BAND_MAX_STDERR` of ``n``, every band free): a column of its own for each, the
    others sharing the cheaper model ``prev`` (its columns on their rows; one common factor
    where they are too few for it). Returns ``(basis, known)``; the basis is None when no band,
    or every band, is known."""
    known = np.asarray(n_err < N_EFF_BAND_MAX_STDERR * n)
    if known.all() or not known.any():
        return None, known
    rest = np.where(known[:, None], 0.0, prev)
    if np.linalg.matrix_rank(rest[~known]) < prev.shape[1]:
        rest = (~known).astype(float)[:, None]
    own = np.eye(n.size)[:, known]
    return np.column_stack([rest, own]), known


def _bands_nm(model, which):
    return ", ".join(f"{c:.4g}" for c in np.asarray(model.cwl)[which]) + " nm"


def _alone_stderr(problem, x, n, scale):
    """Every band's index's standard error with every band free (scaled): what the data say
    of each band alone."""
    _, Jp = _per_band_jacobian(problem.model, x, n)
    with np.errstate(all="ignore"):
        cov = np.linalg.pinv(Jp.T @ Jp)
    return np.sqrt(np.clip(np.diag(cov)[1:], 0.0, None) * scale)


def _index_ladder(problem, x, n, x_err, n_err, chi2, scale, notes):
    """The cheapest index model the data need, from one value (fitted) up: linear in
    wavelength, then one per band (for every band the data know at all; the others sharing the
    cheaper model, :func:`_pinned_basis`). A richer model is taken when it lowers chi-square at
    significance ``N_EFF_P`` (scaled by its own reduced chi-square) and knows every index it
    fits: a shared one to ``N_EFF_REL_STDERR``, a band's own to ``N_EFF_BAND_MAX_STDERR``; it is
    not fitted when one Gauss-Newton step from the current model predicts a gain ten times less
    significant than that. One per band taken, the notes name the bands pinned to
    ``N_EFF_BAND_STDERR`` and those that are not, and a band not known to
    ``N_EFF_REL_STDERR`` keeps the shared model's index with a widened error
    (:func:`_per_band_said`).

    Returns ``(mode, x, x_err, n, n_err, chi2, chi2_red)``, errors scaled; ``chi2_red`` is None
    when one value stays."""
    model = problem.model
    nb = n.size
    t = (model.cwl - model.cwl.mean()) / max(float(np.ptp(model.cwl)) / 2, 1e-9)
    ladder = [("linear in wavelength", np.column_stack([np.ones(nb), t]))] if nb >= 3 else []
    ladder.append(("one per band", np.eye(nb)))
    best = ("one", x, x_err, n, n_err, chi2, None)
    best_basis, best_name = np.ones((nb, 1)), "one value"
    q_best, jacobians, known = 1, {}, np.ones(nb, bool)
    for name, basis in _rungs(ladder):
        q = basis.shape[1]
        per_band = name.startswith("one per band")
        rel = (np.where(known, N_EFF_BAND_MAX_STDERR, N_EFF_REL_STDERR) if per_band
               else np.full(nb, N_EFF_REL_STDERR))
        needed = float(stats.chi2.isf(10 * N_EFF_P, q - q_best)) * scale
        fit = _index_fit(problem, best[1], best[3], basis, needed_gain=needed,
                         jacobians=jacobians, rel_limit=rel)
        if fit.status == "not needed":
            notes.append(f"n_eff not {name}: it would lower chi-square by about {fit.chi2:.3g} "
                         f"for {q - q_best} more parameter{'s' if q - q_best > 1 else ''}")
            continue
        if fit.status == "unconstrained":
            worst = float(np.max(fit.n_err / fit.n))
            said = (f"n_eff not {name}: the data would pin it only to "
                    + (f"{100 * worst:.2g} %" if worst < 1 else "nothing (a band without a "
                       "feature of the target)") + " at worst")
            if name == "one per band":
                sub, known = _pinned_basis(best_basis, fit.n_err, fit.n)
                if sub is not None:
                    said += (f"; bands {_bands_nm(model, ~known)} known to less than "
                             f"{100 * N_EFF_BAND_MAX_STDERR:g} % keep {best_name}, the others "
                             "one each")
                    ladder.append(("one per band (those the data know)", sub))
            notes.append(said)
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
        if pval < N_EFF_P and np.all(ne < rel * fit.n):
            n_fit = fit.n
            if per_band:
                n_fit, ne, told = _per_band_said(problem, fit, ne, known, s, best[3:5],
                                                 best_name, told)
            best = ("per band" if per_band else "linear", fit.x, xe, n_fit, ne, fit.chi2,
                    fit.chi2 / dof)
            best_basis, best_name, q_best, scale = basis, name, q, s
            notes.append(f"n_eff {name}: {told}")
        else:
            notes.append(f"n_eff not {name}: {told} (needs p < {N_EFF_P:g} and "
                         f"{100 * float(np.max(rel)):g} %)")
    return best


def _rungs(ladder):
    """The ladder's rungs in order, including those appended while it is climbed."""
    i = 0
    while i < len(ladder):
        yield ladder[i]
        i += 1


def _per_band_said(problem, fit, ne, known, scale, shared, shared_name, told):
    """One per band taken: which bands are pinned (:data:`N_EFF_BAND_STDERR`), and what is
    given for those that are not. A band known to :data:`N_EFF_REL_STDERR` keeps its own
    index and error. A band known less well has an estimate of its own hardly better than
    noise (and its linearised error is not to be trusted that far from a minimum): it is given
    the shared model's index (``shared``: index and errors) instead, with the error that model
    has widened by the scatter of the other bands' own indices about it (what a band's own
    index may be from the sensor's, as far as the data show). Returns ``(n, n_err, told)``."""
    model = problem.model
    n = np.asarray(fit.n, float).copy()
    if not known.all():
        ne = np.where(known, ne, np.maximum(ne, _alone_stderr(problem, fit.x, fit.n, scale)))
    rel = ne / n
    pinned = rel < N_EFF_BAND_STDERR
    own = rel < N_EFF_REL_STDERR
    told = told.replace("every index known to", "every index known to at worst")
    if pinned.all():
        return n, ne, told + f"; every band pinned to {100 * N_EFF_BAND_STDERR:g} %"
    said = (f"; pinned to {100 * N_EFF_BAND_STDERR:g} %: "
            + (f"bands {_bands_nm(model, pinned)}" if pinned.any() else "no band")
            + f"; not pinned (alone to {100 * float(np.min(rel[~pinned])):.2g}-"
            f"{100 * float(np.max(rel[~pinned])):.2g} %): bands {_bands_nm(model, ~pinned)}")
    if (own & ~pinned).any():
        said += (f" (of these, {_bands_nm(model, own & ~pinned)} keep their own index, known "
                 f"to {100 * N_EFF_REL_STDERR:g} %)")
    if own.all():
        return n, ne, told + said
    n_sh, e_sh = (np.asarray(v, float) for v in shared)
    dev = (n[own] - n_sh[own]) ** 2 - ne[own] ** 2
    spread = math.sqrt(max(float(np.mean(dev)), 0.0)) if own.any() else 0.0
    said += (f"; bands {_bands_nm(model, ~own)} keep {shared_name} "
             f"({float(np.min(n_sh[~own])):.4g}"
             + (f"-{float(np.max(n_sh[~own])):.4g}" if np.ptp(n_sh[~own]) > 0 else "")
             + f"), its error widened by the other bands' scatter about it ({spread:.2g}): "
             "measure them with a target whose features fall in them")
    n[~own] = n_sh[~own]
    ne = ne.copy()
    ne[~own] = np.hypot(e_sh[~own], spread)
    return n, ne, told + said


