"""The vignetted aperture seen from one pixel: the exit pupil cut by the vignetting circles.

All lengths in mm. A pixel at distance ``d = x tan(CRA)`` from the optical axis (Eq. 8) looks
at the exit pupil (radius ``R``, on axis, distance ``x``) through the projected vignetting
circle (radius ``P``, centre ``d_v = h tan(CRA)`` from the axis, Eq. 9). Rays at incidence
angle ``phi`` meet the pupil plane on a circle of radius ``r = x tan(phi)`` about the pixel's
foot. The functions here are the paper's, for one circle; where ``P_mm`` and ``dv_mm`` are
lists (several circles) they hand over to :mod:`snapcorr.optics.discs`. They take the
geometry in the paper's order, as :mod:`snapcorr.optics.goossens2019` does: the exit pupil's
radius ``R``, the pixel's distance ``d``, then the circles' radii ``P`` and centres ``d_v``.

References
----------
.. [1] T. Goossens et al., Appl. Opt. 58, 1789 (2019), Eq. (8)-(9), (14)-(18), (33)-(35),
   (43)-(44).
"""

from __future__ import annotations

import itertools

import numpy as np

from .._validation import MAX_VIGNETTING_CIRCLES, check_disc_count
from . import discs
from .discs import _segment, arc_half_angle, extreme_radii

__all__ = [
    "eta",
    "gamma",
    "lens_area",
    "lens_boundary_arcs",
    "max_radius_eq44",
    "max_radius_mm",
    "min_radius_mm",
    "nu",
    "overlap_area_mm2",
    "overlap_irradiance_mm2",
    "relative_irradiance",
    "vignetted_area_mm2",
]


def _check_circle_count(P_mm):
    """Refuse more circles in the list ``P_mm`` than a lens has."""
    check_disc_count("P_mm", len(P_mm), what="circles", most=MAX_VIGNETTING_CIRCLES)


def _re_arccos(num, den):
    """``Re(arccos(num / den))`` with ``den >= 0``; ``den == 0`` is the limit num/den -> +-inf."""
    num, den = np.broadcast_arrays(np.asarray(num, float), np.asarray(den, float))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # At den == 0 a point on the circle's edge counts as inside (num == 0 -> -inf -> pi).
        z = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.where(num > 0, np.inf, -np.inf))
    # Re(arccos z) = pi for z <= -1 and 0 for z >= 1 (Goossens 2019, after Eq. 15).
    return np.arccos(np.clip(z, -1.0, 1.0))


def eta(r_mm, R_mm, d_mm):
    """Half-angle of the arc of radius ``r`` about the pixel that lies in the pupil, Eq. (15).

    ``eta = Re(arccos((d^2 - R^2 + r^2) / (2 d r)))``. On axis (``d = 0``) or at ``r = 0``
    the limit is taken: ``pi`` inside the pupil, 0 outside.

    Parameters
    ----------
    r_mm : array_like
        Radius of the arc, ``x tan(phi)``, mm.
    R_mm : array_like
        Exit-pupil radius, mm.
    d_mm : array_like
        Pixel distance from the axis (Eq. 8), mm.

    Returns
    -------
    ndarray
        Radians in [0, pi], the broadcast shape.
    """
    r, d, R = (np.asarray(v, float) for v in (r_mm, d_mm, R_mm))
    return _re_arccos(d * d - R * R + r * r, 2.0 * np.abs(d) * r)


def nu(r_mm, dr_mm, P_mm, *, h_ge_x=None):
    """Arc half-angle set by the vignetting circle, Eq. (17), with ``d_r = d - d_v``.

    Eq. (17) covers both regimes: for ``h >= x`` (``d_r <= 0``) it is the half-angle cut
    off, Eq. (16); for ``h < x`` the half-angle kept. At ``d_r = 0`` (CRA = 0, or ``h == x``)
    the value is the limit from the regime's own side, so give ``h_ge_x`` there (default:
    ``d_r <= 0``).

    Parameters
    ----------
    r_mm : array_like
        Radius of the arc, ``x tan(phi)``, mm.
    dr_mm : array_like
        ``d_r = d - d_v``, mm.
    P_mm : array_like
        Vignetting-circle radius, mm.
    h_ge_x : array_like of bool, optional
        The regime, ``h >= x``.

    Returns
    -------
    ndarray
        Radians in [0, pi], the broadcast shape.
    """
    r, dr, P = (np.asarray(v, float) for v in (r_mm, dr_mm, P_mm))
    ge = (dr <= 0) if h_ge_x is None else np.asarray(h_ge_x, bool)
    # Eq. (17) with the sign of d_r moved into the numerator keeps the denominator >= 0:
    # arccos(z / sign(d_r)) = arccos(z) for d_r > 0 and pi - arccos(z) for d_r < 0.
    a = _re_arccos(dr * dr - P * P + r * r, 2.0 * np.abs(dr) * r)
    return np.where(ge, np.pi - a, a)


