"""The exit pupil distance and the filters' effective index from cubes of a spectral target.

Goossens, Geelen, Lambrechts and Van Hoof (OSA Continuum 2, 2217, 2019) find the exit pupil
distance ``x`` from the spectral shift the camera itself sees on a spatially uniform target
with spectral features: a pixel at ``d`` mm from the optical axis has ``tan CRA = d / x``
(Goossens et al. 2019, Eq. 8), its filters move to the blue by Eq. (3), and a target whose
spectrum changes within the bands turns that shift into a change of signal over the field.

:func:`locate_pupil` fits the binned cubes (:mod:`~snapcorr.calibrate.target_model`: the whole
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
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import math
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy import optimize, stats

from .. import __version__
from .._coords import accepts_center_rc
from .._validation import check_center, check_positive
from ..optics.lens import Lens
from ..optics.shift import EffectiveIndexWarning
from ..spectra import colour_filter
from .pupil_solver import _pinv_solve, _Problem, _project_off, _solve, _whiten
from .target_model import (
    PRIOR_SD,
    RadialBins,
    TargetModel,
    radial_bins,
    rebin,
    scaled_circles,
)

__all__ = [
    "CANDIDATE_TARGETS",
    "FeaturelessTargetError",
    "Precision",
    "PupilFit",
    "estimate_target_center",
    "locate_pupil",
    "pupil_precision",
]

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
#: A richer model of the effective index (linear in wavelength, one per band) is taken when it
#: improves the fit at this significance and pins every band's index to this relative
#: standard error.
N_EFF_P = 1e-3
N_EFF_REL_STDERR = 0.01


#: The chief-ray angles at the field's edge the search covers, degrees.
EDGE_CRA_DEG = (1.0, 38.0)
#: Cubes up to this size are read into memory once; larger ones band by band.
IN_MEMORY_BYTES = 2 << 30
#: The effective-index law is validated up to about this angle (Goossens 2019, Sec. 2.2).
AOI_VALIDITY_DEG = 40.0


class FeaturelessTargetError(ValueError):
    """The target's spectrum shows no shift over the field above the noise."""


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
    center_px: tuple
    center_source: str
    spectrum: str
    lens: Lens
    model: TargetModel = field(repr=False)
    coefficients: np.ndarray = field(repr=False)
    notes: list = field(default_factory=list)
    covariance: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((1, 1)))
    """Covariance of ``x`` (mm) and, when fitted as one value, the index scale."""

    @property
    def center_rc(self) -> tuple:
        """The optical centre, ``(row, col)`` pixels (``center_px`` is x first)."""
        return (self.center_px[1], self.center_px[0])

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
        lines.append(f"optical centre row {self.center_px[1]:.2f}, col {self.center_px[0]:.2f} "
                     f"({self.center_source}); target spectrum {self.spectrum}")
        lines.extend(f"note: {t}" for t in self.notes)
        return "\n".join(lines)

    def plot(self, *, bands=4):
        """The data and the model over the field for the most informative bands, and the
        chi-square against ``x``. Returns a matplotlib Figure."""
        from .pupil_report import plot_pupil_fit

        return plot_pupil_fit(self, bands=bands)

    def save_plot(self, path):
        """Write :meth:`plot` to ``path`` (PNG), atomically."""
        import matplotlib.pyplot as plt

        from .._io import save_png

        fig = self.plot()
        try:
            save_png(fig, path, dpi=120)
        finally:
            plt.close(fig)


