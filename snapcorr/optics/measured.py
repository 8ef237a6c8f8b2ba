"""Measured filter responses behind a lens: each band's own curve, every ray scaling it.

A vendor calibration file gives each band's response ``T_b(lambda)`` at normal, collimated
incidence, with all its peaks, and the response ``S(lambda)`` of the system in front of every
band (a band-pass filter). Behind a lens, ray ``k`` of a pixel's cone sees the whole curve
scaled, ``T_b(lambda / a_k)`` with ``a_k = sqrt(1 - sin^2 phi_k / n_eff^2)`` (the shift law,
Goossens et al. 2019 [1]_ Eq. 3, applied to the whole curve as in Eq. 13 and Rienstra 1998
[2]_), weighted by its share of the vignetted pupil (the kernel, Eq. 37). The band-pass is
taken as not shifting: it is broad, and it is measured in front of the sensor as a whole. So
the pixel's response is::

    R_b(lambda; CRA) = S(lambda) sum_k w_k T_b(lambda / a_k)

Each ray's factor is a shift in ``u = log lambda``, so the sum is a convolution on a
log-wavelength grid (one FFT per chief-ray angle for all bands).

**A band's centre.** ``lambda_c = int R dlambda / int (R / lambda) dlambda``: the wavelength of
the response's mean wavenumber. One ray scales it by ``a_k`` exactly, and the pupil by
``E[a]``: for any shape of filter away from the band-pass's edges it moves exactly by the
kernel mean of Eq. 22, so measured and modelled filters agree where they should. Near an edge
of the band-pass it moves less, as the light that reaches the pixel does. Only the band's
main lobe counts (the contiguous part around its main peak above :data:`LOBE_FRACTION` of the
lobe's maximum, through the system at normal incidence): second orders and leaks elsewhere
would make a centre meaningless, and they are kept for what needs them (the virtual bands,
:func:`responses_behind_lens`). The corrected wavelength of a band is its nominal one times
``lambda_c(CRA) / lambda_c(normal incidence)``.

**A band's width.** The width of the part of ``R_b`` at or above half its maximum (around
the main lobe): the FWHM for a single-peaked band. Measured responses have shoulders and
double peaks, and the usual FWHM (between the outermost or the nearest half-maximum
crossings) jumps where one of them crosses half the maximum as the cone widens, by up to
23 nm for one band of a real 5x5 sensor: no table can follow that and no user can rely on it.
This width changes continuously instead.

References
----------
.. [1] T. Goossens, B. Geelen, A. Lambrechts, C. Van Hoof, "Vignetted-aperture correction for
   spectral cameras with integrated thin-film Fabry-Perot filters", Appl. Opt. 58, 1789 (2019).
.. [2] J. L. Rienstra, "Transformation of filter transmission data for f-number and chief ray
   angle", SAND98-0667C (1998).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import check_f_number, check_positive
from .bandwidth import FwhmTable, refine_nodes
from .lens import Lens
from .response import kernel_bins
from .shift import check_n_eff

__all__ = ["LOBE_FRACTION", "MeasuredTable", "common_responses", "main_lobes",
           "moved_peak_transmission", "responses_behind_lens"]

#: A band's main lobe ends where its response (through the system, at normal incidence) falls
#: below this fraction of the lobe's maximum (Flittner & Slater cut their filter profile at
#: 5 % of the peak too).
LOBE_FRACTION = 0.05
#: Log-wavelength step of the centre and width computations, as a fraction of the narrowest
#: band's FWHM (in log wavelength): 0.01 of a 3 nm band at 690 nm is 0.03 nm, for curves
#: known at 1 nm steps.
LOBE_STEP_FWHM = 1 / 100
#: Most samples the bands' lobe windows take together (a few hundred MiB across the arrays
#: made from them); real responses take a few tens of thousands.
LOBE_SAMPLES_MAX = 2**23
#: The widths' interpolation tolerance is at least this fraction of the band's width at normal
#: incidence: a measured response's width, which shoulders and leaks can move by nanometres
#: within a degree, is known no better than its 1 nm samples allow.
WIDTH_TOLERANCE_FRACTION = 0.01
#: Node intervals this short (degrees) are not halved again: where a shoulder crosses half the
#: maximum the width grows as a square root, and the interpolation error over 0.02 deg there is
#: a few hundredths of a nanometre.
WIDTH_MIN_STEP_DEG = 0.02
#: Log-wavelength step of the whole responses (virtual bands): 0.1 nm at 1000 nm, a tenth of
#: the 1 nm grids of calibration files.
WHOLE_STEP = 1e-4
_REF_NM = 1000.0


def main_lobes(wavelength_nm, effective, peak_nm):
    """Each band's main lobe: from the grid point nearest its main peak, up to the local
    maximum, then out on both sides while the response stays at or above
    :data:`LOBE_FRACTION` of that maximum.

    Parameters
    ----------
    wavelength_nm : array_like, shape (n,)
        The response grid, nm.
    effective : array_like, shape (n_bands, n)
        Each band's response through the system.
    peak_nm : array_like, shape (n_bands,)
        Each band's main peak, nm.

    Returns
    -------
    lo, hi : ndarray, shape (n_bands,)
        The lobe's first and last wavelength on the grid, nm.
    """
    grid = np.asarray(wavelength_nm, float)
    eff = np.asarray(effective, float)
    lo, hi = np.empty(eff.shape[0]), np.empty(eff.shape[0])
    for b, (row, peak) in enumerate(zip(eff, np.atleast_1d(peak_nm), strict=True)):
        i = int(np.clip(np.searchsorted(grid, peak), 0, grid.size - 1))
        while i + 1 < grid.size and row[i + 1] > row[i]:  # up to the local maximum
            i += 1
        while i > 0 and row[i - 1] > row[i]:
            i -= 1
        floor = LOBE_FRACTION * row[i]
        j, k = i, i
        while j > 0 and row[j - 1] >= floor:
            j -= 1
        while k + 1 < grid.size and row[k + 1] >= floor:
            k += 1
        lo[b], hi[b] = grid[j], grid[k]
    return lo, hi


def _log_kernel(n_eff, f_number, cra_deg, lens, du):
    """The kernel as offsets ``-log a_k / du`` (>= 0, in grid steps) and weights."""
    mu, w = kernel_bins(_REF_NM, n_eff, f_number, cra_deg, lens, step_nm=du * _REF_NM)
    return -np.log1p(mu / _REF_NM) / du, w


def _spread(curves, offsets, w):
    """``R[:, i] = sum_k w_k curves[:, i + offsets_k]`` (fractional offsets split linearly
    between neighbours; zero beyond the end), by one FFT correlation for every row."""
    from scipy.signal import fftconvolve

    m0 = int(np.floor(offsets.min()))
    pos = offsets - m0
    i = np.floor(pos).astype(int)
    frac = pos - i
    kern = np.zeros(int(i.max()) + 2)
    np.add.at(kern, i, w * (1 - frac))
    np.add.at(kern, i + 1, w * frac)
    n = curves.shape[1]
    full = fftconvolve(curves, kern[None, ::-1], axes=1)
    start = kern.size - 1 + m0  # full[:, start + i] = sum_m kern[m] curves[:, i + m0 + m]
    out = np.zeros_like(curves)
    a, b = max(0, -start), min(n, full.shape[1] - start)
    out[:, a:b] = full[:, start + a:start + b]
    return out


def _groups(n_eff, n_bands):
    n = np.broadcast_to(np.asarray(check_n_eff(n_eff), float), (n_bands,))
    return [(value, np.flatnonzero(n == value)) for value in np.unique(n)]


def responses_behind_lens(responses, n_eff, f_number, cra_deg, lens: Lens, *,
                          wavelength_nm=None):
    """Every band's whole response (all its peaks, through the system) behind ``lens``.

    Parameters
    ----------
    responses : FilterResponses
        The measured curves at normal, collimated incidence and the system's.
    n_eff : float or array_like, shape (n_bands,)
        The filters' effective indices.
    f_number : float
        Nominal f-number.
    cra_deg : array_like, shape (n_cra,)
        Chief-ray angles, degrees.
    lens : Lens
    wavelength_nm : array_like, optional
        Where to evaluate the responses (default: the calibration grid).

    Returns
    -------
    ndarray, shape (n_cra, n_bands, n)
        ``S(lambda) sum_k w_k T_b(lambda / a_k)``; NaN rows at angles where no light reaches
        the pixel.
    """
    check_f_number("f_number", f_number)
    grid = responses.wavelength_nm
    out_nm = grid if wavelength_nm is None else np.asarray(wavelength_nm, float)
    u = np.arange(np.log(grid[0]), np.log(grid[-1]) + WHOLE_STEP, WHOLE_STEP)
    lam = np.exp(u)
    curves = np.stack([np.interp(lam, grid, c, left=0.0, right=0.0)
                       for c in responses.curves])
    system = np.interp(out_nm, grid, responses.system, left=0.0, right=0.0)
    cra = np.atleast_1d(np.asarray(cra_deg, float))
    out = np.full((cra.size, curves.shape[0], out_nm.size), np.nan)
    uo = np.log(out_nm)
    for value, bands in _groups(n_eff, curves.shape[0]):
        for j, c in enumerate(cra):
            try:
                offsets, w = _log_kernel(value, f_number, c, lens, WHOLE_STEP)
            except ValueError:  # the pupil is cut off: no light
                continue
            R = _spread(curves[bands], offsets, w)
            out[j, bands] = np.stack([np.interp(uo, u, r) for r in R]) * system
    return out


def _unmoved_kernel(n_eff, f_number, cra_deg, lens, du):
    """The kernel without its mean scaling: offsets of the rays ``a_k / E[a]`` (grid steps, of
    either sign) and weights. A band spread by it keeps its place at normal incidence (its
    centre, the wavelength of the mean wavenumber, moves by ``E[a]``: module docstring)."""
    offsets, w = _log_kernel(n_eff, f_number, cra_deg, lens, du)
    mean_a = float(np.exp(-offsets * du) @ w / w.sum())
    return offsets + np.log(mean_a) / du, w


def _lobe_window(responses, lam, extra_sd_nm):
    """Where each band's width is read on ``lam`` (n_bands, n): its main lobe through the
    system at normal incidence, widened by three standard deviations of the extra Gaussian."""
    peaks = np.array([p.wavelength_nm for p in responses.main_peaks()])
    lo, hi = main_lobes(responses.wavelength_nm, responses.effective, peaks)
    reach = 3.0 * extra_sd_nm
    return (lam >= (lo - reach)[:, None]) & (lam <= (hi + reach)[:, None])


def common_responses(responses, n_eff, f_number, cra_deg, lens: Lens, *, extra_var_nm2=0.0):
    """Each band as the pixel at ``cra_deg`` sees it, moved back to its place at normal
    incidence: the band's whole curve spread by that pixel's kernel without the kernel's mean
    scaling, behind the system, optionally widened further by a Gaussian::

        R*_b(lambda) = S(lambda) sum_k w_k T_b(lambda E[a] / a_k)   (* Gaussian)

    A pixel's response differs from it by the kernel's mean scaling (the band's move) and by
    the kernel's spread beyond the reference pixel's; near a band-pass edge also by how much
    of the curve the edge cuts, as the pixel's kernel moves the curve against the edge.

    Parameters
    ----------
    responses : FilterResponses
    n_eff : float or array_like, shape (n_bands,)
    f_number : float
    cra_deg : float or array_like, shape (n_bands,)
        The reference pixel's chief-ray angle, for every band or for each.
    lens : Lens
    extra_var_nm2 : float or array_like, shape (n_bands,)
        Variance of a further Gaussian widening, nm^2 (applied in log wavelength about the
        band's main peak).

    Returns
    -------
    responses_nm : ndarray, shape (n_bands, n)
        On the calibration grid.
    width_nm : ndarray, shape (n_bands,)
        Each one's width at or above half its maximum around its main lobe (the width of
        :class:`MeasuredTable`).
    """
    from scipy.ndimage import gaussian_filter1d

    check_f_number("f_number", f_number)
    grid = responses.wavelength_nm
    nb = responses.n_bands
    u = np.arange(np.log(grid[0]), np.log(grid[-1]) + WHOLE_STEP, WHOLE_STEP)
    lam = np.exp(u)
    curves = np.stack([np.interp(lam, grid, c, left=0.0, right=0.0) for c in responses.curves])
    n = np.broadcast_to(np.asarray(check_n_eff(n_eff), float), (nb,))
    cra = np.broadcast_to(np.asarray(cra_deg, float), (nb,))
    extra = np.broadcast_to(np.asarray(extra_var_nm2, float), (nb,))
    peaks = np.array([p.wavelength_nm for p in responses.main_peaks()])
    R = np.empty_like(curves)
    for key in {(float(a), float(b)) for a, b in zip(n, cra, strict=True)}:
        bands = np.flatnonzero((n == key[0]) & (cra == key[1]))
        offsets, w = _unmoved_kernel(key[0], f_number, key[1], lens, WHOLE_STEP)
        R[bands] = _spread(curves[bands], offsets, w)
    for b in np.flatnonzero(extra > 0):  # sd in log wavelength about the band's peak
        R[b] = gaussian_filter1d(R[b], np.sqrt(extra[b]) / peaks[b] / WHOLE_STEP,
                                 mode="constant")
    R *= np.interp(lam, grid, responses.system, left=0.0, right=0.0)
    width = _above_half(np.broadcast_to(lam, R.shape),
                        np.where(_lobe_window(responses, lam, np.sqrt(extra)), R, 0.0))
    return np.stack([np.interp(grid, lam, r) for r in R]), width


def moved_peak_transmission(responses, mean_scale):
    """The system's transmission, over its maximum, at each band's main peak moved by the
    kernel mean (``lambda_peak E[a]``: how a band away from the system's edges moves): where
    it is below half, the band-pass edge has passed the band's peak, and the edge, not the
    filter, shapes the band's response there.

    Parameters
    ----------
    responses : FilterResponses
    mean_scale : array_like, shape (n_cra,) or (n_cra, n_bands)
        The kernel mean's factor ``E[a] = 1 + mean_shift / cwl`` at each angle (for every band,
        or for each).

    Returns
    -------
    ndarray, shape (n_cra, n_bands)
        NaN where ``mean_scale`` is.
    """
    grid, system = responses.wavelength_nm, responses.system
    peaks = np.array([p.wavelength_nm for p in responses.main_peaks()])
    scale = np.asarray(mean_scale, float)
    moved = peaks * (scale[:, None] if scale.ndim == 1 else scale)
    out = np.interp(moved, grid, system) / system.max()
    return np.where(np.isfinite(moved), out, np.nan)


def _above_half(lam, R):
    """The width (nm) of the part of each row of ``R`` (sampled at ``lam``, piecewise
    linear) at or above half the row's maximum: the FWHM of a single-peaked curve, and a
    continuous function of the curve however many peaks it has."""
    half = 0.5 * R.max(axis=1, keepdims=True)
    r0, r1 = R[:, :-1], R[:, 1:]
    step = np.diff(lam, axis=1)
    hi, lo = np.maximum(r0, r1), np.minimum(r0, r1)
    frac = np.where(lo >= half, 1.0,
                    np.where(hi < half, 0.0,
                             (hi - half) / np.where(hi > lo, hi - lo, 1.0)))
    return (frac * step).sum(axis=1)


class _Lobes:
    """Each band's main lobe on its own log-wavelength window, ready to be spread.

    The centre needs no spread curve: with ``R(u_i) = S_i sum_k w_k L(u_i + m_k)``,
    ``int R dlambda = du sum_k w_k G1(m_k)`` and ``int R / lambda dlambda = du sum_k w_k
    G0(m_k)``, where ``G1(m) = sum_i S_i lambda_i L_{i+m}`` and ``G0(m) = sum_i S_i L_{i+m}``
    are computed once for every offset ``m`` (one FFT correlation per band). The width needs
    the curve: the whole curve over the window (cutting the lobe's tails would narrow the
    spread response by up to 0.1 nm at f/1.4), spread by one FFT per angle.
    """

    def __init__(self, responses, reach):
        from scipy.signal import fftconvolve

        grid, eff = responses.wavelength_nm, responses.effective
        peaks = np.array([p.wavelength_nm for p in responses.main_peaks()])
        lo, hi = main_lobes(grid, eff, peaks)
        fwhm = np.array([p.fwhm_nm for p in responses.main_peaks()])
        # never finer than the curves' own sampling can matter (a hundredth of their typical
        # step; not of their finest, which one step made tiny would set): a stated width far
        # below it would otherwise size these windows without bound
        typical = float(np.median(np.diff(np.log(grid))))
        self.du = max(float(np.min(np.log1p(fwhm / peaks))), typical) * LOBE_STEP_FWHM
        n = int(np.ceil((np.max(np.log(hi / lo)) + 2 * reach) / self.du)) + 2
        if n * fwhm.size > LOBE_SAMPLES_MAX:
            raise ValueError(f"the bands' main lobes (widest {np.max(hi - lo):.4g} nm) would take "
                             f"{n * fwhm.size:,} samples at a step of {LOBE_STEP_FWHM:g} of the "
                             f"narrowest FWHM ({np.min(fwhm):.4g} nm): more than "
                             f"{LOBE_SAMPLES_MAX:,}; are the responses' widths and grid in nm?")
        # window b reaches `reach` beyond its lobe on both sides: a ray scaled by
        # a >= exp(-reach) brings the lobe down to its start, and the response at the lobe's
        # end takes the curve from up to `reach` beyond it
        self.u = np.log(lo)[:, None] - reach + self.du * np.arange(n)[None, :]
        self.lam = np.exp(self.u)
        self.whole = np.stack([np.interp(x, grid, c, left=0.0, right=0.0)
                               for x, c in zip(self.lam, responses.curves, strict=True)])
        lobe = np.where((self.lam >= lo[:, None]) & (self.lam <= hi[:, None]), self.whole, 0.0)
        self.system = np.interp(self.lam, grid, responses.system, left=0.0, right=0.0)
        m = int(np.ceil(reach / self.du)) + 2
        g1 = fftconvolve(lobe, (self.system * self.lam)[:, ::-1], axes=1)[:, n - 1:n - 1 + m]
        g0 = fftconvolve(lobe, self.system[:, ::-1], axes=1)[:, n - 1:n - 1 + m]
        self.g = np.stack([g0, g1])  # (2, n_bands, m): G0, G1 at offsets 0 .. m - 1
        # the width is read where the lobe can reach: from its start scaled by the reach to
        # its end
        self.reads = self.lam <= hi[:, None]
        self.reach = reach

    def _centre(self, offsets, w, bands):
        i = np.floor(offsets).astype(int)
        frac = offsets - i
        g = self.g[:, bands]
        s = (g[:, :, i] * (1 - frac) + g[:, :, i + 1] * frac) @ w  # (2, n_bands)
        return s[1] / np.where(s[0] > 0, s[0], np.nan)

    def at(self, n_eff, f_number, cra_deg, lens):
        """Centres and widths (each ``(n_bands, n_cra)``) at the angles; NaN where no light."""
        cra = np.atleast_1d(np.asarray(cra_deg, float))
        nb = self.whole.shape[0]
        centre, width = np.full((nb, cra.size), np.nan), np.full((nb, cra.size), np.nan)
        for value, bands in _groups(n_eff, nb):
            for j, c in enumerate(cra):
                try:
                    offsets, w = _log_kernel(value, f_number, c, lens, self.du)
                except ValueError:
                    continue
                if offsets.max() + 1 >= self.g.shape[2]:
                    raise ValueError(f"rays at CRA {c:g} deg scale the filters by more than the "
                                     "window allows; this is a bug in the table's reach")
                centre[bands, j] = self._centre(offsets, w, bands)
                R = _spread(self.whole[bands], offsets, w) * self.system[bands]
                width[bands, j] = _above_half(self.lam[bands],
                                              np.where(self.reads[bands], R, 0.0))
        return centre, width

    def normal(self):
        """Centres and widths at normal, collimated incidence (the file's conditions)."""
        bands = np.arange(self.whole.shape[0])
        R = np.where(self.reads, self.whole * self.system, 0.0)
        return self._centre(np.zeros(1), np.ones(1), bands), _above_half(self.lam, R)


def _reach(n_eff, f_number, cra_max_deg, lens):
    """How far (in log wavelength) the most oblique ray at ``cra_max_deg`` scales a filter,
    with a margin: the smallest ``a`` over the bands' indices."""
    n_min = float(np.min(check_n_eff(n_eff)))
    half = np.deg2rad(float(lens.cone_angle_deg(f_number)))  # the lens's own pupil
    phi = min(np.deg2rad(float(cra_max_deg)) + half, np.pi / 2)
    a = np.sqrt(max(1e-6, 1.0 - np.sin(phi) ** 2 / n_min**2))
    return float(-np.log(a)) * 1.05 + 1e-4


@dataclass(frozen=True)
class MeasuredTable(FwhmTable):
    """Every band's centre and FWHM behind the lens for measured responses, on chief-ray-angle
    nodes fine enough for linear interpolation within the tolerances (the centres within
    ``tolerance_nm``, the widths within ``fwhm_tolerance_nm``).

    Called like :class:`~snapcorr.optics.FwhmTable` it gives the FWHMs; :meth:`scale` gives
    each band's corrected / nominal wavelength.

    Attributes
    ----------
    cra_deg : ndarray, shape (n_nodes,)
    fwhm_nm : ndarray, shape (n_bands, n_nodes)
    centre_nm : ndarray, shape (n_bands, n_nodes)
        Each band's centre (module docstring) at the nodes.
    normal_centre_nm, normal_fwhm_nm : ndarray, shape (n_bands,)
        Its centre and width at normal, collimated incidence.
    width_tolerance_nm : ndarray, shape (n_bands,)
        Each band's width tolerance: at least :data:`WIDTH_TOLERANCE_FRACTION` of its width.
    """

    centre_nm: np.ndarray = None
    normal_centre_nm: np.ndarray = None
    normal_fwhm_nm: np.ndarray = None
    width_tolerance_nm: np.ndarray = None

    @classmethod
    def build(cls, responses, n_eff, f_number, lens: Lens, *, cra_max_deg, tolerance_nm=0.01,
              fwhm_tolerance_nm=0.01, max_nodes=513):
        """Tabulate centres and FWHMs from 0 to ``cra_max_deg``.

        Parameters
        ----------
        responses : FilterResponses
        n_eff : float or array_like, shape (n_bands,)
        f_number : float
        lens : Lens
            With its vignetting circles for the vignetted model, without for the ideal one.
        cra_max_deg : float
            Largest chief-ray angle tabulated, degrees.
        tolerance_nm, fwhm_tolerance_nm : float
            Largest interpolation errors of the centres and of the widths, nm (the widths':
            at least :data:`WIDTH_TOLERANCE_FRACTION` of each band's).
        max_nodes : int

        Returns
        -------
        MeasuredTable
        """
        check_positive("tolerance_nm", tolerance_nm)
        check_positive("fwhm_tolerance_nm", fwhm_tolerance_nm)
        lobes = _Lobes(responses, _reach(n_eff, f_number, cra_max_deg, lens))
        nb = responses.n_bands
        c0, w0 = lobes.normal()

        def at(c):
            centre, fwhm = lobes.at(n_eff, f_number, c, lens)
            return np.concatenate([centre, fwhm])

        width_tol = np.maximum(float(fwhm_tolerance_nm), WIDTH_TOLERANCE_FRACTION * w0)
        tol = np.r_[np.full(nb, float(tolerance_nm)), width_tol]
        nodes, values = refine_nodes(at, f_number, lens, cra_max_deg=cra_max_deg,
                                     tolerance=tol, max_nodes=max_nodes,
                                     what="the measured responses' table",
                                     min_step_deg=WIDTH_MIN_STEP_DEG)
        return cls(nodes, values[nb:], float(np.max(width_tol)), "measured",
                   centre_nm=values[:nb], normal_centre_nm=c0, normal_fwhm_nm=w0,
                   width_tolerance_nm=width_tol)

    def scale(self, cra_deg, band):
        """Band ``band``'s centre at ``cra_deg`` divided by its centre at normal incidence:
        what its nominal wavelength is multiplied by."""
        return np.interp(cra_deg, self.cra_deg, self.centre_nm[band]) / \
            self.normal_centre_nm[band]