def gamma(r_mm, R_mm, d_mm, P_mm=None, dv_mm=None, *, h_ge_x=None):
    """Half-angle of the contributing arc, Eq. (18).

    ``max(eta - nu, 0)`` for ``h >= x`` and ``min(eta, nu)`` for ``h < x``; ``eta`` alone
    without a vignetting circle (``P_mm=None``). ``h_ge_x`` defaults to ``d_v >= d``. With
    several circles (``P_mm`` and ``dv_mm`` lists) the arc kept by all of them
    (:func:`~snapcorr.optics.discs.arc_half_angle`).

    Parameters
    ----------
    r_mm : array_like
        Radius of the arc, ``x tan(phi)``, mm.
    R_mm : array_like
        Exit-pupil radius, mm.
    d_mm : array_like
        Pixel distance from the axis (Eq. 8), mm.
    P_mm : array_like or list of array_like, optional
        Vignetting-circle radius, mm; a list for several circles. ``None``: no circle.
    dv_mm : array_like or list of array_like, optional
        Vignetting-circle centre ``h tan(CRA)`` (Eq. 9), mm; a list for several circles.
    h_ge_x : array_like of bool, optional
        The regime, ``h >= x`` (one circle only).

    Returns
    -------
    ndarray
        Radians in [0, pi], the broadcast shape.
    """
    if isinstance(P_mm, (list, tuple)):  # several circles
        _check_circle_count(P_mm)
        return arc_half_angle(r_mm, d_mm, [R_mm, *P_mm], [0.0, *dv_mm])
    e = eta(r_mm, R_mm, d_mm)
    if P_mm is None:
        return e
    d, dv = np.asarray(d_mm, float), np.asarray(dv_mm, float)
    ge = (dv >= d) if h_ge_x is None else np.asarray(h_ge_x, bool)
    n = nu(r_mm, d - dv, P_mm, h_ge_x=ge)
    return np.where(ge, np.maximum(e - n, 0.0), np.minimum(e, n))


def vignetted_area_mm2(R_mm, P_mm, dv_mm):
    """Area of the vignetted exit pupil, Eq. (33)-(35).

    ``A = P^2 (alpha - sin alpha cos alpha) + R^2 (beta - sin beta cos beta)``. With
    ``d_v = 0`` the limits of Eq. (34)-(35) give the smaller disc. With several circles
    (``P_mm`` and ``dv_mm`` lists), :func:`overlap_area_mm2` of all of them.

    Parameters
    ----------
    R_mm : array_like
        Exit-pupil radius, mm.
    P_mm : array_like or list of array_like
        Vignetting-circle radius, mm; a list for several circles.
    dv_mm : array_like or list of array_like
        Vignetting-circle centre ``h tan(CRA)`` (Eq. 9), mm; a list for several circles.

    Returns
    -------
    ndarray
        Area in mm^2, the broadcast shape.
    """
    if isinstance(P_mm, (list, tuple)):  # several circles
        _check_circle_count(P_mm)
        return overlap_area_mm2([R_mm, *P_mm], [0.0, *dv_mm])
    R, P, dv = (np.asarray(v, float) for v in (R_mm, P_mm, dv_mm))
    dv = np.abs(dv)
    alpha = _re_arccos(P * P - R * R + dv * dv, 2.0 * P * dv)
    beta = _re_arccos(R * R - P * P + dv * dv, 2.0 * R * dv)
    # d_v = 0 and P == R: both limits are 0/0; the overlap is the whole pupil.
    same = (dv == 0) & (P == R)
    alpha = np.where(same, np.pi, alpha)
    return (
        P * P * (alpha - np.sin(alpha) * np.cos(alpha))
        + R * R * (beta - np.sin(beta) * np.cos(beta)) * ~same
    )


