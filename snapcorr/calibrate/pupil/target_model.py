"""A spatially uniform spectral target seen across the field: radial bins and their model.

Every pixel at the same distance ``d`` from the optical axis sees a uniform target through the
same effective filter, so each band of a flat-fielded cube is reduced to its means over thin
annuli (:func:`radial_bins`; bins of equal width in ``d^2``, i.e. equal area).

The model of a bin (:class:`TargetModel`) is the whole filter behind the lens (Goossens et al.
2019, Eq. 13): band ``b`` at ``d`` sees

    ``y_b(d) = sum_k w_k F_b(cwl_b + delta_bk)``,  ``F_b(c) = int S(l) T_b(l - c) dl / int T_b``

with ``(delta_bk, w_k)`` the pixel's shift kernel (Eq. 37, as point masses from
:func:`~snapcorr.optics.response.kernel_bins`) and ``T_b`` the band's filter profile at normal
incidence. The kernel is computed once per bin as a distribution of ``u = sin^2(phi)`` (pure
geometry) and mapped to each band's shift by Eq. (3), ``delta = cwl (sqrt(1 - u / n^2) - 1)``,
so changing the effective index costs no new kernel. The target ``S`` is either given (one
free scale per cube) or unknown: then it is a sum of hat functions on a grid finer than the
filters, solved for by linear least squares at every trial ``x`` and ``n_eff`` (variable
projection), and only what the bands see of it matters.
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..._coords import accepts_center_rc
from ..._validation import check_center_rc
from ...optics.goossens2019 import PupilCutOffError
from ...optics.lens import Lens
from ...optics.profiles import PROFILES
from ...optics.response import kernel_bins, kernel_bins_batch
from ...optics.shift import EffectiveIndexWarning

__all__ = ["RadialBins", "TargetModel", "radial_bins", "rebin"]

#: How a ray at angle phi changes the filter curve: ``"shift"`` moves it by ``cwl (s - 1)``
#: (Goossens 2019, Eq. 13); ``"scale"`` scales every wavelength by ``s`` (Rienstra 1998; exact
#: for an ideal etalon, whose transmission is a function of ``lambda / cos(theta_inside)``),
#: which also narrows it by ``s`` (to first order in ``s - 1``).
TRANSFORMS = ("scale", "shift")
#: Standard deviation of the unknown target's prior, in units of the largest signal.
PRIOR_SD = 3.0
#: Kernel bins are at most this fraction of the narrowest filter's FWHM wide (at the longest
#: wavelength): the spread a bin leaves out, width^2 / 12, is then ~1e-4 of the filter's.
KERNEL_STEP_FWHM = 1 / 30
#: Index at which the kernels are computed (any value works: they are stored as sin^2 phi).
N_REF = 1.7
#: Filter profiles are cut where they fall below this fraction of their peak (and at
#: +-PROFILE_REACH FWHM for profiles with slowly decaying wings such as the Airy function).
PROFILE_CUT = 1e-4
PROFILE_REACH = 5.0


@dataclass(frozen=True)
class RadialBins:
    """One cube reduced to annulus means per band.

    Attributes
    ----------
    f_number : float
    rho : ndarray, shape (n_bins,)
        Mean ``d^2`` (mm^2) of each bin over every band's pixels in it.
    rho_band, var_rho : ndarray, shape (n_bands, n_bins)
        Each band's own mean and variance of ``d^2`` in the bin.
    mean, stderr : ndarray, shape (n_bands, n_bins)
        Mean value and its standard error (from the scatter about a straight line in ``d^2``
        inside the bin); NaN where a band has fewer than ``min_count`` pixels in the bin.
    count : ndarray, shape (n_bands, n_bins)
    """

    f_number: float
    rho: np.ndarray
    rho_band: np.ndarray
    var_rho: np.ndarray
    mean: np.ndarray
    stderr: np.ndarray
    count: np.ndarray

    @property
    def n_bands(self):
        return self.mean.shape[0]


def _band_rho(rows, cols, b, center_rc, pitch_mm):
    """Band ``b``'s ``d^2`` (mm^2) about ``center_rc = (row, col)`` on its pixel grid."""
    r = rows[:, min(b, rows.shape[1] - 1)]
    c = cols[:, min(b, cols.shape[1] - 1)]
    row, col = center_rc
    return (((r - row) * pitch_mm) ** 2)[:, None] + (((c - col) * pitch_mm) ** 2)[None, :]


