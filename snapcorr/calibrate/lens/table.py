"""A lens calibration's record: the ``[calibration]`` table of the lens profile it writes.

Every number TOML can hold (NaN and infinity spelled out), what the estimator found, the
joint fits' criteria and verdicts, the model choice's rule and the band gains divided out.
"""

from __future__ import annotations

import datetime as _dt
import math

from ... import __version__
from . import choice, predictive


def _clean(v):
    """TOML-safe: floats, with NaN/inf spelled out as strings."""
    v = float(v)
    return v if math.isfinite(v) else ("nan" if math.isnan(v) else "inf")


def _circle_stderrs(res):
    """Standard errors of every circle's P and of its h, for the estimator used."""
    if res.method == "joint":
        fit = res.fits[res.model]
        n = len(res.lens.vignetting)
        names = [("P_mm", "h_mm")] + [(f"P{i}_mm", f"h{i}_mm") for i in range(2, n + 1)]
        return ([fit.stderr[a] for a, _ in names], [fit.stderr[b] for _, b in names])
    of = res.onset_fits[res.method.split("-")[1]]
    return [of.P_stderr_mm], [of.h_stderr_mm]


#: What the profile says of a centre the flats could not show: their image centre, assumed.
ASSUMED_CENTRE = ("image centre (assumed: the flats show no fall-off to find the optical centre "
                  "from)")


def _calibration_table(res, inputs):
    fs = [float(f) for f in res.f_numbers]
    table = {
        "method": res.method,
        "model": res.model,
        "reason": res.reason,
        "date": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "snapcorr_version": __version__,
        "f_numbers": fs,
        "reference_f_number": res.reference_f_number if res.reference_f_number else "none",
        "center_rc": [float(c) for c in res.center_rc],
        "center_px": [float(res.center_rc[1]), float(res.center_rc[0])],  # x first, for 0.1
        "center_source": (ASSUMED_CENTRE if res.center_source == "image centre"
                          else res.center_source),
        "pixel_pitch_um": res.pixel_pitch_um,
        "image_shape_px": [int(res.shape[0]), int(res.shape[1])],
        "image_size_px": [int(res.shape[1]), int(res.shape[0])],  # x first, likewise
        "max_cra_deg": round(res.max_cra_deg, 4),
    }
    if res.lens.has_vignetting:
        table["onset_cra_deg"] = [_clean(v) for v in res.model_onsets_deg()]
        x = res.lens.exit_pupil_mm
        circles = res.lens.vignetting
        held = res.fits[res.model].extra.get("held", {}) if res.method == "joint" else {}
        dh = [1.0 if f"h{i + 1 if i else ''}_mm" in held else 2 * h / x
              for i, (_, h) in enumerate(circles)]
        scaling = {"dP_dx": [_clean(P / x) for P, _ in circles],
                   "dh_dx": [_clean(v) for v in dh],
                   "rule": "the flats fix P / x and h / x^2: P and h scale with x"
                           + ("; a circle held at h = x (pixel vignetting) moves with x"
                              if held else "")
                           + ("; only approximately for a Lambertian pupil, whose every "
                              "ray's cos^4 depends on x: calibrate again at the x found"
                              if res.lens.ray_weight == "cos4" else ""),
                   "exit_pupil_stderr_mm": ("not given" if res.exit_pupil_stderr_mm is None
                                            else _clean(res.exit_pupil_stderr_mm))}
        if res.exit_pupil_stderr_mm is not None:
            sP, sh = _circle_stderrs(res)
            sx = res.exit_pupil_stderr_mm
            scaling["P_stderr_with_x_mm"] = [_clean(math.hypot(e, P / x * sx))
                                             for e, (P, _) in zip(sP, circles, strict=True)]
            scaling["h_stderr_with_x_mm"] = [_clean(math.hypot(e, d * sx))
                                             for e, d in zip(sh, dh, strict=True)]
        table["exit_pupil_scaling"] = scaling
    if res.shift_stderr_nm.size:
        table["shift_stderr_nm"] = [_clean(v) for v in res.shift_stderr_nm]
        table["shift_stderr_filter"] = [choice.REFERENCE_CWL_NM, choice.REFERENCE_N_EFF]
        if res.shift_stderr_fit_nm.size:
            table["shift_stderr_fit_nm"] = [_clean(v) for v in res.shift_stderr_fit_nm]
        if res.shift_stderr_noise_nm.size:
            table["shift_stderr_noise_nm"] = [_clean(v) for v in res.shift_stderr_noise_nm]
        if res.shift_stderr_model_nm.size:
            table["shift_stderr_model_choice_nm"] = [
                _clean(v) for v in res.shift_stderr_model_nm]
    if res.predictive:
        table["estimator_choice"] = {
            "rule": ("each flat but the reference is left out in turn and predicted by each "
                     "estimator fitted without it; the paper's onsets are used only where "
                     "their summed chi2 is lower than the joint fit's by more than "
                     f"{predictive.MIN_PREDICTIVE_GAIN:g}"),
            **{name: pred.as_table() for name, pred in res.predictive.items()}}
    for det, found in res.onsets.items():
        entry = {}
        got = [found.get(f) for f in fs]
        entry["onset_cra_deg"] = [_clean(o.cra_deg) if o else "reference" for o in got]
        entry["onset_stderr_deg"] = [_clean(o.stderr_deg) if o else "reference" for o in got]
        of = res.onset_fits.get(det)
        if of is not None:
            entry.update({
                "P_mm": _clean(of.P_mm), "h_mm": _clean(of.h_mm),
                "P_stderr_mm": _clean(of.P_stderr_mm), "h_stderr_mm": _clean(of.h_stderr_mm),
                "residuals_mm": [_clean(r) for r in of.residuals_mm]})
        table[f"onset_{det}"] = entry
    if res.mosaic:
        table["band_gains"] = _band_gain_table(res.mosaic)
    origin = res.sensor_origin_px
    if origin is not None:  # the flats are a crop (of a mosaic or not): their first pixel
        table["sensor_origin_rc"] = [int(origin[0]), int(origin[1])]
    table["joint_fit"] = _joint_fit_table(res)
    table["model_choice"] = _model_choice_table(res)
    if inputs:
        table["inputs"] = {f"f/{float(k):g}": str(v) for k, v in inputs.items()}
    if res.notes:
        table["notes"] = list(res.notes)
    return table