def overlap_area_mm2(radii_mm, centers_mm):
    """Area common to several discs whose centres lie on one line.

    The exit pupil, the projected vignetting circle (centre ``h tan(CRA)``) and a pixel's own
    acceptance circle (centre ``x tan(CRA)``, pixel vignetting) all have their centres on the
    radial line through the pixel, so their intersection is symmetric about that line and its
    area is ``int 2 min_k c_k(u) du`` with ``c_k`` the half-chord of disc ``k`` at position
    ``u``. Two half-chords are equal at one ``u`` only (``r_i^2 - (u - c_i)^2`` is linear in
    ``u`` after subtracting), so between those points a single disc bounds the area, and each
    piece integrates in closed form (a circular segment). Exact for any number of discs (up
    to :data:`~snapcorr._validation.MAX_DISCS`); with two it equals Eq. (33) of Goossens et
    al. 2019.

    Parameters
    ----------
    radii_mm, centers_mm : sequence of array_like
        One radius (> 0) and one signed centre position per disc; arrays broadcast.

    Returns
    -------
    ndarray
        The common area, mm^2 (0 where the discs do not all overlap).

    Examples
    --------
    >>> float(overlap_area_mm2([1.0, 1.0], [0.0, 0.0]))  # doctest: +ELLIPSIS
    3.14159...
    >>> float(overlap_area_mm2([1.0, 2.0, 5.0], [0.0, 3.5, 0.0]))
    0.0
    """
    k = len(radii_mm)
    if k < 1 or len(centers_mm) != k:
        raise ValueError("need one centre per radius, for at least one disc")
    check_disc_count("radii_mm", k)
    both = np.broadcast_arrays(*[np.asarray(v, float) for v in (*radii_mm, *centers_mm)])
    r, c = np.asarray(both[:k]), np.asarray(both[k:])
    lo, hi = np.max(c - r, axis=0), np.min(c + r, axis=0)
    points = [lo, hi]
    # centres next to each other cross far away: u overflows to inf, taken as no crossing
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for i in range(k):
            for j in range(i + 1, k):
                u = (r[i] ** 2 - r[j] ** 2 + c[j] ** 2 - c[i] ** 2) / (2.0 * (c[j] - c[i]))
                points.append(np.clip(np.where(np.isfinite(u), u, lo), lo, hi))
    pts = np.sort(np.asarray(points), axis=0)

    def antiderivative(u, rk, ck):  # int 2 sqrt(r^2 - t^2) dt
        t = np.clip((u - ck) / rk, -1.0, 1.0)
        return rk * rk * (t * np.sqrt(1.0 - t * t) + np.arcsin(t))

    area = np.zeros(lo.shape)
    for a, b in itertools.pairwise(pts):
        mid = 0.5 * (a + b)
        chord2 = r * r - (mid - c) ** 2
        best = np.argmin(chord2, axis=0)
        rk = np.take_along_axis(r, best[None], 0)[0]
        ck = np.take_along_axis(c, best[None], 0)[0]
        area += np.where(b > a, antiderivative(b, rk, ck) - antiderivative(a, rk, ck), 0.0)
    return np.where(hi > lo, area, 0.0)[()]


#: Gauss-Legendre nodes per arc of :func:`overlap_irradiance_mm2`: its integrand is smooth
#: on each arc, and 12 nodes hold it to 1e-15 of its largest value at f/1 to f/2.8 with one
#: and two circles over tan(CRA) 0-0.7 (against 64 nodes; 8 nodes: 4e-11, 6: 3e-8).
IRRADIANCE_NODES = 12
#: The largest pupil radius and foot distance :func:`overlap_irradiance_mm2` takes, in units
#: of x: within it the result holds to 1e-8 of a quadrature over the pupil.
MAX_PUPIL_TO_DISTANCE = 1000.0
#: Most nodes :func:`overlap_irradiance_mm2` takes (64 already reach the last digit).
MAX_IRRADIANCE_NODES = 256


