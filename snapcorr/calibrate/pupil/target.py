"""The exit-pupil fit's input stage: the target's cubes checked and binned into annuli.

Before :func:`~snapcorr.calibrate.pupil.locate.locate_pupil` fits anything, its inputs are
checked and reduced here: the sensor's indices (:func:`check_modelled`), the cubes (one per
f-number, the sensor's bands), the target's spectrum (given or unknown), then the optical
centre ``(row, col)``, estimated from the fastest cube where it is not given
(:func:`estimate_target_center_rc`), and every cube's radial annuli about it
(:func:`~snapcorr.calibrate.pupil.target_model.radial_bins`), which the fit stage
(:mod:`~snapcorr.calibrate.pupil.distance`) models. :class:`FeaturelessTargetError`, raised here
for a constant spectrum and by the fit stage for a target whose shift is not seen, lives here
too.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import optimize

from ..._coords import called_from_outside, warn_x_first_return
from ..._validation import (
    check_center,  # noqa: F401 (calibrate.pupil_target re-exports it)
    check_center_rc,
    check_positive,
)
from .target_model import radial_bins

__all__ = ["FeaturelessTargetError", "check_modelled", "check_target_spectrum",
           "estimate_target_center", "estimate_target_center_rc"]

#: Cubes up to this size are read into memory once; larger ones band by band.
IN_MEMORY_BYTES = 2 << 30


class FeaturelessTargetError(ValueError):
    """The target's spectrum shows no shift over the field above the noise."""


class ImpreciseTargetError(FeaturelessTargetError):
    """The target's features cannot pin x and n_eff to the shift precision asked for
    (refused before the fit, from the predicted precision)."""


# -- the inputs ---------------------------------------------------------------------------
#: Where the sensor gives no effective index and it is fitted (two f-numbers or more), the
#: fit starts here (a thin-film filter's typical value; the fit spans 0.6-1.6 times it).
N_EFF_START = 1.7


def check_modelled(sensor, what, *, fit_n_eff=False, measured=True):
    """``sensor``'s effective indices for the target model, or a ``ValueError`` naming what
    is not modelled.

    Parameters
    ----------
    sensor : Sensor
    what : str
        What needs them, for the messages.
    fit_n_eff : bool
        The index is fitted (at two f-numbers or more): a sensor that gives none (a vendor
        file) starts from :data:`N_EFF_START`.
    measured : bool
        ``what`` models measured responses behind a band-pass (vendor files: each band's whole
        curve, :class:`~snapcorr.calibrate.pupil.measured_target.MeasuredTargetModel`); False
        refuses them.

    Returns
    -------
    ndarray, shape (n_bands,)
    """
    if sensor.responses is not None and not measured:
        raise ValueError(f"{what} models each band by the sensor's filter shape about its "
                         f"centre; the sensor {sensor.name!r} has measured responses behind a "
                         "band-pass (a vendor file), which it does not model yet "
                         "(locate_pupil with fit_n_eff does, on the command line snapcorr "
                         "pupil --fit-n-eff: fit the cubes directly)")
    if sensor.n_eff is None and fit_n_eff:
        return np.full(sensor.n_bands, N_EFF_START)
    return np.asarray(sensor.require("n_eff", what), float)


#: The fewest pixels a target cube has on each side: the optical centre is found on blocks
#: of 4 x 4 pixels, with a polynomial of degree 4 in the squared distance, which needs more
#: blocks than that across (an 8 x 8 crop ended in numpy's "zero-size array" error).
MIN_CUBE_SIDE_PX = 24

#: The most annuli the field is cut into, and the fewest: each annulus is a row of the model
#: for every band, so a count sizes the fit (1e9 asked for 7.5 GiB), and fewer than 8 cannot
#: follow the shift's growth across the field (one annulus ranked a grey patch best).
N_BINS_RANGE = (8, 4096)


