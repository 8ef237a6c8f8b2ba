"""Kernel and kernel mean of a filter behind an ideal or a vignetted aperture.

The mean shift of the kernel, Eq. (22) in [1]_, is the average of the tilt shift Eq. (3) over the
(vignetted) exit pupil, weighted by area (Eq. 10-12)::

    mean = (1 / A) * integral over the vignetted pupil of Delta(phi(r)) dA.

Three ways to compute it live here:

``mean_shift_contour`` (methods ``"vignetted"`` and ``"ideal"``)
    Exact up to quadrature error. The area integral is turned into a contour integral over the
    boundary of the vignetted pupil with the divergence theorem: for a radial integrand
    ``f(r)`` about the pixel's foot ``F``, ``div(Phi(r)/r^2 (p - F)) = f(r)`` where
    ``Phi(r) = int_0^r f(rho) rho d rho``. For Eq. (3), ``Phi`` has a closed form (below). The
    boundary consists of at most two circular arcs whose end points are the crossings of the
    pupil and the vignetting circle (the ``r*`` of App. B, Eq. 43). Along a circular arc the
    integrand is an analytic, even function of the arc angle -- the square-root singularities of
    the kernel in ``lambda`` (Eq. 37) and of ``gamma(r)`` never appear -- so Gauss-Legendre
    quadrature converges geometrically: 8 nodes per arc give about 1e-8 nm at f/1.2 and
    CRA 30 deg, 16 nodes reach double precision (see ``benchmarks/``).
``mean_shift_riemann`` (method ``"riemann"``)
    The paper's own evaluation (App. B): the closed-form kernel Eq. (37) summed with a left
    Riemann sum in ``lambda`` with a 0.01 nm step between the limits of Eq. (44)-(45). Kept as
    the baseline to beat.
``mean_shift_asymptotic`` (method ``"asymptotic"``)
    Eq. (6), the small-angle mean of the ideal aperture (``theta_cone = arctan(R/x)``).

References
----------
.. [1] T. Goossens, B. Geelen, A. Lambrechts, C. Van Hoof, "Vignetted-aperture correction for
   spectral cameras with integrated thin-film Fabry-Perot filters", Appl. Opt. 58, 1789
   (2019). arXiv:1905.05848.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from .._validation import MAX_VIGNETTING_CIRCLES, check_disc_count
from . import discs
from .aperture import (
    gamma,
    lens_area,
    lens_boundary_arcs,
    max_radius_mm,
    vignetted_area_mm2,
)
from .shift import AOI_VALIDITY_DEG, check_n_eff, warn_validity

__all__ = [
    "DEFAULT_NODES",
    "RIEMANN_STEP_NM",
    "asymptotic_error_estimate_nm",
    "kernel",
    "kernel_asymptotic",
    "lambertian_potentials",
    "mean_shift_asymptotic",
    "mean_shift_contour",
    "mean_shift_riemann",
    "shift_potential",
]

#: Gauss-Legendre nodes per boundary arc used by the ``"ideal"`` and ``"vignetted"`` methods.
DEFAULT_NODES = 12
#: Axial extent (in units of x) below which a pupil counts as a point (see mean_shift_contour).
_TINY_EXTENT = 1e-9
#: Elements per block of the contour quadrature (bounds its memory to a few MB).
_CONTOUR_CHUNK = 16_384
#: Step of the paper's left Riemann sum in wavelength, nm (Goossens 2019, App. B).
RIEMANN_STEP_NM = 0.01


class PupilCutOffError(ValueError):
    """The vignetting circles cut off the whole exit pupil: no light reaches the pixel.

    ``cra_deg``, where known, holds the chief-ray angles (deg) of the inputs cut off.
    """

    def __init__(self, message, cra_deg=None):
        super().__init__(message)
        self.cra_deg = None if cra_deg is None else np.asarray(cra_deg, float)


@cache
def _gauss_legendre(n):
    x, w = np.polynomial.legendre.leggauss(int(n))
    return x, w


def _asinhc(q):
    """``asinh(q) / q``, accurate near 0."""
    small = np.abs(q) < 1e-4
    qs = np.where(small, 1.0, q)
    return np.where(small, 1.0 - q * q / 6.0, np.arcsinh(qs) / qs)


def shift_potential(s, n_eff):
    """``Psi(s) = Phi / (cwl r^2)`` for the tilt shift, in units where ``x = 1``.

    With ``s = r^2 / x^2 = tan^2(phi)`` and ``Delta(s) = -cwl (1 - sqrt(1 - s / (n^2 (1 + s))))``
    (Eq. 3), ``Phi(r) = int_0^r Delta rho d rho = -cwl x^2 E(s) / 2`` where ``E(s) = int_0^s
    (1 - sqrt((1 + a t) / (1 + t))) dt``, ``a = 1 - 1/n^2``. Its antiderivative is elementary,
    ``G(u) = sqrt(u (a u + b)) + (b / sqrt(a)) asinh(sqrt(a u / b))``, ``b = 1/n^2``,
    ``u = 1 + t``. Differences of square roots and of asinh are rewritten so that
    ``Psi = E / (2 s)`` has an absolute error of a few ulp for every ``s >= 0`` (no ``1/s``).

    Returns ``Psi`` such that ``integral of Delta dA = -cwl * contour of Psi (p - F) x dp``.
    """
    n2 = np.asarray(n_eff, float) ** 2
    a = 1.0 - 1.0 / n2
    b = 1.0 / n2
    s = np.asarray(s, float)
    # sqrt-difference: (S(1+s) - S(1)) / s with S(u) = sqrt(u (a u + b)), S(1) = 1.
    s2 = np.sqrt((1.0 + s) * (1.0 + a * s))
    dsq = (2.0 * a + b + a * s) / (1.0 + s2)
    # asinh-difference: asinh(z2) - asinh(z1) = asinh((z2^2 - z1^2) / den), z = sqrt(a u / b).
    z1sq = n2 - 1.0  # a / b
    z2 = np.sqrt(z1sq * (1.0 + s))
    den = z2 * np.sqrt(n2) + np.sqrt(z1sq) * np.sqrt(n2 + z1sq * s)
    q = z1sq * s / den
    dash = np.sqrt(a) / den * _asinhc(q)
    return 0.5 * (1.0 - dsq - dash)


def lambertian_potentials(s, n_eff):
    """``(Psi_dw, Psi_w)``: the potentials of the shift and of the weight for a Lambertian
    pupil (each ray weighted by ``cos^4(phi) = (1 + s)^-2`` per unit area), ``x = 1``.

    With ``Psi_f(s) = (1 / 2s) int_0^s f(t) dt`` (so that ``integral of f dA = contour of
    Psi_f (p - F) x dp``, as for :func:`shift_potential`): ``Psi_w = 1 / (2 (1 + s))``, and
    for ``f = delta w`` with ``delta = 1 - sqrt(1 - q)``, ``q = s / (n^2 (1 + s)) =
    sin^2(phi) / n^2``, the substitution ``tau = 1 / (1 + t)`` makes the integral elementary,
    ``int_0^s delta w dt = s / (1 + s) - (2 n^2 / 3) (1 - (1 - q)^(3/2))``, written without
    cancellation as ``n^2 q^2 (1 + 2a) / (3 (1 + a)^2)``, ``a = sqrt(1 - q)``.
    """
    n2 = np.asarray(n_eff, float) ** 2
    s = np.asarray(s, float)
    a = np.sqrt(1.0 - s / (n2 * (1.0 + s)))
    psi_dw = s * (1.0 + 2.0 * a) / (6.0 * n2 * (1.0 + s) ** 2 * (1.0 + a) ** 2)
    return psi_dw, 0.5 / (1.0 + s)


def _relative_shift(s, n):
    """``delta(s) = 1 - sqrt(1 - q)``, ``q = s / (n^2 (1 + s))``, without cancellation."""
    q = s / ((1.0 + s) * n * n)
    return q / (1.0 + np.sqrt(1.0 - q))


def _contour_sums(s, geom, s_ref, n, w, pupil):
    """The boundary sums of one arc set: ``(rest, weight)`` with ``rest`` the potential's
    integral less its reference value, and ``weight`` the Lambertian weight's (None for the
    paper's uniform pupil, whose weight integral is the area)."""
    if pupil == "paper":
        return ((shift_potential(s, n) - shift_potential(s_ref, n)) * geom) @ w, None
    psi_dw, psi_w = lambertian_potentials(s, n)
    _, psi_w_ref = lambertian_potentials(s_ref, n)
    delta_ref = _relative_shift(s_ref, n)
    return ((psi_dw - delta_ref * psi_w) * geom) @ w, ((psi_w - psi_w_ref) * geom) @ w