def overlap_irradiance_mm2(radii_mm, centers_mm, foot_mm, x_mm, *, nodes=IRRADIANCE_NODES):
    """The discs' common area weighted by ``cos^4(phi)``: the irradiance a pixel receives
    from a pupil of uniform radiance (a Lambertian disc) through it, in units of ``L / x^2``.

    A pupil element ``dA`` at ``p`` seen from the pixel (foot ``F`` on the pupil plane, at
    distance ``x``) under the angle ``phi``, ``tan^2(phi) = |p - F|^2 / x^2``, gives it
    ``L cos^4(phi) dA / x^2``. Over the discs' intersection (all centres and the foot on one
    line, :mod:`snapcorr.optics.discs`) the weight ``w(s) = (1 + s)^-2``, ``s = tan^2(phi)``,
    has the potential ``Psi(s) = (1 / 2s) int_0^s w = 1 / (2 (1 + s))``, and Green's theorem
    turns the area integral into one along the boundary's arcs, ``contour of Psi (p - F) x dp``
    (the part on the line adds nothing), each by a Gauss-Legendre rule. It tends to
    :func:`overlap_area_mm2` as ``x`` grows.

    Parameters
    ----------
    radii_mm, centers_mm : sequence of array_like
        One radius (> 0) and one signed centre position per disc along the pixel's radial
        line: the exit pupil, the projected vignetting circles.
    foot_mm : array_like
        The pixel's foot on the pupil plane, ``x tan(CRA)`` along the same line.
    x_mm : array_like
        Distance of the pupil plane from the sensor, > 0.
    nodes : int
        Gauss-Legendre nodes per arc.

    Returns
    -------
    ndarray
        ``integral of cos^4(phi) dA`` over the intersection, mm^2 (0 where the discs do not
        all overlap). Within 1e-8 of a quadrature over the pupil for a foot up to ``1000 x``
        from the axis (a CRA of 89.94 deg) and a pupil up to ``1000 x`` wide; beyond, the
        potential's contour cancels and the geometry is refused. Any larger ``x`` is
        taken (the area, as ``x`` grows).

    Raises
    ------
    ValueError
        A radius or ``x`` not finite and > 0, a centre or the foot not finite, or the pupil
        or the foot beyond :data:`MAX_PUPIL_TO_DISTANCE` times ``x``.

    Examples
    --------
    >>> round(float(overlap_irradiance_mm2([1.0], [0.0], 0.0, 1.0)), 6)  # pi / 2
    1.570796
    """
    if isinstance(nodes, bool) or not isinstance(nodes, (int, np.integer)) or not (
            1 <= nodes <= MAX_IRRADIANCE_NODES):
        raise ValueError(f"nodes must be a whole number from 1 to {MAX_IRRADIANCE_NODES}, got "
                         f"{nodes!r}")
    x = np.asarray(x_mm, float)
    _check_discs(radii_mm, centers_mm, foot_mm, x)
    # lengths in units of the first disc's radius L (no underflow however far x is), the
    # weight (1 + k |p - F|^2)^-2 with k = (L / x)^2
    L = np.asarray(radii_mm[0], float)
    k = (L / x) ** 2
    if np.any(k > MAX_PUPIL_TO_DISTANCE**2) or np.any(
            np.abs(np.asarray(foot_mm, float)) > MAX_PUPIL_TO_DISTANCE * x):
        raise ValueError(f"the pupil's radius and the foot must lie within "
                         f"{MAX_PUPIL_TO_DISTANCE:g} x of the pupil plane's distance (a "
                         "working f-number of 0.5 gives R = x); beyond, the contour cancels")
    radii = [np.asarray(r, float) / L for r in radii_mm]
    centers = [np.asarray(c, float) / L for c in centers_mm]
    F = np.asarray(foot_mm, float) / L
    b = discs.boundary(radii, centers)
    rk, ck, t_right, t_left = discs.arc_angles(b, radii, centers)
    F = np.broadcast_to(F, b.lo.shape)
    area = discs.upper_area(b, rk, t_right, t_left)
    xi, w = np.polynomial.legendre.leggauss(int(nodes))
    half = 0.5 * (t_left - t_right)
    c = np.cos(t_right[..., None] + half[..., None] * (1.0 + xi))
    e = (ck - F)[..., None]
    rr = rk[..., None]
    rec = rr * e * c  # |p - F|^2 = e^2 + r^2 + 2 r e cos(t); (p - F) x dp = r^2 + r e cos(t)
    kk = np.broadcast_to(k, b.lo.shape)
    s_ref = kk * (0.5 * (b.lo + b.hi) - F) ** 2  # a point inside: the rest small and smooth
    psi_ref = 0.5 / (1.0 + s_ref)
    psi = 2.0 * rec
    psi += e * e + rr * rr
    psi *= kk[..., None]
    psi += 1.0
    np.divide(0.5, psi, out=psi)
    psi -= psi_ref[..., None]
    rec += rr * rr
    psi *= rec
    rest = np.sum(half * (psi @ w), axis=0)
    upper = rest + 2.0 * psi_ref * area
    return (np.where(b.hi > b.lo, 2.0 * upper, 0.0) * L * L)[()]