# -- the optical centre -------------------------------------------------------------------
def _block_mean(img, k):
    ny, nx = (s // k * k for s in img.shape)
    v = img[:ny, :nx].reshape(ny // k, k, nx // k, k)
    with warnings.catch_warnings():  # blocks without a finite pixel are NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(v, axis=(1, 3))


def estimate_target_center(band_image, n_bands, rows, cols, *, start=None, n_use=12,
                           block=4, degree=4):
    """The optical centre (column, row) in sensor pixels from a cube of a uniform target.

    Every band's image is a function of the distance to the centre only; the centre is where
    a polynomial in ``d^2`` (per band, solved for) fits the most informative bands best
    (``scipy.optimize.least_squares`` on ``(cx, cy)``; the images block-averaged).

    Parameters
    ----------
    band_image : callable
        ``band_image(b)`` -> the cube's 2-D image of band ``b``.
    n_bands : int
        Number of bands.
    rows, cols : ndarray, shape (ny, nb or 1) and (nx, nb or 1)
        Sensor row and column of the cube's pixels
        (:func:`snapcorr.correct.geometry.cube_positions`).
    start : (cx, cy), optional
        Where the search starts (default: the middle of the cube's sensor positions).
    n_use : int
        How many bands are fitted: those whose spread over the field is largest against their
        noise.
    block : int
        Side of the blocks averaged before the fit, pixels.
    degree : int
        Degree of each band's polynomial in ``d^2``.

    Returns
    -------
    (cx, cy), (sx, sy) : the centre and its standard errors, pixels.
    """
    stats_ = []
    for b in range(n_bands):
        v = np.asarray(band_image(b), float)
        dv = np.abs(np.diff(v, axis=1))
        if np.count_nonzero(np.isfinite(dv)) < 0.1 * dv.size:  # a band masked almost whole
            stats_.append(-np.inf)
            continue
        noise = np.nanmedian(dv) / (0.6745 * math.sqrt(2)) + 1e-12
        spread = np.nanpercentile(v, 95) - np.nanpercentile(v, 5)
        stats_.append(spread / noise)
    use = np.argsort(stats_)[::-1][:n_use]
    ys, rr, cc, noise = [], [], [], []
    for b in use:
        v = _block_mean(np.asarray(band_image(int(b)), float), block)
        # the scatter of neighbouring block means: noise plus a little of the trend
        noise.append(np.nanmedian(np.abs(np.diff(v, axis=1))) / (0.6745 * math.sqrt(2))
                     + 1e-12)
        r = _block_mean(np.repeat(rows[:, min(b, rows.shape[1] - 1), None], cols.shape[0],
                                  axis=1), block)
        c = _block_mean(np.repeat(cols[None, :, min(b, cols.shape[1] - 1)], rows.shape[0],
                                  axis=0), block)
        ok = np.isfinite(v)
        ys.append(v[ok])
        rr.append(r[ok])
        cc.append(c[ok])
    scale = float(max(np.ptp(np.concatenate(rr)), np.ptp(np.concatenate(cc)), 1.0))
    if start is None:
        start = (0.5 * (cols.min() + cols.max()), 0.5 * (rows.min() + rows.max()))

    def residuals(p):
        out = []
        for y, r, c, s in zip(ys, rr, cc, noise, strict=True):
            rho = ((r - p[1]) ** 2 + (c - p[0]) ** 2) / scale**2
            V = np.vander(rho, degree + 1)
            coef, *_ = np.linalg.lstsq(V, y, rcond=None)
            out.append((y - V @ coef) / s)
        return np.concatenate(out)

    sol = optimize.least_squares(residuals, np.asarray(start, float), x_scale=scale * 0.05,
                                 diff_step=1e-6)
    J = sol.jac
    dof = max(sol.fun.size - 2 - len(ys) * (degree + 1), 1)
    try:
        cov = np.linalg.inv(J.T @ J) * max(1.0, float(sol.fun @ sol.fun) / dof)
        err = tuple(float(v) for v in np.sqrt(np.clip(np.diag(cov), 0, None)))
    except np.linalg.LinAlgError:
        err = (math.inf, math.inf)
    return (float(sol.x[0]), float(sol.x[1])), err


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


def _fit(problem, x0, fit_k, x_lo, x_hi, k_bounds=(0.6, 1.6)):
    """Least squares in ``x`` (and the index scale ``k``) with numerical derivatives of the
    profiled residuals; the covariance from their Jacobian (exact for variable projection)."""
    def fun(p):
        return problem.residuals(p[0], p[1] if fit_k else 1.0)[0]

    p0 = [x0, 1.0] if fit_k else [x0]
    lo = [x_lo, k_bounds[0]] if fit_k else [x_lo]
    hi = [x_hi, k_bounds[1]] if fit_k else [x_hi]
    sol = optimize.least_squares(fun, p0, bounds=(lo, hi), x_scale=[x0 * 0.05, 0.02][:len(p0)],
                                 diff_step=1e-5, method="trf", xtol=1e-10, ftol=1e-12)
    r, s, rank = problem.residuals(sol.x[0], sol.x[1] if fit_k else 1.0, rank=True)
    J = sol.jac
    try:
        cov = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((len(p0), len(p0)), np.inf)
    return sol.x, cov, r, s, rank


def _per_band_jacobian(model, x, n):
    """Whitened residuals and their Jacobian in ``(x, n_1..n_B)`` at fixed target
    coefficients, projected off the target's columns (variable projection)."""
    A = model.design(x, n)
    s, r, _ = _solve(model, A)
    base = A @ s
    eps_n = 1e-4 * n
    # every band's rows depend on its own index only: one evaluation gives every column
    dn = (model.design(x, n + eps_n) @ s - base) / model.sigma
    dx = (model.design(x * (1 + 1e-5), n) @ s - base) / (x * 1e-5) / model.sigma
    Jn = np.zeros((model.n_rows, n.size))
    for _, k, rows, _ in model.blocks:
        Jn[rows, k] = dn[rows] / eps_n[k]
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


def _field_radius(bins):
    return float(math.sqrt(max(b.rho.max() for b in bins)))


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


@accepts_center_rc
@_one_blas_thread
def locate_pupil(cubes, sensor, *, lens: Lens | None = None, fit_n_eff=False, center_px=None,
                 target_spectrum=None, sensor_origin_px=None, magnification=None,
                 pupil_magnification=None, profile="gaussian", n_bins=96, inputs=None,
                 name=None, progress=None, scale_circles=None, pupil=None) -> PupilFit:
    """The exit pupil distance ``x`` (and ``n_eff``) from flat-fielded cubes of a target.

    Parameters
    ----------
    cubes : dict of float -> xarray.DataArray
        Flat-fielded cubes (``(y, x, band)``, the sensor's bands) of one spatially uniform
        target with spectral features, keyed by f-number.
    sensor : Sensor
    lens : Lens, optional
        Its vignetting circles (P, h), magnification and pupil magnification are used in the
        model and copied to the result; its ``x`` is not used (the search scans the chief-ray
        angles at the field's edge, :data:`EDGE_CRA_DEG`). Give the circles wherever the
        fastest f-number is vignetted inside the field: without them that cube misleads.
    fit_n_eff : bool
        Fit the effective index too: one value (the sensor's values times one factor), or,
        where the data ask for it and constrain it (``N_EFF_P``, ``N_EFF_REL_STDERR``), the
        sensor's values times a factor linear in wavelength, or one per band. With
        one f-number only ``x * n_eff`` is determined: the result says so.
    center_rc, center_px : (row, col), optional
        Optical centre in sensor pixels (default: found from the cubes); ``center_px=(cx,
        cy)`` is the deprecated x-first form.
    target_spectrum : callable or (wavelength_nm, value), optional
        The target's spectrum, known up to a scale per cube. Default: unknown, solved for.
    sensor_origin_px : (row, col), optional
        Sensor position of the cubes' first pixel, for crops that do not carry positions.
    magnification, pupil_magnification : float, optional
        When no lens is given (default 0 and 1).
    profile : str
        The filters' shape (a name in :data:`snapcorr.optics.PROFILES`).
    n_bins : int
        Annuli per cube.
    progress : callable, optional
        ``progress(step)`` before every evaluation of the model, for a progress bar.
    scale_circles : bool, optional
        The lens's circles came from flat fields at its ``x`` (``calibrate_lens``): flats fix
        ``P / x`` and ``h / x^2``, so at every trial ``x`` the circles are scaled to it, and
        the profile written holds them at the ``x`` found: one run gives a consistent
        profile. Default: when the lens's calibration says it came from flats
        (``exit_pupil_scaling``).
    pupil : {None, "paper", "lambertian", "auto"}
        How the light fills the pupil (:data:`snapcorr.optics.lens.PUPILS`). None: the lens's
        (the paper's without a lens). ``"auto"``: both are fitted, and the Lambertian one is
        kept only if it lowers chi-square by more than :data:`PUPIL_CHI2_GAIN` (they have the
        same parameters); the choice and the two chi-squares are in the notes and the profile.
        A lens with circles keeps its own pupil (they were found with its radius).

    Returns
    -------
    PupilFit

    Raises
    ------
    FeaturelessTargetError
        The target's signal does not change over the field above the noise.
    """
    if lens is not None and lens.has_vignetting and pupil not in (None, lens.pupil):
        raise ValueError(f"the lens's vignetting circles belong to the {lens.pupil} pupil (its "
                         f"radius sets their onsets); the {pupil} pupil would need them found "
                         "again: fit flats and target together (calibrate_with_target, "
                         "snapcorr calibrate --target-cube) with pupil 'auto'")
    if pupil == "auto":
        return _either_pupil(locals())
    return _locate(**locals())


def _locate(cubes, sensor, *, lens, fit_n_eff, center_px, target_spectrum, sensor_origin_px,
            magnification, pupil_magnification, profile, n_bins, inputs, name, progress,
            scale_circles, pupil):
    """:func:`locate_pupil` for one pupil (its body)."""
    n_design = check_modelled(sensor, "the exit-pupil fit (snapcorr pupil)")
    cubes = _check_cubes(cubes, sensor)
    base = lens or Lens(30.0, (), magnification or 0.0,
                        pupil_magnification if pupil_magnification is not None else 1.0)
    if pupil is not None:
        base = dataclasses.replace(base, pupil=pupil)
    spectrum, spectrum_desc = _spectrum(target_spectrum, sensor)
    nb = sensor.n_bands
    bins, center, center_source = _annuli(cubes, sensor, lens, sensor_origin_px, center_px,
                                          n_bins)
    r_max = _field_radius(bins)
    x_lo, x_hi = _trial_range(r_max)
    cone = math.radians(float(base.cone_angle_deg(min(cubes))))  # the fastest cube's cone
    max_rel = _max_shift_rel(r_max, x_lo, n_design, cone)
    circles_at = _circles_at(lens, base, scale_circles)
    model, coarse = _target_models(bins, sensor, base, n_design, spectrum, profile, max_rel,
                                   circles_at)
    problem = _Problem(model, n_design, progress)
    several = len(cubes) >= 2
    fit_k = bool(fit_n_eff) and several
    p, cov, r, s, rank = _fit_x(problem, coarse, sensor, r_max, x_lo, x_hi, fit_k)
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
    notes = ["one f-number: the field fixes only x * n_eff; x assumes the sensor's n_eff. A "
             "cube at a second f-number (far apart, e.g. f/2 and f/8) separates them through "
             "the cone term"] if fit_n_eff and not several else []
    if fit_k and nb >= 2:
        mode, x, x_err, n, n_err, chi2, red = _index_ladder(problem, x, n, float(err[0]),
                                                            n_err, chi2, scale, notes)
        if mode != "one":
            err, cov, chi2_red = np.array([x_err]), np.array([[x_err**2 / scale]]), red
    xn, xn_err = _x_n_eff(x, n, err, cov * scale, k, n_design, fit_k and mode == "one")
    notes += _validity_notes(r_max, x, cone, chi2_red)
    out_lens = _result_lens(base, lens, x, err[0], n, n_err, mode, xn, xn_err, chi2_red, dof,
                            center, center_source, sensor, cubes, spectrum_desc, profile,
                            inputs, name, circles_at)
    return PupilFit(x, float(err[0]), np.asarray(n, float),
                    None if n_err is None else np.asarray(n_err, float), mode, xn, xn_err,
                    chi2_red, dof, center, center_source, spectrum_desc, out_lens, model, s,
                    notes, cov * scale)


#: ``pupil="auto"`` keeps the Lambertian pupil only if it lowers chi-square by more than this
#: (the two models have the same parameters: a likelihood ratio of exp(5), as the lens
#: calibration's :data:`~snapcorr.calibrate.choice.MIN_BIC_GAIN`).
PUPIL_CHI2_GAIN = 10.0


def _either_pupil(args):
    """``locate_pupil(pupil="auto")``: both pupils fitted, the paper's kept unless the
    Lambertian one fits clearly better."""
    args = {k: v for k, v in args.items() if k != "pupil"}
    fits = {}
    for name in ("paper", "lambertian"):
        try:
            fits[name] = locate_pupil(**args, pupil=name)
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


def choose_pupil(results, chi2, what):
    """The result to keep of ``results`` (pupil -> a result with ``notes`` and ``lens``):
    the paper's pupil unless the Lambertian one lowers ``chi2`` (pupil -> chi-square) by more
    than :data:`PUPIL_CHI2_GAIN`; the choice and both chi-squares go into its notes and its
    lens's ``[calibration] pupil_choice``."""
    gain = chi2.get("paper", np.inf) - chi2.get("lambertian", np.inf)
    name = "lambertian" if "paper" not in results or gain > PUPIL_CHI2_GAIN else "paper"
    got = results[name]
    said = ", ".join(f"{k} {v:.6g}" for k, v in chi2.items())
    got.notes.append(f"pupil: {name} ({what} {said}; the Lambertian pupil is kept only for a "
                     f"gain above {PUPIL_CHI2_GAIN:g})")
    cal = dict(got.lens.calibration)
    cal["pupil_choice"] = {"chosen": name, "rule": f"chi-square gain > {PUPIL_CHI2_GAIN:g}",
                           "chi2": {k: float(f"{v:.6g}") for k, v in chi2.items()}}
    got.lens = dataclasses.replace(got.lens, calibration=cal)
    return got


def _band_reader(cube):
    """``band -> 2-D float image`` of a cube, read into memory once where it is small enough."""
    cube = cube.transpose("y", "x", "band")
    if cube.nbytes <= IN_MEMORY_BYTES:  # one read of the file, not one per band
        data = np.asarray(cube.values)
        return lambda b: data[:, :, b].astype(float)
    return lambda b: np.asarray(cube.isel(band=b).values, float)


def _annuli(cubes, sensor, lens, sensor_origin_px, center_px, n_bins):
    """Every cube's radial annuli about the optical centre (given or found), and the centre."""
    from ..correct.geometry import cube_positions

    pitch = sensor.pixel_pitch_mm
    positions = {f: cube_positions(c, sensor, lens, sensor_origin_px) for f, c in cubes.items()}
    nb = sensor.n_bands
    if center_px is not None:
        center, center_source = check_center(center_px), "given"
    else:
        f0 = min(cubes)  # the fastest f-number: the largest shifts, the sharpest centre
        rows, cols = positions[f0]
        center, err = estimate_target_center(_band_reader(cubes[f0]), nb, rows, cols)
        center_source = f"found from the f/{f0:g} cube (+- {err[0]:.2g}, {err[1]:.2g} px)"
    bins = [radial_bins(_band_reader(c), nb, *positions[f], center, pitch, f_number=f,
                        n_bins=n_bins)
            for f, c in cubes.items()]
    return bins, center, center_source


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
    model = TargetModel(bins, sensor.cwl_nm, sensor.fwhm_nm, base, **common)
    coarse = TargetModel([rebin(b, 4) for b in bins], sensor.cwl_nm, sensor.fwhm_nm, base,
                         **common)
    return model, coarse


def _fit_x(problem, coarse_model, sensor, r_max, x_lo, x_hi, fit_k):
    """Least squares in ``x`` (and the index scale) from the best minimum of a coarse scan."""
    n_design = problem.n_design
    # the start: a scan of a coarse copy (four annuli in one), its minima refined
    coarse = _Problem(coarse_model, n_design, problem.progress)
    grid = _scan_grid(r_max, x_lo, x_hi, float(np.mean(n_design)),
                      float(np.mean(sensor.cwl_nm)), float(np.min(sensor.fwhm_nm)) / 8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EffectiveIndexWarning)  # trials beyond 40 degrees
        x0 = _start(coarse, grid)
        return _fit(problem, x0, fit_k, x_lo, x_hi)


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
        return TargetModel(half_bins, sensor.cwl_nm, sensor.fwhm_nm, base, spectrum=spectrum,
                           profile=profile, n_eff_design=n_design, max_shift_rel=max_rel,
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


def _x_n_eff(x, n, err, cov, k, n_design, one_k):
    """The product ``x * mean(n_eff)`` and its standard error (``cov`` scaled)."""
    xn = x * float(np.mean(n))
    if one_k:
        g = np.array([k, x]) * float(np.mean(n_design))
        xn_err = float(np.sqrt(max(g @ cov @ g, 0.0)))
    else:
        xn_err = float(err[0]) * float(np.mean(n))
    return xn, xn_err


def _validity_notes(r_max, x, cone_rad, chi2_red):
    """Notes where rays pass the index law's validated angle, or the model misfits."""
    notes = []
    aoi = math.degrees(math.atan(r_max / x) + cone_rad)
    if aoi > AOI_VALIDITY_DEG:
        notes.append(f"rays reach the filters at up to {aoi:.1f} deg; the effective-index law "
                     f"is validated up to about {AOI_VALIDITY_DEG:g} deg (Goossens 2019, Sec. "
                     "2.2): x rests on its extrapolation")
    if chi2_red > 2.0:
        notes.append(f"reduced chi-square {chi2_red:.3g}: the model misses something (a target "
                     "that is not uniform, stray light, another filter shape); the errors are "
                     "scaled by it")
    return notes

def check_modelled(sensor, what):
    """``sensor``'s indices, for a model of filters by their shape about each centre: sensors
    with measured responses behind a band-pass (vendor files) are not modelled here yet."""
    if sensor.responses is not None:
        raise ValueError(f"{what} models each band by the sensor's filter shape about its "
                         f"centre; the sensor {sensor.name!r} has measured responses behind a "
                         "band-pass (a vendor file), whose bands move otherwise near the "
                         "band-pass's edges, and these are not modelled here yet: give n_eff "
                         "from the vendor's design value in a sensor TOML naming the file")
    return np.asarray(sensor.require("n_eff", what), float)


def _check_cubes(cubes, sensor):
    if not cubes:
        raise ValueError("give at least one cube")
    out = {}
    for f, cube in cubes.items():
        fv = check_positive("f-number", f)
        if fv in out:
            raise ValueError(f"f/{fv:g} given twice")
        sensor.check_cube(cube, f"the f/{fv:g} cube", atol_nm=0.5)
        out[fv] = cube
    return dict(sorted(out.items()))


def _spectrum(target, sensor):
    """The target spectrum as a callable (or None) and a description."""
    if target is None:
        return None, "unknown (solved for, the field centre as reference)"
    if callable(target):
        return target, f"given ({getattr(target, '__name__', 'a function')})"
    try:
        wl, val = (np.asarray(v, float) for v in target)
    except (TypeError, ValueError):
        raise ValueError("target_spectrum must be a function or (wavelength_nm, value)") from None
    from .._validation import check_curve, check_wavelengths_nm

    check_wavelengths_nm("target spectrum wavelengths", wl)
    wl, val = check_curve(wl, val)
    cwl = np.asarray(sensor.cwl_nm)
    fwhm = np.asarray(sensor.fwhm_nm)
    need_lo, need_hi = float(np.min(cwl - 2 * fwhm)), float(np.max(cwl + 2 * fwhm))
    if wl[0] > need_lo or wl[-1] < need_hi:
        raise ValueError(f"the target spectrum covers {wl[0]:g}-{wl[-1]:g} nm, but the bands "
                         f"need {need_lo:g}-{need_hi:g} nm")
    if np.ptp(val) <= 0:
        raise FeaturelessTargetError("the target spectrum is constant: a featureless target "
                                     "cannot show a spectral shift")
    return (lambda lam: np.interp(lam, wl, val)), f"given ({wl.size} points, " \
        f"{wl[0]:g}-{wl[-1]:g} nm)"


def _result_lens(base, lens, x, x_err, n, n_err, mode, xn, xn_err, chi2_red, dof, center,
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
        "center_rc": [r(center[1], 8), r(center[0], 8)],
        "center_px": [r(center[0], 8), r(center[1], 8)],  # x first, for earlier readers
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
                calibration=cal, pupil=base.pupil)


# -- choosing a target ----------------------------------------------------------------------
# (the colour filter of Goossens et al. 2019 is :func:`snapcorr.spectra.colour_filter`)
def white_tile(lam):
    """A white reference tile: no spectral feature at all."""
    return np.full(np.shape(lam), 0.95)


#: Absorption bands (centre, FWHM nm, depth) of a holmium/didymium-like rare-earth glass.
RARE_EARTH_BANDS = ((446.0, 4.0, 0.5), (453.0, 3.0, 0.45), (485.0, 5.0, 0.35),
                    (536.0, 6.0, 0.55), (573.0, 8.0, 0.45), (586.0, 4.0, 0.5),
                    (640.0, 5.0, 0.4), (685.0, 6.0, 0.3), (741.0, 8.0, 0.45),
                    (803.0, 9.0, 0.5), (865.0, 7.0, 0.3))


def rare_earth_glass(lam):
    """A holmium/didymium-like glass: narrow absorption bands (:data:`RARE_EARTH_BANDS`) on
    a high continuum."""
    lam = np.asarray(lam, float)
    t = np.full(lam.shape, 0.92)
    for c, w, d in RARE_EARTH_BANDS:
        t = t * (1 - d * np.exp(-4 * math.log(2) * ((lam - c) / w) ** 2))
    return t


#: Mercury-argon lamp lines (nm) between 430 and 920 nm.
LAMP_LINES_NM = (435.8, 546.1, 577.0, 579.1, 696.5, 706.7, 738.4, 750.4, 763.5, 794.8,
                 811.5, 826.5, 842.5, 852.1, 912.3)


def line_lamp(lam):
    """Narrow emission lines (:data:`LAMP_LINES_NM`, 0.3 nm FWHM) of a mercury-argon lamp
    seen through a diffuser, on a weak continuum; the scale is arbitrary."""
    lam = np.asarray(lam, float)
    out = np.full(lam.shape, 0.01)
    for c in LAMP_LINES_NM:
        out = out + np.exp(-4 * math.log(2) * ((lam - c) / 0.3) ** 2)
    return out


#: Targets :func:`pupil_precision` compares by default.
CANDIDATE_TARGETS = {
    "white tile": white_tile,
    "colour filter (Goossens 2019)": colour_filter,
    "rare-earth glass": rare_earth_glass,
    "emission lines (Hg-Ar lamp)": line_lamp,
}


@dataclass(frozen=True)
class Precision:
    """Predicted standard errors (one standard deviation) of :func:`pupil_precision`."""

    x_stderr_mm: float
    n_eff_stderr: float | None
    spectrum_known: bool
    noise: float
    exit_pupil_mm: float = math.nan

    @property
    def informative(self) -> bool:
        """Whether the target would pin ``x`` at all (to ``MAX_REL_STDERR``)."""
        return bool(self.x_stderr_mm < MAX_REL_STDERR * self.exit_pupil_mm)


def _synthetic_bins(sensor, f_number, n_bins, size_px=None):
    """Annuli of the full sensor (centred on the axis) with their pixel counts per band."""
    rows, cols = size_px or sensor.size_px
    pitch = sensor.pixel_pitch_mm
    y = (np.arange(rows) - (rows - 1) / 2) * pitch
    x = (np.arange(cols) - (cols - 1) / 2) * pitch
    rho = (y**2)[:, None] + (x**2)[None, :]
    edges = np.linspace(0, rho.max() * (1 + 1e-12), n_bins + 1)
    idx = np.clip(np.searchsorted(edges, rho.ravel(), side="right") - 1, 0, n_bins - 1)
    n = np.bincount(idx, minlength=n_bins).astype(float)
    s1 = np.bincount(idx, rho.ravel(), minlength=n_bins)
    s2 = np.bincount(idx, rho.ravel() ** 2, minlength=n_bins)
    mean = s1 / np.maximum(n, 1)
    var = np.maximum(s2 / np.maximum(n, 1) - mean**2, 0)
    cells = 1 if sensor.layout == "snapscan" else sensor.mosaic_shape[0] * sensor.mosaic_shape[1]
    nb = sensor.n_bands
    count = np.tile(n / cells, (nb, 1))
    # an annulus no pixel falls in (a small sensor, many annuli) enters no row: NaN
    empty = np.tile(n == 0, (nb, 1))
    return RadialBins(float(f_number), mean, np.tile(mean, (nb, 1)), np.tile(var, (nb, 1)),
                      np.where(empty, np.nan, 0.0), np.where(empty, np.nan, 1.0), count)


@_one_blas_thread
def pupil_precision(spectrum, sensor, f_numbers, lens: Lens, *, noise=0.01, fit_n_eff=False,
                    spectrum_known=False, size_px=None, n_bins=64, profile="gaussian",
                    absolute_noise=False):
    """Predicted standard error of ``x`` (and ``n_eff``) from cubes of a target.

    The Cramer-Rao bound of the model :func:`locate_pupil` fits: the Fisher information of
    the annulus means over the full sensor, with the target's spectrum solved for (or known
    up to a scale, ``spectrum_known``) and per-pixel noise of standard deviation ``noise``
    times the brightest band's signal (the exposure set so that the brightest band is near
    full scale).

    Parameters
    ----------
    spectrum : callable
        ``S(lambda_nm)``.
    sensor : Sensor
        Needs ``size_px`` unless ``size_px`` is given.
    f_numbers : sequence of float
        The f-numbers of the cubes.
    lens : Lens
        The true lens (x, circles, magnifications).
    noise : float
    fit_n_eff : bool
        Count ``n_eff`` as unknown (one common value).
    absolute_noise : bool
        ``noise`` is in the cube's units (flat-fielded: white = 1), not a fraction of the
        brightest band.

    Returns
    -------
    Precision
        For a target without features ``x_stderr_mm`` is ``inf`` or merely huge (the bound of
        an almost singular information); ``informative`` is False either way.
    """
    size = size_px or sensor.size_px
    if size is None:
        raise ValueError(f"the sensor {sensor.name!r} has no size_px: give size_px")
    if not (math.isfinite(noise) and noise > 0):
        raise ValueError(f"noise must be > 0, got {noise!r}")
    n_design = check_modelled(sensor, "the exit pupil's precision (snapcorr pupil --predict)")
    bins = [_synthetic_bins(sensor, f, n_bins, size) for f in f_numbers]
    x = float(lens.exit_pupil_mm)
    truth = TargetModel(bins, sensor.cwl_nm, sensor.fwhm_nm, lens, spectrum=spectrum,
                        profile=profile, n_eff_design=n_design, max_shift_rel=0.15)
    y = np.asarray(truth.design(x, n_design).sum(axis=1)).ravel()
    sigma_px = noise * (1.0 if absolute_noise else float(np.max(np.abs(y))))
    for b in bins:
        b.mean[:] = 0.0
    model = TargetModel(bins, sensor.cwl_nm, sensor.fwhm_nm, lens,
                        spectrum=spectrum if spectrum_known else None, profile=profile,
                        n_eff_design=n_design, max_shift_rel=0.15)
    if model.prior_sd is not None:  # the fit's prior, for the signal the target gives
        model.prior_mean = float(np.median(y))
        model.prior_sd = PRIOR_SD * float(np.max(np.abs(y)))
    count = np.empty(model.n_rows)
    for j, k, rows, ok in model.blocks:
        count[rows] = bins[j].count[k, ok]
    model.sigma = sigma_px / np.sqrt(count)
    A = model.design(x, n_design)
    s_true, _ = _pinv_solve(A, y)  # the noise-free means as the model has them
    cols = [(model.design(x * (1 + 1e-5), n_design) - model.design(x * (1 - 1e-5), n_design))
            @ s_true / (2e-5 * x)]
    if fit_n_eff:
        cols.append((model.design(x, n_design * (1 + 1e-5))
                     - model.design(x, n_design * (1 - 1e-5))) @ s_true / 2e-5)
    J = np.column_stack(cols) / model.sigma[:, None]
    Jp = _project_off(_whiten(model, A), J)
    F = Jp.T @ Jp
    if not np.all(np.isfinite(F)) or np.linalg.cond(F) > 1e14 or F[0, 0] <= 0:
        return Precision(math.inf, math.inf if fit_n_eff else None, spectrum_known, noise, x)
    cov = np.linalg.inv(F)
    n_err = float(math.sqrt(cov[1, 1]) * np.mean(n_design)) if fit_n_eff else None
    return Precision(float(math.sqrt(cov[0, 0])), n_err, spectrum_known, noise, x)
