"""The error of an optical centre found from the cubes, carried into x's and n_eff's errors.

The target's shift depends on a pixel's radius over ``x`` only (the chief ray's angle is
``atan(r / x)``), so moving the centre by ``d`` moves x by about ``x`` times the mean
relative change of the radii. About the middle of a field that change cancels to second
order; on a crop beside the axis every radius moves one way, and a centre found to a few
tenths of a pixel moves x by tens of its own errors (a crop a corner away from the axis:
x 16 mm +- 0.003 mm with the centre's error left out, 0.09 mm with it). The fit is made again
about the centre moved by one standard error along the row and along the column, and the
two deviations of x, n_eff and ``x n_eff`` are added in quadrature (and to the covariance),
where an estimate of them says they could matter (:data:`NEGLIGIBLE_SHARE`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .magnification import recorded_errors, widen_by_deviations

__all__ = ["NEGLIGIBLE_SHARE", "account_for_a_disagreeing_centre", "account_for_the_centre",
           "centre_sensitivity_mm", "fastest_positions"]

#: The centre's error is carried into x's only where its estimated effect on x
#: (:func:`centre_sensitivity_mm`) is above this share of x's error: below it, adding it in
#: quadrature would change the error by less than 0.5 %, not worth two more fits.
NEGLIGIBLE_SHARE = 0.1


def fastest_positions(cubes, sensor, lens=None, sensor_origin_px=None):
    """The sensor rows and columns of the fastest cube's pixels, as
    :func:`~snapcorr.correct.geometry.cube_positions` gives them.

    Parameters
    ----------
    cubes : dict of float -> xarray.DataArray
        Target cubes by f-number.
    sensor : Sensor
    lens : Lens, optional
    sensor_origin_px : (row, col), optional
        The sensor row and column of the cubes' first pixel.

    Returns
    -------
    rows, cols : ndarray
    """
    from ...correct.geometry import cube_positions
    from .target import _check_cubes

    cubes = _check_cubes(cubes, sensor, min_side=1)
    return cube_positions(cubes[min(cubes)], sensor, lens, sensor_origin_px)


def centre_sensitivity_mm(x_mm, center_rc, err_rc, rows, cols):
    """An estimate of how far x moves when the centre moves by its standard errors: ``x``
    times the radii's mean relative change, weighted by ``r^2`` (the shift's growth with the
    radius), to first order, plus the second-order term that remains about a field's middle.

    Parameters
    ----------
    x_mm : float
    center_rc, err_rc : (float, float)
        The centre and its standard errors, sensor pixels.
    rows, cols : array_like
        The sensor rows and columns of the cube's pixels (any shape; the outer grid is used).

    Returns
    -------
    float
        mm.
    """
    r_ = np.asarray(rows, float).ravel()[:, None] - center_rc[0]
    c_ = np.asarray(cols, float).ravel()[None, :] - center_rc[1]
    r2 = float(np.mean(r_**2) + np.mean(c_**2))
    if not r2 > 0:
        return math.inf
    first = (abs(float(np.mean(r_))) * err_rc[0] + abs(float(np.mean(c_))) * err_rc[1]) / r2
    second = (err_rc[0] ** 2 + err_rc[1] ** 2) / r2
    return float(x_mm) * (first + second)


def account_for_the_centre(fit, err_rc, rows, cols, refit, whose="the optical centre"):
    """Widen a :class:`~snapcorr.calibrate.pupil.locate.PupilFit` made about a centre found
    with standard errors ``err_rc`` (row, col) by the deviations of the fits about the centre
    moved by each: x, n_eff and ``x n_eff`` in quadrature, noted and recorded in the profile.
    Left as it is where :func:`centre_sensitivity_mm` is below :data:`NEGLIGIBLE_SHARE` of
    x's error (also recorded).

    Parameters
    ----------
    fit : PupilFit
    err_rc : (float, float)
    rows, cols : array_like
        The fastest cube's sensor rows and columns.
    refit : callable
        ``refit(center_rc) -> PupilFit``, the same fit about another centre.
    whose : str
        The centre as the note names it (``"the flats' optical centre"``).

    Returns
    -------
    PupilFit
    """
    c = fit.center_rc
    bound = centre_sensitivity_mm(fit.exit_pupil_mm, c, err_rc, rows, cols)
    rule = {"center_stderr_px": [float(f"{e:.3g}") for e in err_rc],
            "estimated_x_shift_mm": float(f"{bound:.3g}")}
    if bound < NEGLIGIBLE_SHARE * fit.exit_pupil_stderr_mm:
        rule["carried"] = (f"no: its estimated effect on x is below {NEGLIGIBLE_SHARE:g} of "
                           "x's error")
        return _with_record(fit, rule)
    moved = [refit((c[0] + err_rc[0], c[1])), refit((c[0], c[1] + err_rc[1]))]
    before = fit.exit_pupil_stderr_mm
    sx, sn = widen_by_deviations(fit, moved)
    index = (f", n_eff +- {sn:.2g}" if sn is not None else "")
    note = (f"{whose} was found to +- {err_rc[0]:.2g} px (row), {err_rc[1]:.2g} px "
            f"(column): fitted again about it moved by those, x moves by {sx:.3g} mm{index}, "
            f"in the errors in quadrature (x's was {before:.2g} mm without it)")
    fit.notes.append(note)
    rule.update(carried="yes: fitted again about the centre moved by each standard error, "
                        "the deviations in the errors in quadrature",
                x_shift_mm=float(f"{sx:.3g}"))
    return _with_record(fit, rule, note)


def account_for_a_disagreeing_centre(fit, other, found_rc, whose="the optical centre given"):
    """Widen a fit about a given centre by its difference from ``other``, the fit about the
    centre the cubes place (``found_rc``), where the cubes place it far from the given one by
    their errors and fit about it no worse beyond chi-square's spread: which is right the
    cubes cannot tell, and x rests on it (centres 2-10 px off fitted at reduced chi-squares
    of 1.04-1.07 with x 29-37 of its errors off). x, n_eff and ``x n_eff`` take the difference
    in quadrature; noted and recorded in the profile.

    Parameters
    ----------
    fit, other : PupilFit
    found_rc : (float, float)
    whose : str
        The given centre as the note names it.

    Returns
    -------
    PupilFit
    """
    before = fit.exit_pupil_stderr_mm
    sx, sn = widen_by_deviations(fit, [other])
    index = (f", n_eff by {sn:.2g}" if sn is not None else "")
    note = (f"{whose} (row {fit.center_rc[0]:g}, col {fit.center_rc[1]:g}) lies far from the "
            f"one the cubes place (row {found_rc[0]:.2f}, col {found_rc[1]:.2f}) by their "
            f"errors, and they fit about either within chi-square's spread: x about theirs "
            f"differs by {sx:.3g} mm{index}, in the errors in quadrature (x's was {before:.2g} "
            "mm without it)")
    fit.notes.append(note)
    rule = {"center_found_rc": [float(f"{v:.6g}") for v in found_rc],
            "carried": "yes: the fit about the centre the cubes place differs by this, in the "
                       "errors in quadrature", "x_shift_mm": float(f"{sx:.3g}")}
    return _with_record(fit, rule, note)


def _with_record(fit, rule, note=None):
    """``fit`` with its profile recording ``rule`` and, where the errors were widened, them
    and ``note``."""
    cal = dict(fit.lens.calibration) if note is None else recorded_errors(fit,
                                                                           fit.lens.calibration)
    cal["center_error"] = rule
    if note is not None:
        cal["notes"] = [*cal.get("notes", []), note]
    fit.lens = dataclasses.replace(fit.lens, calibration=cal)
    return fit
