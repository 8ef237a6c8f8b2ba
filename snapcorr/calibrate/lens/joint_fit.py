"""Joint fit of the vignetting circle(s) and the optical centre to all flat fields at once.

Each flat at f-number ``F`` is, block by block,

    I_F(block) = e_F * G(block) * A_F(CRA),

with ``A_F`` the fraction of the exit pupil (radius ``R_F``, Eq. 28) left by the vignetting
circle(s) (Goossens et al. 2019, Eq. 33; several circles via
:func:`~snapcorr.optics.pupil.overlap_area_mm2`), ``e_F`` the flat's exposure and ``G`` all
that does not depend on the aperture: natural (cos^4) fall-off, the source's non-uniformity,
the pixels' response. The paper divides every flat by the one at the highest f-number, which
cancels ``G`` but puts that one flat's noise into every ratio. Here ``G`` of every block and
the exposures are solved for at each step instead (variable projection: ``G`` in closed
form, the exposures by a few Gauss-Newton steps), so every flat informs ``G`` and no flat's
noise is shared by all the others. Weighted by each flat's measured noise curve
(:func:`~snapcorr.calibrate.noise_model`), the standard errors of the shift the fit predicts
are those of the Cramér-Rao bound of the flats (within 15 %, tested against a bound written
independently in ``tests/oracles/cramer_rao.py``); the ratios with a straight-line noise model were
1.4-1.55 times it. The fit (scipy ``least_squares``) runs on block-averaged flats.

With a single flat nothing separates ``G`` from ``A``: the flat itself is fitted with
``cos^4`` for ``G`` (the h must be given). :class:`BlockData` also holds ratio images
``q_F = s_F A_F / A_ref`` (one profile at a time, for the model-based onsets).

Models have no vignetting circle (exposures only), one circle (P, h and the centre, row
first) and up to three (more P, h: pixel vignetting is a circle with h = x);
:mod:`snapcorr.calibrate.lens.choice` decides between them. Every centre here is
``(row, col)``, as everywhere in snapcorr; the x-first keywords of earlier releases
(``center``, ``fix_center``) still work and warn (:func:`snapcorr._coords.accepts_center_rc`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from ..._coords import accepts_center_rc
from ..._validation import called_from_outside, warn_renamed
from ...optics.aperture import overlap_area_mm2, relative_irradiance

__all__ = ["CIRCLE_MODELS", "BlockData", "ModelFit", "block_average", "block_centroids",
           "fit_model"]

#: The joint fit's models of the vignetting, by their number of circles (none to three).
CIRCLE_MODELS = ("none", "one", "two", "three")
#: The earlier name of :data:`CIRCLE_MODELS` (``MODELS`` in :mod:`snapcorr.optics.mean` is
#: the correction's ladder).
MODELS = CIRCLE_MODELS
#: Number of vignetting circles of each model.
N_CIRCLES = {name: i for i, name in enumerate(CIRCLE_MODELS)}
#: Starting points are screened and run on about this many blocks before a final polish.
SCREEN_BLOCKS = 3000
#: Most evaluations of the polish on all blocks (from a minimum it takes a few).
POLISH_NFEV = 60
#: Block sides up to this are averaged pixel by pixel when the block rule's own error is
#: measured (:func:`_rule_bias`); larger blocks by a product Gauss-Legendre rule of
#: ``_EXACT_NODES`` squared points.
_EXACT_SIDE = 8
_EXACT_NODES = 6


@dataclass
class BlockData:
    """Block-averaged flats (``gains``) or ratio images ready for fitting (one row per
    f-number)."""

    q: np.ndarray  # (n_f, n_blocks) block means of the flats, or ratios; 0 where not used
    sigma: np.ndarray  # (n_f, n_blocks) standard deviations; inf where not used
    xpix: np.ndarray  # (n_blocks,) block centres, full-resolution pixel coordinates
    ypix: np.ndarray
    R_mm: np.ndarray  # (n_f,) exit-pupil radii of the flats fitted
    R_ref_mm: float | None  # reference exit-pupil radius (None: no reference, raw flats)
    pitch_mm: float
    x_mm: float
    natural: bool = False  # model includes cos^4 (a single flat, no reference)
    #: how the pupil weights a ray (:data:`snapcorr.optics.lens.RAY_WEIGHTS`): ``"cos4"``
    #: models each flat as the cos^4-weighted area of every ray, whose fall-off differs
    #: between f-numbers (the chief ray's cos^4, in the gains, does not)
    ray_weight: str = "area"
    #: side of the square blocks, pixels: the model is averaged over each block (1: centres)
    block_px: int = 1
    #: (n_f, n_blocks) offsets of each flat's valid pixels' centroid from the block centre,
    #: and their standard deviations about it, pixels (None: all pixels valid)
    xoff: np.ndarray | None = None
    yoff: np.ndarray | None = None
    xsd: np.ndarray | None = None
    ysd: np.ndarray | None = None
    gains: bool = False  # q holds every flat; each block's gain G is solved for
    #: log exposures of the last evaluation of each model, the next one's start
    warm: dict = field(default_factory=dict, repr=False, compare=False)

    @functools.cached_property
    def weights(self):
        """``(1 / sigma^2, 1 / sigma, q / sigma^2)``, for :func:`_profiled` (a copy made with
        :func:`dataclasses.replace` works out its own)."""
        return _weights(self.q, self.sigma)

    @property
    def n_used(self) -> int:
        """Number of values fitted."""
        return int(np.sum(np.isfinite(self.sigma)))

    @property
    def n_nuisance(self) -> int:
        """Parameters solved for besides the circles and the centre: the exposures (ratio
        scales), and the gain of every block used."""
        if not self.gains:
            return self.q.shape[0]
        return self.q.shape[0] - 1 + int(np.sum(np.isfinite(self.sigma).any(axis=0)))


#: The names the centre's parameters had when the vector held it x first, ``(cx, cy)``.
EARLIER_NAMES = {"cx_px": "center_col_px", "cy_px": "center_row_px"}


class _Named(dict):
    """A fit's values by parameter name; the centre's earlier names (:data:`EARLIER_NAMES`)
    still find their values, and warn."""

    def __missing__(self, key):
        return self._earlier(key, KeyError)

    def get(self, key, default=None):
        if key in self:
            return self[key]
        return self._earlier(key, default)

    def _earlier(self, key, otherwise):
        """The value of ``key``'s present name, warning (3 frames up: the caller of
        ``[]`` or ``get``); ``otherwise`` where ``key`` is no earlier name (KeyError: raised)."""
        new = EARLIER_NAMES.get(key)
        if new is None or new not in self:
            if otherwise is KeyError:
                raise KeyError(key)
            return otherwise
        if called_from_outside(3):
            warn_renamed(f"the parameter name {key!r}", repr(new), stacklevel=4)
        return dict.__getitem__(self, new)


@dataclass
class ModelFit:
    """Result of fitting one model.

    ``params`` and ``stderr`` are by name (:func:`param_names`), ``covariance`` in the order
    of ``names``; the optical centre is ``center_row_px``, ``center_col_px`` (``cx_px``,
    ``cy_px``, its earlier names, still read and warn).
    """

    model: str
    params: dict
    stderr: dict
    covariance: np.ndarray | None
    names: tuple
    chi2: float
    n: int
    k: int
    scales: np.ndarray
    success: bool
    message: str = ""
    #: ``"held"``: the parameters held at given values (``fit_model(fixed=...)``), by name
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        self.params = _Named(self.params)
        self.stderr = _Named(self.stderr)

    @property
    def bic(self) -> float:
        return self.chi2 + self.k * np.log(self.n)

    @property
    def reduced_chi2(self) -> float:
        return self.chi2 / max(self.n - self.k, 1)


def block_average(images, valids, variances, block):
    """Masked block means of several images and the variance of each mean.

    Block sums come from OpenCV's area resampling (exact block means for an integer factor).

    Parameters
    ----------
    images : sequence of 2-D arrays
        The images, all of one shape; rows and columns past the last whole block are left out.
    valids : sequence of 2-D bool arrays
        Which pixels of each image are used.
    variances : sequence of 2-D arrays
        Each pixel's variance.
    block : int
        Side of the square blocks, pixels.

    Returns
    -------
    means, variances, counts : lists of 2-D arrays
        Per image: each block's mean over its valid pixels and the variance of that mean (NaN
        where no pixel is valid), and the number of valid pixels.
    x, y : 2-D arrays
        Block centres, full-resolution pixel coordinates.
    """
    import cv2

    ny, nx = images[0].shape
    by, bx = ny // block, nx // block

    def block_sum(a):
        a = np.ascontiguousarray(a[: by * block, : bx * block], dtype=np.float32)
        if block == 1:
            return a.astype(np.float64)
        mean = cv2.resize(a, (bx, by), interpolation=cv2.INTER_AREA)
        return mean.astype(np.float64) * (block * block)

    out, var, cnt = [], [], []
    for img, ok, v in zip(images, valids, variances, strict=True):
        w = np.rint(block_sum(ok))
        s = block_sum(np.where(ok, img, 0.0))
        vv = block_sum(np.where(ok, v, 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append(np.where(w > 0, s / w, np.nan))
            var.append(np.where(w > 0, vv / w**2, np.nan))
        cnt.append(w)
    yy, xx = np.mgrid[:by, :bx]
    c = (block - 1) / 2.0
    return out, var, cnt, xx * block + c, yy * block + c


def block_centroids(valids, block):
    """Where each block's valid pixels lie: the offsets (x, y) of their centroid from the
    block's centre and their standard deviations about it, pixels; one tuple of four 2-D
    arrays per mask (0 where no pixel is valid).

    A masked pixel (hot, dead, saturated) moves the block mean's effective position; where
    the fall-off is steep, by much more than its noise: a few pixels masked on the dark side
    of an 8-pixel block near the pupil's full cut-off biased its mean by 1 % (17 standard
    errors). The model is averaged over points with these first and second moments."""
    import cv2

    ny, nx = valids[0].shape
    by, bx = ny // block, nx // block
    c = (block - 1) / 2.0
    jj = np.tile(np.arange(block, dtype=np.float32) - c, bx)[None, :]
    ii = np.tile(np.arange(block, dtype=np.float32) - c, by)[:, None]

    def mean(a):
        return cv2.resize(np.ascontiguousarray(a, np.float32), (bx, by),
                          interpolation=cv2.INTER_AREA).astype(np.float64)

    out = []
    for ok in valids:
        ok = ok[: by * block, : bx * block].astype(np.float32)
        w = mean(ok)
        with np.errstate(invalid="ignore", divide="ignore"):
            w = np.where(w > 0, w, np.nan)
            dx, dy = mean(ok * jj) / w, mean(ok * ii) / w
            sx = np.sqrt(np.clip(mean(ok * jj * jj) / w - dx * dx, 0.0, None))
            sy = np.sqrt(np.clip(mean(ok * ii * ii) / w - dy * dy, 0.0, None))
        out.append(tuple(np.nan_to_num(v) for v in (dx, dy, sx, sy)))
    return out


def _area_fraction(R, circles, t, x_mm=None, weight="area"):
    """Fraction of the pupil (radius R) left by the circles [(P, h), ...] at tan(CRA) = t;
    for a Lambertian pupil (``weight="cos4"``) the flat's signal relative to the full pupil
    on the axis, every ray's cos^4 included (:func:`~snapcorr.optics.aperture.
    relative_irradiance`)."""
    if weight == "cos4":
        radii = [R] + [P for P, _ in circles]
        centers = [np.zeros_like(t)] + [h * t for _, h in circles]
        return relative_irradiance(radii, centers, x_mm * t, x_mm, weight="cos4")
    if not circles:
        return np.ones_like(t)
    radii = [R] + [P for P, _ in circles]
    centers = [0.0] + [h * t for _, h in circles]
    return overlap_area_mm2(radii, centers) / (np.pi * R * R)


#: The names of the optical centre's parameters, row first (indices 2 and 3 of the vector).
CENTER_NAMES = ("center_row_px", "center_col_px")


def param_names(model):
    """Parameter names of a model: circle 1, the optical centre (row, col), then circles 2,
    3: ``P_mm, h_mm, center_row_px, center_col_px, P2_mm, h2_mm, ...``."""
    n = N_CIRCLES[model]
    if n == 0:
        return []
    return ["P_mm", "h_mm", *CENTER_NAMES] + [
        name for i in range(2, n + 1) for name in (f"P{i}_mm", f"h{i}_mm")]


def circles_of(model, p):
    """The circles [(P, h), ...] of a model's parameter vector (see :func:`param_names`)."""
    n = N_CIRCLES[model]
    if n == 0:
        return []
    return [(p[0], p[1])] + [(p[2 * i], p[2 * i + 1]) for i in range(2, n + 1)]


#: Nodes of the Gauss-Legendre rule that averages the model over a block along the radius.
BLOCK_NODES = 3
#: Points of the tabulated area fraction over tan(CRA), interpolated linearly.
GRID_POINTS = 4096


def _block_radii(X, Y, sx, sy):
    """Radii (pixels) and weights of the points that average a function of the radius over
    a block: ``(k, ...)`` radii and ``(k,)`` weights.

    A block's value is the mean of its valid pixels. Where the area fraction bends sharply,
    as it does at a circle's onset and near the pupil's full cut-off (where it falls to 0 like
    a power 3/2), its value at the block's centre is not that mean: for 8-pixel blocks the
    bias reached 10^-3 relative next to the cut-off, where the relative noise is smallest,
    and moved P and h by 0.05 %. The model depends on the radius only, so the mean is taken
    along the radius: the valid pixels' centroid at ``(X, Y)`` from the optical centre, their
    spread ``sx``, ``sy``; the tangential spread lifts the mean radius to
    ``sqrt(r^2 + s_t^2)``, and a ``BLOCK_NODES``-point Gauss-Legendre rule with the radial
    spread ``s_r`` takes the mean over it (tested against pupil sampling of every pixel).
    """
    r2 = X * X + Y * Y
    with np.errstate(invalid="ignore", divide="ignore"):
        cos2 = np.where(r2 > 0, X * X / r2, 1.0)
    sin2 = 1.0 - cos2
    sr = np.sqrt(cos2 * sx * sx + sin2 * sy * sy)
    rm = np.sqrt(r2 + sin2 * sx * sx + cos2 * sy * sy)
    u, w = np.polynomial.legendre.leggauss(BLOCK_NODES)
    u = u * np.sqrt(3.0)  # unit variance
    radii = np.maximum(rm[None] + u.reshape((-1,) + (1,) * rm.ndim) * sr[None], 0.0)
    return radii, w / 2.0


def model_ratio(data: BlockData, model, p, tan_cra, weights=None, per_flat=False,
                grid_points=GRID_POINTS):
    """Model ratio image(s) A_F / A_ref (times cos^4 for a single flat), shape (n_f, n).

    ``tan_cra`` is ``(n,)``, or ``(k, n)`` with ``weights`` ``(k,)``: then each block's model
    is the weighted mean over its ``k`` points (of ``A_F`` and ``A_ref`` each, then the
    ratio, as the data are ratios of block means). With ``per_flat`` (no reference), it is
    ``(n_f, k, n)``: each flat's own points.
    """
    circles = circles_of(model, p)
    tan_cra = np.asarray(tan_cra, float)
    tmax = float(np.max(tan_cra)) * 1.0001 + 1e-9
    n_grid = grid_points
    grid = np.linspace(0.0, tmax, n_grid + 1)
    # linear interpolation on the uniform grid (np.interp's search is slow on unsorted points)
    pos = tan_cra * (n_grid / tmax)
    i = np.minimum(pos.astype(np.int64), n_grid - 1)
    frac = pos - i
    # every f-number (and the reference) in one call: the grid is small, the call overhead not
    R = np.asarray(list(data.R_mm) + ([] if data.R_ref_mm is None else [data.R_ref_mm]))
    a = _area_fraction(R[:, None], circles, grid[None, :], data.x_mm, data.ray_weight)
    a = np.broadcast_to(a, (R.size, grid.size))
    chief_cos4 = data.natural and data.ray_weight != "cos4"  # cos4: every ray's, in a
    if per_flat:
        m = np.empty(i.shape)
        for f in range(R.size):
            lo = a[f, i[f]]
            m[f] = lo + (a[f, i[f] + 1] - lo) * frac[f]
        if chief_cos4:
            m *= (1.0 + tan_cra**2) ** -2
        return np.einsum("fkn,k->fn", m, weights)
    m = a[:, i] + (a[:, i + 1] - a[:, i]) * frac
    if chief_cos4:
        m *= (1.0 + tan_cra**2) ** -2  # cos^4
    if weights is not None:
        m = np.tensordot(m, weights, axes=([1], [0]))
    if data.R_ref_mm is not None:
        ref = m[-1]
        with np.errstate(invalid="ignore", divide="ignore"):
            m = np.where(ref > 1e-9, m[:-1] / np.where(ref > 1e-9, ref, 1.0), np.nan)
    return m


def _block_model(data: BlockData, model, p, center_rc):
    """The model of every block, averaged over the block's valid pixels
    (:func:`_block_radii`, :func:`block_centroids`), about the centre ``(row, col)``."""
    row, col = center_rc
    if data.block_px <= 1:
        return model_ratio(data, model, p, _tan(data, center_rc))
    per_flat = data.xoff is not None and data.R_ref_mm is None
    if per_flat:  # each flat's own valid pixels: (n_f, n)
        X = (data.xpix - col)[None, :] + data.xoff
        Y = (data.ypix - row)[None, :] + data.yoff
        sx, sy = data.xsd, data.ysd
    else:  # every pixel of the block
        X, Y = data.xpix - col, data.ypix - row
        sx = sy = np.sqrt((data.block_px**2 - 1) / 12.0)
    radii, w = _block_radii(X, Y, sx, sy)
    tan = radii * (data.pitch_mm / data.x_mm)
    if per_flat:
        tan = np.moveaxis(tan, 0, 1)  # (n_f, k, n)
    return model_ratio(data, model, p, tan, w, per_flat=per_flat)


def _tan(data, center_rc):
    """tan(CRA) of every block's centre about the optical centre ``(row, col)`` (Eq. 8)."""
    row, col = center_rc
    return np.hypot(data.xpix - col, data.ypix - row) * data.pitch_mm / data.x_mm


#: Gauss-Newton steps for the exposures at most (from the start it takes two to four).
_EXPOSURE_STEPS = 12


def _profiled(q, sigma, A, start=None, weights=None, return_gains=False):
    """Residuals of ``q = e_F G A`` with each block's gain ``G`` and each flat's exposure
    ``e_F`` (the last one 1) at their least-squares values, and the exposures.

    For given exposures the gains are a weighted mean per block; the exposures, few and well
    determined, follow by Gauss-Newton on ``log e`` with the gains eliminated (variable
    projection): the Jacobian includes how the gains move with them. ``start``: log
    exposures to start from (a fit's previous step: then one or two steps suffice).
    ``weights``: ``(1 / sigma^2, 1 / sigma, q / sigma^2)`` if already at hand.
    """
    w, sw, wq = weights if weights is not None else _weights(q, sigma)
    n_f = q.shape[0]
    wA2 = w * A * A
    wqA = wq * A
    if start is not None and np.all(np.isfinite(start)):
        e = np.exp(np.array(start, float))
    else:  # each block's gain from the flats it sees, then the exposures against it
        with np.errstate(invalid="ignore", divide="ignore"):
            g0 = np.sum(wqA, axis=0) / np.sum(wA2, axis=0)
            g0 = np.where(np.isfinite(g0), g0, 0.0)
            e = (wqA @ g0) / (wA2 @ (g0 * g0))
        e = np.where(np.isfinite(e) & (e > 0), e, 1.0)
    e = e / e[-1]
    k = n_f - 1
    for _ in range(_EXPOSURE_STEPS if n_f > 1 else 0):
        D = (e * e) @ wA2
        D = np.where(D > 0, D, 1.0)
        G = (e @ wqA) / D
        # With mu = e A G the residual is r = sw (q - mu); its Jacobian in u = log e_j
        # (j < n_f - 1) is -(a_k c_j + delta_kj m_k) per block, with a = sw e A,
        # m = sw mu and c_j = dG/du_j = (e_j wqA_j - 2 e_j^2 wA2_j G) / D. Since
        # sum_k a_k r_k = 0 (G is optimal), J^T r = -sum_b w mu (q - mu), and J^T J needs
        # only (n_f - 1) x blocks products.
        e1, e2 = e[:k, None], (e * e)[:k, None]
        am = e2 * wA2[:k] * G  # a * m
        c = (e1 * wqA[:k] - 2.0 * am) / D
        JtJ = (c * D) @ c.T + am @ c.T + c @ am.T + np.diag(am @ G)
        Jtr = -(e1[:, 0] * (wqA[:k] @ G) - am @ G)
        try:
            step = np.linalg.solve(JtJ, -Jtr)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(step)):
            break
        step = np.clip(step, -1.0, 1.0)  # a factor e at most: a bad start cannot run away
        e[:k] *= np.exp(step)
        if np.max(np.abs(step)) < 1e-6:  # quadratic convergence: now within ~1e-12
            break
    D = (e * e) @ wA2
    G = (e @ wqA) / np.where(D > 0, D, 1.0)
    r = ((q - (e[:, None] * A) * G) * sw).ravel()
    return (r, e, G) if return_gains else (r, e)


def _weights(q, sigma):
    w = 1.0 / sigma**2  # 0 where not used
    return w, np.sqrt(w), w * q


def _every_pixel_model(data: BlockData, model, p, center_rc):
    """The model of every block as the mean over all its pixels (each at its own radius, on
    a table four times finer), what :func:`_block_model`'s radial rule approximates."""
    row, col = center_rc
    b = data.block_px
    if b <= _EXACT_SIDE:
        offs = np.arange(b) - (b - 1) / 2.0
        w1 = np.full(b, 1.0 / b)
    else:
        u, w = np.polynomial.legendre.leggauss(_EXACT_NODES)
        offs, w1 = u * (b / 2.0), w / 2.0
    dx, dy = np.meshgrid(offs, offs)
    X = (data.xpix - col)[None, :] + dx.ravel()[:, None]
    Y = (data.ypix - row)[None, :] + dy.ravel()[:, None]
    tan = np.hypot(X, Y) * (data.pitch_mm / data.x_mm)
    return model_ratio(data, model, p, tan, np.outer(w1, w1).ravel(),
                       grid_points=4 * GRID_POINTS)


def _rule_bias(data: BlockData, model, p, center_rc, J, free):
    """How far the block model's approximations (its radial rule and tabulated area) move
    the fitted parameters: the least-squares step, through the fit's Jacobian ``J`` (free
    parameters), that the residuals' change from the block model to the mean over every
    pixel of each block asks for (all pixels of a block taken as valid, for both). A vector
    over the free parameters, one systematic direction with its correlations, not a floor
    on each: it is added to the covariance as its outer product."""
    if data.block_px <= 1 or J is None or not np.size(J):
        return np.zeros(len(free))
    c = _center_of(p, center_rc)
    full = replace(data, xoff=None, yoff=None, xsd=None, ysd=None, warm={})
    r_rule, _ = _model_residuals(full, _block_model(full, model, p, c), model)
    r_fine, _ = _model_residuals(full, _every_pixel_model(full, model, p, c), model)
    J = np.asarray(J.toarray() if hasattr(J, "toarray") else J, float)
    step, *_ = np.linalg.lstsq(J, r_fine - r_rule, rcond=None)
    return np.where(np.isfinite(step), step, 0.0)


def _center_of(p, center_rc):
    """The optical centre ``(row, col)``: ``center_rc`` where held, else the vector's."""
    return center_rc if center_rc is not None else (p[2], p[3])


def _residuals(data, model, p, center_rc):
    m = _block_model(data, model, p, _center_of(p, center_rc))
    return _model_residuals(data, m, model)


def _model_residuals(data, m, model):
    """Residuals of block model values ``m`` and the scales (exposures) that go with them."""
    if data.gains:
        r, e = _profiled(data.q, data.sigma, m, data.warm.get(model), data.weights)
        data.warm[model] = np.log(e)
        return r, e[:-1]  # as ratio scales to the last flat
    w = 1.0 / data.sigma**2
    ok = np.isfinite(m)
    num = np.sum(np.where(ok, w * data.q * m, 0.0), axis=1)
    den = np.sum(np.where(ok, w * m * m, 0.0), axis=1)
    s = num / np.where(den > 0, den, 1.0)
    r = (data.q - s[:, None] * m) / data.sigma
    # blocks the model cannot reach (reference fully cut off) count as a large misfit
    return np.where(ok, r, 10.0).ravel(), s


@accepts_center_rc(old="center", new="center_rc")
def floor_chi2(data: BlockData, fit: ModelFit, floor_rel, center_rc=None):
    """Chi-square of a fit with a systematic floor: each block's variance is
    ``sigma^2 + (floor_rel * q)^2``, the part of the misfit no area model removes (the source,
    pupil aberrations, the block model's approximations). With millions of pixels, any tiny
    mismatch is "significant" against pixel noise alone; against the floor only a difference
    the size of a real fall-off counts.

    ``center_rc``: the optical centre ``(row, col)`` where it was held (and of the model
    without a circle); else the fit's. ``center=(cx, cy)`` is its deprecated x-first form.
    """
    p = [fit.params[k] for k in fit.names]
    c = center_rc if fit.model == "none" or center_rc is not None else (p[2], p[3])
    m = _block_model(data, fit.model, p, c if c is not None else (0.0, 0.0))
    if data.gains:  # the gains and exposures again, under the floored weights
        r, _ = _profiled(data.q, np.sqrt(data.sigma**2 + (floor_rel * data.q) ** 2), m)
        return float(r @ r)
    ok = np.isfinite(m)
    r = np.where(ok, (data.q - fit.scales[:, None] * m), 10.0 * data.sigma)
    var = data.sigma ** 2 + (floor_rel * data.q) ** 2
    return float(np.sum(r * r / var))


@accepts_center_rc(old="center", new="center_rc")
def fit_model(data: BlockData, model, starts, *, center_rc=None, fixed_h=None, max_nfev=60,
              keep=2, fixed=None, screen=True):
    """Fit one model from several starting points; return the best :class:`ModelFit`.

    The first circle's h is kept positive: mirroring every circle through the axis
    (all h -> -h) leaves every area unchanged, so only the signs of the others relative to it
    are seen. The others may have any sign.

    Parameters
    ----------
    model : {"none", "one", "two", "three"}
    starts : list of sequences
        Starting values in the order of :func:`param_names`: (P, h, row, col) for "one",
        plus (P2, h2) for "two", plus (P3, h3). The centre is row first (snapcorr 0.1 held
        it x first).
    center_rc : (row, col), optional
        Keep the optical centre fixed here instead of fitting it; ``center=(cx, cy)`` is
        its deprecated x-first form.
    fixed_h : float, optional
        Keep h fixed (a single f-number cannot tell P from h).
    keep : int
        The fit is run from the ``keep`` starting points with the lowest cost.
    fixed : dict, optional
        Further parameters held at given values, by name (``{"h2_mm": x}``: a second circle
        that is pixel vignetting); they count as no parameter and have no standard error.
    screen : bool
        Run the starts on a subset of the blocks first, then polish the best on all of them
        (default); False: on all blocks from the start (a start at a minimum already, whose
        subset's own minimum lies elsewhere by the subset's noise).
    """
    n = data.n_used
    if n == 0:
        raise ValueError("no usable pixels in the flats (all masked, dark or saturated)")
    if model == "none":
        r, s = _residuals(data, "none", (), center_rc or (0.0, 0.0))
        return ModelFit("none", {}, {}, None, (), float(r @ r), n, data.n_nuisance, s, True)
    names = param_names(model)
    free = _free(names, center_rc, fixed_h, fixed)
    x = data.x_mm
    lo_all = np.array([1e-3, 1e-3, -np.inf, -np.inf] + [1e-3, -20 * x] * 2)[: len(names)]
    hi_all = np.array([20 * x, 20 * x, np.inf, np.inf] + [20 * x, 20 * x] * 2)[: len(names)]

    def full(pf, base):
        p = np.array(base, float)
        p[free] = pf
        return p

    # Starts are screened and run on every k-th block (about SCREEN_BLOCKS of them); the best
    # is then polished on all blocks. The minimum barely moves with the subset, and this is
    # where the time goes.
    step, subset = _screening_subset(data) if screen else (1, data)
    margin = np.where(np.isfinite(lo_all), 1e-4 * np.maximum(np.abs(lo_all), 1.0), 0.0)
    bases = []
    for start in starts:
        base = np.array(start, float)[: len(names)]
        if center_rc is not None:
            base[2:4] = center_rc
        if fixed_h is not None:
            base[1] = fixed_h
        for nm, v in (fixed or {}).items():
            base[names.index(nm)] = v
        base[free] = np.clip(base[free], (lo_all + margin)[free], (hi_all - margin)[free])
        r = _residuals(subset, model, base, center_rc)[0]
        bases.append((float(r @ r), base))
    bases.sort(key=lambda cb: cb[0])
    best = None
    for i, (_, base) in enumerate(bases[:keep]):
        p0 = base[free]

        def fun(pf, base=base, d=subset):
            return _residuals(d, model, full(pf, base), center_rc)[0]

        # the most promising start gets a longer run
        res = least_squares(fun, p0, bounds=(lo_all[free], hi_all[free]), x_scale="jac",
                            max_nfev=max_nfev * (3 if i == 0 else 1))
        if best is None or res.cost < best[0].cost:
            best = (res, base)
    if step > 1:
        res, base = best
        p0 = np.clip(res.x, (lo_all + margin)[free], (hi_all - margin)[free])
        res = least_squares(lambda pf: _residuals(data, model, full(pf, base), center_rc)[0], p0,
                            bounds=(lo_all[free], hi_all[free]), x_scale="jac",
                            max_nfev=POLISH_NFEV)
        best = (res, base)
    res, base = best
    p = full(res.x, base)
    r, s = _residuals(data, model, p, center_rc)
    chi2 = float(r @ r)
    k = len(free) + data.n_nuisance
    bias = _rule_bias(data, model, p, center_rc, res.jac, free)
    cov, err, noise_cov = _covariance(res.jac, p, free, names, chi2 / max(n - k, 1), bias)
    params = dict(zip(names, map(float, p), strict=True))
    stderr = dict(zip(names, map(float, err), strict=True))
    extra = {"held": dict(fixed)} if fixed else {}
    # the parts of the covariance: the noise's (scaled by the misfit) and the block rule's
    extra["noise_covariance"] = noise_cov
    extra["rule_bias"] = {names[i]: float(b) for i, b in sorted(zip(free, bias, strict=True))}
    extra["misfit_scale"] = float(max(chi2 / max(n - k, 1), 1.0))
    return ModelFit(model, params, stderr, cov, tuple(names), chi2, n, k, s, bool(res.success),
                    str(res.message), extra=extra)


def _free(names, center_rc, fixed_h, fixed):
    """Indices of the parameters fitted, in the order the least squares takes them: that of
    ``names``, but the centre's column before its row. That is the order every calibration
    was checked in, and it matters: where a circle is barely seen (a flat valley), the point
    the solver stops at follows the rounding of its steps, which depends on the variables'
    order (a rejected third circle's h came out at -1.5 mm one way and 42 mm the other)."""
    free = [i for i, nm in enumerate(names)
            if not (center_rc is not None and nm in CENTER_NAMES)
            and not (fixed_h is not None and nm == "h_mm")
            and nm not in (fixed or {})]
    return sorted(free, key=lambda i: {2: 3, 3: 2}.get(i, i))


def _screening_subset(data: BlockData):
    """The step between the blocks screened, and those blocks (``data`` itself for step 1)."""
    step = max(1, int(np.ceil(data.q.shape[1] / SCREEN_BLOCKS)))
    screen = data if step == 1 else replace(
        data, q=data.q[:, ::step], sigma=data.sigma[:, ::step], xpix=data.xpix[::step],
        ypix=data.ypix[::step], warm={},
        **{k: None if getattr(data, k) is None else getattr(data, k)[:, ::step]
           for k in ("xoff", "yoff", "xsd", "ysd")})
    return step, screen


def _covariance(J, p, free, names, reduced_chi2, bias=None):
    """Covariance of all parameters (zero for the fixed ones), their standard errors, and the
    noise's part of the covariance alone. ``bias``: the block rule's systematic step over
    the free parameters (:func:`_rule_bias`), added as its outer product."""
    # Covariance from the SVD of the Jacobian in relative units (a change of each parameter by
    # its own size), so that no parameter's scale decides what counts as constrained.
    scale = np.maximum(np.abs(p[free]), 1e-3)
    _, sv, vt = np.linalg.svd(J * scale, full_matrices=False)
    strong = sv > 1e-9 * max(sv.max(), 1e-300)
    inv = (vt[strong].T / sv[strong] ** 2) @ vt[strong]
    cov_free = inv * np.outer(scale, scale) * max(reduced_chi2, 1.0)
    noise = np.full((len(names), len(names)), 0.0)
    noise[np.ix_(free, free)] = cov_free
    cov = noise.copy()
    if bias is not None:
        cov[np.ix_(free, free)] += np.outer(bias, bias)
    err = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    # Parameters along directions the data do not (or hardly) constrain have no standard
    # error: a second circle that cuts no ray in the field, say.
    weak = vt[~strong]
    if weak.size:
        loose = np.abs(weak).max(axis=0) > 0.1
        err[np.asarray(free)[loose]] = np.inf
    return cov, err, noise