def _contour_mean(s_ref, n, rest, weight, upper_area, pupil):
    """The relative mean shift from the boundary sums (:func:`_contour_sums`) and the
    vignetted pupil's upper-half area."""
    if pupil == "paper":
        return -(2.0 * shift_potential(s_ref, n) + rest / upper_area)
    _, psi_w_ref = lambertian_potentials(s_ref, n)
    total = weight + 2.0 * upper_area * psi_w_ref  # the weight's integral over the upper half
    return -(_relative_shift(s_ref, n) + rest / total)


def _validate_geometry(x_mm, R_mm, d_mm, P_mm, dv_mm):
    """Broadcast and normalise by x; flip so that the vignetting circle sits at v >= 0."""
    x = np.asarray(x_mm, float)
    rho1 = np.asarray(R_mm, float) / x
    F = np.asarray(d_mm, float) / x
    if P_mm is None:
        rho2 = np.full_like(rho1, np.inf)
        v = np.zeros_like(rho1)
    else:
        rho2 = np.asarray(P_mm, float) / x
        v = np.asarray(dv_mm, float) / x
    F, rho1, rho2, v = np.broadcast_arrays(F, rho1, rho2, v)
    flip = v < 0
    return np.where(flip, -F, F), rho1, rho2, np.abs(v)


