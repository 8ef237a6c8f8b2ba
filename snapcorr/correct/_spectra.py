"""The compiled per-pixel pass shared by resampling and harmonising.

Both walk every pixel's spectrum, sampled at its corrected wavelengths ``cwl_b * s(y, x,
column[b])`` (put in increasing order, :func:`sort_samples`), and give a value at each
nominal wavelength: the straight line through the samples (:mod:`snapcorr.correct.resample`),
or that line averaged with a Gaussian (:mod:`snapcorr.correct.harmonise`). A Gaussian of
zero width is the straight line itself, so one pass (:func:`spectra_pass`) serves both;
resampling runs it with ``widen=False`` (the line everywhere, :func:`line_value`, no widths
read), harmonising's direct path with each value's widening. The tabulated harmonising pass
computes its few direct values (finite spectra) from the line's kinks instead
(:func:`smoothed_line_value`), the same to 1e-9 and two to three times faster.

The helpers say ``fastmath=False`` outright: Numba compiles a function called from a
``fastmath`` one (the tabulated harmonising pass) with its caller's flags unless it sets them
itself, and the values would then depend, in the last bit, on which pass ran first.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["REACH", "cdf", "line_slopes", "line_value", "pdf", "smoothed_line_value",
           "sort_samples", "spectra_pass", "spectrum_value"]

#: The Gaussian is cut at this many standard deviations (the mass beyond: 2e-9).
REACH = 6.0
_SQRT2 = math.sqrt(2.0)
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


@numba.njit(cache=True, fastmath=False)
def pdf(z):  # pragma: no cover - compiled
    """The standard normal density."""
    return _INV_SQRT_2PI * math.exp(-0.5 * z * z)


@numba.njit(cache=True, fastmath=False)
def cdf(z):  # pragma: no cover - compiled
    """The standard normal distribution function."""
    return 0.5 * (1.0 + math.erf(z / _SQRT2))


@numba.njit(cache=True, fastmath=False)
def sort_samples(lam, d, n):  # pragma: no cover - compiled
    """Put a pixel's samples ``(lam, d)`` (first ``n``) in increasing wavelength, in place,
    and merge those at the same wavelength into their mean; returns how many remain.

    Bands whose corrected wavelengths cross (two measured filters a few nm apart that shift
    differently) are taken in the order the light has them; the usual, already increasing
    spectrum costs one comparison per band.
    """
    for i in range(1, n):  # insertion sort: linear on sorted input
        li, di = lam[i], d[i]
        j = i - 1
        while j >= 0 and lam[j] > li:
            lam[j + 1] = lam[j]
            d[j + 1] = d[j]
            j -= 1
        lam[j + 1] = li
        d[j + 1] = di
    m = 0
    i = 0
    while i < n:
        k = i + 1
        acc = d[i]
        while k < n and lam[k] == lam[i]:
            acc += d[k]
            k += 1
        lam[m] = lam[i]
        d[m] = acc / (k - i)
        m += 1
        i = k
    return m


@numba.njit(cache=True, fastmath=False, inline="always")
def line_value(lam, d, t, j0):  # pragma: no cover - compiled
    """The straight line through ``(lam, d)`` (increasing ``lam``) at ``t``, within their
    range, found from segment ``j0`` on; returns the value and the segment, the next call's
    start (``t`` increases between calls)."""
    n = lam.size
    j = j0
    while j < n - 2 and lam[j + 1] < t:
        j += 1
    u = (t - lam[j]) / (lam[j + 1] - lam[j])
    return d[j] + u * (d[j + 1] - d[j]), j


@numba.njit(cache=True, fastmath=False)
def spectrum_value(lam, d, t, sigma, j0):  # pragma: no cover - compiled
    """The straight line through ``(lam, d)`` (increasing ``lam``, held constant beyond the
    ends) averaged with a Gaussian of standard deviation ``sigma`` about ``t``; at
    ``sigma <= 0`` the line's value at ``t``. Only the segments within reach of ``t`` are
    visited, found from segment ``j0`` (``t`` increases between calls; ``sigma`` may change
    freely, the search steps back as far as a wider reach needs). Returns the value and the
    first segment in reach, the next call's start."""
    if sigma <= 0.0:
        return line_value(lam, d, t, j0)
    n = lam.size
    reach = REACH * sigma
    j = j0
    while j > 0 and lam[j] > t - reach:  # a wider Gaussian than the last call's reaches back
        j -= 1
    while j < n - 2 and lam[j + 1] < t - reach:
        j += 1
    start = j
    acc = 0.0
    if lam[0] > t - reach:
        acc += d[0] * cdf((lam[0] - t) / sigma)
    if lam[n - 1] < t + reach:
        acc += d[n - 1] * (1.0 - cdf((lam[n - 1] - t) / sigma))
    za = (lam[j] - t) / sigma
    ca, pa = cdf(za), pdf(za)
    while j < n - 1 and lam[j] <= t + reach:
        a, b = lam[j], lam[j + 1]
        zb = (b - t) / sigma
        cb, pb = cdf(zb), pdf(zb)
        mass = cb - ca
        right = ((t - a) * mass + sigma * (pa - pb)) / (b - a)
        acc += right * d[j + 1] + (mass - right) * d[j]
        ca, pa = cb, pb
        j += 1
    return acc, start


def _ramp_excess_exact(a):
    """``E[max(Z - a, 0)] - max(-a, 0)`` for a standard normal ``Z`` (even in ``a``): what a
    Gaussian average adds to a ramp whose kink is ``a`` standard deviations from the point;
    below 2e-10 beyond six. Python floats: makes the table of :func:`_ramp_excess`."""
    a = abs(a)
    return _INV_SQRT_2PI * math.exp(-0.5 * a * a) - 0.5 * a * math.erfc(a / _SQRT2)