def check_n_bins(n_bins):
    """``n_bins`` as an int inside :data:`N_BINS_RANGE`, or a clear ``ValueError``."""
    from ..._validation import check_integers, shown

    n = check_integers("n_bins", n_bins)
    lo, hi = N_BINS_RANGE
    if n.ndim or not lo <= int(n) <= hi:
        raise ValueError(f"n_bins must be one whole number from {lo} to {hi} (the annuli the "
                         f"field is cut into), got {shown(n_bins)}")
    return int(n)


def _check_cubes(cubes, sensor, min_side=MIN_CUBE_SIDE_PX):
    if not cubes:
        raise ValueError("give at least one cube")
    out = {}
    for f, cube in cubes.items():
        fv = check_positive("f-number", f)
        if fv in out:
            raise ValueError(f"f/{fv:g} given twice")
        if not hasattr(cube, "sizes") or not {"y", "x", "band"} <= set(cube.sizes):
            raise TypeError(f"the f/{fv:g} cube must be a cube (an xarray.DataArray with dims "
                            f"y, x and band, e.g. from read_cube), got {type(cube).__name__}")
        sensor.check_cube(cube, f"the f/{fv:g} cube", atol_nm=0.5)
        ny, nx = (int(cube.sizes[d]) for d in ("y", "x"))
        if min(ny, nx) < min_side:
            raise ValueError(f"the f/{fv:g} cube is {ny} x {nx} pixels: too few to find the "
                             f"optical centre and follow the shift across the field (at least "
                             f"{min_side} on each side; give the centre to fit smaller cubes)")
        if not bool(np.isfinite(cube).any()):
            raise ValueError(f"the f/{fv:g} cube has no finite value (every pixel NaN or "
                             "infinite): nothing to fit")
        out[fv] = cube
    return dict(sorted(out.items()))


def check_target_spectrum(wavelength_nm, values, sensor):
    """A target's spectrum (samples) checked as a fit checks it: wavelengths in nm (not
    micrometres), a curve that covers every band and its flanks (``cwl +- 2 fwhm``; nothing
    is held at its ends), not constant (:class:`FeaturelessTargetError`).

    Parameters
    ----------
    wavelength_nm, values : array_like
        The spectrum's samples.
    sensor : Sensor
        Its bands (``cwl_nm``, ``fwhm_nm``) set the range the spectrum must cover.

    Returns
    -------
    callable
        ``S(lambda_nm)``, interpolated linearly.
    """
    return _spectrum((wavelength_nm, values), sensor)[0]


def _spectrum(target, sensor):
    """The target spectrum as a callable (or None) and a description."""
    if target is None:
        return None, "unknown (solved for, the field centre as reference)"
    if callable(target):
        return target, f"given ({getattr(target, '__name__', 'a function')})"
    try:
        wl, val = (np.asarray(v, float) for v in target)
    except (TypeError, ValueError, OverflowError):
        raise ValueError("target_spectrum must be a function or (wavelength_nm, value)") from None
    from ..._validation import check_curve, check_wavelengths_nm

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
    def spectrum(lam):
        return np.interp(lam, wl, val)

    spectrum.range_nm = (float(wl[0]), float(wl[-1]))
    return spectrum, f"given ({wl.size} points, {wl[0]:g}-{wl[-1]:g} nm)"


def spectrum_short_of_the_edge(spectrum, sensor, r_max_mm, x_mm, n_eff, cone_rad, f_number):
    """What a target spectrum given as samples leaves out where the field's edge moves the
    bands, or None. A filter's curve is ``T0(lambda / s)``; ``s`` is smallest for the ray
    from the rim of the fastest cube's pupil farthest from the edge's pixel, and the bands
    respond down to ``s`` times their blue ends (2 FWHM below the bluest centre), where a
    spectrum stopping short is held at its end value. The fit hardly weighs those wings (a
    feature at 472 nm, FWHM 10 nm, depth 0.8, the spectrum cut at 476 nm where the edge asks
    for 457 nm: x 16.002 +- 0.006 mm, against 16.006 with the whole spectrum), so it is said,
    not refused."""
    rng = getattr(spectrum, "range_nm", None)
    if rng is None:
        return None
    cra = math.atan(float(r_max_mm) / float(x_mm))
    phi = math.atan(float(r_max_mm) / float(x_mm) + math.tan(float(cone_rad)))  # pupil's rim
    s = math.sqrt(max(1 - math.sin(phi) ** 2 / float(np.min(n_eff)) ** 2, 0.0))
    need = float(np.min(np.asarray(sensor.cwl_nm) - 2 * np.asarray(sensor.fwhm_nm))) * s
    if rng[0] <= need:
        return None
    return (f"the target spectrum given starts at {rng[0]:g} nm, but at the field's edge (the "
            f"chief ray at {math.degrees(cra):.1f} deg and the f/{f_number:g} cone, x = "
            f"{x_mm:.4g} mm) the bands' wings reach {need:.0f} nm, where it is held at its "
            "end value: give it down to there if it has features")