def circle_list(P_mm, dv_mm):
    """The vignetting circles as ``[(P, d_v), ...]``: none (``P_mm=None``), one (array-likes)
    or several (``P_mm`` and ``dv_mm`` lists with one entry per circle)."""
    if P_mm is None:
        return []
    if isinstance(P_mm, (list, tuple)):
        if not isinstance(dv_mm, (list, tuple)) or len(dv_mm) != len(P_mm):
            raise ValueError("give one circle centre dv_mm per radius P_mm")
        check_disc_count("P_mm", len(P_mm), what="circles", most=MAX_VIGNETTING_CIRCLES)
        return list(zip(P_mm, dv_mm, strict=True))
    return [(P_mm, dv_mm)]


def mean_shift_contour(cwl_nm, n_eff, x_mm, R_mm, d_mm, P_mm=None, dv_mm=None, *, nodes=None,
                       pupil="paper"):
    """Exact kernel mean, Eq. (22), by Gauss-Legendre on the vignetted pupil's boundary.

    Parameters
    ----------
    cwl_nm, n_eff : array_like
        Filter central wavelength (nm) and effective index.
    x_mm, R_mm, d_mm : array_like
        Exit-pupil distance, exit-pupil radius (Eq. 28) and pixel distance from the axis (Eq. 8).
    P_mm, dv_mm : array_like or list of array_like, optional
        Vignetting-circle radius and centre ``d_v = h tan(CRA)`` (Eq. 9); lists of one entry
        per circle for several circles. ``None``: ideal aperture.
    nodes : int, optional
        Gauss-Legendre nodes per arc (default :data:`DEFAULT_NODES`).
    pupil : {"paper", "lambertian", "paper-lambertian"}
        Each ray weighted by its area in the pupil plane (Eq. 22), or by ``cos^4(phi)`` per
        area (both Lambertian pupils, :data:`snapcorr.optics.lens.RAY_WEIGHTS`,
        :func:`lambertian_potentials`); the pupil's radius is ``R_mm``, as given.

    Returns
    -------
    mean : ndarray
        Mean shift in nm (<= 0).

    Raises
    ------
    PupilCutOffError
        Where the vignetting circles leave no part of the pupil.
    """
    if pupil not in ("paper", "lambertian", "paper-lambertian"):
        raise ValueError("pupil must be 'paper', 'lambertian' or 'paper-lambertian', got "
                         f"{pupil!r}")
    circles = circle_list(P_mm, dv_mm)
    if len(circles) > 1:
        return _mean_shift_discs(cwl_nm, n_eff, x_mm, R_mm, d_mm, circles, nodes, pupil)
    P_mm, dv_mm = circles[0] if circles else (None, None)
    return _mean_shift_two_discs(cwl_nm, n_eff, x_mm, R_mm, d_mm, P_mm, dv_mm, nodes, pupil)