def _ramp_excess_table(pieces=12, degree=10):
    """Polynomials (highest power first) in ``s = 2 (a - a_i) / w - 1`` for
    :func:`_ramp_excess_exact` on ``pieces`` intervals ``[a_i, a_i + w]`` over
    ``[0, REACH]``: its Chebyshev interpolant on each (1e-15 from it)."""
    from numpy.polynomial import chebyshev

    w = REACH / pieces
    table = np.empty((pieces, degree + 1))
    for i in range(pieces):
        s = chebyshev.chebpts1(degree + 1)
        f = [_ramp_excess_exact(i * w + (si + 1.0) * w / 2.0) for si in s]
        table[i] = chebyshev.cheb2poly(chebyshev.chebfit(s, f, degree))[::-1]
    return table


_RAMP_TABLE = _ramp_excess_table()
_RAMP_SCALE = _RAMP_TABLE.shape[0] / REACH


@numba.njit(cache=True, fastmath=False)
def _ramp_excess(z):  # pragma: no cover - compiled
    """:func:`_ramp_excess_exact` for ``|z| <= REACH`` (beyond: its value at ``REACH``), from
    its table: ten multiply-adds, where the formula takes an ``exp`` and an ``erfc`` (three
    times as long)."""
    a = min(abs(z), REACH)
    i = min(int(a * _RAMP_SCALE), _RAMP_TABLE.shape[0] - 1)
    s = 2.0 * (a * _RAMP_SCALE - i) - 1.0
    c = _RAMP_TABLE[i]
    r = c[0]
    for k in range(1, c.size):
        r = r * s + c[k]
    return r


@numba.njit(cache=True, fastmath=False)
def line_slopes(lam, d, slope):  # pragma: no cover - compiled
    """``slope[m]`` (``m < lam.size - 1``): the slope of the straight line through
    ``(lam, d)`` between samples ``m`` and ``m + 1``, once per spectrum for
    :func:`smoothed_line_value` (a division per sample, not two per kink it visits)."""
    for m in range(lam.size - 1):
        slope[m] = (d[m + 1] - d[m]) / (lam[m + 1] - lam[m])


@numba.njit(cache=True, fastmath=False)
def _kink(slope, n, m):  # pragma: no cover - compiled
    """The change of slope of the straight line of ``n`` samples (held constant beyond the
    ends) at sample ``m``, from its :func:`line_slopes`."""
    right = slope[m] if m < n - 1 else 0.0
    left = slope[m - 1] if m > 0 else 0.0
    return right - left


@numba.njit(cache=True, fastmath=False)
def smoothed_line_value(lam, d, slope, t, sigma, j0):  # pragma: no cover - compiled
    """:func:`spectrum_value` for finite ``d`` within the samples' range
    (``lam[0] <= t <= lam[-1]``; ``slope`` their :func:`line_slopes`), from the line's
    kinks: the line is a sum of ramps, a
    Gaussian average leaves a straight stretch as it is, so the value is the line's at ``t``
    plus, for each sample within reach, its change of slope times ``sigma`` times
    :func:`_ramp_excess` (a polynomial). Nothing transcendental, and only the kinks within
    ``REACH`` standard deviations (none where the Gaussian sees only a straight stretch),
    where :func:`spectrum_value` takes an ``erf`` and an ``exp`` at every sample it visits;
    the two agree to 1e-9 of the values (the Gaussian's mass beyond its reach, which they
    leave out differently). Returns the value and the segment of ``t``, the next call's
    start (``t`` increases between calls; the kinks are walked from it both ways, however
    the widths change)."""
    v, j = line_value(lam, d, t, j0)
    if sigma <= 0.0:
        return v, j
    n = lam.size
    reach = REACH * sigma
    acc = 0.0
    m = j
    while m >= 0 and lam[m] >= t - reach:
        acc += _kink(slope, n, m) * _ramp_excess((lam[m] - t) / sigma)
        m -= 1
    m = j + 1
    while m < n and lam[m] <= t + reach:
        acc += _kink(slope, n, m) * _ramp_excess((lam[m] - t) / sigma)
        m += 1
    return v + sigma * acc, j


@numba.njit(parallel=True, cache=True)
def spectra_pass(data, scale, column, cwl, sigma, out,
                 widen=True):  # pragma: no cover - compiled
    """``out[y, x, k]``: :func:`spectrum_value` of pixel ``(y, x)`` at ``cwl[k]`` with
    ``sigma[y, x, k]`` (any strides), NaN outside the pixel's corrected range; with
    ``widen=False`` the straight line (:func:`line_value`) everywhere, ``sigma`` not read.
    Parallel over rows."""
    ny, nx, nb = data.shape
    for y in numba.prange(ny):
        lam = np.empty(nb)
        d = np.empty(nb)
        for x in range(nx):
            for b in range(nb):
                lam[b] = cwl[b] * scale[y, x, column[b]]
                d[b] = data[y, x, b]
            m = sort_samples(lam, d, nb)
            lm, dm = lam[:m], d[:m]  # once per pixel, not per value
            j = 0
            for k in range(nb):
                t = cwl[k]
                if m < 2 or t < lam[0] or t > lam[m - 1]:
                    out[y, x, k] = np.nan
                    continue
                s = sigma[y, x, k] if widen else 0.0
                if s <= 0.0:  # resampling, or a value harmonising leaves as it is
                    out[y, x, k], j = line_value(lm, dm, t, j)
                else:
                    out[y, x, k], j = spectrum_value(lm, dm, t, s, j)
