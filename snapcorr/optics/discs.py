"""The intersection of several discs whose centres lie on one line: the vignetted exit pupil.

A pixel sees the exit pupil (radius ``R``, on the axis) through every projected vignetting
circle (radius ``P_i``, centre ``h_i tan(CRA)``, Goossens 2019 Eq. 9); its own foot
``F = x tan(CRA)`` (Eq. 8) lies on the same radial line. So the light reaching the pixel is
the intersection of discs with collinear centres: a region symmetric about that line, bounded
above by ``y(u) = min_k c_k(u)``, with ``c_k`` the half-chord of disc ``k`` at position ``u``
along the line. Two half-chords are equal at one ``u`` only, so the sorted crossings cut
``[lo, hi]`` into pieces on each of which one disc bounds the region: the upper boundary is a
chain of circular arcs. Everything here works on that chain, for any number of discs (up to
:data:`~snapcorr._validation.MAX_DISCS`, the most a lens gives); with
two discs it reduces to the arcs of Eq. (34)-(35).

All functions take ``radii`` and ``centres`` as sequences (one entry per disc) of arrays that
broadcast together; at most :data:`~snapcorr._validation.MAX_DISCS` discs (the pupil, the
circles of a lens and a pixel's acceptance circle).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._validation import check_disc_count

__all__ = [
    "Boundary",
    "arc_angles",
    "arc_half_angle",
    "boundary",
    "extreme_radii",
    "upper_area",
]


class Boundary(NamedTuple):
    """Upper boundary of the intersection, as a chain of arcs.

    ``u`` and ``y`` (shape ``(M + 1, ...)``) are the break points along the line and the
    boundary's height there (0 at both ends), increasing in ``u``; ``disc`` (``(M, ...)``) is
    the disc whose arc bounds each piece; ``lo`` and ``hi`` the region's extent along the line
    (``hi < lo``: empty).
    """

    u: np.ndarray
    y: np.ndarray
    disc: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def _stack(radii, centers):
    k = len(radii)
    if k < 1 or len(centers) != k:
        raise ValueError("need one centre per radius, for at least one disc")
    check_disc_count("radii", k)
    both = np.broadcast_arrays(*[np.asarray(v, float) for v in (*radii, *centers)])
    return np.asarray(both[:k]), np.asarray(both[k:])


def _half_chord(r, c, u):
    """``sqrt(r^2 - (u - c)^2)`` in factored form, 0 outside the disc."""
    du = u - c
    return np.sqrt(np.clip((r - du) * (r + du), 0.0, None))


def boundary(radii, centers) -> Boundary:
    """The arcs bounding the upper half of the discs' intersection.

    Break points are the ends of the region and every pairwise crossing of half-chords inside
    it. A crossing's height comes from the triangle of the two radii and the centres' distance
    in Heron's factored form, which stays accurate up to tangency; every other break point
    takes the smallest half-chord there.
    """
    r, c = _stack(radii, centers)
    k = r.shape[0]
    lo, hi = np.max(c - r, axis=0), np.min(c + r, axis=0)
    points, heights = [lo, hi], [np.zeros_like(lo), np.zeros_like(lo)]
    for i in range(k):
        for j in range(i + 1, k):
            D = np.abs(c[j] - c[i])
            Ds = np.where(D > 0, D, 1.0)
            # centres next to each other cross far away (a overflows to inf: outside)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                # distance of the crossing from c_i along the line, towards c_j
                a = (r[i] ** 2 - r[j] ** 2 + Ds * Ds) / (2.0 * Ds)
                u = c[i] + np.sign(c[j] - c[i]) * a
                heron = (r[i] + r[j] - Ds) * (r[j] + Ds - r[i]) * (r[i] + Ds - r[j]) * (
                    r[i] + r[j] + Ds)
                y = np.sqrt(np.clip(heron, 0.0, None)) / (2.0 * Ds)
            inside = (D > 0) & (u > lo) & (u < hi) & (heron > 0)
            points.append(np.where(inside, u, lo))
            heights.append(np.where(inside, y, 0.0))
    u = np.asarray(points)
    y = np.asarray(heights)
    # Where a crossing is not on the boundary another disc lies lower there.
    others = np.min([_half_chord(r[m][None], c[m][None], u) for m in range(k)], axis=0)
    y = np.where(y > 0, np.minimum(y, np.where(others < y, others, y)), 0.0)
    order = np.argsort(u, axis=0, kind="stable")
    u = np.take_along_axis(u, order, 0)
    y = np.take_along_axis(y, order, 0)
    mid = 0.5 * (u[:-1] + u[1:])
    chord2 = np.stack([(r[m] - (mid - c[m])) * (r[m] + (mid - c[m])) for m in range(k)])
    disc = np.argmin(chord2, axis=0)
    return Boundary(u, y, disc, lo, hi)


def arc_angles(b: Boundary, radii, centers):
    """For each piece: its disc's radius and centre, and the polar angles (about that centre,
    from the +line direction) of its right and left ends, ``t_right <= t_left`` in [0, pi].

    Parameters
    ----------
    b : Boundary
        From :func:`boundary` on the same discs.
    radii : sequence of array_like
        Radius of each disc (the pupil ``R``, the projected circles ``P_i``), mm.
    centers : sequence of array_like
        Each disc's centre along the line, mm; one per radius, broadcasting with them.

    Returns
    -------
    rk, ck, t_right, t_left : ndarray
        Shape ``(M, ...)``, one per piece of ``b``; lengths as given, angles in radians.
    """
    r, c = _stack(radii, centers)
    rk = np.take_along_axis(r, b.disc, 0)
    ck = np.take_along_axis(c, b.disc, 0)
    t_right = np.arctan2(b.y[1:], b.u[1:] - ck)
    t_left = np.arctan2(b.y[:-1], b.u[:-1] - ck)
    t_left = np.maximum(t_left, t_right)
    return rk, ck, t_right, t_left


def _segment(theta):
    """``theta - sin(theta) cos(theta)``, accurate for small ``theta`` (~ 2 theta^3 / 3)."""
    x = 2.0 * np.asarray(theta, float)
    small = x < 0.6
    xs = np.where(small, x, 0.0)
    x2 = xs * xs
    # x - sin x = x^3/3! - x^5/5! + ... ; the x^15 term is < 1e-16 of the first at x = 0.6.
    series = xs * x2 * (1 / 6 - x2 * (1 / 120 - x2 * (1 / 5040 - x2 * (1 / 362880 - x2 * (
        1 / 39916800 - x2 * (1 / 6227020800))))))
    return 0.5 * np.where(small, series, x - np.sin(x))


def upper_area(b: Boundary, rk, t_right, t_left):
    """Area of the upper half of the intersection: under the chord chain (trapezoids, all
    positive) plus the circular segment between each chord and its arc.

    Parameters
    ----------
    b : Boundary
        From :func:`boundary`.
    rk : ndarray
        Radius of each piece's disc, shape ``(M, ...)`` (from :func:`arc_angles`).
    t_right, t_left : ndarray
        Polar angles of each piece's ends, radians (from :func:`arc_angles`).

    Returns
    -------
    ndarray
        Area in the square of the length unit (mm^2), the discs' broadcast shape; the full
        intersection is twice it.
    """
    trap = 0.5 * (b.u[1:] - b.u[:-1]) * (b.y[1:] + b.y[:-1])
    seg = rk * rk * _segment(0.5 * (t_left - t_right))
    return np.sum(trap + seg, axis=0)


def arc_half_angle(r, F, radii, centers):
    """Half-angle of the arc of radius ``r`` about ``F`` that lies inside every disc.

    The generalisation of ``eta`` (Eq. 15) and ``gamma`` (Eq. 18) to any number of discs:
    disc ``k`` keeps the angles (from the +line direction, about ``F``) on ``[0, a_k]`` if its
    centre lies beyond ``F`` and on ``[b_k, pi]`` if before it; the arc kept by all is
    ``[max b, min a]``, symmetric about the line.

    Parameters
    ----------
    r : array_like
        Radius of the arc, mm.
    F : array_like
        Its centre along the line (the pixel's foot, Eq. 8), mm.
    radii : sequence of array_like
        Radius of each disc (the pupil ``R``, the projected circles ``P_i``), mm.
    centers : sequence of array_like
        Each disc's centre along the line, mm; one per radius, broadcasting with them.

    Returns
    -------
    ndarray
        ``min a - max b`` in radians, in [0, pi] (0: nothing kept); the broadcast shape.
    """
    rr, c = _stack(radii, centers)
    r = np.asarray(r, float)
    F = np.asarray(F, float)
    upper = np.pi
    lower = 0.0
    for k in range(rr.shape[0]):
        e = c[k] - F
        num = r * r + e * e - rr[k] * rr[k]
        den = 2.0 * r * np.abs(e)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(den > 0, num / np.where(den > 0, den, 1.0),
                         np.where(num <= 0, -np.inf, np.inf))
        ang = np.arccos(np.clip(z, -1.0, 1.0))  # half-angle kept about the centre's side
        upper = np.where(e > 0, np.minimum(upper, ang), upper)
        lower = np.where(e < 0, np.maximum(lower, np.pi - ang), lower)
        # centre at F: all of the circle (r inside) or none
        gone = (e == 0) & (num > 0)
        upper = np.where(gone, 0.0, upper)
    return np.maximum(upper - lower, 0.0)


def extreme_radii(F, radii, centers):
    """Smallest and largest distance from ``F`` (on the line) to the intersection.

    On a circular arc the distance to a point of the line is monotonic in the polar angle on
    ``[0, pi]``, so both extremes lie at break points; the smallest is 0 where ``F`` is inside.
    Both are 0 where the intersection is empty.

    Parameters
    ----------
    F : array_like
        The point along the line, mm.
    radii : sequence of array_like
        Radius of each disc (the pupil ``R``, the projected circles ``P_i``), mm.
    centers : sequence of array_like
        Each disc's centre along the line, mm; one per radius, broadcasting with them.

    Returns
    -------
    rmin, rmax : ndarray
        Distances, mm; the broadcast shape.
    """
    b = boundary(radii, centers)
    F = np.asarray(F, float)
    dist = np.hypot(b.u - F, b.y)
    empty = b.hi < b.lo
    inside = (F >= b.lo) & (F <= b.hi)
    rmin = np.where(inside | empty, 0.0, np.min(dist, axis=0))
    rmax = np.where(empty, 0.0, np.max(dist, axis=0))
    return rmin, rmax
