"""What bandwidth each pixel really has: the FWHM of a filter's whole response behind a lens.

Behind a lens a pixel's filter is seen by a cone of rays; each ray moves the filter's curve to
the blue (the shift law), so the pixel's response is the filter's curve spread over the
kernel of shifts (Goossens et al. 2019, Eq. 13, with the closed-form kernel Eq. 37). The mean
of the kernel moves the band (Eq. 22); its spread widens it, more at larger chief-ray angles
and faster f-numbers, and optical vignetting, which cuts the most oblique rays, narrows it
again (Goossens et al., "A vignetting advantage for thin-film filter arrays in hyperspectral
cameras", arXiv 2003.11983).

Each ray scales the whole curve by its factor ``a = sqrt(1 - sin^2 phi / n_eff^2)`` (as an
etalon does; to first order this is Eq. 13's shift, with the width scaled alike), so the
response is a convolution in ``log(lambda)``: ``R(log lambda) = sum_k w_k T(log lambda -
log a_k)``. :func:`response_fwhm` evaluates it on a fine grid for every band at once (one
inverse FFT per chief-ray angle; the bands' spectra are computed once, for every angle of a
:class:`FwhmTable`) and reads the FWHM off the curve: ``method="exact"``.
``method="variance"`` is the moment shortcut ``sqrt(FWHM_0^2 + 8 ln 2 var(kernel))``, exact
only for a Gaussian filter and a Gaussian kernel; the kernel is a box-like spread of shifts,
and measured against the exact curve it is off by up to 1.7 nm for a 10 nm Gaussian filter at
f/1.4 (by 0.02 nm on axis at f/2.8): use it only to rank, not to correct.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import check_f_number, check_positive, check_positive_array, validate_method
from .lens import Lens
from .profiles import FILTER_PROFILES
from .response import kernel_bins, kernel_bins_batch
from .shift import check_n_eff

__all__ = ["FWHM_METHODS", "FwhmTable", "band_profile", "kernel_log_variance", "refine_nodes",
           "response_fwhm"]

FWHM_METHODS = ("exact", "variance")
#: Grid step of the exact method, as a fraction of the narrowest band's FWHM: for smooth
#: shapes (error 5e-4 nm against a step four times finer, 10 nm bands at f/1.4), and for
#: shapes with edges (the Pi shape, a measured curve; error 0.05 nm at the coarser step).
GRID_STEP_FWHM = 1 / 100
GRID_STEP_FWHM_EDGES = 1 / 400
#: Half-width of the grid about a band's centre, in its FWHM (plus the kernel's reach).
GRID_HALF_WIDTH_FWHM = 4.0
_REF_NM = 1000.0  # kernels are computed at this wavelength and scaled (shifts scale with cwl)


def band_profile(profile, cwl_nm, fwhm_nm, n_eff):
    """The transmission curve of one band at normal incidence: a callable of wavelength (nm).

    Parameters
    ----------
    profile : str or (offset_nm, transmission)
        A name of :data:`~snapcorr.optics.FILTER_PROFILES` (``"gaussian"``, ``"airy"``,
        ``"multi_lorentzian"``, ``"pi"``), or a measured shape about the band's centre, the
        same for every band: offsets (nm, increasing) and transmissions, zero outside.
    cwl_nm : float
        Central wavelength, nm.
    fwhm_nm : float
        FWHM, nm (not used by a measured shape).
    n_eff : float
        Effective index (not used by a measured shape).

    Returns
    -------
    callable
        ``curve(wavelength_nm)`` -> transmission.
    """
    if isinstance(profile, str):
        if profile not in FILTER_PROFILES or profile == "tabulated":
            names = ", ".join(repr(p) for p in FILTER_PROFILES if p != "tabulated")
            raise ValueError(f"profile must be one of {names} or (offset_nm, transmission), "
                             f"got {profile!r}")
        curve = FILTER_PROFILES[profile](float(cwl_nm), float(fwhm_nm), float(n_eff))
        return lambda lam: curve(lam, 0.0)
    offset, trans = (np.asarray(v, float) for v in profile)
    return lambda lam: np.interp(np.asarray(lam, float) - cwl_nm, offset, trans, left=0.0,
                                 right=0.0)


def _kernel_log(n_eff, f_number, cra_deg, lens, step_nm=0.005):
    """The kernel as log-scale factors ``log a_k`` and weights (scaled from ``_REF_NM``)."""
    mu, w = kernel_bins(_REF_NM, n_eff, f_number, cra_deg, lens, step_nm=step_nm)
    return np.log1p(mu / _REF_NM), w


def kernel_log_variance(n_eff, f_number, cra_deg, lens: Lens):
    """The kernel's variance in ``log(lambda)`` at each chief-ray angle (NaN where no light).

    A band's response is its filter curve convolved with the kernel in ``log(lambda)`` (each
    ray scales the whole curve), so the response's variance there is the filter's plus this,
    whatever the filter's shape: two pixels' responses differ in variance by exactly the
    difference of their kernels' (times ``cwl^2`` in nm^2), which is what a Gaussian
    widening must add (:mod:`snapcorr.correct.harmonise`). Their FWHMs do not add so: the
    kernel is a box-like spread of shifts, and an Airy filter's core is no Gaussian.

    Parameters
    ----------
    n_eff : float
        The filters' effective index.
    f_number : float
        Nominal f-number.
    cra_deg : array_like
        Chief-ray angles, degrees.
    lens : Lens
        Exit pupil, circles and magnifications.

    Returns
    -------
    ndarray
        One variance per angle (dimensionless, in ``log(lambda)``).

    Examples
    --------
    >>> from snapcorr import Lens
    >>> v = kernel_log_variance(1.7, 1.4, [0.0, 10.0], Lens(21.0))
    >>> bool(0 < v[0] < v[1])
    True
    """
    cra = np.atleast_1d(np.asarray(cra_deg, float))
    out = np.full(cra.shape, np.nan)
    for j, kern in enumerate(_kernel_logs(n_eff, f_number, cra.ravel(), lens, step_nm=0.05)):
        if kern is not None:  # else the pupil is cut off: no light
            la, w = kern
            out.flat[j] = w @ (la - la @ w) ** 2
    return out


def _fwhm_rows(u, R):
    """FWHM (in u) of every row of ``R`` sampled at ``u``, by linear interpolation at half
    maximum between the outermost samples above it; NaN when a half-maximum is not inside."""
    half = 0.5 * R.max(axis=1, keepdims=True)
    above = R >= half
    rows = np.arange(R.shape[0])
    i = np.argmax(above, axis=1)
    j = R.shape[1] - 1 - np.argmax(above[:, ::-1], axis=1)
    ok = (i > 0) & (j < R.shape[1] - 1)
    i, j = np.clip(i, 1, R.shape[1] - 1), np.clip(j, 0, R.shape[1] - 2)
    h = half[:, 0]
    left = u[i - 1] + (h - R[rows, i - 1]) / (R[rows, i] - R[rows, i - 1]) * (u[i] - u[i - 1])
    right = u[j] + (R[rows, j] - h) / (R[rows, j] - R[rows, j + 1]) * (u[j + 1] - u[j])
    return np.where(ok, left, np.nan), np.where(ok, right, np.nan)


def response_fwhm(cwl_nm, fwhm_nm, n_eff, f_number, cra_deg, lens: Lens, *, profile="gaussian",
                  method="exact"):
    """FWHM of each band's response behind ``lens``: its filter curve spread by the kernel.

    Parameters
    ----------
    cwl_nm, fwhm_nm, n_eff : array_like, shape (n_bands,)
        Each band's central wavelength and FWHM at normal incidence (nm) and effective index
        (scalars apply to every band).
    f_number : float
    cra_deg : array_like, shape (n_cra,)
        Chief-ray angles.
    lens : Lens
    profile : str or (offset_nm, transmission)
        The filters' shape (see :func:`band_profile`).
    method : {"exact", "variance"}
        The curve's own FWHM, or the moment shortcut (module docstring).

    Returns
    -------
    ndarray, shape (n_bands, n_cra)
        FWHM in nm; NaN where no light reaches the pixel.

    Examples
    --------
    On axis at f/8 the cone is narrow and a 10 nm filter widens only a little:

    >>> from snapcorr import Lens
    >>> w = response_fwhm([700.0], [10.0], [1.8], 8.0, [0.0], Lens(21.0))
    >>> bool(10.0 < w[0, 0] < 10.05)
    True
    """
    validate_method(method, FWHM_METHODS)
    return _Bands(cwl_nm, fwhm_nm, n_eff, f_number, profile, method)(f_number, cra_deg, lens)


class _Bands:
    """The bands of :func:`response_fwhm`, checked once, with what every chief-ray angle
    shares: each band's curve on the common grid of ``log(lambda / cwl)`` and its spectrum
    (method ``"exact"``), or its own FWHM (``"variance"``). :meth:`FwhmTable.build` asks for
    the responses at many angles; the curves and their FFT are computed once for all of them.
    """

    def __init__(self, cwl_nm, fwhm_nm, n_eff, f_number, profile, method):
        cwl = np.atleast_1d(np.asarray(cwl_nm, float))
        fwhm = np.broadcast_to(np.asarray(fwhm_nm, float), cwl.shape).astype(float)
        n = np.broadcast_to(np.asarray(check_n_eff(n_eff), float), cwl.shape).astype(float)
        check_f_number("f_number", f_number)
        check_positive_array("cwl_nm", cwl, "nm")
        check_positive_array("fwhm_nm", fwhm, "nm")
        self.cwl, self.n, self.method = cwl, n, method
        rho = fwhm / cwl
        smooth = profile in ("gaussian", "airy", "multi_lorentzian")
        self.du = du = float(rho.min()) * (GRID_STEP_FWHM if smooth else GRID_STEP_FWHM_EDGES)
        self._spectra = {}  # FFT length -> rfft of every band's curve
        if method == "exact":
            reach = GRID_HALF_WIDTH_FWHM * float(rho.max())
            self.u = np.arange(-reach, reach + du, du)
            # every band's curve about its centre, on a common grid of log(lambda / cwl)
            self.curves = np.stack([band_profile(profile, c, w, k)(c * np.exp(self.u))
                                    for c, w, k in zip(cwl, fwhm, n, strict=True)])
        else:
            self.fwhm0 = np.array([_own_fwhm(profile, c, w, k)
                                   for c, w, k in zip(cwl, fwhm, n, strict=True)])

    def __call__(self, f_number, cra_deg, lens):
        """``(n_bands, n_cra)`` FWHMs (nm) at ``cra_deg``; NaN where no light arrives."""
        cwl, n = self.cwl, self.n
        cra = np.atleast_1d(np.asarray(cra_deg, float))
        out = np.full((cwl.size, cra.size), np.nan)
        for value in np.unique(n):
            bands = np.flatnonzero(n == value)
            kernels = _kernel_logs(value, f_number, cra.ravel(), lens)
            lit = [j for j, kern in enumerate(kernels) if kern is not None]
            if not lit:
                continue
            if self.method == "variance":
                for j in lit:
                    la, w = kernels[j]
                    mean = la @ w
                    var = (w @ (la - mean) ** 2) * cwl[bands] ** 2
                    out[bands, j] = np.sqrt(self.fwhm0[bands] ** 2 + 8 * np.log(2) * var)
                continue
            out[bands[:, None], lit] = self._exact(bands, [kernels[j] for j in lit])
        return out

    def _spectrum(self, size):
        got = self._spectra.get(size)
        if got is None:
            from scipy.fft import rfft

            # one length is kept: the table's angles all fit the first (or a longer) one
            self._spectra = {size: rfft(self.curves, size, axis=1)}
            got = self._spectra[size]
        return got

    def _exact(self, bands, kernels):
        """FWHMs (nm) of ``bands`` for each ``(log a_k, w_k)`` kernel: ``(n_bands, n_kernels)``.

        The curves and the kernels (each mass split linearly between its two neighbours on
        the grid) are convolved by FFT at one length that fits the longest kernel, with the
        curves' spectrum computed once for it: the same full linear convolution as
        ``fftconvolve`` per kernel, to the last few bits.
        """
        from scipy.fft import irfft, next_fast_len, rfft

        u, du = self.u, self.du
        grid = [_grid_kernel(la, w, du) for la, w in kernels]
        longest = max(kern.size for _, kern in grid)
        size = next((m for m in self._spectra if m >= u.size + longest - 1), None)
        size = size or next_fast_len(u.size + longest - 1, real=True)
        spec = self._spectrum(size)
        if bands.size != spec.shape[0]:
            spec = spec[bands]
        padded = np.zeros((len(grid), size))
        for j, (_, kern) in enumerate(grid):
            padded[j, :kern.size] = kern
        kspec = rfft(padded, axis=1)
        out = np.empty((bands.size, len(grid)))
        cwl = self.cwl[bands]
        for j, (k0, kern) in enumerate(grid):
            full = u.size + kern.size - 1  # the full convolution; beyond it only round-off
            # (not overwrite_x=True: measured four times slower with scipy 1.17)
            R = irfft(spec * kspec[j], size, axis=1)[:, :full]
            ur = u[0] + k0 * du + du * np.arange(full)
            left, right = _fwhm_rows(ur, R)
            out[:, j] = cwl * (np.exp(right) - np.exp(left))
        return out


def _grid_kernel(la, w, du):
    """The kernel on the grid of step ``du``: each mass split linearly between its two
    neighbours. Returns the first node's index ``k0`` (its position is ``k0 * du``) and the
    masses on the nodes from there."""
    k0 = int(np.floor(la.min() / du))
    pos = la / du - k0
    i = np.floor(pos).astype(np.intp)
    frac = pos - i
    # one bincount adds in the order np.add.at(kern, i, ...); np.add.at(kern, i + 1, ...) did
    kern = np.bincount(np.concatenate([i, i + 1]), np.concatenate([w * (1 - frac), w * frac]),
                       minlength=int(i.max()) + 2)
    return k0, kern


def _kernel_logs(n_eff, f_number, cra_deg, lens, step_nm=0.005):
    """:func:`_kernel_log` at every angle of ``cra_deg`` (1-D); None where no light arrives.

    The kernels of all angles in one pass (:func:`kernel_bins_batch`, the same as angle by
    angle); where the pupil is cut off at some of them, those that are lit in one pass and the
    others one by one."""
    out = [None] * cra_deg.size
    try:
        todo = np.arange(cra_deg.size)
        bins = kernel_bins_batch(_REF_NM, n_eff, f_number, cra_deg, lens, step_nm=step_nm)
    except ValueError:  # some angle is cut off (or out of range)
        try:
            todo = np.flatnonzero(lens.relative_illumination(f_number, cra_deg) > 0)
            bins = kernel_bins_batch(_REF_NM, n_eff, f_number, cra_deg[todo], lens,
                                     step_nm=step_nm)
        except ValueError:
            todo, bins = np.arange(0), []
        for j in np.setdiff1d(np.arange(cra_deg.size), todo):
            try:
                out[j] = _kernel_log(n_eff, f_number, float(cra_deg[j]), lens, step_nm)
            except ValueError:  # the pupil is cut off: no light, no response
                pass
    for j, (mu, w) in zip(todo, bins, strict=True):
        out[j] = np.log1p(mu / _REF_NM), w
    return out


def _own_fwhm(profile, cwl, fwhm, n):
    from .profiles import fwhm_of

    lam = cwl + np.linspace(-4 * fwhm, 4 * fwhm, 16001)
    return fwhm_of(lam, band_profile(profile, cwl, fwhm, n)(lam))


def refine_nodes(at, f_number, lens: Lens, *, cra_max_deg, tolerance, max_nodes=513,
                 what="the table", min_step_deg=1e-4, start_step_deg=0.5):
    """Chief-ray-angle nodes from 0 to ``cra_max_deg`` at which ``at`` is tabulated, fine
    enough that linear interpolation between them stays within ``tolerance``.

    Nodes start at most ``start_step_deg`` apart, with every onset of vignetting and three
    points just after each (where the cut cap grows as depth^(3/2) and a midpoint alone can
    miss the bend); each interval whose midpoint misses linear interpolation by more than
    half the tolerance (for any row) is halved.

    Parameters
    ----------
    at : callable
        ``at(cra_deg)`` for an array of angles -> ``(n_rows, n_angles)`` values (NaN allowed
        where no light arrives).
    f_number : float
    lens : Lens
    cra_max_deg : float
        Largest chief-ray angle tabulated, degrees (finite, >= 0).
    tolerance : float or array_like
        Largest interpolation error, one value or one per row.
    max_nodes : int
        Most nodes allowed.
    what : str
        The table's name, for the error.
    start_step_deg : float
        Largest spacing of the first nodes, degrees.
    min_step_deg : float
        Intervals this short are not halved again (a width that grows as a square root where
        a shoulder crosses half the maximum would ask for ever shorter ones).

    Returns
    -------
    nodes : ndarray, shape (n_nodes,)
    values : ndarray, shape (n_rows, n_nodes)

    Raises
    ------
    ValueError
        When ``max_nodes`` cannot reach the tolerance.
    """
    cra_max = float(cra_max_deg)
    if not (np.isfinite(cra_max) and cra_max >= 0):
        raise ValueError(f"cra_max_deg must be finite and >= 0, got {cra_max_deg!r}")
    kinks = [float(v) for v in np.atleast_1d(lens.onset_cra_deg(f_number))
             if 0 < v < cra_max] if lens.has_vignetting else []
    after = [k + d for k in kinks for d in (0.05, 0.15, 0.3) if k + d < cra_max]
    start = np.linspace(0.0, cra_max, max(9, int(np.ceil(cra_max / start_step_deg)) + 1))
    nodes = np.unique(np.concatenate([start, kinks, after]))
    values = at(nodes)
    tol = np.broadcast_to(np.asarray(tolerance, float), values.shape[:1])
    pending = [(nodes[k], nodes[k + 1], values[:, k], values[:, k + 1])
               for k in range(nodes.size - 1)]
    got_c, got_v = list(nodes), list(values.T)
    while pending:
        mid = np.array([0.5 * (a + b) for a, b, _, _ in pending])
        vm = at(mid)
        split = []
        for k, (a, b, va, vb) in enumerate(pending):
            got_c.append(mid[k])
            got_v.append(vm[:, k])
            miss = np.abs(vm[:, k] - 0.5 * (va + vb))
            # half the tolerance at the midpoint: the worst point of an interval is not
            # always its middle
            ok = np.isfinite(miss)
            if np.any(miss[ok] > 0.5 * tol[ok]) and b - a > min_step_deg:
                split += [(a, mid[k], va, vm[:, k]), (mid[k], b, vm[:, k], vb)]
        if len(got_c) + len(split) > max_nodes:  # each pending interval adds a midpoint
            raise ValueError(f"{what} did not reach {float(np.min(tol)):g} nm with "
                             f"{max_nodes} nodes; raise the tolerance")
        pending = split
    order = np.argsort(got_c)
    return np.asarray(got_c)[order], np.asarray(got_v)[order].T


@dataclass(frozen=True)
class FwhmTable:
    """Every band's response FWHM on chief-ray-angle nodes, fine enough that linear
    interpolation between them stays within ``tolerance_nm``.

    Attributes
    ----------
    cra_deg : ndarray, shape (n_nodes,)
    fwhm_nm : ndarray, shape (n_bands, n_nodes)
    """

    cra_deg: np.ndarray
    fwhm_nm: np.ndarray
    tolerance_nm: float
    profile: object

    @classmethod
    def build(cls, cwl_nm, fwhm_nm, n_eff, f_number, lens: Lens, *, cra_max_deg,
              profile="gaussian", tolerance_nm=0.01, max_nodes=513):
        """Nodes from 0 to ``cra_max_deg``: every onset of vignetting, then halving each
        interval whose midpoint misses linear interpolation by more than half
        ``tolerance_nm`` (for any band).

        Parameters
        ----------
        cwl_nm, fwhm_nm, n_eff : array_like, shape (n_bands,)
            Each band's central wavelength and FWHM at normal incidence (nm) and effective
            index, as for :func:`response_fwhm`.
        f_number : float
            Nominal f-number.
        lens : Lens
        cra_max_deg : float
            Largest chief-ray angle tabulated, degrees (finite, >= 0).
        profile : str or (offset_nm, transmission)
            The filters' shape (see :func:`band_profile`).
        tolerance_nm : float
            Largest error of linear interpolation between nodes, nm.
        max_nodes : int
            Most nodes allowed.

        Returns
        -------
        FwhmTable

        Raises
        ------
        ValueError
            When ``max_nodes`` cannot reach the tolerance.
        """
        check_positive("tolerance_nm", tolerance_nm)
        bands = []  # checked (and their curves computed) once, at the first angles

        def at(c):
            if not bands:
                bands.append(_Bands(cwl_nm, fwhm_nm, n_eff, f_number, profile, "exact"))
            return bands[0](f_number, c, lens)

        nodes, values = refine_nodes(at, f_number, lens, cra_max_deg=cra_max_deg,
                                     tolerance=tolerance_nm, max_nodes=max_nodes,
                                     what="the FWHM table")
        return cls(nodes, values, float(tolerance_nm), profile)

    def __call__(self, cra_deg):
        """FWHM at ``cra_deg`` (any shape) for every band: shape ``cra_deg.shape + (n_bands,)``."""
        c = np.asarray(cra_deg, float)
        i = np.clip(np.searchsorted(self.cra_deg, c, side="right") - 1, 0,
                    self.cra_deg.size - 2)
        lo, hi = self.cra_deg[i], self.cra_deg[i + 1]
        w = ((c - lo) / (hi - lo))[..., None]
        return self.fwhm_nm[:, i].transpose(*range(1, c.ndim + 1), 0) * (1 - w) + \
            self.fwhm_nm[:, i + 1].transpose(*range(1, c.ndim + 1), 0) * w