def _cut_off(F):
    """The error for the inputs at ``F = tan(CRA)`` whose pupil is cut off, with their angles."""
    cra = np.degrees(np.arctan(np.abs(np.asarray(F, float))))
    where = (f"at CRA {cra.min():.3f} deg" if cra.min() == cra.max() else
             f"at CRA {cra.min():.3f}-{cra.max():.3f} deg")
    return PupilCutOffError(
        f"the vignetting circles cut off the whole exit pupil for {cra.size} input(s) {where}: "
        "no light reaches those pixels, so their filter shift is undefined. Restrict the "
        "chief-ray angles to below Lens.cutoff_cra_deg(f_number).", cra_deg=cra)


def _point_mean(s_mid, n):
    """Relative shift at one point (a pupil thinner than ``_TINY_EXTENT``)."""
    return -_relative_shift(s_mid, n)


def _mean_shift_two_discs(cwl_nm, n_eff, x_mm, R_mm, d_mm, P_mm, dv_mm, nodes, pupil="paper"):
    """The pupil and at most one vignetting circle: two arcs, found in closed form."""
    n = check_n_eff(n_eff)
    F, rho1, rho2, v = _validate_geometry(x_mm, R_mm, d_mm, P_mm, dv_mm)
    shape = np.broadcast_shapes(F.shape, np.shape(cwl_nm), n.shape)
    F, rho1, rho2, v, n = (np.broadcast_to(a, shape).ravel() for a in (F, rho1, rho2, v, n))
    beta, alpha = lens_boundary_arcs(rho1, rho2, v)
    area = lens_area(rho1, rho2, beta, alpha)
    if np.any(area <= 0):
        raise _cut_off(F[area <= 0])
    # Subtract the potential at a point inside the vignetted pupil (the middle of its extent
    # along the axis): the constant part integrates exactly (to 2 A Psi_ref), and the
    # remainder stays small where the boundary terms cancel -- slivers near the full cut-off
    # and pupils far smaller than their distance from the pixel's foot.
    x_mid = 0.5 * (np.maximum(-rho1, v - rho2) + np.minimum(rho1, v + rho2))
    s_ref = (x_mid - F) ** 2
    xi, w = _gauss_legendre(nodes or DEFAULT_NODES)
    r2 = np.where(np.isfinite(rho2), rho2, 0.0)
    rest, weight = np.zeros_like(F), np.zeros_like(F)
    # Arc k: centre offset e from the pixel's foot, radius rho, half-angle theta, and the sign
    # of its polar axis (the pupil arc faces +x, the vignetting arc -x).
    arcs = ((rho1, -F, beta, 1.0), (r2, v - F, alpha, -1.0))
    for lo_i in range(0, F.size, _CONTOUR_CHUNK):  # bounded memory for any input size
        sl = slice(lo_i, lo_i + _CONTOUR_CHUNK)
        for rho, e, theta, sign in arcs:
            half = 0.5 * theta[sl]
            if not np.any(half > 0):
                continue
            t = half[:, None] * (1.0 + xi)
            c, s_ = sign * np.cos(t), np.sin(t)
            rr, ee = rho[sl, None], e[sl, None]
            s = (ee + rr * c) ** 2 + (rr * s_) ** 2  # |p - F|^2, >= 0 by construction
            r_k, w_k = _contour_sums(s, rr * rr + rr * ee * c, s_ref[sl, None], n[sl, None], w,
                                     pupil)
            rest[sl] += half * r_k
            if w_k is not None:
                weight[sl] += half * w_k
    # The mirrored halves double both the integral and the area: the factor 2 cancels.
    mean = _contour_mean(s_ref, n, rest, weight, 0.5 * area, pupil)
    # A pupil (or the sliver left just before the full cut-off) thinner than _TINY_EXTENT
    # along the axis is a point for Eq. (3): its mean is the shift at its middle to ~1e-7 nm,
    # while the contour terms would cancel to their last digits.
    tiny = (np.minimum(rho1, v + rho2) - np.maximum(-rho1, v - rho2)) < _TINY_EXTENT
    if np.any(tiny):
        mean[tiny] = _point_mean(s_ref[tiny], n[tiny])
    return (np.broadcast_to(cwl_nm, shape).ravel() * mean).reshape(shape)


