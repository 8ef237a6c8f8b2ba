"""Measured responses harmonised: each band's value through its common response, estimated
from all the pixel's bands by Wiener matrices tabulated over the chief-ray angle
(:mod:`snapcorr.correct.harmonise` tells why measured responses are not widened)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
import xarray as xr

from .._threads import one_blas_thread
from .resample import _output_dtype, _units_of
from .wavelengths import DEFAULT_TOLERANCE_NM, relative_shift
from .widths import _kernel_variance

__all__ = ["MATCH_ALPHA", "MatchedTable", "harmonise_matched", "matched_table"]

#: real imec 4x4 VIS responses behind the paper's lens at f/2.8 (22 smooth spectra, the
#: largest difference across the field): 0.0020 here; at 1e-7 0.0018, the values' noise grown
#: to 1.8 x a band's (1.3 x here); at 1e-5 the noise falls below the bands' (0.87 x) but the
#: spectra stay up to 0.0072 apart.
MATCH_ALPHA = 1e-6
#: The Markov prior's mean (:data:`snapcorr.optics.wiener.PRIOR`) replaced by one far above
#: any reflectance: the spectrum's level is left free, so a flat spectrum is kept flat (to
#: 1e-7 rather than the 7e-5 the fitted mean gives at :data:`MATCH_ALPHA`).
MATCH_PRIOR_MEAN = 10.0
#: Interpolating the matrices linearly between chief-ray-angle nodes moves no value of a
#: typical spectrum (a level and smooth shapes, :func:`_probes`) by more than this.
MATCH_TOLERANCE = 1e-4
#: Grid points where every response and target is below this fraction of its maximum are
#: left out of the estimate (a band-pass blocks most of a calibration grid): the same
#: matrices, a few times faster.
_NEGLIGIBLE = 1e-9


class MatchedTable(NamedTuple):
    """The matrices that take a pixel's bands to the common responses, on chief-ray-angle
    nodes (:func:`matched_table`)."""

    cra_deg: np.ndarray
    matrices: np.ndarray  # (n_nodes, n_bands out, n_bands in)
    noise_gain: np.ndarray  # (n_bands,): the largest norm of each row over the nodes
    alpha: float


def _probes(grid, weights, k=8):
    """Band values of typical spectra, on which the interpolation between nodes is judged: a
    level of 0.5 and Legendre polynomials of degree 1 to ``k - 1`` of amplitude 0.3 over the
    grid (smooth shapes down to about a ``k``-th of its span), seen through ``weights``."""
    x = np.linspace(-1.0, 1.0, grid.size)
    shapes = [np.full(grid.size, 0.5)] + [0.3 * np.polynomial.legendre.Legendre.basis(d)(x)
                                          for d in range(1, k)]
    return weights @ np.stack(shapes, axis=1)


def matched_table(responses, targets, n_eff, f_number, lens, *, cra_max_deg,
                  alpha=MATCH_ALPHA, tolerance=MATCH_TOLERANCE, max_nodes=257):
    """Wiener matrices from each pixel's bands (their responses behind the lens) to the
    common responses, tabulated from 0 to ``cra_max_deg``.

    At chief-ray angle ``theta`` the matrix is ``A = g Phi s^T (s Phi s^T + alpha I)^-1``
    (Pratt & Mancill 1976; :func:`snapcorr.optics.wiener.wiener_matrix`) with ``s`` the
    bands' averaging weights behind the lens there
    (:func:`snapcorr.optics.measured.responses_behind_lens`: the whole measured curves,
    every ray scaling them, behind the system), ``g`` the targets and ``Phi`` the Markov
    prior of the virtual bands with its mean left free (:data:`MATCH_PRIOR_MEAN`). A pixel
    whose bands are the targets gets the identity; a flat spectrum stays flat.

    Parameters
    ----------
    responses : FilterResponses
    targets : ndarray, shape (n_bands, n)
        The common responses on the calibration grid (any scale: each row is normalised).
    n_eff : float or array_like, shape (n_bands,)
    f_number : float
    lens : Lens
    cra_max_deg : float
        The largest chief-ray angle tabulated, degrees.
    alpha : float
        Band noise variance (:data:`MATCH_ALPHA`).
    tolerance : float
        Largest change of a value of a typical spectrum that interpolating between nodes may
        make.
    max_nodes : int

    Returns
    -------
    MatchedTable
    """
    from ..optics.bandwidth import refine_nodes
    from ..optics.measured import responses_behind_lens
    from ..optics.wiener import markov_prior, normalised, wiener_matrix

    grid = responses.wavelength_nm
    g = normalised(grid, targets)
    eff = responses.effective
    keep = np.any(eff > _NEGLIGIBLE * eff.max(axis=1, keepdims=True), axis=0) | \
        np.any(g > _NEGLIGIBLE * g.max(axis=1, keepdims=True), axis=0)
    lo, hi = np.flatnonzero(keep)[[0, -1]]
    part = slice(max(lo - 1, 0), hi + 2)  # (the weights of a cut grid's ends are its own)
    phi = markov_prior(grid[part], mean=MATCH_PRIOR_MEAN)
    probes = _probes(grid[part], normalised(grid[part], eff[:, part]))
    g = normalised(grid[part], targets[:, part])
    found = {}

    def at(c):
        R = responses_behind_lens(responses, n_eff, f_number, c, lens)
        out = np.full((np.size(c), g.shape[0] * probes.shape[1]), np.nan)
        for j, cj in enumerate(np.atleast_1d(c)):
            if np.all(np.isfinite(R[j])):
                A = wiener_matrix(normalised(grid[part], R[j][:, part]), g, phi, alpha)
                found[float(cj)] = A
                out[j] = (A @ probes).ravel()
        return out.T

    nodes, _ = refine_nodes(at, f_number, lens, cra_max_deg=cra_max_deg,
                            tolerance=float(tolerance), max_nodes=max_nodes,
                            what="the harmonising matrices", start_step_deg=1.0)
    missing = [float(c) for c in nodes if float(c) not in found]
    if missing:
        raise ValueError(f"no light reaches pixels at CRA {missing[0]:.2f} deg through the "
                         "lens: their bands cannot be harmonised")
    mats = np.stack([found[float(c)] for c in nodes])
    return MatchedTable(nodes, mats, np.sqrt(np.max(np.sum(mats**2, axis=2), axis=0)),
                        float(alpha))


@numba.njit(parallel=True, cache=True)
def _matched(data, cra, nodes, mats, out):  # pragma: no cover - compiled
    # out[y, x, b] = row b of the matrix at band b's own chief-ray angle (a mosaic's bands sit
    # at different places), interpolated linearly between its two nodes, times the pixel's
    # bands; NaN rows give NaN
    ny, nx, nb = data.shape
    m = nodes.size
    per_band = cra.shape[2] > 1
    for y in numba.prange(ny):
        for x in range(nx):
            for b in range(nb):
                c = cra[y, x, b if per_band else 0]
                lo, hi = 0, m - 1
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if nodes[mid] <= c:
                        lo = mid
                    else:
                        hi = mid
                t = min(max((c - nodes[lo]) / (nodes[hi] - nodes[lo]), 0.0), 1.0)
                s0 = 0.0
                s1 = 0.0
                for j in range(nb):
                    d = data[y, x, j]
                    s0 += mats[lo, b, j] * d
                    s1 += mats[hi, b, j] * d
                out[y, x, b] = s0 + t * (s1 - s0) if math.isfinite(c) else math.nan


def harmonise_matched(data, cra_deg, table, *, out=None):
    """Each pixel's bands taken to the common responses by the table's matrices
    (:func:`matched_table`), each output band by its row at that band's own chief-ray angle.

    Parameters
    ----------
    data : ndarray, shape (ny, nx, nb)
        In the sensor's band order.
    cra_deg : ndarray, shape (ny, nx, nb) or (ny, nx, 1)
        Each band's (or each pixel's) chief-ray angle, degrees.
    table : MatchedTable
    out : ndarray, shape (ny, nx, nb), optional

    Returns
    -------
    ndarray
        Float32 for float32 data, else float64; NaN where a band the row draws on is NaN,
        and in the bands whose rows are NaN.
    """
    data = np.asarray(data)
    dtype = np.float32 if data.dtype == np.float32 else np.float64
    if out is None:
        out = np.empty(data.shape, dtype)
    nodes = np.ascontiguousarray(table.cra_deg, dtype=np.float64)
    if nodes.size < 2:
        raise ValueError("the harmonising matrices need at least two nodes")
    _matched(np.ascontiguousarray(data), np.ascontiguousarray(cra_deg, dtype=np.float64),
             nodes, np.ascontiguousarray(table.matrices, dtype=np.float64), out)
    return out


def _harmonised_measured(ds, cube, cra, angles, target_fwhm_nm, target, how, n_eff, sensor,
                         f, lens):
    """``harmonised`` for measured responses: each band's value through its common response
    (:func:`snapcorr.optics.measured.common_responses` at the pixel of the largest kernel
    variance in the field, ``angles`` its chief-ray angles), estimated from every band of the
    pixel by the Wiener matrix at its angle (:func:`~snapcorr.correct.harmonise.matched_table`);
    the bands the band-pass edge cuts are NaN (:func:`_edge_bands`)."""
    from ..optics.measured import common_responses
    from .harmonise import harmonise_matched, matched_table

    cwl = np.asarray(sensor.cwl_nm, float)
    kv = _kernel_variance(angles, n_eff, cwl, f, lens)
    ref = angles[np.nanargmax(np.where(np.isnan(kv), -np.inf, kv), axis=1)]
    with one_blas_thread():  # small matrices: 16 x faster on one thread (measured)
        targets, width = common_responses(sensor.responses, n_eff, f, ref, lens)
        if target_fwhm_nm is not None:  # widened until each is as wide as asked
            targets, width = _widened(sensor, n_eff, f, ref, lens, target, width)
        table = matched_table(sensor.responses, targets, n_eff, f, lens,
                              cra_max_deg=max(float(angles.max()), 1e-6))
    cut, cut_note = _edge_bands(sensor, n_eff, f, lens, angles)
    mats = table.matrices.copy()
    mats[:, cut, :] = np.nan
    table = table._replace(matrices=mats)
    dtype = _output_dtype(cube)

    def block(data, c):
        return harmonise_matched(np.asarray(data, dtype), c, table)

    cr = xr.DataArray(cra, dims=("y", "x", "c"))
    data = cube
    if cube.chunks is not None:
        data = cube.chunk({"band": -1})
        cr = cr.chunk({"y": data.chunks[0], "x": data.chunks[1], "c": -1})
    out = xr.apply_ufunc(block, data, cr, input_core_dims=[["band"], ["c"]],
                         output_core_dims=[["band"]], dask="parallelized",
                         output_dtypes=[dtype]).transpose("y", "x", "band")
    seen = ("each band's measured response as the pixel of the largest kernel variance in the "
            f"field (CRA {', '.join(f'{c:.2f}' for c in np.unique(np.round(ref, 2)))} deg) "
            "sees it, moved back to its place at normal incidence")
    if target_fwhm_nm is not None:
        seen += f", widened by a Gaussian to {how}"
    out.attrs = _measured_attrs(cube, sensor, seen, table, cut_note)
    ds["harmonised"] = out
    ds["fwhm_harmonised"] = ("band", width, {
        "units": "nm", "long_name": "FWHM of the common response of harmonised",
        "source": f"the width at or above half the maximum of {seen}"})
    return ds


def _widened(sensor, n_eff, f, ref, lens, target, width):
    """The common responses widened by Gaussians until each is ``target`` wide, within 0.001
    nm (those as wide already kept): each band's variance found by regula falsi (Illinois) on
    its width, which for a measured curve does not add in quadrature (a band the edge cuts
    widens far less)."""
    from ..optics.measured import common_responses

    def miss(var):
        out, w = common_responses(sensor.responses, n_eff, f, ref, lens, extra_var_nm2=var)
        return out, w, w - target

    need = width < target
    lo, f_lo = np.zeros(target.size), width - target
    hi = np.where(need, (target**2 - width**2) / (8 * math.log(2)) + 1e-3, 0.0)
    span = np.ptp(sensor.responses.wavelength_nm)
    while True:  # a bracket: at least as wide as asked at hi
        out, w, f_hi = miss(hi)
        short = need & (f_hi < 0)
        if not short.any():
            break
        if np.any(hi[short] > span**2):  # a Gaussian wider than the whole grid
            b = np.flatnonzero(short)[0]
            raise ValueError(f"target_fwhm_nm {target[b]:g} nm: the {sensor.cwl_nm[b]:g} nm "
                             "band's response behind the band-pass cannot be made that wide")
        hi = np.where(short, 4.0 * hi, hi)
    for _ in range(60):
        done = ~need | (np.abs(f_hi) <= 1e-3)
        if np.all(done):
            return out, w
        mid = np.where(done, hi, hi - f_hi * (hi - lo) / np.where(f_hi > f_lo, f_hi - f_lo, 1))
        out, w, f_mid = miss(mid)
        over = f_mid >= 0  # [lo, mid] brackets: mid is the new hi; else lo moves up
        f_lo = np.where(over & ~done, f_lo / 2, np.where(~over, f_mid, f_lo))  # (Illinois)
        lo = np.where(~over, mid, lo)
        hi, f_hi = np.where(over, mid, hi), np.where(over, f_mid, f_hi)
    raise ValueError("the common responses could not be widened to target_fwhm_nm; this is a "
                     "bug")


def _edge_bands(sensor, n_eff, f, lens, angles):
    """The bands whose main peak, moved by the kernel mean at some angle of the field, leaves
    the band-pass (falls where the system transmits less than ``PASSBAND_FRACTION`` of its
    maximum, the pass band of :meth:`~snapcorr.cube.responses.FilterResponses.main_peaks`):
    there the edge, not the filter, shapes the band, whose response then changes shape as
    the field moves rather than only moving and widening. A mask, and what to say of it."""
    from ..cube.responses import PASSBAND_FRACTION
    from ..optics.measured import moved_peak_transmission

    cwl = np.asarray(sensor.cwl_nm, float)
    n = np.broadcast_to(np.asarray(n_eff, float), cwl.shape)
    scale = np.empty((angles.size, cwl.size))
    for value in np.unique(n):  # the kernel mean, Eq. 22, as the wavelengths' tables give it
        scale[:, n == value] = 1.0 + relative_shift(
            value, f, angles, lens, model="vignetted", tolerance_nm=DEFAULT_TOLERANCE_NM,
            cwl_max_nm=float(cwl.max()))[:, None]
    passed = moved_peak_transmission(sensor.responses, scale)
    least = np.nanmin(np.where(np.isnan(passed), np.inf, passed), axis=0)
    cut = least < PASSBAND_FRACTION
    if not cut.any():
        return cut, ("none: every band's main peak, moved by the kernel mean, stays inside the "
                     f"band-pass (where it transmits at least {PASSBAND_FRACTION:.0%} of its "
                     "maximum) over the field")
    at = angles[np.nanargmin(np.where(np.isnan(passed), np.inf, passed), axis=0)]
    named = ", ".join(f"{cwl[b]:g} nm (the band-pass passes {least[b]:.0%} of its maximum at "
                      f"its moved peak, CRA {at[b]:.1f} deg)" for b in np.flatnonzero(cut))
    return cut, (f"{named}: NaN. The band's main peak, moved by the kernel mean, leaves the "
                 f"band-pass (below {PASSBAND_FRACTION:.0%} of its maximum) in the field: the "
                 "edge, not the filter, shapes its response there, which changes shape rather "
                 "than only moving and widening across the field, and its value rests on where "
                 "the band-pass edge sits at each angle, which the sensor file gives at normal "
                 "incidence only")


def _measured_attrs(cube, sensor, common, table, cut_note):
    """The attributes of ``harmonised`` for measured responses: how it was made, the common
    response, the bands left out, the noise, and what the bands can sample."""
    cwl = np.sort(np.asarray(sensor.cwl_nm, float))
    gaps = np.diff(cwl)
    return {**_units_of(cube),
            "long_name": f"{cube.attrs.get('long_name', cube.name or 'radiance')} through one "
                         "response per band",
            "source": "each band's value through its common response, estimated from all the "
                      "pixel's bands by the Wiener matrix for their responses behind the lens "
                      "at the band's chief-ray angle (Pratt & Mancill 1976; the sensor's "
                      "measured curves, every ray scaling the whole curve, behind the band-pass; "
                      "the Markov spectrum prior of the virtual bands with its level left free, "
                      f"band noise variance {table.alpha:g}), on {table.cra_deg.size} "
                      "chief-ray-angle nodes",
            "common_response": common,
            "not_harmonised": cut_note,
            "noise_gain": f"each value's noise is up to {np.nanmax(table.noise_gain):.2f} x a "
                          "band's (the largest norm of a matrix row)",
            "limits": f"{cwl.size} bands {gaps.min():.3g}-{gaps.max():.3g} nm apart (median "
                      f"{np.median(gaps):.3g} nm): spectra come out the same across the field "
                      "where their features are wider than about twice the gap between the "
                      f"bands around them ({2 * np.median(gaps):.3g} nm at the median gap, "
                      f"{2 * gaps.max():.3g} nm at the largest); narrower ones (the absorption "
                      "lines of a rare-earth glass) fall between the bands, which cannot sample "
                      "them, and keep differences however harmonised",
            "note": "NaN in the bands named in not_harmonised, and where a band the value "
                    "draws on is NaN"}
