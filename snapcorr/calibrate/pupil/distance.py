"""The exit-pupil fit's x stage: the search for ``x`` and the test that the target shows a shift.

From the annuli of the input stage (:mod:`~snapcorr.calibrate.pupil.target`) the target
models are built (:func:`_target_models`: every annulus, and a coarse copy for the scan), the
trial range of ``x`` is set by the chief-ray angles at the field's edge
(:data:`EDGE_CRA_DEG`), a coarse scan evenly spaced in the edge's shift finds the deepest
minima (:func:`_scan_grid`, :func:`_start`), and damped Gauss-Newton in ``x`` (and one scale of
the index) refines the best (:func:`_fit`, :func:`_fit_x`). :func:`_check_shift_seen` then
refuses a target whose field explains the data no better than a field without shift, in
sample and held out (:func:`_heldout_gain`). The richer index models come after, in
:mod:`~snapcorr.calibrate.pupil.index`.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import NamedTuple

import numpy as np
from scipy import optimize

from ...optics.shift import EffectiveIndexWarning
from .index import N_EFF_REL_STDERR, _per_band_jacobian
from .measured_target import target_model
from .solver import _Problem, _solve
from .target import FeaturelessTargetError
from .target_model import rebin

#: The field must explain the data better than a field without any shift by at least this
#: chi-square or the target is refused as featureless.
MIN_DELTA_CHI2 = 25.0
#: ... and, held out, by this many standard deviations of what noise alone gives: fitted on
#: every other annulus (x, n_eff and the target's spectrum), the field must predict the annuli
#: in between better than a field without shift (:func:`_heldout_gain`).
MIN_HELDOUT_SIGMA = 5.0
#: ... unless the in-sample difference exceeds this many times what noise gives at most (the
#: parameters the field adds plus five standard deviations): the held-out test refits twice.
HELDOUT_SKIP = 10.0
#: A fit whose relative standard error of x exceeds this is refused as uninformative.
MAX_REL_STDERR = 0.2


#: The chief-ray angles at the field's edge the search covers, degrees.
EDGE_CRA_DEG = (1.0, 38.0)


def _one_blas_thread(func):
    """Run ``func`` with one BLAS thread: the fit solves hundreds of small systems (a few
    hundred unknowns), where threaded BLAS only adds synchronisation, and on a busy machine
    makes each solve hundreds of times slower (measured)."""
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper


# -- the search's setting -----------------------------------------------------------------
def _field_radius(bins):
    return float(math.sqrt(max(b.rho.max() for b in bins)))


def _trial_range(r_max):
    """The smallest and largest trial ``x``, mm."""
    # trial range: chief-ray angles at the field's edge from EDGE_CRA_DEG down to ~1 degree
    x_lo = r_max / math.tan(math.radians(EDGE_CRA_DEG[1]))
    x_hi = r_max / math.tan(math.radians(EDGE_CRA_DEG[0]))
    return x_lo, x_hi


def _max_shift_rel(r_max, x_lo, n_design, cone_rad):
    """The largest relative shift a trial may give: the edge's chief ray and the cone."""
    phi_max = math.atan(r_max / x_lo) + cone_rad
    return 1.2 * (1 - math.sqrt(max(1 - math.sin(phi_max) ** 2
                                    / (0.6 * n_design.min()) ** 2, 0.05)))


def _circles_at(lens, base, scale_circles):
    """The x the lens's circles were found at, when they are to scale with x (else None)."""
    if scale_circles is None:  # a profile from flats says so
        scale_circles = lens is not None and "exit_pupil_scaling" in lens.calibration
    return base.exit_pupil_mm if scale_circles and base.has_vignetting else None


def _target_models(bins, sensor, base, n_design, spectrum, profile, max_rel,
                   circles_at_mm=None):
    """The target model of the annuli, and a coarse copy (four annuli in one) for the scan."""
    common = dict(spectrum=spectrum, profile=profile, n_eff_design=n_design,
                  max_shift_rel=max_rel, circles_at_mm=circles_at_mm)
    model = target_model(bins, sensor, base, **common)
    coarse = target_model([rebin(b, 4) for b in bins], sensor, base, **common)
    return model, coarse


# -- the fit ------------------------------------------------------------------------------
def _scan_grid(r_max, x_lo, x_hi, n_mean, cwl_mean, step_nm):
    """Trial x from ``x_hi`` to ``x_lo``, evenly spaced in the shift they give at the field's
    edge (steps of ``step_nm``): every trial shift pattern differs from its neighbours alike."""
    def edge_shift(x):
        return 1.0 - math.sqrt(1.0 - math.sin(math.atan(r_max / x)) ** 2 / n_mean**2)

    lo, hi = edge_shift(x_hi), edge_shift(x_lo)
    count = int(np.clip(math.ceil((hi - lo) * cwl_mean / step_nm), 16, 80))
    eps = np.linspace(lo, hi, count)
    sin_t = np.sqrt(n_mean**2 * (1.0 - (1.0 - eps) ** 2))
    return r_max / np.tan(np.arcsin(np.clip(sin_t, 1e-9, 0.999)))