def _mean_shift_discs(cwl_nm, n_eff, x_mm, R_mm, d_mm, circles, nodes, pupil="paper"):
    """The pupil and several vignetting circles: the boundary is a chain of arcs
    (:func:`~snapcorr.optics.discs.boundary`), each integrated as in the two-disc case."""
    n = check_n_eff(n_eff)
    x = np.asarray(x_mm, float)
    args = [np.asarray(d_mm, float) / x, np.asarray(R_mm, float) / x]
    for P, dv in circles:
        args += [np.asarray(P, float) / x, np.asarray(dv, float) / x]
    shape = np.broadcast_shapes(*(a.shape for a in args), np.shape(cwl_nm), n.shape)
    flat = [np.broadcast_to(a, shape).ravel() for a in (*args, n)]
    F, rho = flat[0], flat[1]
    rad = [rho, *flat[2:-1:2]]
    cen = [np.zeros_like(rho), *flat[3:-1:2]]
    n = flat[-1]
    xi, w = _gauss_legendre(nodes or DEFAULT_NODES)
    mean = np.empty(F.shape)
    for lo_i in range(0, F.size, _CONTOUR_CHUNK):  # bounded memory for any input size
        sl = slice(lo_i, lo_i + _CONTOUR_CHUNK)
        radii, centers, Fs, ns = [a[sl] for a in rad], [a[sl] for a in cen], F[sl], n[sl]
        b = discs.boundary(radii, centers)
        rk, ck, t_right, t_left = discs.arc_angles(b, radii, centers)
        area = discs.upper_area(b, rk, t_right, t_left)
        if np.any(area <= 0):
            raise _cut_off(Fs[area <= 0])
        x_mid = 0.5 * (b.lo + b.hi)
        s_ref = (x_mid - Fs) ** 2
        half = 0.5 * (t_left - t_right)  # (pieces, n)
        t = t_right[..., None] + half[..., None] * (1.0 + xi)
        e = (ck - Fs)[..., None]
        rr = rk[..., None]
        c = np.cos(t)
        s = (e + rr * c) ** 2 + (rr * np.sin(t)) ** 2
        r_k, w_k = _contour_sums(s, rr * rr + rr * e * c, s_ref[:, None], ns[:, None], w,
                                 pupil)
        rest = np.sum(half * r_k, axis=0)
        weight = None if w_k is None else np.sum(half * w_k, axis=0)
        m = _contour_mean(s_ref, ns, rest, weight, area, pupil)
        tiny = (b.hi - b.lo) < _TINY_EXTENT
        if np.any(tiny):
            m[tiny] = _point_mean(s_ref[tiny], ns[tiny])
        mean[sl] = m
    return (np.broadcast_to(cwl_nm, shape).ravel() * mean).reshape(shape)


def max_aoi_deg(x_mm, R_mm, d_mm, P_mm=None, dv_mm=None):
    """Largest angle of incidence of any ray reaching the pixel, degrees (App. B limits)."""
    r = max_radius_mm(R_mm, d_mm, P_mm, dv_mm)
    return np.rad2deg(np.arctan(r / np.asarray(x_mm, float)))


