"""Flats and a target without the lens's magnifications: their spread in the joint errors.

:func:`~snapcorr.calibrate.calibrate_with_target` not given m and m_P assumes them (m = 0,
m_P = 1, as :func:`~snapcorr.calibrate.calibrate_lens`). Neither data set can tell them: the
flats fix ``P (1 + m / m_P)`` and ``h (1 + m / m_P)`` (:mod:`snapcorr.calibrate.lens.
magnification`), and the target fixes about ``x n_eff`` and ``tan(theta_cone) / n_eff``, the
cone set by ``1 + m / m_P`` (:mod:`snapcorr.calibrate.pupil.magnification`). So a wrong ratio
moves x, n_eff, P, h and the mean shift together, by far more than the noise's errors (x by
about -4 % for the paper's lens at m / m_P = 0.046, n_eff fitted).

Here the target is fitted again at the nodes of the ratio's plausible range, each time with
the circles the flats give at that ratio (P and h rescaled exactly: the flats need no new
fit), and the RMS deviation over the range enters the joint covariance (one systematic: the
outer product of the deviations) and the mean shift's error (at each pixel, its distance
from the axis held); the assumption is said (:class:`~snapcorr.calibrate.lens.magnification.
MagnificationWarning`, a note) and recorded in the profile's ``[calibration.magnification]``.
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings

import numpy as np

from ..optics.lens import Lens
from .lens import choice
from .lens.magnification import (
    PUPIL_MAGNIFICATION_RANGE,
    MagnificationWarning,
    _held,
    _rescaled,
)
from .pupil.magnification import range_nodes, rms_covariance

__all__ = ["account_for_target_magnifications"]

#: Distances from the axis (per f-number, over the flats' field) the shift is compared at.
_N_FIELD = 48


def account_for_target_magnifications(res, given, rng, refit, *, stacklevel=2):
    """Widen a :class:`~snapcorr.calibrate.unknown_lens.LensAndPupil` made with an assumed
    ``m / m_P`` (that of its lens) by the spread over ``rng``; warn, note and record. Changed
    in place.

    Parameters
    ----------
    res : LensAndPupil
    given : str
        What was given (:func:`~snapcorr.calibrate.lens.magnification.ratio_range`).
    rng : (float, float)
        Its range judged.
    refit : callable
        ``refit(lens) -> PupilFit``: the target fitted with the circles of ``lens`` scaled
        at every trial x, as the nominal fit was.
    stacklevel : int
        Of the warning.

    Returns
    -------
    LensAndPupil
        ``res``.
    """
    cal = res.calibration
    x0 = float(res.pupil.exit_pupil_mm)
    d_mm = np.linspace(0.0, x0 * math.tan(math.radians(cal.max_cra_deg)), _N_FIELD)
    nodes, w = range_nodes(rng)
    devs, shifts, xs = [], [], []
    for r in nodes:
        fit = refit(_rescaled(cal.lens, float(r), _held(cal)))
        devs.append(_deviation(res, fit))
        shifts.append(_shift_difference(res.lens, fit.lens, cal.f_numbers, d_mm))
        xs.append(fit.exit_pupil_mm)
    res.covariance = res.covariance + rms_covariance(devs, w)
    res.stderr = np.sqrt(np.clip(np.diag(res.covariance), 0, None))
    spread_nm = np.sqrt(np.tensordot(w, np.square(np.asarray(shifts, float)), axes=1))
    if res.shift_stderr_nm.size:
        res.shift_stderr_nm = np.hypot(res.shift_stderr_nm, spread_nm)
    else:
        res.shift_stderr_nm = spread_nm
    note = _note(given, rng, res, devs, w, spread_nm)
    warnings.warn(note, MagnificationWarning, stacklevel=stacklevel)
    res.notes = [*res.notes, note]
    res.lens = _recorded(res, given, rng, nodes, xs, spread_nm, note)
    return res


def _deviation(res, fit):
    """The deviation of ``fit`` (the target at another ratio) from ``res`` in ``res.names``:
    x, the index, every P and h at the x each found; the centre does not move."""
    out = []
    lens, other = res.lens.vignetting, fit.lens.vignetting
    for name, value in zip(res.names, res.values, strict=True):
        circle = re.fullmatch(r"([Ph])(\d*)_mm", name)
        if name == "exit_pupil_mm":
            out.append(fit.exit_pupil_mm - value)
        elif name in ("n_eff", "n_eff_factor"):
            n0 = float(np.mean(res.pupil.n_eff))
            out.append(value * (float(np.mean(fit.n_eff)) / n0 - 1.0))
        elif circle and len(other) == len(lens):
            i, j = int(circle.group(2) or 1) - 1, 0 if circle.group(1) == "P" else 1
            out.append(other[i][j] - lens[i][j])
        else:
            out.append(0.0)
    return out


def _field_shift(lens, f, d_mm):
    """The predicted mean shift (reference filter) at distances ``d_mm`` from the axis."""
    from ..optics.mean import mean_shift

    cra = np.degrees(np.arctan(d_mm / lens.exit_pupil_mm))
    cut = float(lens.cutoff_cra_deg(f)) if lens.has_vignetting else 90.0
    cra = np.where(cra < cut, cra, np.nan)
    return mean_shift(choice.REFERENCE_CWL_NM, choice.REFERENCE_N_EFF, f, cra, lens,
                      method="vignetted")


def _shift_difference(a: Lens, b: Lens, f_numbers, d_mm):
    """Largest difference of the predicted mean shift between two lenses over the field, at
    the same distance from the axis (each with its own x), per f-number."""
    out = []
    for f in f_numbers:
        diff = np.abs(_field_shift(a, f, d_mm) - _field_shift(b, f, d_mm))
        out.append(float(np.nanmax(diff)) if np.any(np.isfinite(diff)) else 0.0)
    return np.array(out)


def _rms(devs, w, k):
    return float(np.sqrt(np.dot(w, np.square([d[k] for d in devs]))))


def _note(given, rng, res, devs, w, spread_nm):
    lo, hi = rng
    what = {"neither": "no magnifications given: m = 0 (focused at infinity) and m_P = 1 "
                       f"assumed; m / m_P judged over [{lo:g}, {hi:g}]",
            "m only": "no pupil magnification given: m_P = 1 assumed; m_P judged over "
                      f"[{PUPIL_MAGNIFICATION_RANGE[0]:g}, {PUPIL_MAGNIFICATION_RANGE[1]:g}]",
            "m_P only": "no magnification given: m = 0 (focused at infinity) assumed; "
                        f"m / m_P judged over [{lo:g}, {hi:g}]"}[given]
    sx = _rms(devs, w, res.names.index("exit_pupil_mm"))
    worst = float(np.max(spread_nm)) if spread_nm.size else 0.0
    return (f"{what}. Neither the flats nor the target can tell 1 + m / m_P (the working "
            "f-number, Eq. 27): the target fixes about x n_eff and the cone over n_eff, the "
            "flats P and h times 1 + m / m_P, so x, n_eff, P, h and the mean shift are only "
            "as good as the assumption: their errors include its spread (x +- "
            f"{sx:.3g} mm, mean shift up to {worst:.3g} nm; more frames do not lower it); "
            "give m and m_P (--magnification, --pupil-magnification; m = 0 alone if the lens "
            "was focused at infinity) to remove this term")


def _recorded(res, given, rng, nodes, xs, spread_nm, note):
    """The profile with the widened errors and the ``[calibration.magnification]`` record."""
    def r(v, d=4):
        v = float(v)
        return float(f"{v:.{d}g}") if math.isfinite(v) else "nan"

    lens = res.lens
    table = dict(lens.calibration)
    joint = dict(table["joint"])
    joint["stderr"] = [r(v) for v in res.stderr]
    joint["covariance"] = [[r(v, 6) for v in row] for row in res.covariance]
    table["joint"] = joint
    if res.shift_stderr_nm.size:
        table["shift_stderr_nm"] = [r(v) for v in res.shift_stderr_nm]
    names = list(res.names)
    if "n_eff" in names and "n_eff_stderr" in table:
        table["n_eff_stderr"] = r(res.stderr[names.index("n_eff")], 3)
    scaling = table.get("exit_pupil_scaling")
    if isinstance(scaling, dict):
        scaling = dict(scaling)
        scaling["exit_pupil_stderr_mm"] = float(res.stderr[names.index("exit_pupil_mm")])
        for key, letter in (("P_stderr_with_x_mm", "P"), ("h_stderr_with_x_mm", "h")):
            got = [float(res.stderr[k]) for k, n in enumerate(names)
                   if re.fullmatch(rf"{letter}\d*_mm", n)]
            if key in scaling and len(got) == len(scaling[key]):
                scaling[key] = got
        table["exit_pupil_scaling"] = scaling
    table["magnification"] = {
        "assumed": True, "given": given, "magnification": lens.magnification,
        "pupil_magnification": lens.pupil_magnification,
        "m_over_m_P_range": [float(rng[0]), float(rng[1])],
        "rule": ("neither the flats (P and h times 1 + m / m_P) nor the target (x n_eff, the "
                 "cone over n_eff) fix m / m_P: the target fitted again at the range's "
                 "Gauss-Legendre nodes with the flats' circles rescaled; the RMS deviation "
                 "(m / m_P uniform) is in the joint covariance and the shift's error"),
        "m_over_m_P_nodes": [float(v) for v in nodes],
        "exit_pupil_mm_at_nodes": [r(v, 8) for v in xs],
        "shift_stderr_magnification_nm": [r(v) for v in spread_nm]}
    table["notes"] = [*table.get("notes", []), note]
    return dataclasses.replace(lens, calibration=table)