def _check_discs(radii_mm, centers_mm, foot_mm, x):
    """Refuse discs of no number, of radii or a distance not finite and > 0, or centres or a
    foot not finite, naming the argument."""
    if len(radii_mm) == 0 or len(radii_mm) != len(centers_mm):
        raise ValueError(f"radii_mm and centers_mm must give the same number of discs, at "
                         f"least one (the pupil), got {len(radii_mm)} and {len(centers_mm)}")
    for name, values, positive in (("x_mm", [x], True), ("radii_mm", radii_mm, True),
                                   ("centers_mm", centers_mm, False),
                                   ("foot_mm", [foot_mm], False)):
        for v in values:
            v = np.asarray(v, float)
            if not np.all(np.isfinite(v)) or (positive and not np.all(v > 0)):
                raise ValueError(f"{name} must be finite" + (" and > 0" if positive else "")
                                 + f", got {v if v.size < 5 else '...'}")


def relative_irradiance(radii_mm, centers_mm, foot_mm, x_mm, *, weight="area",
                        natural=True):
    """A flat field's signal through the discs, relative to the full pupil on the axis.

    ``weight="area"`` (the paper's pupil, rays uniform per area): the common area over
    ``pi R^2`` (``R`` the first disc's radius), times ``cos^4(CRA)`` of the chief ray with
    ``natural``. ``weight="cos4"`` (a Lambertian pupil): the ``cos^4(phi)``-weighted area of
    every ray (:func:`overlap_irradiance_mm2`) over its value on the axis,
    ``pi R^2 x^2 / (x^2 + R^2)``; without ``natural``, the area fraction alone. The two
    differ where the pupil is wide: unvignetted, at a CRA of 20 deg, the Lambertian pupil
    gives 4.8 % more signal than the chief ray's cos^4 says at f/1.4 and 0.17 % at f/8 (x =
    21 mm), a difference between f-numbers no gain per pixel can take up.

    Parameters
    ----------
    radii_mm, centers_mm : sequence of array_like
        The exit pupil first (centre 0), then the projected vignetting circles, along the
        pixel's radial line.
    foot_mm : array_like
        ``x tan(CRA)``.
    x_mm : float
        Exit-pupil distance.
    weight : {"area", "cos4"}
        How the pupil weights a ray (:data:`snapcorr.optics.lens.RAY_WEIGHTS`).
    natural : bool
        Include the cos^4 fall-off (the chief ray's, or every ray's).

    Returns
    -------
    ndarray
        1 on the axis for an unvignetted pupil.
    """
    x = np.asarray(x_mm, float)
    if weight == "cos4" and natural:  # overlap_irradiance_mm2 checks the discs
        v = overlap_irradiance_mm2(radii_mm, centers_mm, foot_mm, x)
        R = np.asarray(radii_mm[0], float)
        return v * ((x * x + R * R) / (np.pi * R * R * x * x))
    _check_discs(radii_mm, centers_mm, foot_mm, x)
    R = np.asarray(radii_mm[0], float)
    if weight not in ("area", "cos4"):
        raise ValueError(f"weight must be 'area' or 'cos4', got {weight!r}")
    v = overlap_area_mm2(radii_mm, centers_mm) / (np.pi * R * R)
    if natural:
        t = np.asarray(foot_mm, float) / x
        v = v / (1.0 + t * t) ** 2
    return v