def _start(problem, grid, *, candidates=3):
    """The best of the scan's deepest local minima, each refined by a bounded 1-D search."""
    c2 = np.array([problem.chi2(x) for x in grid])
    inner = [i for i in range(grid.size)
             if (i == 0 or c2[i] <= c2[i - 1]) and (i == grid.size - 1 or c2[i] <= c2[i + 1])]
    best = (math.inf, float(grid[int(np.argmin(c2))]))
    for i in sorted(inner, key=lambda i: c2[i])[:candidates]:
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        lo, hi = min(a, b), max(a, b)
        if hi <= lo:
            continue
        sol = optimize.minimize_scalar(problem.chi2, bounds=(lo, hi), method="bounded",
                                       options={"xatol": 1e-4 * lo})
        best = min(best, (float(sol.fun), float(sol.x)))
    return best[1]


#: The Gauss-Newton search stops when a step moves every parameter by less than this many
#: standard errors, or after :data:`MAX_STEPS` steps.
STEP_TOL = 0.01
MAX_STEPS = 40
#: A step moves x and the index scale by at most this relative amount.
MAX_STEP_REL = 0.05


#: The index's common scale is searched within these factors of the sensor's index.
INDEX_SCALE_BOUNDS = (0.6, 1.6)


def _fit(problem, x0, fit_k, x_lo, x_hi, k_bounds=INDEX_SCALE_BOUNDS):
    """Least squares in ``x`` (and the index scale ``k``) by damped Gauss-Newton on the
    profiled residuals (:meth:`~snapcorr.calibrate.pupil.solver._Problem.jacobian`: the
    index's derivative analytic where the model has it, ``x``'s a forward difference), each
    step halved until chi-square does not rise; the covariance from the Jacobian at the
    end. A few steps from the scan's start, where finite differences of every residual
    took a hundred model evaluations for the same minimum."""
    p = np.array([x0, 1.0] if fit_k else [x0], float)
    lo = np.array([x_lo, k_bounds[0]][:p.size])
    hi = np.array([x_hi, k_bounds[1]][:p.size])

    def at(q):
        return problem.evaluate(q[0], q[1] if fit_k else 1.0)

    r, s, _, A = at(p)
    chi2 = float(r @ r)
    for _ in range(MAX_STEPS):
        J = problem.jacobian(p[0], p[1] if fit_k else 1.0, A, s, fit_k)
        cov = _inverse(J)
        step = cov @ (J.T @ r)
        if not np.all(np.isfinite(step)):
            break  # no information on some parameter: the covariance says so
        step /= max(1.0, float(np.max(np.abs(step) / (MAX_STEP_REL * np.abs(p)))))
        for _ in range(8):
            trial = np.clip(p + step, lo, hi)
            rt, st, _, At = at(trial)
            if float(rt @ rt) <= chi2 * (1 + 1e-12):
                break
            step = step / 2
        else:
            break  # no step lowers chi-square: the minimum, to the model's precision
        moved = trial - p
        p, r, s, A, chi2 = trial, rt, st, At, float(rt @ rt)
        if np.all(np.abs(moved) <= STEP_TOL * np.sqrt(np.clip(np.diag(cov), 0, None))):
            break
    r, s, rank, A = problem.evaluate(p[0], p[1] if fit_k else 1.0, rank=True)
    cov = _inverse(problem.jacobian(p[0], p[1] if fit_k else 1.0, A, s, fit_k))
    return p, cov, r, s, rank


def _inverse(J):
    try:
        return np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        return np.full((J.shape[1], J.shape[1]), np.inf)


def _fit_x(problem, coarse_model, sensor, r_max, x_lo, x_hi, fit_k, before=None):
    """Least squares in ``x`` (and the index scale) from the best minimum of a coarse scan;
    ``before(x0)`` is called at the scan's best ``x0``, before the least squares (it may
    refuse the target)."""
    n_design = problem.n_design
    # the start: a scan of a coarse copy (four annuli in one), its minima refined
    coarse = _Problem(coarse_model, n_design, problem.progress)
    grid = _scan_grid(r_max, x_lo, x_hi, float(np.mean(n_design)),
                      float(np.mean(sensor.cwl_nm)), float(np.min(sensor.fwhm_nm)) / 8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EffectiveIndexWarning)  # trials beyond 40 degrees
        x0 = _start(coarse, grid)
        if before is not None:
            before(x0)
        return _fit(problem, x0, fit_k, x_lo, x_hi)