@accepts_center_rc
def radial_bins(band_image, n_bands, rows, cols, center_px, pitch_mm, *, f_number,
                n_bins=96, min_count=16, center_rc=None):
    """Reduce a cube to means over annuli of equal area about the optical centre.

    Parameters
    ----------
    band_image : callable
        ``band_image(b)`` returns band ``b`` as a 2-D float array (NaN marks a masked pixel).
    n_bands : int
    rows, cols : ndarray, shape (ny, n_bands or 1), (nx, n_bands or 1)
        Sensor row and column of every cube pixel (see
        :func:`~snapcorr.correct.geometry.cube_positions`).
    center_px : (cx, cy) or None
        The optical centre x first: its deprecated form, kept in its place for the callers of
        earlier releases; give ``None`` here and ``center_rc``.
    pitch_mm : float
    f_number : float
    n_bins : int
        Bins between the smallest and largest ``d^2`` the cube covers.
    min_count : int
        Fewer finite pixels than this leave a band's bin empty (NaN).
    center_rc : (row, col)
        Optical centre in sensor pixels, row first.

    Returns
    -------
    RadialBins
    """
    center_rc = check_center_rc(center_rc)
    row, col = center_rc
    dy = (rows - row) * pitch_mm
    dx = (cols - col) * pitch_mm
    lo = float(np.min(np.min(dy**2, axis=0) + np.min(dx**2, axis=0)))
    hi = float(np.max(np.max(dy**2, axis=0) + np.max(dx**2, axis=0)))
    edges = np.linspace(lo, hi + 1e-9 * max(hi, 1e-12), n_bins + 1)
    shape = (n_bands, n_bins)
    count, rho_b, var_rho, mean, stderr = (np.full(shape, np.nan) for _ in range(5))
    for b in range(n_bands):
        v = np.asarray(band_image(b), dtype=float)
        rho = _band_rho(rows, cols, b, center_rc, pitch_mm)
        ok = np.isfinite(v)
        rho, v = rho[ok], v[ok]
        idx = np.clip(np.searchsorted(edges, rho, side="right") - 1, 0, n_bins - 1)
        n = np.bincount(idx, minlength=n_bins).astype(float)
        ref = float(np.median(v)) if v.size else 0.0
        v = v - ref  # sums of squares about a typical value: no cancellation
        s = [np.bincount(idx, weights=w, minlength=n_bins)
             for w in (rho, rho * rho, v, v * rho, v * v)]
        with np.errstate(invalid="ignore", divide="ignore"):
            m_r, m_rr, m_v, m_vr, m_vv = (x / n for x in s)
            vr = np.maximum(m_rr - m_r**2, 0.0)
            cov = m_vr - m_r * m_v
            resid = np.maximum(m_vv - m_v**2 - np.where(vr > 0, cov**2 / vr, 0.0), 0.0)
            se = np.sqrt(resid * n / np.maximum(n - 2, 1) / n)
        good = n >= min_count
        count[b] = n
        rho_b[b] = np.where(good, m_r, np.nan)
        var_rho[b] = np.where(good, vr, np.nan)
        mean[b] = np.where(good, m_v + ref, np.nan)
        stderr[b] = np.where(good, se, np.nan)
    with np.errstate(invalid="ignore"):
        pooled = np.nansum(rho_b * count, axis=0) / np.nansum(np.where(np.isfinite(rho_b),
                                                                       count, 0), axis=0)
    mid = 0.5 * (edges[:-1] + edges[1:])
    pooled = np.where(np.isfinite(pooled), pooled, mid)
    return RadialBins(float(f_number), pooled, rho_b, var_rho, mean, stderr, count)