def _check_validity(x_mm, R_mm, d_mm, P_mm=None, dv_mm=None, stacklevel=4):
    aoi = max_aoi_deg(x_mm, R_mm, d_mm, P_mm, dv_mm)
    if np.any(aoi > AOI_VALIDITY_DEG):
        warn_validity(float(np.max(aoi)), stacklevel=stacklevel)


def _g(lam, cwl, n2):
    """``g(lambda)`` of Eq. (38)."""
    u = lam / cwl
    return 2.0 * n2 / cwl * (1.0 + u) / (1.0 + 2.0 * n2 * u + n2 * u * u) ** 2


def _inverse_shift_tan(lam, cwl, n2):
    """``tan(Delta^-1(lambda))`` from Eq. (40), i.e. ``r / x``."""
    u = lam / cwl
    s2 = np.clip(-n2 * u * (2.0 + u), 0.0, None)  # sin^2(phi)
    return np.sqrt(s2 / np.clip(1.0 - s2, 1e-300, None))


def kernel(lam_nm, cwl_nm, n_eff, x_mm, R_mm, d_mm, P_mm=None, dv_mm=None):
    """Closed-form kernel ``K(lambda)``, Eq. (37)-(38), in 1/nm (``lambda`` = shift, <= 0).

    ``K = g(lambda) gamma(Delta^-1(lambda)) x^2 / A``; zero outside the incidence angles that
    reach the pixel. Without a vignetting circle ``gamma = eta`` and ``A = pi R^2`` (Eq. 5).

    Parameters
    ----------
    lam_nm : array_like
        Shift from ``cwl_nm`` at which to evaluate the kernel, nm (<= 0).
    cwl_nm : array_like
        Central wavelength at normal incidence, nm.
    n_eff : array_like
        Effective refractive index (> 1).
    x_mm : array_like
        Exit-pupil distance, mm.
    R_mm : array_like
        Exit-pupil radius (Eq. 28), mm.
    d_mm : array_like
        Pixel distance from the axis, ``x tan(CRA)`` (Eq. 8), mm.
    P_mm, dv_mm : array_like or list of array_like, optional
        Vignetting-circle radius and centre ``d_v = h tan(CRA)`` (Eq. 9), mm; lists of one
        entry per circle for several circles. ``None``: ideal aperture.

    Returns
    -------
    ndarray
        ``K`` in 1/nm, the arguments' broadcast shape.
    """
    n2 = check_n_eff(n_eff) ** 2
    lam = np.asarray(lam_nm, float)
    x = np.asarray(x_mm, float)
    r = x * _inverse_shift_tan(lam, cwl_nm, n2)
    if P_mm is None:
        g_ = gamma(r, R_mm, d_mm)
        A = np.pi * np.asarray(R_mm, float) ** 2
    else:
        g_ = gamma(r, R_mm, d_mm, P_mm, dv_mm)
        A = vignetted_area_mm2(R_mm, P_mm, dv_mm)
    valid = (lam <= 0) & (-(lam / cwl_nm) * (2.0 + lam / cwl_nm) * n2 < 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = _g(lam, cwl_nm, n2) * g_ * x * x / A
    return np.where(valid & np.isfinite(k), k, 0.0)


def kernel_asymptotic(lam_nm, cwl_nm, n_eff, x_mm, R_mm, d_mm, P_mm=None, dv_mm=None):
    """Small-shift approximation of the kernel, Eq. (21) (Eq. 5 without vignetting).

    Parameters
    ----------
    lam_nm : array_like
        Shift from ``cwl_nm``, nm (<= 0; the kernel is 0 above).
    cwl_nm : array_like
        Central wavelength at normal incidence, nm.
    n_eff : array_like
        Effective refractive index (> 1).
    x_mm : array_like
        Exit-pupil distance, mm.
    R_mm : array_like
        Exit-pupil radius (Eq. 28), mm.
    d_mm : array_like
        Pixel distance from the axis, ``x tan(CRA)`` (Eq. 8), mm.
    P_mm, dv_mm : array_like or list of array_like, optional
        Vignetting-circle radius and centre ``d_v = h tan(CRA)`` (Eq. 9), mm; lists of one
        entry per circle for several circles. ``None``: ideal aperture.

    Returns
    -------
    ndarray
        ``K`` in 1/nm, the arguments' broadcast shape.
    """
    n = check_n_eff(n_eff)
    lam = np.asarray(lam_nm, float)
    x = np.asarray(x_mm, float)
    phi = n * np.sqrt(np.clip(-2.0 * lam / cwl_nm, 0.0, None))
    r = x * np.tan(np.clip(phi, 0.0, np.pi / 2 - 1e-9))
    if P_mm is None:
        g_ = gamma(r, R_mm, d_mm)
        A = np.pi * np.asarray(R_mm, float) ** 2
    else:
        g_ = gamma(r, R_mm, d_mm, P_mm, dv_mm)
        A = vignetted_area_mm2(R_mm, P_mm, dv_mm)
    k = 2.0 * n * n / cwl_nm * g_ * x * x / A
    return np.where(lam <= 0, k, 0.0)


def mean_shift_riemann(
    cwl_nm,
    n_eff,
    x_mm,
    R_mm,
    d_mm,
    P_mm=None,
    dv_mm=None,
    *,
    step_nm=RIEMANN_STEP_NM,
    chunk=256,
):
    """Kernel mean by the paper's left Riemann sum in wavelength (App. B).

    ``lambda`` runs from ``lambda_min = Delta(arctan(r_max / x))`` (Eq. 44-45) to 0 in steps of
    ``step_nm``; the mean is ``sum(lambda K) / sum(K)`` (Eq. 22, first line) with ``K`` from
    Eq. (37). The cost grows with the kernel width divided by the step.

    Parameters
    ----------
    cwl_nm : array_like
        Central wavelength at normal incidence, nm.
    n_eff : array_like
        Effective refractive index (> 1).
    x_mm : array_like
        Exit-pupil distance, mm.
    R_mm : array_like
        Exit-pupil radius (Eq. 28), mm.
    d_mm : array_like
        Pixel distance from the axis, ``x tan(CRA)`` (Eq. 8), mm.
    P_mm, dv_mm : array_like or list of array_like, optional
        Vignetting-circle radius and centre ``d_v = h tan(CRA)`` (Eq. 9), mm; lists of one
        entry per circle for several circles. ``None``: ideal aperture.
    step_nm : float
        Step of the sum, nm (the paper's 0.01 nm by default).
    chunk : int
        Elements summed together (bounds the memory).

    Returns
    -------
    ndarray
        Mean shift in nm (<= 0), the arguments' broadcast shape.

    Raises
    ------
    ValueError
        Where the kernel is narrower than the step (no sample sees it).
    """
    n = check_n_eff(n_eff)
    circles = circle_list(P_mm, dv_mm)
    flat_circles = [v for c in circles for v in c]
    arrays = np.broadcast_arrays(
        *(np.asarray(a, float) for a in (cwl_nm, n, x_mm, R_mm, d_mm, *flat_circles)))
    shape = arrays[0].shape
    cwl, n, x, R, d = (a.ravel() for a in arrays[:5])
    Ps, dvs = [a.ravel() for a in arrays[5::2]], [a.ravel() for a in arrays[6::2]]

    def circle_args(sel):  # the kernel's P_mm, dv_mm for the elements sel
        if not circles:
            return None, None
        if len(circles) == 1:
            return Ps[0][sel], dvs[0][sel]
        return [P[sel] for P in Ps], [dv[sel] for dv in dvs]

    # App. B's limits; the exact r_max (equal to Eq. 44 wherever Eq. 44 holds) is also right
    # when the vignetting circle sits wholly inside the pupil.
    rmax = max_radius_mm(R, d, *circle_args(slice(None)))
    s2max = np.sin(np.arctan(rmax / x)) ** 2 / n**2
    lam_min = -cwl * s2max / (1.0 + np.sqrt(1.0 - s2max))  # Eq. (45)
    out = np.empty_like(cwl)
    # Chunks of similar kernel width keep the padding (and the baseline) honest.
    order = np.argsort(lam_min)
    for lo in range(0, cwl.size, chunk):
        sl = order[lo : lo + chunk]
        steps = int(np.ceil(np.max(-lam_min[sl]) / step_nm)) + 1
        k = np.arange(steps)
        lam = lam_min[sl, None] + k * step_nm
        inside = lam < 0
        args = [a[sl, None] for a in (cwl, n, x, R, d)]
        K = kernel(lam, *args, *circle_args((sl, None))) * inside
        norm = np.sum(K, axis=1)
        if np.any(norm <= 0):
            raise ValueError(
                f"the kernel is narrower than the Riemann step ({step_nm} nm) for "
                f"{int(np.sum(norm <= 0))} input(s) (a nearly collimated beam, or a pupil cut off "
                "by vignetting): the sum sees no sample. Goossens 2019 App. B advises Eq. (6) "
                "there; use method='auto' or 'vignetted'."
            )
        out[sl] = np.sum(lam * K, axis=1) / norm
    return out.reshape(shape)


def mean_shift_asymptotic(cwl_nm, n_eff, cone_rad, cra_rad):
    """Eq. (6): ``-cwl (theta_cone^2 / (4 n^2) + theta_CRA^2 / (2 n^2))``.

    A small-angle formula for the ideal aperture; it ignores vignetting. At f/1.4 and
    CRA 20 deg (n_eff 1.7, 700 nm) it is already 2.7 nm off the exact ideal mean.

    Parameters
    ----------
    cwl_nm : array_like
        Central wavelength at normal incidence, nm.
    n_eff : array_like
        Effective refractive index (> 1).
    cone_rad : array_like
        Cone half-angle ``theta_cone = arctan(R / x)``, radians.
    cra_rad : array_like
        Chief-ray angle, radians.

    Returns
    -------
    ndarray
        Mean shift in nm (<= 0), the arguments' broadcast shape.
    """
    n2 = check_n_eff(n_eff) ** 2
    return -np.asarray(cwl_nm, float) * (
        np.asarray(cone_rad) ** 2 / (4.0 * n2) + np.asarray(cra_rad) ** 2 / (2.0 * n2)
    )


def asymptotic_error_estimate_nm(cwl_nm, n_eff, tan_cone, tan_cra):
    """Leading (fourth-order) term of ``exact ideal mean - Eq. (6)``.

    Expanding Eq. (3) in ``s = tan^2(phi)`` and averaging over a disc of radius ``rho = R/x``
    offset by ``d = tan(CRA)`` (``E[s] = d^2 + rho^2/2``, ``E[s^2] = rho^4/3 + 2 d^2 rho^2 +
    d^4``), and ``atan^2(t) = t^2 - 2 t^4 / 3 + ...`` in Eq. (6)::

        err = -cwl [ (rho^4/6 + d^4/3) / n^2 + (1/(8 n^4) - 1/(2 n^2)) E[s^2] ]

    Sixth-order terms are neglected, so use it with a safety factor where it is small.

    Parameters
    ----------
    cwl_nm : array_like
        Central wavelength at normal incidence, nm.
    n_eff : array_like
        Effective refractive index (> 1).
    tan_cone : array_like
        ``rho = R / x``, the tangent of the cone half-angle.
    tan_cra : array_like
        ``tan(CRA) = d / x``.

    Returns
    -------
    ndarray
        The estimated error in nm (signed), the arguments' broadcast shape.
    """
    n2 = check_n_eff(n_eff) ** 2
    rho2 = np.asarray(tan_cone, float) ** 2
    d2 = np.asarray(tan_cra, float) ** 2
    es2 = rho2 * rho2 / 3.0 + 2.0 * d2 * rho2 + d2 * d2
    return -np.asarray(cwl_nm, float) * (
        (rho2 * rho2 / 6.0 + d2 * d2 / 3.0) / n2 + (1.0 / (8.0 * n2 * n2) - 0.5 / n2) * es2
    )