# -- the optical centre -------------------------------------------------------------------
def _block_mean(img, k):
    ny, nx = (s // k * k for s in img.shape)
    v = img[:ny, :nx].reshape(ny // k, k, nx // k, k)
    with warnings.catch_warnings():  # blocks without a finite pixel are NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(v, axis=(1, 3))


#: The centre's standard errors are also found by a delete-a-group jackknife over the blocks,
#: split into this many groups (interleaved, the same split in every band): the errors from
#: the fit's Jacobian alone hold only where the centre's cost is near quadratic over its
#: scatter, and with a band's spread over the field near its block noise it is not (the
#: scatter over noise draws ran 2-4 times the Jacobian's errors, benchmarks/README.md); the
#: larger of the two is reported.
JACKKNIFE_GROUPS = 10


def _block_groups(shape, n_groups=JACKKNIFE_GROUPS):
    """Each block's jackknife group, interleaved over the block grid (a fixed shuffle)."""
    n = int(np.prod(shape))
    order = np.random.default_rng(0).permutation(n)
    return (order % n_groups).reshape(shape)


def _jackknife_err(residuals, x, groups, scale, n_groups=JACKKNIFE_GROUPS):
    """Delete-a-group jackknife standard errors of the solver's vector ``x``: refitted from
    ``x`` without each group of blocks in turn (MINPACK's Levenberg-Marquardt, twice as quick
    here as the trust region of the fit itself, to the same tolerances: looser ones stop the
    refits short of their minima where the cost is flat, and shrink the errors)."""
    fits = []
    for g in range(n_groups):
        keep = [grp != g for grp in groups]
        try:
            sol = optimize.least_squares(lambda p, keep=keep: residuals(p, keep), x,
                                         x_scale=scale * 0.05, diff_step=1e-6, method="lm")
        except (ValueError, np.linalg.LinAlgError):
            return np.array([math.inf, math.inf])
        fits.append(sol.x)
    fits = np.asarray(fits)
    return np.sqrt((n_groups - 1) / n_groups * ((fits - fits.mean(axis=0)) ** 2).sum(axis=0))


def estimate_target_center(band_image, n_bands, rows, cols, *, start=None, n_use=12,
                           block=4, degree=4):
    """The optical centre x first, ``(cx, cy)``: the earlier form of
    :func:`estimate_target_center_rc`, which gives it row first; removed in snapcorr 0.3.

    Parameters
    ----------
    band_image, n_bands, rows, cols, n_use, block, degree
        As for :func:`estimate_target_center_rc`.
    start : (cx, cy), optional
        Where the search starts, x first (default: the middle of the cube's sensor
        positions).

    Returns
    -------
    (cx, cy), (sx, sy) : the centre and its standard errors, pixels, x first.
    """
    if called_from_outside(2):
        warn_x_first_return("estimate_target_center", "estimate_target_center_rc",
                            stacklevel=3)
    (row, col), (s_row, s_col) = estimate_target_center_rc(
        band_image, n_bands, rows, cols, start_rc=None if start is None else
        (start[1], start[0]), n_use=n_use, block=block, degree=degree)
    return (col, row), (s_col, s_row)


def estimate_target_center_rc(band_image, n_bands, rows, cols, *, start_rc=None, n_use=12,
                              block=4, degree=4):
    """The optical centre ``(row, col)`` in sensor pixels from a cube of a uniform target.

    Every band's image is a function of the distance to the centre only; the centre is where
    a polynomial in ``d^2`` (per band, solved for) fits the most informative bands best
    (``scipy.optimize.least_squares`` on the centre; the images block-averaged).

    Parameters
    ----------
    band_image : callable
        ``band_image(b)`` -> the cube's 2-D image of band ``b``.
    n_bands : int
        Number of bands.
    rows, cols : ndarray, shape (ny, nb or 1) and (nx, nb or 1)
        Sensor row and column of the cube's pixels
        (:func:`snapcorr.correct.geometry.cube_positions`).
    start_rc : (row, col), optional
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
    (row, col), (s_row, s_col) : the centre and its standard errors, pixels: the larger of
        the fit's (from its Jacobian) and a delete-a-group jackknife's over the blocks
        (:data:`JACKKNIFE_GROUPS`), which holds where the signal is near the noise.
    """
    center, errors = _center_fit(band_image, n_bands, rows, cols, start_rc, n_use, block,
                                 degree)
    return center, errors()


def _center_fit(band_image, n_bands, rows, cols, start_rc, n_use, block, degree):
    """:func:`estimate_target_center_rc`'s centre ``(row, col)`` and ``errors()``, which gives
    its standard errors on demand (the jackknife's refits cost some seconds: a caller that
    needs only the centre where it lies near skips them)."""
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
    ys, rr, cc, noise, gg = [], [], [], [], []
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
        gg.append(_block_groups(v.shape)[ok])
        ys.append(v[ok])
        rr.append(r[ok])
        cc.append(c[ok])
    scale = float(max(np.ptp(np.concatenate(rr)), np.ptp(np.concatenate(cc)), 1.0))
    # the solver's vector is (col, row), the order every fit was checked with (its steps'
    # rounding depends on it): p[0] the column, p[1] the row
    if start_rc is None:
        start = (0.5 * (cols.min() + cols.max()), 0.5 * (rows.min() + rows.max()))
    else:
        start = (start_rc[1], start_rc[0])

    def residuals(p, keep=None):
        out = []
        for i, (y, r, c, s) in enumerate(zip(ys, rr, cc, noise, strict=True)):
            if keep is not None:
                k = keep[i]
                y, r, c = y[k], r[k], c[k]
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
        err = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        err = np.array([math.inf, math.inf])

    def errors():
        e = err
        if np.all(np.isfinite(e)):
            e = np.maximum(e, _jackknife_err(residuals, sol.x, gg, scale))
        e = tuple(float(v) for v in e)
        return (e[1], e[0])

    errors.jacobian = (float(err[1]), float(err[0]))  # the fit's own, without the jackknife
    return (float(sol.x[1]), float(sol.x[0])), errors


# -- the annuli ---------------------------------------------------------------------------
def _band_reader(cube):
    """``band -> 2-D float image`` of a cube, read into memory once where it is small enough."""
    cube = cube.transpose("y", "x", "band")
    if cube.nbytes <= IN_MEMORY_BYTES:  # one read of the file, not one per band
        data = np.asarray(cube.values)
        return lambda b: data[:, :, b].astype(float)
    return lambda b: np.asarray(cube.isel(band=b).values, float)


#: A given optical centre is refused where the cubes place it more than this many standard
#: errors away (a wide margin: the found centre's scatter has heavier tails than a normal
#: one where the signal is near the noise) ...
GIVEN_CENTER_SIGMAS = 20.0
#: ... and further than this share of the cubes' diagonal: x is fitted to the annuli about
#: the centre, so a wrong one gives a wrong x (--center 5000,5000 on a 1088 x 2048 sensor:
#: x = 86 +- 0.25 mm for 21 mm). The cubes speak only where they place the centre inside
#: their field, this share of it from every edge: a crop that does not hold the axis puts
#: its estimate at its edge, with errors that say nothing of how far the axis is.
GIVEN_CENTER_SHARE = 0.25
EDGE_SHARE = 0.1


#: Where a given optical centre came from, as :func:`check_given_center` and
#: :func:`~snapcorr.calibrate.pupil.locate.locate_pupil` say it: the caller's own, or the
#: flats' (``calibrate_with_target`` hands the centre its flats fitted to the target's fit).
CENTER_FROM = {"given": "the optical centre given", "flats": "the flats' optical centre"}


def check_center_from(center_from):
    """``center_from`` checked: one of :data:`CENTER_FROM`."""
    if center_from not in CENTER_FROM:
        raise ValueError(f"center_from must be one of {', '.join(map(repr, CENTER_FROM))}, "
                         f"got {center_from!r}")
    return center_from


def check_given_center(cubes, sensor, lens, sensor_origin_px, center_rc, center_from="given"):
    """What the cubes say against an optical centre ``(row, col)`` given to the fit, or None:
    where they place it further than :data:`GIVEN_CENTER_SIGMAS` standard errors and
    :data:`GIVEN_CENTER_SHARE` of their diagonal away. Where they cannot place it (the
    estimate fails, or lands near their field's edge), None. A crop far from the axis can
    place it wrongly inside its field, so this alone refuses nothing:
    :func:`~snapcorr.calibrate.pupil.locate.locate_pupil` refuses where the fit about the
    given centre also misses the data, and notes it otherwise. ``center_from`` (a key of
    :data:`CENTER_FROM`) names where the centre came from in the text.

    The centre's standard errors (a jackknife: seconds) are found only where the cubes place
    it further than that share of their diagonal, the one condition they do not enter."""

    what = CENTER_FROM[check_center_from(center_from)]
    center = check_center_rc(center_rc)
    placed = _placed_centre(cubes, sensor, lens, sensor_origin_px)
    if placed is None:
        return None
    f0, rows, cols, found, errors = placed
    for v, at in ((found[0], rows), (found[1], cols)):
        lo, hi = float(np.min(at)), float(np.max(at))
        if not lo + EDGE_SHARE * (hi - lo) <= v <= hi - EDGE_SHARE * (hi - lo):
            return None
    d = np.subtract(center, found)
    span = float(np.hypot(np.ptp(rows), np.ptp(cols)))
    if not float(np.hypot(*d)) > GIVEN_CENTER_SHARE * span:
        return None
    err = np.asarray(errors(), float)
    if not np.all(np.isfinite(err)) or np.any(err <= 0):
        return None
    z = float(np.hypot(*(d / err)))
    if z > GIVEN_CENTER_SIGMAS:
        return (f"{what} (row {center[0]:g}, col {center[1]:g}) is "
                f"{float(np.hypot(*d)):.0f} px ({z:.0f} standard errors) from where the "
                f"f/{f0:g} cube places it (row {found[0]:.1f} +- {err[0]:.2g}, col "
                f"{found[1]:.1f} +- {err[1]:.2g})")
    return None


def cubes_center_rc(cubes, sensor, lens, sensor_origin_px):
    """The optical centre ``(row, col)`` the fastest cube places and the fit's own standard
    errors (from its Jacobian, without the jackknife: seconds saved, and often too small),
    or None where it cannot (the estimate fails)."""
    placed = _placed_centre(cubes, sensor, lens, sensor_origin_px)
    if placed is None:
        return None
    found, errors = placed[3:]
    return (found, errors.jacobian) if np.all(np.isfinite(found)) else None


def _placed_centre(cubes, sensor, lens, sensor_origin_px):
    """The fastest cube's f-number, sensor rows and columns, and the centre it places with
    its ``errors()`` (:func:`_center_fit`), or None where the estimate fails."""
    from ...correct.geometry import cube_positions

    cubes = _check_cubes(cubes, sensor, min_side=1)
    f0 = min(cubes)
    rows, cols = cube_positions(cubes[f0], sensor, lens, sensor_origin_px)
    try:
        found, errors = _center_fit(_band_reader(cubes[f0]), sensor.n_bands, rows, cols, None,
                                    12, 4, 4)
    except (ValueError, np.linalg.LinAlgError):
        return None
    return f0, rows, cols, found, errors


#: A centre the cubes find is refused where its standard error is above this share of the
#: sensor's diagonal (the cubes' field's, without a sensor size), or where it lies outside the
#: sensor by more than :data:`FOUND_CENTER_SIGMAS` standard errors: it is not a measurement
#: (a 64 x 80 crop of an f/2 mosaic, seed 103, found row 979 +- 848, col 2480 +- 2695 on a
#: 1088 x 2048 sensor, whose axis is at its middle; the other 23 seeds at f/2 and 12 at f/11
#: found it within 80 px, with errors up to 385 px, and are kept).
FOUND_CENTER_SHARE = 0.25
FOUND_CENTER_SIGMAS = 3.0


def check_found_center(center, err, rows, cols, sensor, f_number):
    """Refuse an optical centre ``(row, col)`` the cubes found with standard errors ``err``
    where it is not a measurement (:data:`FOUND_CENTER_SHARE`, :data:`FOUND_CENTER_SIGMAS`);
    ``rows``, ``cols``: the cube's sensor positions (its field, where the sensor has no
    size). The refusal names the way out: the centre given."""
    if sensor.size_px is not None:
        lo = (-0.5, -0.5)
        hi = (sensor.size_px[0] - 0.5, sensor.size_px[1] - 0.5)
    else:
        lo = (float(np.min(rows)), float(np.min(cols)))
        hi = (float(np.max(rows)), float(np.max(cols)))
    span = float(np.hypot(hi[0] - lo[0], hi[1] - lo[1]))
    err = np.asarray(err, float)
    out = [max(a - v, v - b, 0.0) for v, a, b in zip(center, lo, hi, strict=True)]
    why = None
    if not (np.all(np.isfinite(err)) and np.all(np.isfinite(center))):
        why = "with no finite standard error"
    elif float(np.hypot(*err)) > FOUND_CENTER_SHARE * span:
        whose = "the sensor's" if sensor.size_px is not None else "the cubes'"
        why = (f"+- {float(np.hypot(*err)):.0f} px in all, more than {FOUND_CENTER_SHARE:g} "
               f"of {whose} diagonal ({span:.0f} px)")
    elif sensor.size_px is not None and any(
            o > FOUND_CENTER_SIGMAS * e for o, e in zip(out, err, strict=True)):
        why = (f"outside the {sensor.size_px[0]} x {sensor.size_px[1]} px sensor by more than "
               f"{FOUND_CENTER_SIGMAS:g} of its standard errors")
    if why is not None:
        raise ValueError(
            f"the f/{f_number:g} cube cannot place the optical centre: it finds row "
            f"{center[0]:.1f} +- {_px(err[0])}, col {center[1]:.1f} +- {_px(err[1])}, {why} (a "
            "target too weak or too even over the field, or a crop far from the axis): give "
            "the centre (center_rc=), from the lens's flats")


def _px(v):
    """A standard error in pixels, as said: two digits, whole pixels from 100."""
    return f"{v:.2g}" if not v >= 100 else f"{v:.0f}"


def _annuli(cubes, sensor, lens, sensor_origin_px, center_rc, n_bins):
    """Every cube's radial annuli about the optical centre (given or found), the centre,
    ``(row, col)``, where it came from, and its standard errors (None where given)."""
    from ...correct.geometry import cube_positions

    pitch = sensor.pixel_pitch_mm
    positions = {f: cube_positions(c, sensor, lens, sensor_origin_px) for f, c in cubes.items()}
    nb = sensor.n_bands
    if center_rc is not None:
        center, center_source, err = check_center_rc(center_rc), "given", None
    else:
        f0 = min(cubes)  # the fastest f-number: the largest shifts, the sharpest centre
        rows, cols = positions[f0]
        center, err = estimate_target_center_rc(_band_reader(cubes[f0]), nb, rows, cols)
        check_found_center(center, err, rows, cols, sensor, f0)
        center_source = (f"found from the f/{f0:g} cube (+- {err[0]:.2g} px in the row, "
                         f"{err[1]:.2g} px in the column)")
    bins = [radial_bins(_band_reader(c), nb, *positions[f], None, pitch, center_rc=center,
                        f_number=f, n_bins=n_bins)
            for f, c in cubes.items()]
    return bins, center, center_source, err