def max_radius_eq44(R_mm, d_mm, P_mm=None, dv_mm=None):
    """Largest ray radius ``r_max`` on the pupil plane as App. B Eq. (43)-(44) states it.

    ``min(R + d, P + d_r)`` for ``h < x``; for ``h >= x``, ``min(R + d, r*)`` with ``r*`` the
    radius where the pupil and vignetting circles cross, Eq. (43) (``R + d`` where they do not
    cross). It is exact whenever the vignetting circle is not wholly inside the pupil; when it
    is (``P < R`` with ``h >= x``) it over-estimates, which is harmless as an integration limit.
    :func:`max_radius_mm` is exact everywhere.

    Parameters
    ----------
    R_mm : array_like
        Exit-pupil radius, mm.
    d_mm : array_like
        Pixel distance from the axis (Eq. 8), mm.
    P_mm : array_like, optional
        Vignetting-circle radius, mm. ``None``: no circle.
    dv_mm : array_like, optional
        Vignetting-circle centre ``h tan(CRA)`` (Eq. 9), mm.

    Returns
    -------
    ndarray
        Radius in mm, the broadcast shape.
    """
    d, R = np.asarray(d_mm, float), np.asarray(R_mm, float)
    if P_mm is None:
        return R + d
    dv, P = np.asarray(dv_mm, float), np.asarray(P_mm, float)
    dr = d - dv
    with np.errstate(divide="ignore", invalid="ignore"):
        inner = (d - dr) * (d * (P * P - dr * dr) + dr * (d * d - R * R))
        rstar = np.sqrt(inner) / np.abs(d - dr)
    rstar = np.where(np.isfinite(rstar), rstar, np.inf)
    return np.where(dv > d, np.minimum(R + d, rstar), np.minimum(R + d, P + dr))


def max_radius_mm(R_mm, d_mm, P_mm=None, dv_mm=None):
    """Exact largest distance from the pixel's foot to the vignetted pupil, mm.

    The farthest point lies on the boundary (:func:`lens_boundary_arcs`): on an arc of a circle
    with centre ``c`` and radius ``rho`` the distance ``|c - d + rho e^{it}|`` is monotonic in
    ``t`` on ``[0, pi]``, so it peaks at an end of the arc. Zero where the pupil is cut off.

    Parameters
    ----------
    R_mm : array_like
        Exit-pupil radius, mm.
    d_mm : array_like
        Pixel distance from the axis (Eq. 8), mm.
    P_mm : array_like or list of array_like, optional
        Vignetting-circle radius, mm; a list for several circles. ``None``: no circle.
    dv_mm : array_like or list of array_like, optional
        Vignetting-circle centre ``h tan(CRA)`` (Eq. 9), mm; a list for several circles.

    Returns
    -------
    ndarray
        Radius in mm, the broadcast shape.
    """
    if isinstance(P_mm, (list, tuple)):  # several circles
        _check_circle_count(P_mm)
        return extreme_radii(d_mm, [R_mm, *P_mm], [0.0, *dv_mm])[1]
    d, R = np.asarray(d_mm, float), np.asarray(R_mm, float)
    if P_mm is None:
        return np.abs(d) + R
    dv, P = np.asarray(dv_mm, float), np.asarray(P_mm, float)
    flip = dv < 0
    d, dv = np.where(flip, -d, d), np.abs(dv)
    beta, alpha = lens_boundary_arcs(R, P, dv)

    def dist(c, rho, t):
        return np.hypot(c - d + rho * np.cos(t), rho * np.sin(t))

    r1 = np.where(beta > 0, np.maximum(dist(0.0, R, 0.0), dist(0.0, R, beta)), 0.0)
    r2 = np.where(alpha > 0, np.maximum(dist(dv, P, np.pi), dist(dv, P, np.pi - alpha)), 0.0)
    return np.maximum(r1, r2)


def min_radius_mm(R_mm, d_mm, P_mm=None, dv_mm=None):
    """Smallest distance from the pixel's foot to the vignetted pupil, mm (0 inside it).

    The smallest incidence angle reaching the pixel is ``arctan(r_min / x)``. Outside the
    region the nearest point is on its boundary, at an end of an arc (see
    :func:`max_radius_mm`).

    Parameters
    ----------
    R_mm : array_like
        Exit-pupil radius, mm.
    d_mm : array_like
        Pixel distance from the axis (Eq. 8), mm.
    P_mm : array_like or list of array_like, optional
        Vignetting-circle radius, mm; a list for several circles. ``None``: no circle.
    dv_mm : array_like or list of array_like, optional
        Vignetting-circle centre ``h tan(CRA)`` (Eq. 9), mm; a list for several circles.

    Returns
    -------
    ndarray
        Radius in mm, the broadcast shape.
    """
    if isinstance(P_mm, (list, tuple)):  # several circles
        _check_circle_count(P_mm)
        return extreme_radii(d_mm, [R_mm, *P_mm], [0.0, *dv_mm])[0]
    d, R = np.abs(np.asarray(d_mm, float)), np.asarray(R_mm, float)
    if P_mm is None:
        return np.maximum(d - R, 0.0)
    dv, P = np.asarray(dv_mm, float), np.asarray(P_mm, float)
    flip = dv < 0
    d = np.where(flip, -np.asarray(d_mm, float), np.asarray(d_mm, float))
    dv = np.abs(dv)
    beta, alpha = lens_boundary_arcs(R, P, dv)

    def dist(c, rho, t):
        return np.hypot(c - d + rho * np.cos(t), rho * np.sin(t))

    inf = np.inf
    r1 = np.where(beta > 0, np.minimum(dist(0.0, R, 0.0), dist(0.0, R, beta)), inf)
    r2 = np.where(alpha > 0, np.minimum(dist(dv, P, np.pi), dist(dv, P, np.pi - alpha)), inf)
    inside = (np.abs(d) <= R) & (np.abs(d - dv) <= P)
    return np.where(inside, 0.0, np.minimum(r1, r2))


