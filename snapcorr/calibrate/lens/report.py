"""A calibration's result for a person: the summary text and the picture (the paper's Fig. 8).
"""

from __future__ import annotations

import numpy as np

from .choice import REFERENCE_CWL_NM, REFERENCE_N_EFF
from .joint_fit import CIRCLE_MODELS, BlockData, model_ratio

__all__ = ["CIRCLES", "plot", "save_plot", "summary"]

CIRCLES = {"none": "no circle", "one": "one circle", "two": "two circles",
           "three": "three circles"}


def _fmt_onset(o):
    return f"{o.cra_deg:6.2f} +- {o.stderr_deg:.2f}" if o.found else \
        f"none up to {o.max_cra_deg:.1f}"


def summary(res) -> str:
    """A few lines: centre, onsets (the paper's detectors against the chosen model), every
    model tried with its verdict, the choice and why."""
    origin = (getattr(res, "mosaic", None) or {}).get("sensor_origin_px")
    where = ("" if origin is None else " of the flats (sensor row "
             f"{res.center_rc[0] + origin[0]:.1f}, col {res.center_rc[1] + origin[1]:.1f})")
    source = ("image centre, assumed: no fall-off to find it from"
              if res.center_source == "image centre" else res.center_source)
    lines = [f"optical centre: row {res.center_rc[0]:.1f}, col {res.center_rc[1]:.1f} px{where} "
             f"({source}); chief-ray angles checked up to {res.max_cra_deg:.1f} deg"]
    model_on = res.model_onsets_deg()
    lines.append("onsets (deg): ratio-profile discontinuity | area model per profile | "
                 "chosen model")
    for j, f in enumerate(res.f_numbers):
        o1, o2 = res.onsets["ratio"].get(float(f)), res.onsets["model"].get(float(f))
        if o1 is None:
            continue
        lines.append(f"  f/{f:<4g} {_fmt_onset(o1):>22} | {_fmt_onset(o2):>22} | "
                     f"{model_on[j]:6.2f}")
    check = res.onset_check_deg()
    if check is not None:
        lines.append(f"paper's onsets (ratio profiles) against the chosen model: largest "
                     f"difference {check:.2f} deg")
    for det, of in res.onset_fits.items():
        if of is not None:
            lines.append(f"onset-{det} (Eq. 26): P = {of.P_mm:.4f} +- {of.P_stderr_mm:.4f} "
                         f"mm, h = {of.h_mm:.3f} +- {of.h_stderr_mm:.3f} mm")
    for name, fit in res.fits.items():
        v = res.verdicts.get(name)
        head = f"joint fit, {CIRCLES[name]}"
        held = getattr(fit, "extra", {}).get("held", {})
        txt = ", ".join(f"{k} = {fit.params[k]:.4g} " + (
            "(held: pixel vignetting, h = x)" if k in held else f"+- {fit.stderr[k]:.2g}")
            for k in fit.names)
        stats = (f"BIC with floor {res.bic_floor[name]:.4g}, reduced chi2 "
                 f"{fit.reduced_chi2:.4g}")
        lines.append(f"{head}: {txt + '; ' if txt else ''}{stats}")
        if v is not None:
            lines.append(f"  -> {'chosen' if v.chosen else 'rejected'}: {v.why}")
    lens = res.lens
    if lens.has_vignetting:
        lines.append(f"chosen: {res.method}, {CIRCLES[res.model]}: "
                     f"{lens.describe_vignetting()}")
    else:
        lines.append(f"chosen: no optical vignetting up to {res.max_cra_deg:.1f} deg "
                     "(the ideal-aperture model suffices)")
    if res.next_best is not None:
        diff = ", ".join(f"f/{f:g} {d:.4f}" for f, d in
                         zip(res.f_numbers, res.shift_difference_nm, strict=True))
        lines.append(f"mean-shift difference to the next best ({CIRCLES[res.next_best]}), "
                     f"nm, for a filter at {REFERENCE_CWL_NM:g} nm with n_eff "
                     f"{REFERENCE_N_EFF:g}: {diff}")
    if res.shift_stderr_nm.size:
        err = ", ".join(f"f/{f:g} {e:.4f}" for f, e in
                        zip(res.f_numbers, res.shift_stderr_nm, strict=True))
        sp = getattr(res, "magnification_spread", None)
        src = "P, h and the assumed magnifications" if sp is not None else "P and h"
        lines.append(f"mean-shift standard error from {src} (largest over the field), nm, "
                     f"same filter: {err}")
    lines += _magnification_lines(res)
    if res.predictive:
        per = " | ".join(
            f"{name}: " + ", ".join(f"f/{f:g} {c:.4g}" for f, c in pred.chi2.items())
            + f" (total {pred.total:.4g})" for name, pred in res.predictive.items())
        blocks = next(iter(res.predictive.values())).n
        lines.append(f"each flat left out and predicted by the estimators fitted without it, "
                     f"chi2 over {max(blocks.values(), default=0)} blocks each: {per}")
    lines.append(f"why: {res.reason}")
    lines.extend(f"note: {n}" for n in res.notes)
    return "\n".join(lines)