def x_times_n_eff_bound(problem, x, k=1.0):
    """The standard error of ``x * n_eff`` the cubes in ``problem`` give at ``x`` and the
    index's scale ``k``, both fitted (the information matrix of :func:`target_precision`,
    with the noise the annuli show); inf where it is singular."""
    nd = problem.n_design * k
    _, Jp = _per_band_jacobian(problem.model, x, nd, central=True)
    J = np.column_stack([Jp[:, 0], Jp[:, 1:] @ nd])
    F = J.T @ J
    if not np.all(np.isfinite(F)) or np.linalg.cond(F) > 1e14:
        return math.inf
    n = float(np.mean(nd))
    g = np.array([n, x * n])  # d(x n k)/dx, d/d(scale) at the scale k
    return float(math.sqrt(max(g @ np.linalg.inv(F) @ g, 0.0)))


class OneFNumberIndex(NamedTuple):
    """What one f-number said of the index: its relative standard error with ``x`` (chi-square
    scaled), and ``x * n_eff`` with the index free (its error includes the index's)."""
    rel_stderr: float
    x_n_eff_mm: float
    x_n_eff_stderr_mm: float


def _index_at_one_f_number(problem, fit, x_lo, x_hi, n_rows, predicted_rel=0.0):
    """``(fit, said)`` for cubes at one f-number, ``fit`` from :func:`_fit` in ``x`` and the
    index's scale together.

    The field's curvature (``sin^2`` against ``tan^2`` of the chief-ray angle) and the cone's
    tilt off axis tell the index from ``x`` without a second f-number where the field is wide
    and the cone fast: behind the paper lens at f/2, 15 degrees at the edge, to 0.17 %, where
    holding the index at a value 3 % off moved ``x * n_eff`` by 1.5 %, 30 of its errors. A
    scale pinned to :data:`~snapcorr.calibrate.pupil.index.N_EFF_REL_STDERR` (and inside
    :data:`INDEX_SCALE_BOUNDS`) keeps ``fit`` (``said`` None). Otherwise ``x`` is fitted again
    with the sensor's index held (``x`` assumes it), and ``said`` keeps ``x * n_eff`` of the
    fit with the index free, whose error includes how little the index is known. The scale's
    error is the larger of the fit's and ``predicted_rel`` (the prediction before the fit,
    relative): a fit that ends where the model is not smooth reports too small a one (at f/8,
    1 % where the prediction and the result said 6 %)."""
    p, cov, r, _, rank = fit
    scale = max(1.0, float(r @ r) / max(round(n_rows - rank - p.size), 1))
    var = np.asarray(cov, float) * scale
    x, k = float(p[0]), float(p[1])
    n = float(np.mean(problem.n_design))
    with np.errstate(invalid="ignore"):
        rel = math.sqrt(var[1, 1]) / k if np.all(np.isfinite(var)) and var[1, 1] >= 0 \
            else math.inf
    rel = max(rel, float(predicted_rel))
    inside = INDEX_SCALE_BOUNDS[0] < k < INDEX_SCALE_BOUNDS[1]
    if rel <= N_EFF_REL_STDERR and inside:
        return fit, None
    g = np.array([k, x]) * n
    xn = x * k * n
    xn_err = math.sqrt(max(float(g @ var @ g), 0.0)) if np.all(np.isfinite(var)) else math.inf
    held = _fit(problem, x * k, False, x_lo, x_hi)
    # the bound where the fit ended and where the index is held: a fit that ends where the
    # model is not smooth (an onset at an annulus's edge) reports too small an error
    xn_err = max(xn_err, *(x_times_n_eff_bound(problem, at, kk) * math.sqrt(scale)
                           for at, kk in ((x, k), (float(held[0][0]), 1.0))))
    if not inside:  # the scale stopped at a bound: its linear error is not the whole story
        xn_err = math.hypot(xn_err, abs(xn - float(held[0][0]) * n))
    return held, OneFNumberIndex(rel, xn, xn_err)


# -- is a shift seen at all ---------------------------------------------------------------
def _half(bins, parity):
    """``bins`` with every other annulus (those of the other parity) left empty."""
    mean = bins.mean.copy()
    mean[:, np.arange(mean.shape[1]) % 2 != parity] = np.nan
    return dataclasses.replace(bins, mean=mean)