def lens_boundary_arcs(rho1, rho2, v):
    """Boundary of the intersection of the pupil disc and the vignetting disc.

    The pupil is centred at 0 with radius ``rho1``, the vignetting disc at ``v >= 0`` on the
    same axis with radius ``rho2`` (``rho2 = inf`` for no vignetting). By symmetry about the
    axis the boundary is two mirrored pairs of arcs, given by their half-angles: the pupil arc
    ``|t| <= beta`` about the pupil's centre, facing the vignetting circle (polar angle ``t``
    from the +axis), and the vignetting arc ``|tau| <= alpha`` about its centre, facing the
    pupil (``tau`` from the -axis). These are the ``beta`` and ``alpha`` of Eq. (34)-(35).

    The crossing point's height comes from the triangle (``rho1``, ``rho2``, ``v``) in Heron's
    factored form, so the angles stay accurate right up to external or internal tangency, where
    the naive ``sqrt(rho1^2 - a^2)`` loses all its digits.

    Parameters
    ----------
    rho1 : array_like
        Pupil radius.
    rho2 : array_like
        Vignetting-disc radius (``inf``: none).
    v : array_like
        Distance between the centres (>= 0), in the same unit (mm, or normalised by ``x``).

    Returns
    -------
    beta, alpha : ndarray
        ``(pi, 0)``: the whole pupil; ``(0, pi)``: the whole vignetting disc; ``(0, 0)``:
        empty (fully cut off).
    """
    rho1, rho2, v = np.broadcast_arrays(*(np.asarray(a, float) for a in (rho1, rho2, v)))
    pupil_inside = v + rho1 <= rho2
    circle_inside = v + rho2 <= rho1
    apart = v >= rho1 + rho2
    crossing = ~(pupil_inside | circle_inside | apart)
    vs = np.where(crossing, v, 1.0)
    r1, r2 = np.where(crossing, rho1, 1.0), np.where(crossing, rho2, 1.0)
    heron = (r1 + r2 - vs) * (r2 + vs - r1) * (r1 + vs - r2) * (r1 + r2 + vs)
    y = np.sqrt(np.clip(heron, 0.0, None)) / (2.0 * vs)
    with np.errstate(over="ignore"):
        beta = np.arctan2(y, (r1 * r1 - r2 * r2 + vs * vs) / (2.0 * vs))
        alpha = np.arctan2(y, (r2 * r2 - r1 * r1 + vs * vs) / (2.0 * vs))
    beta = np.where(crossing, beta, np.where(pupil_inside, np.pi, 0.0))
    alpha = np.where(crossing, alpha, np.where(circle_inside & ~pupil_inside, np.pi, 0.0))
    return beta, alpha


def lens_area(rho1, rho2, beta, alpha):
    """Area of the vignetted pupil from its arcs: Eq. (33), ``R^2 seg(beta) + P^2 seg(alpha)``
    with ``seg(t) = t - sin t cos t`` evaluated without cancellation.

    Parameters
    ----------
    rho1 : array_like
        Pupil radius.
    rho2 : array_like
        Vignetting-disc radius, same unit (``inf``: none).
    beta, alpha : array_like
        The arcs' half-angles from :func:`lens_boundary_arcs`, radians.

    Returns
    -------
    ndarray
        Area in the square of the length unit.
    """
    r2 = np.where(np.isfinite(rho2), rho2, 0.0)
    return rho1 * rho1 * _segment(beta) + r2 * r2 * _segment(alpha)