def _magnification_lines(res):
    """What the assumed magnifications leave (:mod:`snapcorr.calibrate.lens.magnification`):
    P's and h's errors with their spread; nothing where m and m_P were given."""
    sp = getattr(res, "magnification_spread", None)
    if sp is None:
        return []
    rec = res.lens.calibration.get("magnification", {})
    if not isinstance(rec, dict):
        return []
    lo, hi = sp.ratio_range
    out = [f"magnifications assumed (m = {res.lens.magnification:g}, m_P = "
           f"{res.lens.pupil_magnification:g}; m / m_P judged over [{lo:g}, {hi:g}]): the "
           "flats cannot tell them; give --magnification and --pupil-magnification"]
    for i, (P, h) in enumerate(res.lens.vignetting):
        if i < len(rec.get("P_stderr_mm", ())):
            out.append(f"  circle {i + 1}: P = {P:.4f} +- {rec['P_stderr_mm'][i]:.4f} mm, "
                       f"h = {h:.3f} +- {rec['h_stderr_mm'][i]:.3f} mm with that spread")
    return out


def plot(res, ax=None):
    """The paper's Fig. 8: vignetting profiles; ratio profiles, detected onsets and the
    chosen model's prediction."""
    import matplotlib.pyplot as plt

    if ax is None:
        fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
    else:
        axes = np.atleast_1d(ax)
        fig = axes[0].figure
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    ax0 = axes[0]
    for i, f in enumerate(res.f_numbers):
        prof = res.profiles[float(f)]
        norm = np.nanmax(prof.value[: max(3, prof.value.size // 20)])
        ax0.plot(prof.cra_deg, prof.value / norm, ".", ms=2, color=colors[i % len(colors)],
                 label=f"f/{f:g}")
    ax0.set(xlabel="chief-ray angle (deg)", ylabel="flat field / centre",
            title="vignetting profiles")
    ax0.legend(fontsize=8)
    if len(axes) > 1 and res.ratio_profiles:
        _plot_ratios(res, axes[1], colors)
    elif len(axes) > 1:
        _plot_single(res, axes[1])
    return fig


def _plot_ratios(res, ax1, colors):
    theta = np.linspace(0, res.max_cra_deg, 400)
    tan = np.tan(np.deg2rad(theta))
    model_on = res.model_onsets_deg()
    for i, f in enumerate(res.f_numbers):
        prof = res.ratio_profiles.get(float(f))
        if prof is None:
            continue
        c = colors[i % len(colors)]
        scale = _ratio_scale(res, float(f), prof)
        ax1.errorbar(prof.cra_deg, prof.value / scale, prof.stderr / scale, fmt=".",
                     ms=2, lw=0.5, color=c, label=f"f/{f:g}")
        ax1.plot(theta, _predicted_ratio(res, float(f), tan), "k-", lw=0.8)
        o = res.onsets["ratio"].get(float(f))
        if o is not None and o.found:
            ax1.plot(o.cra_deg, np.interp(o.cra_deg, prof.cra_deg, prof.value) / scale,
                     "o", mfc="none", mec="k", ms=7)
        if np.isfinite(model_on[i]):
            ax1.axvline(model_on[i], color=c, lw=0.6, ls=":")
    ax1.set(xlabel="chief-ray angle (deg)", ylabel=f"ratio to f/{res.reference_f_number:g}")
    ax1.set_title(f"o onsets found; black: {res.method} fit, {CIRCLES[res.model]}; "
                  "dotted: its first onsets", fontsize=10)
    ax1.legend(fontsize=8)


def _plot_single(res, ax1):
    """One flat: the profile without cos^4 against the model."""
    f = float(res.f_numbers[0])
    prof = res.profiles[f]
    q = prof.value / np.cos(np.deg2rad(prof.cra_deg)) ** 4
    norm = float(np.nanmax(q[: max(3, q.size // 20)]))
    ax1.plot(prof.cra_deg, q / norm, ".", ms=2, label=f"f/{f:g} / cos^4")
    theta = np.linspace(0, res.max_cra_deg, 400)
    ax1.plot(theta, res.lens.relative_illumination(f, theta), "k-", lw=0.8, label="model")
    o = res.onsets["ratio"].get(f)
    if o is not None and o.found:
        ax1.axvline(o.cra_deg, color="k", ls=":", lw=0.8)
    ax1.set(xlabel="chief-ray angle (deg)", ylabel="relative illumination")
    ax1.set_title(f"one flat, h given: {res.method} fit; dotted: onset found", fontsize=10)
    ax1.legend(fontsize=8)


def _ratio_scale(res, f, prof):
    fit = res.fits.get(res.model)
    if res.method == "joint" and fit is not None and fit.scales.size:
        idx = [float(v) for v in res.f_numbers if v != res.reference_f_number].index(f)
        return float(fit.scales[idx])
    return float(np.nanmax(prof.value[: max(3, prof.value.size // 20)]))


def _predicted_ratio(res, f, tan):
    """The chosen lens's area ratio A_F / A_ref at ``tan(CRA)``."""
    lens = res.lens
    circles = list(lens.vignetting)
    data = BlockData(np.zeros((1, 1)), np.ones((1, 1)), np.zeros(1), np.zeros(1),
                     np.array([lens.exit_pupil_radius_mm(f)]),
                     float(lens.exit_pupil_radius_mm(res.reference_f_number)), 1.0,
                     lens.exit_pupil_mm, ray_weight=lens.ray_weight)
    p = []
    for i, (P, h) in enumerate(circles):
        p += [P, h] + ([0.0, 0.0] if i == 0 else [])
    return model_ratio(data, CIRCLE_MODELS[len(circles)], p, tan)[0]


def save_plot(res, path):
    """Write :func:`plot` to ``path`` (PNG), atomically."""
    import matplotlib.pyplot as plt

    from ...files.png import save_png

    fig = plot(res)
    try:
        save_png(fig, path, dpi=120)
    finally:
        plt.close(fig)