def rebin(bins: RadialBins, factor: int) -> RadialBins:
    """Merge every ``factor`` neighbouring annuli (count-weighted): a coarser, cheaper copy."""
    nb, n = bins.mean.shape
    m = -(-n // factor)
    pad = m * factor - n

    def grouped(a):
        return np.pad(a, ((0, 0), (0, pad)), constant_values=np.nan).reshape(nb, m, factor)

    c = grouped(np.where(np.isfinite(bins.mean), bins.count, 0.0))
    c = np.nan_to_num(c)
    tot = c.sum(axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        def wmean(a):
            return np.nansum(grouped(a) * c, axis=2) / tot

        rho_b = wmean(bins.rho_band)
        var = wmean(bins.var_rho) + wmean(bins.rho_band**2) - rho_b**2
        mean = wmean(bins.mean)
        se = np.sqrt(np.nansum((grouped(bins.stderr) * c) ** 2, axis=2)) / tot
        cr = grouped(np.where(np.isfinite(bins.rho_band), bins.count, 0.0))
        cr = np.nan_to_num(cr)
        pooled = (np.nansum(np.nan_to_num(grouped(bins.rho_band)) * cr, axis=(0, 2))
                  / cr.sum(axis=(0, 2)))
    empty = tot == 0
    for a in (rho_b, var, mean, se):
        a[empty] = np.nan
    keep = np.isfinite(pooled)
    return RadialBins(bins.f_number, pooled[keep], rho_b[:, keep], np.maximum(var, 0)[:, keep],
                      mean[:, keep], se[:, keep], tot[:, keep])


def _lerp(table, pos, other=None):
    """``table`` (and ``other``, of the same length) at fractional indices ``pos``, linearly
    interpolated, zero outside."""
    n = table.size
    i = np.floor(pos).astype(int)
    f = pos - i
    ok0 = (i >= 0) & (i < n)
    ok1 = (i >= -1) & (i < n - 1)
    i0, i1 = np.clip(i, 0, n - 1), np.clip(i + 1, 0, n - 1)
    w0, w1 = np.where(ok0, 1 - f, 0.0), np.where(ok1, f, 0.0)
    first = table[i0] * w0 + table[i1] * w1
    return first if other is None else (first, other[i0] * w0 + other[i1] * w1)


def _lerp_slope(table, pos):
    """The derivative of :func:`_lerp` ``(table, pos)`` in ``pos`` (each piece's slope)."""
    n = table.size
    i = np.floor(pos).astype(int)
    ok0 = (i >= 0) & (i < n)
    ok1 = (i >= -1) & (i < n - 1)
    i0, i1 = np.clip(i, 0, n - 1), np.clip(i + 1, 0, n - 1)
    return np.where(ok1, table[i1], 0.0) - np.where(ok0, table[i0], 0.0)


def _derivatives(x):
    """Matrices D1, D2 with ``D1 @ f ~ f'`` and ``D2 @ f ~ f''`` on the increasing grid ``x``
    (three-point formulas; the end rows use the nearest interior triple)."""
    n = x.size
    D1, D2 = np.zeros((n, n)), np.zeros((n, n))
    if n < 3:
        if n == 2:
            D1[:, 0], D1[:, 1] = -1 / (x[1] - x[0]), 1 / (x[1] - x[0])
        return D1, D2
    for i in range(n):
        c = min(max(i, 1), n - 2)
        a, b, d = x[c - 1], x[c], x[c + 1]
        h0, h1 = b - a, d - b
        if not (h0 > 0 and h1 > 0):  # not a strictly increasing triple: no correction
            continue
        D2[i, c - 1:c + 2] = 2 / (h0 * (h0 + h1)), -2 / (h0 * h1), 2 / (h1 * (h0 + h1))
        t = x[i]  # derivative of the parabola through the triple, at x[i]
        D1[i, c - 1] = (2 * t - b - d) / ((a - b) * (a - d))
        D1[i, c] = (2 * t - a - d) / ((b - a) * (b - d))
        D1[i, c + 1] = (2 * t - a - b) / ((d - a) * (d - b))
    return D1, D2


def _profile_shape(profile, cwl, fwhm, n_eff):
    """The band's normal-incidence curve as a function of ``lambda - cwl``."""
    if callable(profile):
        return lambda t: np.asarray(profile(cwl + t), float)
    try:
        make = PROFILES[profile]
    except KeyError:
        raise ValueError(f"profile must be one of {sorted(set(PROFILES) - {'tabulated'})}, "
                         f"got {profile!r}") from None
    curve = make(cwl, fwhm, n_eff)
    peak = float(getattr(curve, "cwl_nm", cwl))
    return lambda t: np.asarray(curve(peak + t), float)


def scaled_circles(circles, x_from, x_to):
    """Vignetting circles found from flat fields at ``x_from``, at ``x_to``.

    Flats fix ``P / x`` and ``h / x^2`` exactly (scaling ``x`` scales the pupil, every circle
    and every chief ray alike), so ``P`` scales as ``x`` and ``h`` as ``x^2``
    (:func:`snapcorr.calibrate.calibrate_lens` records these derivatives).

    >>> scaled_circles([(7.0, 17.0)], 21.0, 23.1)
    [(7.7, 20.57)]
    """
    k = float(x_to) / float(x_from)
    return [(round(P * k, 12), round(h * k * k, 12)) for P, h in circles]


#: Gauss-Legendre nodes on either side of a vignetting onset inside an annulus.
ONSET_NODES = 4


def _onset_nodes(b, x, lens):
    """Nodes in ``d^2`` (and weights) for the annuli of ``b`` that a vignetting onset crosses.

    Where a circle starts to cut the pupil (at ``d_e = x tan(onset CRA)``, Eq. 24-25) a
    bin's curve goes as ``smooth + c (d^2 - d_e^2)^(3/2)``: a Taylor step from the bin's mean
    with the curvature between neighbouring bins misses it. Such a bin (its pixels spread
    uniformly in ``d^2`` over ``mean +- sqrt(3 var)``, as an annulus of equal area is) is
    averaged instead over :data:`ONSET_NODES` Gauss-Legendre nodes on either side of the
    onset. Returns a list of ``(bin, d^2, weight)``, the weights of a bin summing to 1.
    """
    if not lens.has_vignetting:
        return []
    onsets = np.atleast_1d(lens.circle_onsets_cra_deg(b.f_number)).ravel()
    rho_e = [(x * math.tan(math.radians(c))) ** 2 for c in onsets
             if math.isfinite(c) and 0.0 < c < 89.0]
    if not rho_e:
        return []
    ok = np.isfinite(b.var_rho)
    var = np.where(ok, b.var_rho, 0.0).sum(axis=0) / np.maximum(ok.sum(axis=0), 1)
    half = np.sqrt(3.0 * var)
    lo, hi = b.rho - half, b.rho + half
    xi, wi = np.polynomial.legendre.leggauss(ONSET_NODES)
    out = []
    for i in range(b.rho.size):
        cuts = sorted(r for r in rho_e if lo[i] < r < hi[i])
        if not cuts or not half[i] > 0:
            continue
        edges = [max(lo[i], 0.0), *cuts, hi[i]]
        span = edges[-1] - edges[0]
        for a, c in itertools.pairwise(edges):
            for t, wt in zip(xi, wi, strict=True):
                out.append((i, a + (c - a) * (t + 1) / 2, wt * (c - a) / (2 * span)))
    return out


class TargetModel:
    """The binned cubes of a uniform target as a function of ``x`` and ``n_eff``.

    Parameters
    ----------
    bins : sequence of RadialBins
        One per cube (f-number).
    cwl_nm, fwhm_nm : array_like, shape (n_bands,)
    lens : Lens
        Supplies the vignetting circles, magnification and pupil magnification; its exit
        pupil distance is replaced by each trial ``x``.
    spectrum : callable, optional
        ``S(lambda_nm)``, the target's spectrum, known up to a scale per cube. ``None``: unknown
        (solved for on a grid of hat functions ``basis_step_nm`` apart).
    profile : str
        The filters' shape at normal incidence: a name in :data:`~snapcorr.optics.PROFILES`
        (built from each band's centre and FWHM), cut below ``PROFILE_CUT`` of its peak and
        beyond ``PROFILE_REACH`` FWHM.
    n_eff_design : float or array_like
        The filters' index, for profiles whose shape depends on it (Airy).
    max_shift_rel : float
        Largest relative blue shift any trial may produce (sizes the target's grid).
    transform : {"scale", "shift"}
        How each ray changes the filter (:data:`TRANSFORMS`).
    circles_at_mm : float, optional
        The lens's circles were found from flat fields at this ``x``: at each trial ``x``
        they are scaled as the flats fix them (:func:`scaled_circles`). None: kept as they
        are.
    basis_step_nm, grid_step_nm : float, optional
        Spacing of the hat functions (default FWHM / 6) and of the fine grid on which kernels
        and filters meet (default FWHM / 200; the smallest FWHM).
    """

    def __init__(self, bins, cwl_nm, fwhm_nm, lens: Lens, *, spectrum=None, profile="gaussian",
                 n_eff_design=1.7, max_shift_rel=0.1, basis_step_nm=None, grid_step_nm=None,
                 transform="scale", circles_at_mm=None):
        if transform not in TRANSFORMS:
            raise ValueError(f"transform must be one of {TRANSFORMS}, got {transform!r}")
        self.transform = transform
        self.bins = list(bins)
        self.cwl = np.asarray(cwl_nm, float)
        self.fwhm = np.broadcast_to(np.asarray(fwhm_nm, float), self.cwl.shape).copy()
        nd = np.broadcast_to(np.asarray(n_eff_design, float), self.cwl.shape)
        self.lens = lens
        self.circles_at_mm = circles_at_mm
        self.known = spectrum is not None
        self.h = float(grid_step_nm or self.fwhm.min() / 200.0)
        q = max(1, round((basis_step_nm or self.fwhm.min() / 6.0) / self.h))
        self.q, self.step = q, q * self.h
        self._grid(profile, nd, spectrum, max_shift_rel)
        self._rows()
        if self.known:
            self.prior_mean = self.prior_sd = None
        else:
            # A weak prior on the target: its hat coefficients scatter by PRIOR_SD times the
            # largest signal about the typical one. Real targets never feel it; it removes the
            # wildly oscillating spectra that could mimic any shift inside a band alone.
            self.prior_mean = float(np.median(self.y))
            self.prior_sd = PRIOR_SD * float(np.max(np.abs(self.y)))
        self._kernel_cache = {}

    # -- set-up ----------------------------------------------------------------------------
    def _grid(self, profile, n_design, spectrum, max_shift_rel):
        """The target's grid of hat functions (``lam0``, ``n_basis``) and the bands' tables."""
        reach = [self._support(profile, c, w, n) for c, w, n in zip(self.cwl, self.fwhm,
                                                                  n_design, strict=True)]
        lo = float(np.min(self.cwl * (1 - max_shift_rel))) - max(r[0] for r in reach) - self.step
        hi = float(np.max(self.cwl)) + max(r[0] for r in reach) + 2 * self.step
        self.lam0 = math.floor(lo / self.step) * self.step  # a multiple of the basis step
        self.n_basis = math.ceil((hi - self.lam0) / self.step) + 1
        self.n_fine = (self.n_basis - 1) * self.q + 1
        self._tables(profile, n_design, spectrum, reach)

    def _support(self, profile, cwl, fwhm, n_eff):
        shape = _profile_shape(profile, cwl, fwhm, n_eff)
        t = np.arange(-PROFILE_REACH * fwhm, PROFILE_REACH * fwhm + self.h / 2, self.h)
        v = shape(t)
        keep = np.flatnonzero(v >= PROFILE_CUT * v.max())
        half = float(max(abs(t[keep[0]]), abs(t[keep[-1]]))) + self.h
        return half, shape

    def _tables(self, profile, n_design, spectrum, reach):
        """Per band: the filter response on the fine grid, to the target (known) or to one hat
        function at offset ``t`` (unknown; ``H_b(j h)``)."""
        self.H, self.J, self.F, self.HD, self.FD = [], [], [], [], []
        lam = self.lam0 + self.h * np.arange(self.n_fine)
        S = None if spectrum is None else np.asarray(spectrum(lam), float)
        if S is not None and not np.all(np.isfinite(S)):
            raise ValueError("the target spectrum is not finite over the bands' range")
        for half, shape in reach:
            J = math.ceil(half / self.h)
            t = self.h * np.arange(-J, J + 1)
            T = np.clip(shape(t), 0.0, None)
            T[shape(t) < PROFILE_CUT * T.max()] = 0.0
            T = T / T.sum()
            # a ray that scales the curve by s: T(t / s) / s ~ T + (s - 1) D (same area)
            D = -(T + t * np.gradient(T, self.h))
            self.J.append(J)
            if S is None:
                hat = np.maximum(0.0, 1.0 - np.abs(np.arange(-self.q, self.q + 1)) / self.q)
                # H(c - lambda_m) = sum_l hat(l - lambda_m) T(l - c): a correlation
                self.H.append(np.convolve(hat, T[::-1]))  # index j + J + q <-> offset j h
                self.HD.append(np.convolve(hat, D[::-1]))
            else:
                # F(c) = sum_l S(l) T(l - c) on the fine grid (zero beyond the ends)
                self.F.append(np.correlate(np.pad(S, (J, J)), T, mode="valid"))
                self.FD.append(np.correlate(np.pad(S, (J, J)), D, mode="valid"))

    def _rows(self):
        """Which (cube, band, bin) enter, with their values and standard errors."""
        ys, ss, self.blocks = [], [], []
        start = 0
        for j, b in enumerate(self.bins):
            for k in range(b.n_bands):
                ok = np.flatnonzero(np.isfinite(b.mean[k]) & np.isfinite(b.stderr[k])
                                    & (b.stderr[k] > 0))
                ys.append(b.mean[k, ok])
                ss.append(b.stderr[k, ok])
                self.blocks.append((j, k, slice(start, start + ok.size), ok))
                start += ok.size
        self.y = np.concatenate(ys)
        self.sigma = np.concatenate(ss)
        self.n_rows = self.y.size
        if self.n_rows == 0:
            raise ValueError("no annulus of the target cubes has a mean with a standard error "
                             "(too few pixels in each, or a field too small or too close to "
                             "the optical centre): the exit pupil needs cubes that reach well "
                             "off the centre")
        self._D = [_derivatives(b.rho) for b in self.bins]

    @property
    def n_columns(self):
        return len(self.bins) if self.known else self.n_basis

    # -- kernels ---------------------------------------------------------------------------
    def _lens(self, x):
        L = self.lens
        circles = (L.vignetting if self.circles_at_mm is None
                   else scaled_circles(L.vignetting, self.circles_at_mm, x))
        return Lens(x, circles, L.magnification, L.pupil_magnification,
                    pupil_radiance=L.pupil_radiance)

    def kernels(self, x, *, field=True):
        """Per cube: the kernels of every bin as masses ``w`` at ``sin^2(phi) = u``,
        concatenated: ``(u, w, bin index, number of bins and nodes, combine)``; ``combine``
        lists ``(bin, node, weight)``: the rows of the bins an onset crosses are the weighted
        sums of their nodes' rows (:func:`_onset_nodes`).

        ``field=False`` puts every bin on the axis (no chief-ray angle): the model of a target
        whose spectrum does not change over the field.
        """
        key = (float(x), field)
        if key in self._kernel_cache:
            return self._kernel_cache[key]
        lens = self._lens(float(x))
        out = []
        with warnings.catch_warnings():
            # trial x may send rays beyond the index law's validated 40 degrees; the fit says
            # so for the x it settles on
            warnings.simplefilter("ignore", EffectiveIndexWarning)
            step = KERNEL_STEP_FWHM * float(self.fwhm.min() / self.cwl.max())
            for b in self.bins:
                out.append(self._cube_kernels(b, x, lens, field, step))
        if len(self._kernel_cache) > 64:
            self._kernel_cache.clear()
        self._kernel_cache[key] = out
        return out

    @staticmethod
    def _cube_kernels(b, x, lens, field, step):
        """One cube's kernels at every bin, concatenated (see :meth:`kernels`), then those of
        the nodes inside the bins a vignetting onset crosses (:func:`_onset_nodes`): the last
        item says which bin each node's row goes to and with what weight."""
        cra_of = (lambda rho: np.rad2deg(np.arctan(np.sqrt(rho) / x))) if field else (
            lambda rho: np.zeros_like(rho))
        extra = _onset_nodes(b, x, lens) if field else []
        rho = np.concatenate([b.rho, [r for _, r, _ in extra]])
        cra = cra_of(rho)
        try:  # every angle in one pass; angle by angle where some pixel gets no light
            kerns = kernel_bins_batch(1.0, N_REF, b.f_number, cra, lens, step_nm=step)
        except PupilCutOffError:
            kerns = []
            for c in cra:
                try:
                    kerns.append(kernel_bins(1.0, N_REF, b.f_number, float(c), lens,
                                             step_nm=step))
                except PupilCutOffError:
                    kerns.append(None)
        per_bin = [None if kw is None else (N_REF**2 * (1.0 - (1.0 + kw[0]) ** 2), kw[1])
                   for kw in kerns]
        lit = [(i, kw) for i, kw in enumerate(per_bin) if kw is not None]
        u = np.concatenate([kw[0] for _, kw in lit]) if lit else np.zeros(0)
        w = np.concatenate([kw[1] for _, kw in lit]) if lit else np.zeros(0)
        owner = (np.concatenate([np.full(kw[1].size, i) for i, kw in lit]) if lit
                 else np.zeros(0, int))
        dark = {i for i, kw in enumerate(per_bin) if kw is None}
        combine = [(i, b.rho.size + q, wq) for q, (i, _, wq) in enumerate(extra)]
        # a bin whose node gets no light keeps its Taylor step (the cut-off is not an onset)
        bad = {i for i, node, _ in combine if node in dark}
        combine = [c for c in combine if c[0] not in bad]
        return u, w, owner, len(per_bin), combine

    # -- the model -------------------------------------------------------------------------
    def design(self, x, n_eff, *, field=True, dn=False):
        """The model matrix ``A`` (sparse, rows as :attr:`y`): ``y ~ A @ s``.

        ``s`` is the target's hat coefficients (unknown spectrum) or one scale per cube (known
        spectrum). Rows of bins no light reaches are zero.

        Parameters
        ----------
        x : float
            Trial exit-pupil distance, mm (replaces the lens's).
        n_eff : float or array_like
            Trial effective index, one or one per band (shape ``(n_bands,)``).
        field : bool
            False: every bin on the axis (see :meth:`kernels`).
        dn : bool
            The derivative of ``A`` in the index instead: each band's rows in its own index
            (models that have it, :attr:`analytic_dn`; else ``NotImplementedError``).

        Returns
        -------
        scipy.sparse.csr_array
            Shape ``(n_rows, n_columns)``.
        """
        from scipy import sparse

        n = np.broadcast_to(np.asarray(n_eff, float), self.cwl.shape)
        kern = self.kernels(x, field=field)
        ri, ci, vals = [], [], []
        for j, k, rows, ok in self.blocks:
            if ok.size == 0:
                continue
            first, full = self._band_block(kern[j], k, n[k], dn=dn)
            D1, D2 = self._D[j]
            b = self.bins[j]
            nbin = b.rho.size
            block = full[:nbin]
            d = np.nan_to_num(b.rho_band[k] - b.rho)
            v = np.nan_to_num(b.var_rho[k])
            # the mean over a bin of a curve, from its value at the pooled mean d^2: a Taylor
            # step to the band's own mean plus half the curvature times the spread
            block = block + d[:, None] * (D1 @ block) + 0.5 * (v + d * d)[:, None] * (D2 @ block)
            combine = kern[j][4]
            if combine:  # a bin an onset crosses: the curve is not smooth there, its nodes'
                # rows averaged instead (the Taylor step's curvature, taken across the onset,
                # biased x by half its standard error at f/1.4 behind the paper lens)
                at = sorted({i for i, _, _ in combine})
                block[at] = 0.0
                for i, node, wq in combine:
                    block[i] += wq * full[node]
            block = block[ok]
            r = np.arange(rows.start, rows.stop)
            c = np.full(1, j) if self.known else first + np.arange(block.shape[1])
            ri.append(np.repeat(r, c.size))
            ci.append(np.tile(c, r.size))
            vals.append(block.ravel())
        shape = (self.n_rows, self.n_columns)
        if not ri:
            return sparse.csr_array(shape)
        v = np.concatenate(vals)
        # entries from the filters' far wings: dropped (they would only leave subnormal numbers
        # in the normal equations, which slow every later step a thousandfold)
        v[np.abs(v) < 1e-12 * np.max(np.abs(v))] = 0.0
        A = sparse.csr_array((v, (np.concatenate(ri), np.concatenate(ci))), shape=shape)
        A.eliminate_zeros()
        return A

    #: Whether :meth:`design` gives the derivative in the index (``dn=True``).
    analytic_dn = True

    def _masses(self, u, w, owner, nb, cwl, n, dn):
        """Every kernel mass's weight, correction weight (``"scale"``; else None) and filter
        centre in fine-grid units at index ``n``, and with ``dn`` their derivatives in ``n``
        (None otherwise): ``(w, wd, p), (dw, dwd, dp)``."""
        a2 = 1.0 - u / (n * n)
        scale = np.sqrt(np.clip(a2, 0.0, None))  # Eq. 3: lambda_c / cwl
        ds = (np.where(a2 > 0, u / (n**3 * np.where(a2 > 0, scale, 1.0)), 0.0) if dn
              else None)
        p = (cwl * scale - self.lam0) / self.h  # each mass's filter centre, fine-grid units
        dp = None if ds is None else cwl * ds / self.h
        if self.transform != "scale":
            return (w, None, p), (None if ds is None else np.zeros_like(w), None, dp)
        # the curve T(l / s) has s times the area: each ray passes s times the light (the
        # white reference sees the same, so only the weights' ratios change)
        ws = w * scale
        tot = np.bincount(owner, ws, minlength=nb)[owner]
        wn = ws / tot
        if ds is None:
            return (wn, wn * (scale - 1.0), p), (None, None, None)
        dws = w * ds
        dwn = (dws - wn * np.bincount(owner, dws, minlength=nb)[owner]) / tot
        return (wn, wn * (scale - 1.0), p), (dwn, dwn * (scale - 1.0) + wn * ds, dp)

    def _band_block(self, kern, k, n, *, dn=False):
        """Rows for every bin of one cube and band ``k``: every kernel mass reads the band's
        response table at its filter centre (linear interpolation on the fine grid). Returns the
        first column (hat) the block covers and the block. With ``dn`` the block's derivative
        in the index ``n`` instead: the masses' centres (Eq. 3, ``d scale / dn = u / (n^3
        scale)``) through each interpolation piece's slope, and their weights' change."""
        u, w, owner, nb = kern[:4]
        cwl = self.cwl[k]
        if u.size == 0:
            return 0, np.zeros((nb, 1))
        (w, wd, p), (dw, dwd, dp) = self._masses(u, w, owner, nb, cwl, n, dn)
        if self.known:
            tables = [(w, dw, self.F[k])] + ([] if wd is None else [(wd, dwd, self.FD[k])])
            out = np.zeros(nb)
            for c, dc, T in tables:
                v = (c * _lerp(T, p) if not dn
                     else dc * _lerp(T, p) + c * _lerp_slope(T, p) * dp)
                out += np.bincount(owner, v, minlength=nb)
            return 0, out[:, None]
        J, q = self.J[k], self.q
        # every mass reaches the hats m with |p - q m| < J + q: H at lag p - q m + J + q
        first = np.ceil((p - J - q) / q).astype(int)
        reach = (2 * (J + q)) // q + 2
        m = first[:, None] + np.arange(reach)[None, :]
        lag = p[:, None] - q * m + (J + q)
        inside = (m >= 0) & (m < self.n_basis)  # the grid covers every trial (max_shift_rel)
        m = np.clip(m, 0, self.n_basis - 1)
        m_lo = int(m.min())
        cols = int(m.max()) - m_lo + 1
        flat = (owner[:, None] * cols + (m - m_lo)).ravel()
        tables = [(w, dw, self.H[k])] + ([] if wd is None else [(wd, dwd, self.HD[k])])
        vals = 0.0
        for c, dc, T in tables:
            vals = vals + (c[:, None] * _lerp(T, lag) if not dn else
                           dc[:, None] * _lerp(T, lag)
                           + (c * dp)[:, None] * _lerp_slope(T, lag))
        vals = np.where(inside, vals, 0.0).ravel()
        out = np.bincount(flat, vals, minlength=nb * cols).reshape(nb, cols)
        return m_lo, out