def _heldout_gain(bins, make_models, fit_x, n_eff):
    """Two-fold cross-validated chi-square gain of the field over a field without shift.

    The annuli are split into even and odd ones (disjoint pixels, independent noise). On one
    half the search for ``x`` is repeated (the coarse scan and a 1-D refinement, the index
    held at ``n_eff``, the whole fit's), then the target's spectrum is fitted with the field
    and without it, and both predictions are scored on the other half; the two folds' gains
    are summed. Noise on pixels the fit did not see cannot be
    predicted: for a target without features inside the bands the gain has a mean below zero
    (about minus the parameters the field adds) and a standard deviation of about
    ``2 sqrt(2 extra)``, however wide the search, while a target whose spectrum moves over the
    field gains about the whole chi-square difference. (Scored at the ``x`` fitted to all the
    annuli instead, a white tile gained up to +78 where fixed trial ``x`` gave -25 to -61:
    the search over ``x`` alone fits that much noise.)
    """
    gain = 0.0
    for p in (0, 1):
        model, coarse = make_models([_half(b, p) for b in bins])
        test, _ = make_models([_half(b, 1 - p) for b in bins], coarse=False)
        if model.n_rows == 0 or test.n_rows == 0:
            return 0.0
        x, n = fit_x(_Problem(model, n_eff), coarse), n_eff
        for shifted, sign in ((False, 1.0), (True, -1.0)):
            s, _, _ = _solve(model, model.design(x, n, field=shifted))
            r = (test.y - test.design(x, n, field=shifted) @ s) / test.sigma
            gain += sign * float(r @ r)
    return gain


def _heldout(bins, sensor, base, n_design, spectrum, profile, max_rel, circles_at, search,
             n_eff):
    """``heldout()``: :func:`_heldout_gain` with the fit's own models and search."""
    r_max, x_lo, x_hi = search

    def make_models(half_bins, coarse=True):
        if coarse:
            return _target_models(half_bins, sensor, base, n_design, spectrum, profile,
                                  max_rel, circles_at)
        return target_model(half_bins, sensor, base, spectrum=spectrum, profile=profile,
                            n_eff_design=n_design, max_shift_rel=max_rel,
                            circles_at_mm=circles_at), None

    def fit_x(half_problem, half_coarse):  # the scan and a 1-D refinement, index held
        grid = _scan_grid(r_max, x_lo, x_hi, float(np.mean(half_problem.n_design)),
                          float(np.mean(sensor.cwl_nm)), float(np.min(sensor.fwhm_nm)) / 8)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", EffectiveIndexWarning)
            return _start(_Problem(half_coarse, half_problem.n_design), grid)

    return lambda: _heldout_gain(bins, make_models, fit_x, n_eff)


def _check_shift_seen(problem, x, k, chi2, rank, n_params, scale, x_err, heldout):
    """Refuse a target whose field explains the data no better than a field without shift.

    The stated criterion: in sample, the field must beat the nested model without shift by
    ``MIN_DELTA_CHI2``; and unless it beats it by far more than noise could (``HELDOUT_SKIP``
    times the parameters it adds plus five standard deviations), held out too (``heldout()``,
    :func:`_heldout_gain`) by ``MIN_HELDOUT_SIGMA`` standard deviations of the held-out gain
    of noise; and x's relative standard error must be below ``MAX_REL_STDERR``. The in-sample
    difference alone has no usable null distribution: ``x`` (and ``n_eff``) are searched over
    a wide range, every trial a different set of wavelengths the target is seen at, and the
    optical centre is found from the same noise (a white tile gave 34-87 for about 42
    parameters added, and relative standard errors of ``x`` of 1-9 %, from the noise the
    fitted spectrum takes up, so ``MAX_REL_STDERR`` does not tell it either). The message
    says which test refused."""
    r_flat, _, rank_flat = problem.residuals(x, k, field=False, rank=True)
    flat = float(r_flat @ r_flat)
    extra = max(rank - rank_flat, 0.0) + n_params
    noise_sd = 2.0 * math.sqrt(2.0 * extra)
    need = MIN_HELDOUT_SIGMA * noise_sd * scale
    gain = math.inf
    if flat - chi2 < HELDOUT_SKIP * (extra + MIN_HELDOUT_SIGMA * noise_sd / 2) * scale:
        gain = heldout()
    why = []
    if flat - chi2 < MIN_DELTA_CHI2 * scale:
        why.append(f"a field without any shift fits within chi-square {max(flat - chi2, 0):.3g}"
                   f" of the best, below {MIN_DELTA_CHI2 * scale:.3g}")
    if gain < need:
        why.append(f"fitted on every other annulus, the field predicts the others better than "
                   f"no shift by {gain:.3g}, where {need:.3g} ({MIN_HELDOUT_SIGMA:g} standard "
                   "deviations of noise) is needed")
    if not x_err < MAX_REL_STDERR * x:
        why.append(f"x's relative standard error {x_err / x:.2g} exceeds "
                   f"{MAX_REL_STDERR:g}")
    if why:
        raise FeaturelessTargetError(
            "the target shows no spectral shift over the field above the noise ("
            + "; ".join(why) + "): its spectrum has no features inside the bands (a white "
            "tile?). Use a target whose spectrum changes within the bands: a colour filter, a "
            "rare-earth glass or a line lamp (see pupil_precision)")