def _band_gain_table(mosaic):
    """Which mosaic's band gains were divided out of the flats, and the gains of each."""
    sensor, origin = mosaic["sensor"], mosaic["sensor_origin_px"]
    return {
        "removed": True,
        "rule": ("each flat's band gains fitted (median per band of each pixel over a "
                 "symmetric tile-sized local mean, where lit) and divided out before the fit; "
                 "pixels outside the filter area not used"),
        "sensor": sensor.name,
        **({"sensor_file": sensor.vendor_file} if sensor.vendor_file else {}),
        "mosaic_shape": [int(v) for v in sensor.mosaic_shape],
        "filter_area_px": (list(sensor.filter_area_px) if sensor.filter_area_px is not None
                           else "the whole sensor"),
        "sensor_origin_rc": ([int(origin[0]), int(origin[1])] if origin is not None
                             else "whole sensor"),
        "band_cwl_nm": [float(v) for v in sensor.cwl_nm],
        "gains": {f"f/{float(f):g}": [_clean(v) for v in g]
                  for f, g in sorted(mosaic["band_gains"].items())},
    }


def _joint_fit_table(res):
    """Each joint fit's criteria, verdict, parameters and standard errors."""
    joint = {}
    for name, fit in res.fits.items():
        entry = {"bic": _clean(fit.bic), "bic_with_floor": _clean(res.bic_floor[name]),
                 "reduced_chi2": _clean(fit.reduced_chi2), "converged": bool(fit.success)}
        v = res.verdicts.get(name)
        if v is not None:
            entry["chosen"] = v.chosen
            entry["why"] = v.why
        held = fit.extra.get("held", {})
        for k in fit.names:
            entry[k] = _clean(fit.params[k])
            entry[k.replace("_mm", "_stderr_mm").replace("_px", "_stderr_px")] = \
                "held" if k in held else _clean(fit.stderr[k])
        joint[name] = entry
    return joint


def _model_choice_table(res):
    """The rule that chose the model, its rivals, and how far the next best lies."""
    table = {
        "models_tried": list(res.fits),
        "rule": ("circles must be identifiable (onset inside the field at >= 2 f-numbers, "
                 f"standard errors < {100 * choice.MAX_REL_ERROR:g} % of P and h, |h| > "
                 f"{choice.MIN_H_SIGMAS:g} sigma); a further circle must lower the BIC with a "
                 f"{100 * choice.FLOOR_REL:g} % systematic floor by > {choice.MIN_BIC_GAIN:g} "
                 f"and move the mean shift by > {res.tolerance_nm:g} nm and by > "
                 f"{choice.MIN_SHIFT_SIGMAS:g} of its standard errors"),
        "tolerance_nm": res.tolerance_nm,
        "reference_filter": {"cwl_nm": choice.REFERENCE_CWL_NM,
                             "n_eff": choice.REFERENCE_N_EFF},
    }
    if res.rivals:  # not chosen; in the model choice's error where identifiable
        table["rivals"] = {
            name: {"bic": _clean(fit.bic), "bic_with_floor": _clean(b),
                   "reduced_chi2": _clean(fit.reduced_chi2), "converged": bool(fit.success),
                   **{k: _clean(fit.params[k]) for k in fit.names}}
            for name, (fit, b) in res.rivals.items()}
    if res.next_best is not None:
        table["next_best"] = res.next_best
        table["shift_difference_to_next_best_nm"] = [
            _clean(d) for d in res.shift_difference_nm]
    check = res.onset_check_deg()
    if check is not None:
        table["paper_onsets_vs_chosen_max_deg"] = _clean(check)
    return table
