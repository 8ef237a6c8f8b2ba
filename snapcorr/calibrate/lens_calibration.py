"""Flat fields at several f-numbers in, a lens profile out (Goossens et al. 2019, Sec. 2.7, 3.2).

Two estimators of the vignetting circle are run on the same flats and both are reported:

``onset``
    The paper's: each flat is divided by the flat at the highest f-number, the onset of
    vignetting is located in the radial profile of that ratio (:func:`detect_onset`), and the
    onsets give P and h through the least squares of Eq. (26). It uses only where the fall-off
    starts, so effects the area model leaves out (pupil aberrations, an f-number-dependent
    natural fall-off) barely bias it; but it throws away the shape of the fall-off.
``joint``
    The vignetted-pupil area model fitted to every ratio image at once, with the optical centre
    (:mod:`snapcorr.calibrate.joint_fit`). It uses every pixel, so it is several times more
    precise at a given noise (``benchmarks/``), and it compares no, one and two vignetting
    circles by the Bayesian information criterion.

``method="auto"`` keeps the joint fit when its reduced chi-square says the area model
describes the flats (below ``MISFIT_CHI2``) and falls back to the onset method otherwise.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field

import numpy as np

from .. import __version__
from .._validation import check_positive
from ..optics.lens import Lens
from .flats import (
    clean_flat,
    cra_deg_map,
    estimate_center,
    radial_profile,
)
from .joint_fit import BlockData, ModelFit, block_average, fit_model, model_ratio
from .onset_fit import OnsetFit, solve_vignetting_circle
from .onsets import Onset, detect_onset

__all__ = ["METHODS", "LensCalibration", "calibrate_lens"]

METHODS = ("auto", "joint", "onset-ratio", "onset-model")
#: Reduced chi-square above which the joint fit's area model is taken not to describe the
#: flats (then ``auto`` uses the onset method).
MISFIT_CHI2 = 1.5
#: Largest side of the block-averaged images used by the joint fit.
FIT_GRID = 160
_CIRCLES = {"none": "no circle", "one": "one circle", "two": "two circles"}
#: Pixels where the reference flat is below this fraction of its peak are not used (past its
#: own cut-off a ratio is noise over noise).
LIT_FRACTION = 0.05
#: Width of the radial-profile bins, degrees of chief-ray angle.
BIN_DEG = 0.1
#: Largest side of the images the radial profiles are taken from (larger flats are binned).
PROFILE_SIZE = 1024


@dataclass
class LensCalibration:
    """Everything a calibration found, and the lens profile it gives.

    Attributes
    ----------
    lens : Lens
        The profile (P and h of the chosen estimate; none if no vignetting was found).
    method, model : str
        Estimator used (``"joint"``, ``"onset-ratio"`` or ``"onset-model"``) and vignetting
        model chosen (``"none"``, ``"one"`` or ``"two"`` circles).
    reason : str
        Why, in a sentence.
    f_numbers : ndarray
    center_px : (float, float)
        Optical centre used, pixels.
    center_source : str
        ``"given"``, ``"contours"``, ``"joint fit"`` or ``"image centre"``.
    onsets : dict
        Detector -> {f-number -> :class:`Onset`}: ``"ratio"``, the discontinuity of the ratio
        profile (the paper's way), and ``"model"``, the area model fitted to each profile.
    onset_fits : dict
        Detector -> :class:`OnsetFit` of Eq. (26) over its onsets (None with fewer than two).
    fits : dict
        Model name -> :class:`ModelFit` of the joint fit.
    profiles, ratio_profiles : dict
        f-number -> :class:`RadialProfile` of each flat and of its ratio to the reference.
    """

    lens: Lens
    method: str
    model: str
    reason: str
    f_numbers: np.ndarray
    reference_f_number: float | None
    center_px: tuple
    center_source: str
    max_cra_deg: float
    onsets: dict
    onset_fits: dict
    fits: dict
    profiles: dict
    ratio_profiles: dict
    pixel_pitch_um: float
    shape: tuple
    notes: list = field(default_factory=list)

    # -- derived ------------------------------------------------------------------------
    def model_onsets_deg(self):
        """Onset of each f-number predicted by the chosen P and h (NaN past the field)."""
        lens = self.lens
        on = np.asarray(lens.onset_cra_deg(self.f_numbers), float)
        return np.where(on <= self.max_cra_deg, on, np.nan)

    def summary(self) -> str:
        """A few lines for a person."""
        lines = [f"optical centre: ({self.center_px[0]:.1f}, {self.center_px[1]:.1f}) px "
                 f"({self.center_source}); chief-ray angles checked up to "
                 f"{self.max_cra_deg:.1f} deg"]
        model_on = self.model_onsets_deg()

        def fmt(o):
            return (f"{o.cra_deg:6.2f} +- {o.stderr_deg:.2f}" if o.found
                    else f"none up to {o.max_cra_deg:.1f}")

        lines.append("onsets (deg): ratio-profile discontinuity | area model per profile | "
                     "chosen P, h")
        for j, f in enumerate(self.f_numbers):
            o1, o2 = self.onsets["ratio"].get(float(f)), self.onsets["model"].get(float(f))
            if o1 is None:
                continue
            lines.append(f"  f/{f:<4g} {fmt(o1):>22} | {fmt(o2):>22} | {model_on[j]:6.2f}")
        for det, of in self.onset_fits.items():
            if of is not None:
                lines.append(f"onset-{det} (Eq. 26): P = {of.P_mm:.4f} +- {of.P_stderr_mm:.4f} "
                             f"mm, h = {of.h_mm:.3f} +- {of.h_stderr_mm:.3f} mm")
        for name, fit in self.fits.items():
            if name == "none":
                lines.append(f"joint fit, no circle: BIC {fit.bic:.1f}, "
                             f"reduced chi2 {fit.reduced_chi2:.2f}")
                continue
            p, e = fit.params, fit.stderr
            txt = ", ".join(f"{k} = {p[k]:.4g} +- {e[k]:.2g}" for k in fit.names)
            lines.append(f"joint fit, {_CIRCLES[name]}: {txt}; BIC {fit.bic:.1f}, "
                         f"reduced chi2 {fit.reduced_chi2:.2f}")
        lens = self.lens
        if lens.has_vignetting:
            lines.append(f"chosen: {self.method}, {_CIRCLES[self.model]}: "
                         f"{lens.describe_vignetting()}")
        else:
            lines.append(f"chosen: no optical vignetting up to {self.max_cra_deg:.1f} deg "
                         "(the ideal-aperture model suffices)")
        lines.append(f"why: {self.reason}")
        lines.extend(f"note: {n}" for n in self.notes)
        return "\n".join(lines)

    def plot(self, ax=None):
        """The paper's Fig. 8: ratio profiles, detected onsets and the model prediction."""
        import matplotlib.pyplot as plt

        if ax is None:
            fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
        else:
            axes = np.atleast_1d(ax)
            fig = axes[0].figure
        colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
        ax0 = axes[0]
        for i, f in enumerate(self.f_numbers):
            prof = self.profiles[float(f)]
            norm = np.nanmax(prof.value[: max(3, prof.value.size // 20)])
            ax0.plot(prof.cra_deg, prof.value / norm, ".", ms=2, color=colors[i % len(colors)],
                     label=f"f/{f:g}")
        ax0.set(xlabel="chief-ray angle (deg)", ylabel="flat field / centre",
                title="vignetting profiles")
        ax0.legend(fontsize=8)
        if len(axes) > 1 and self.ratio_profiles:
            ax1 = axes[1]
            theta = np.linspace(0, self.max_cra_deg, 400)
            tan = np.tan(np.deg2rad(theta))
            model_on = self.model_onsets_deg()
            for i, f in enumerate(self.f_numbers):
                prof = self.ratio_profiles.get(float(f))
                if prof is None:
                    continue
                c = colors[i % len(colors)]
                scale = self._ratio_scale(float(f), prof)
                ax1.errorbar(prof.cra_deg, prof.value / scale, prof.stderr / scale, fmt=".",
                             ms=2, lw=0.5, color=c, label=f"f/{f:g}")
                pred = self._predicted_ratio(float(f), tan)
                if pred is not None:
                    ax1.plot(theta, pred, "k-", lw=0.8)
                o = self.onsets["ratio"].get(float(f))
                if o is not None and o.found:
                    ax1.plot(o.cra_deg, np.interp(o.cra_deg, prof.cra_deg, prof.value) / scale,
                             "o", mfc="none", mec="k", ms=7)
                j = list(self.f_numbers).index(f)
                if np.isfinite(model_on[j]):
                    ax1.axvline(model_on[j], color=c, lw=0.6, ls=":")
            ax1.set(xlabel="chief-ray angle (deg)",
                    ylabel=f"ratio to f/{self.reference_f_number:g}")
            ax1.set_title(f"o onsets found; black: {self.method} fit, {_CIRCLES[self.model]}; "
                          "dotted: its onsets", fontsize=10)
            ax1.legend(fontsize=8)
        elif len(axes) > 1:  # one flat: the profile without cos^4 against the model
            ax1 = axes[1]
            f = float(self.f_numbers[0])
            prof = self.profiles[f]
            q = prof.value / np.cos(np.deg2rad(prof.cra_deg)) ** 4
            norm = float(np.nanmax(q[: max(3, q.size // 20)]))
            ax1.plot(prof.cra_deg, q / norm, ".", ms=2, label=f"f/{f:g} / cos^4")
            theta = np.linspace(0, self.max_cra_deg, 400)
            ax1.plot(theta, self.lens.relative_illumination(f, theta), "k-", lw=0.8,
                     label="model")
            o = self.onsets["ratio"].get(f)
            if o is not None and o.found:
                ax1.axvline(o.cra_deg, color="k", ls=":", lw=0.8)
            ax1.set(xlabel="chief-ray angle (deg)", ylabel="relative illumination")
            ax1.set_title(f"one flat, h given: {self.method} fit; dotted: onset found",
                          fontsize=10)
            ax1.legend(fontsize=8)
        return fig

    def _ratio_scale(self, f, prof):
        fit = self.fits.get(self.model)
        if self.method == "joint" and fit is not None and fit.scales.size:
            idx = [float(v) for v in self.f_numbers if v != self.reference_f_number].index(f)
            return float(fit.scales[idx])
        return float(np.nanmax(prof.value[: max(3, prof.value.size // 20)]))

    def _predicted_ratio(self, f, tan):
        lens = self.lens
        if self.reference_f_number is None:
            return None
        circles = []
        circles.extend(lens.vignetting)
        second = self.lens.calibration.get("second_circle")
        if second:
            circles.append((second["radius_mm"], second["distance_mm"]))
        data = BlockData(np.zeros((1, 1)), np.ones((1, 1)), np.zeros(1), np.zeros(1),
                         np.array([lens.exit_pupil_radius_mm(f)]),
                         float(lens.exit_pupil_radius_mm(self.reference_f_number)), 1.0,
                         lens.exit_pupil_mm)
        p = [v for c in circles for v in c]
        model = ("none", "one", "two")[len(circles)]
        if model == "two":
            p = [p[0], p[1], 0.0, 0.0, p[2], p[3]]
        return model_ratio(data, model, p, tan)[0]

    def save_plot(self, path):
        """Write :meth:`plot` to ``path`` (PNG), atomically."""
        from .._io import atomic_write

        fig = self.plot()
        import matplotlib.pyplot as plt

        try:
            atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=120, format="png"))
        finally:
            plt.close(fig)


def _check_inputs(flats, dark):
    if not flats:
        raise ValueError("give at least one flat field")
    items = []
    for f, img in flats.items():
        try:
            fv = float(f)
        except (TypeError, ValueError):
            raise ValueError(f"f-number {f!r} is not a number") from None
        if not math.isfinite(fv) or fv <= 0:
            raise ValueError(f"f-number must be finite and > 0, got {f!r}")
        arr = np.asarray(img)
        if arr.ndim != 2:
            raise ValueError(f"the flat at f/{fv:g} must be a 2-D image, got shape {arr.shape}")
        items.append((fv, arr))
    fs = [f for f, _ in items]
    if len(set(fs)) != len(fs):
        dup = sorted({f for f in fs if fs.count(f) > 1})
        raise ValueError(f"f-number(s) given twice: {', '.join(f'f/{f:g}' for f in dup)}")
    shapes = {a.shape for _, a in items}
    if len(shapes) > 1:
        listing = ", ".join(f"f/{f:g}: {a.shape[1]} x {a.shape[0]}" for f, a in items)
        raise ValueError(f"flat fields differ in size ({listing}); all must come from the "
                         "same sensor area")
    if min(items[0][1].shape) < 16:
        raise ValueError(f"flat fields of {items[0][1].shape[1]} x {items[0][1].shape[0]} "
                         "pixels are too small to calibrate from (16 x 16 at least)")
    if dark is not None and np.shape(dark) != items[0][1].shape:
        raise ValueError(f"the dark frame is {np.shape(dark)}, the flats "
                         f"{items[0][1].shape}")
    return sorted(items)


def calibrate_lens(flats, *, exit_pupil_mm, pixel_pitch_um, magnification=0.0,
                   pupil_magnification=1.0, dark=None, center_px=None, saturation=None,
                   vignetting_distance_mm=None, method="auto", name="calibrated lens",
                   inputs=None):
    """Characterise a lens from flat fields at several f-numbers.

    Parameters
    ----------
    flats : mapping
        f-number -> 2-D flat-field image (integrating sphere, or lamp and plaque).
    exit_pupil_mm : float
        Distance x from the sensor to the exit pupil.
    pixel_pitch_um : float
    magnification, pupil_magnification : float
        m and m_P of the working f-number, Eq. (27).
    dark : 2-D array, optional
        Dark frame, subtracted from every flat.
    center_px : (cx, cy), optional
        Optical centre in pixels (pixel (row i, column j) is centred at x=j, y=i). Default:
        found from the flats and refined by the joint fit.
    saturation : float or mapping, optional
        Values at or above are saturated and ignored (one level, or f-number -> level).
    vignetting_distance_mm : float, optional
        h, if known. Required with a single f-number, whose flat cannot tell P from h.
    method : {"auto", "joint", "onset-ratio", "onset-model"}
        ``"joint"``: the area model fitted to every ratio image at once; ``"onset-ratio"``:
        the paper's onsets of the ratio profiles, then Eq. 26; ``"onset-model"``: onsets from
        the area model fitted per profile, then Eq. 26; ``"auto"``: the joint fit, or the
        paper's onsets when the joint fit's reduced chi-square exceeds ``MISFIT_CHI2``.
    name : str
        Lens name for the profile.
    inputs : mapping, optional
        f-number -> file name, recorded in the profile.

    Returns
    -------
    LensCalibration
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    exit_pupil_mm = check_positive("exit_pupil_mm", exit_pupil_mm)
    pixel_pitch_um = check_positive("pixel_pitch_um", pixel_pitch_um)
    if vignetting_distance_mm is not None:
        vignetting_distance_mm = check_positive("vignetting_distance_mm", vignetting_distance_mm)
    if center_px is not None:
        try:
            cx, cy = (float(v) for v in center_px)
        except (TypeError, ValueError):
            raise ValueError(f"center_px must be two numbers (cx, cy), got {center_px!r}") \
                from None
        if not (math.isfinite(cx) and math.isfinite(cy)):
            raise ValueError(f"center_px must be finite, got {center_px!r}")
        center_px = (cx, cy)
    items = _check_inputs(flats, dark)
    base = Lens(exit_pupil_mm, (), magnification, pupil_magnification, name=name)
    if len(items) == 1 and vignetting_distance_mm is None:
        raise ValueError(
            f"one f-number (f/{items[0][0]:g}) cannot tell the vignetting circle's radius P "
            "from its distance h (Eq. 26 needs two or more onsets): give flats at two or more "
            "f-numbers, or give h (vignetting_distance_mm / --vignetting-distance-mm)")
    fs = np.array([f for f, _ in items])
    shape = items[0][1].shape
    x = float(exit_pupil_mm)
    pitch_mm = pixel_pitch_um * 1e-3
    R = base.exit_pupil_radius_mm(fs)
    notes = []

    sat = saturation if isinstance(saturation, dict) else {f: saturation for f, _ in items}
    cleaned = [clean_flat(img, dark=dark, saturation=sat.get(f)) for f, img in items]
    images = [c[0] for c in cleaned]
    valids = [c[1] for c in cleaned]
    variances = [c[2] for c in cleaned]
    for (f, _), ok in zip(items, valids, strict=True):
        lost = 1.0 - ok.mean()
        if lost > 0.05:
            notes.append(f"f/{f:g}: {100 * lost:.1f} % of pixels masked (saturated, dead, hot "
                         "or non-finite)")
        if ok.mean() < 0.2:
            raise ValueError(f"the flat at f/{f:g} has only {100 * ok.mean():.0f} % usable "
                             "pixels (saturated, dead or non-finite); lower the exposure or "
                             "check the file")
    for (f, _), img, ok in zip(items, images, valids, strict=True):
        if not np.percentile(img[ok], 99) > 0:
            raise ValueError(f"the flat at f/{f:g} has no signal above the dark frame")
    single = len(items) == 1
    ref = None if single else len(items) - 1
    block = max(1, math.ceil(max(shape) / FIT_GRID))
    bimgs, bvars, bcnt, bx, by = block_average(images, valids, variances, block)
    enough = [c >= 0.5 * block * block for c in bcnt]

    # ratio images (block level) to the highest f-number
    if single:
        ratios, rvars, rok = bimgs, bvars, enough
    else:
        # Only where the reference itself is lit: past its own cut-off (or outside the image
        # circle) a ratio is noise over noise. The set is fixed here, not by the fit.
        ref_peak = float(np.nanpercentile(np.where(enough[ref], bimgs[ref], np.nan), 99))
        with np.errstate(invalid="ignore"):
            lit = (bimgs[ref] > LIT_FRACTION * ref_peak) & (
                bimgs[ref] > 5.0 * np.sqrt(bvars[ref]))
        ratios, rvars, rok = [], [], []
        for i in range(len(items) - 1):
            with np.errstate(invalid="ignore", divide="ignore"):
                q = bimgs[i] / bimgs[ref]
                v = q * q * (bvars[i] / bimgs[i] ** 2 + bvars[ref] / bimgs[ref] ** 2)
            ok = enough[i] & enough[ref] & np.isfinite(q) & lit & (v > 0)
            ratios.append(q)
            rvars.append(v)
            rok.append(ok)

    # optical centre
    if center_px is not None:
        center = (float(center_px[0]), float(center_px[1]))
        center_source = "given"
    else:
        c, _ = estimate_center(ratios, rok) if not single else (None, None)
        if c is None:
            c, _ = estimate_center(bimgs, enough)
        if c is None:
            center = ((shape[1] - 1) / 2.0, (shape[0] - 1) / 2.0)
            center_source = "image centre"
            notes.append("no radial fall-off to find the optical centre from: the image "
                         "centre is used")
        else:  # block coordinates -> pixels
            center = (c[0] * block + (block - 1) / 2.0, c[1] * block + (block - 1) / 2.0)
            center_source = "contours"

    # radial profiles, from pixels binned k x k on large sensors (k <= PROFILE_SIZE / side
    # keeps a binned pixel well under a bin's 0.1 deg)
    k = max(1, math.ceil(max(shape) / PROFILE_SIZE))
    if k > 1:
        pimgs, _, pcnt, _, _ = block_average(images, valids, variances, k)
        pvalid = [c >= 0.5 * k * k for c in pcnt]
        pimgs = [np.where(ok, im, 0.0) for im, ok in zip(pimgs, pvalid, strict=True)]
        pcentre = ((center[0] - (k - 1) / 2.0) / k, (center[1] - (k - 1) / 2.0) / k)
    else:
        pimgs, pvalid, pcentre = images, valids, center
    cra = cra_deg_map(pimgs[0].shape, pcentre, pixel_pitch_um * k, x)
    max_cra = float(cra_deg_map(shape, center, pixel_pitch_um, x).max())
    profiles = {float(f): radial_profile(pimgs[i], pvalid[i], cra, bin_deg=BIN_DEG)
                for i, f in enumerate(fs)}
    short = [f for f, p in profiles.items() if p.cra_deg.size < 8]
    if short:
        n_bins = profiles[short[0]].cra_deg.size
        raise ValueError(
            f"the flats span only {max_cra:.2f} deg of chief-ray angle ({n_bins} bins of "
            f"{BIN_DEG} deg): too few to see a fall-off; check the pixel pitch and the "
            "exit-pupil distance, and that the flats hold signal")
    if single:
        notes.append("one flat: nothing cancels the source's non-uniformity or other fall-off "
                     "(cos^4 is divided out); use an integrating sphere, or flats at several "
                     "f-numbers")
    ratio_profiles = {}
    onsets = {"ratio": {}, "model": {}}
    R_ref = None if single else float(R[ref])
    for i in range(len(items) - (0 if single else 1)):
        f = float(fs[i])
        if single:
            prof = profiles[f]
            cos4 = np.cos(np.deg2rad(prof.cra_deg)) ** 4
            onsets["ratio"][f] = detect_onset(prof.cra_deg, prof.value / cos4, prof.stderr / cos4)
        else:
            ref_img = np.where(pimgs[ref] > LIT_FRACTION * ref_peak, pimgs[ref], 0.0)
            prof = radial_profile(pimgs[i], pvalid[i] & pvalid[ref], cra, bin_deg=BIN_DEG,
                                  denominator=ref_img)
            ratio_profiles[f] = prof
            onsets["ratio"][f] = detect_onset(prof.cra_deg, prof.value, prof.stderr)
        onsets["model"][f] = _model_onset(prof, float(R[i]), R_ref, x, max_cra,
                                          fixed_h=vignetting_distance_mm, natural=single)[0]

    # Eq. (26) over the onsets of each detector
    onset_fits = {det: _solve_onsets(onsets[det], base, vignetting_distance_mm)
                  for det in onsets}

    # the joint fit
    fit_idx = list(range(len(items) - (0 if single else 1)))
    q = np.stack([ratios[i] for i in fit_idx])
    okall = np.stack([rok[i] for i in fit_idx]).all(axis=0)
    data = BlockData(
        q=q[:, okall], sigma=np.sqrt(np.stack([rvars[i] for i in fit_idx]))[:, okall],
        xpix=bx[okall], ypix=by[okall], R_mm=R[fit_idx], R_ref_mm=R_ref, pitch_mm=pitch_mm,
        x_mm=x, natural=single)
    fix_center = center if (center_px is not None or single) else None
    # from the centre found and, should the contours have misled, from the image centre
    centers = [center]
    if fix_center is None:
        centers.append(((shape[1] - 1) / 2.0, (shape[0] - 1) / 2.0))
    starts = _starts(onset_fits.values(), R, x, centers, max_cra, vignetting_distance_mm)
    fits = {"none": fit_model(data, "none", [], center=center)}
    fits["one"] = fit_model(data, "one", starts, center=fix_center,
                            fixed_h=vignetting_distance_mm)
    # A second circle is tried only where one circle is needed at all.
    if not single and fits["one"].success and fits["one"].bic < fits["none"].bic:
        p1 = fits["one"].params
        starts2 = [[p1["P_mm"], p1["h_mm"], p1["cx_px"], p1["cy_px"], R[0] + h2 * math.tan(
            math.radians(th)), h2] for h2 in (0.5 * x, x, 2 * x) for th in (4.0, 10.0)]
        fits["two"] = fit_model(data, "two", starts2, center=fix_center)
    for k, v in fits.items():
        if not v.success:
            notes.append(f"the joint fit with {_CIRCLES[k]} stopped before converging "
                         f"({v.message})")
    model = min(fits, key=lambda k: fits[k].bic)
    bic_txt = ", ".join(f"{k}: {v.bic:.1f}" for k, v in fits.items())
    chosen = fits[model]
    if model != "none" and fix_center is None:
        center = (chosen.params["cx_px"], chosen.params["cy_px"])
        center_source = "joint fit"

    second = None
    misfit = model != "none" and chosen.reduced_chi2 > MISFIT_CHI2
    if model == "none" and fits["none"].reduced_chi2 > MISFIT_CHI2:
        notes.append(f"no model describes these flats well (reduced chi2 without a circle "
                     f"{fits['none'].reduced_chi2:.1f}); check the optical centre, the "
                     "f-numbers and the files")
    if method == "auto":
        if model == "none":
            used = "joint"
            reason = (f"no optical vignetting inside the field up to {max_cra:.1f} deg: the "
                      f"model without a circle has the lowest BIC ({bic_txt}); the "
                      "ideal-aperture model suffices")
        elif misfit and _sane(onset_fits["ratio"], x):
            used = "onset-ratio"
            reason = (f"the area model misfits the flats (reduced chi2 "
                      f"{chosen.reduced_chi2:.1f} > {MISFIT_CHI2}), so only where the fall-off "
                      "starts is trusted: Eq. (26) over the onsets of the ratio profiles")
        else:
            used = "joint"
            if misfit:
                notes.append(f"the joint fit misfits (reduced chi2 {chosen.reduced_chi2:.1f}) "
                             "but the paper's onsets give no usable P and h to fall back to")
            reason = (f"{_CIRCLES[model]}: lowest BIC ({bic_txt}); the joint fit uses every "
                      f"pixel (reduced chi2 {chosen.reduced_chi2:.2f})")
    else:
        used = method
        reason = f"method {method!r} asked for (joint-fit BIC {bic_txt})"
    if used == "joint":
        if model == "none":
            lens_P = lens_h = None
        elif model == "two":
            (lens_P, lens_h), second = _primary(chosen, R[0])
        else:
            lens_P, lens_h = chosen.params["P_mm"], chosen.params["h_mm"]
    else:
        of = onset_fits[used.split("-")[1]]
        if of is None:
            n_found = sum(o.found for o in onsets[used.split("-")[1]].values())
            raise ValueError(f"the {used} method needs onsets at two or more f-numbers (found "
                             f"{n_found} inside the field, up to {max_cra:.1f} deg); use the "
                             "joint fit")
        if not _sane(of, x):
            raise ValueError(f"the {used} method gives P = {of.P_mm:.4g} mm, h = "
                             f"{of.h_mm:.4g} mm, which is not a lens; use the joint fit")
        lens_P, lens_h = of.P_mm, of.h_mm
        model = "one"
    circles = [(lens_P, lens_h)] if lens_P is not None else []
    lens = Lens(x, circles, magnification, pupil_magnification, name=name)
    result = LensCalibration(
        lens=lens, method=used, model=model,
        reason=reason, f_numbers=fs, reference_f_number=None if single else float(fs[ref]),
        center_px=center, center_source=center_source, max_cra_deg=max_cra, onsets=onsets,
        onset_fits=onset_fits, fits=fits, profiles=profiles, ratio_profiles=ratio_profiles,
        pixel_pitch_um=float(pixel_pitch_um), shape=shape, notes=notes)
    calibration = _calibration_table(result, inputs)
    if second is not None:
        calibration["second_circle"] = second
    result.lens = Lens(x, circles, magnification, pupil_magnification, name=name,
                       calibration=calibration)
    return result


def _sane(of, x):
    """An Eq. (26) solution that describes a lens: P, h > 0, finite, not absurdly large."""
    return (of is not None and np.isfinite([of.P_mm, of.h_mm, of.P_stderr_mm]).all()
            and 0 < of.P_mm < 20 * x and 0 < of.h_mm < 20 * x)


def _model_onset(prof, R_F, R_ref, x, max_cra, fixed_h=None, natural=False):
    """Onset from fitting the vignetted-area ratio to one profile (model-based detection)."""
    tan = np.tan(np.deg2rad(prof.cra_deg))
    ok = prof.stderr > 0
    data = BlockData(q=prof.value[None, ok], sigma=prof.stderr[None, ok], xpix=tan[ok] * x,
                     ypix=np.zeros(ok.sum()), R_mm=np.array([R_F]), R_ref_mm=R_ref,
                     pitch_mm=1.0, x_mm=x, natural=natural)
    starts = [[R_F + h * math.tan(math.radians(th)), h, 0.0, 0.0]
              for h in ((fixed_h,) if fixed_h else (0.5 * x, 0.8 * x, 1.2 * x, 2.0 * x))
              for th in (0.1 * max_cra, 0.4 * max_cra, 0.7 * max_cra)]
    none = fit_model(data, "none", [], center=(0.0, 0.0))
    fit = fit_model(data, "one", starts, center=(0.0, 0.0), fixed_h=fixed_h, keep=3)
    if not fit.success or fit.bic >= none.bic:
        return Onset(float("nan"), float("inf"), False, max_cra), fit
    P, h = fit.params["P_mm"], fit.params["h_mm"]
    u = max(P - R_F, 0.0) / h
    on = math.degrees(math.atan(u))
    g = np.array([1.0, -u]) / (h * (1 + u * u)) if P > R_F else np.zeros(2)
    var = float(g @ fit.covariance[:2, :2] @ g)
    err = math.degrees(math.sqrt(max(var, 0.0))) if np.isfinite(var) else float("inf")
    if on > max_cra:
        return Onset(float("nan"), float("inf"), False, max_cra), fit
    return Onset(on, err, True, max_cra), fit


def _primary(fit: ModelFit, R0):
    """Of two circles, the one that starts cutting first at the lowest f-number."""
    p = fit.params
    c1 = (p["P_mm"], p["h_mm"])
    c2 = (p["P2_mm"], p["h2_mm"])

    def onset(c):
        return math.atan(max(c[0] - R0, 0.0) / c[1])

    first, other = (c1, c2) if onset(c1) <= onset(c2) else (c2, c1)
    return first, {"radius_mm": float(other[0]), "distance_mm": float(other[1]),
                   "note": "second vignetting circle of the two-circle fit (pixel vignetting "
                           "if h = x); the correction uses the first circle only"}


def _solve_onsets(onsets, base, h_given):
    """Eq. (26) over the onsets found (None with fewer than two, or one without h)."""
    # An onset at 0 means the circle cuts the pupil already on axis (P < R): that is an
    # inequality, not an equation of Eq. (26).
    # An onset without a finite error (at the start of the profile) cannot be weighted.
    found = [(f, o) for f, o in onsets.items()
             if o.found and o.cra_deg > 0 and np.isfinite(o.stderr_deg)]
    if h_given is not None and found:
        # h known: each onset gives P = R + h tan(onset); average them, weighted.
        t = np.tan(np.deg2rad([o.cra_deg for _, o in found]))
        Rf = base.exit_pupil_radius_mm([f for f, _ in found])
        P_i = Rf + h_given * t
        err = np.maximum(h_given * (1 + t * t) * np.deg2rad([o.stderr_deg for _, o in found]),
                         1e-12)
        w = 1.0 / err**2
        P = float(np.sum(w * P_i) / np.sum(w))
        return OnsetFit(P, float(h_given), float(1.0 / np.sqrt(np.sum(w))), 0.0, P_i - P)
    if len(found) < 2:
        return None
    t = np.array([o.cra_deg for _, o in found])
    if np.ptp(t) == 0:
        return None
    return solve_vignetting_circle(t, base.exit_pupil_radius_mm([f for f, _ in found]),
                                   onset_stderr_deg=[max(o.stderr_deg, 1e-3) for _, o in found])


def _starts(onset_fits, R, x, centers, max_cra, h_given):
    starts = []
    for cx, cy in centers:
        for of in onset_fits:
            if of is not None and of.h_mm > 0 and of.P_mm > 0:
                starts.append([of.P_mm, of.h_mm, cx, cy])
        for hf in (0.5, 0.8, 1.2, 2.0):
            h = h_given or hf * x
            for th in (0.3 * max_cra, 0.7 * max_cra):
                starts.append([R[0] + h * math.tan(math.radians(th)), h, cx, cy])
    return starts


def _clean(v):
    """TOML-safe: floats, with NaN/inf spelled out as strings."""
    v = float(v)
    return v if math.isfinite(v) else ("nan" if math.isnan(v) else "inf")


def _calibration_table(res: LensCalibration, inputs):
    fs = [float(f) for f in res.f_numbers]
    table = {
        "method": res.method,
        "model": res.model,
        "reason": res.reason,
        "date": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "snapcorr_version": __version__,
        "f_numbers": fs,
        "reference_f_number": res.reference_f_number if res.reference_f_number else "none",
        "center_px": [float(c) for c in res.center_px],
        "center_source": res.center_source,
        "pixel_pitch_um": res.pixel_pitch_um,
        "image_size_px": [int(res.shape[1]), int(res.shape[0])],
        "max_cra_deg": round(res.max_cra_deg, 4),
    }
    if res.lens.has_vignetting:
        table["onset_cra_deg"] = [_clean(v) for v in res.model_onsets_deg()]
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
    joint = {}
    for name, fit in res.fits.items():
        entry = {"bic": _clean(fit.bic), "reduced_chi2": _clean(fit.reduced_chi2),
                 "converged": bool(fit.success)}
        for k in fit.names:
            entry[k] = _clean(fit.params[k])
            entry[k.replace("_mm", "_stderr_mm").replace("_px", "_stderr_px")] = \
                _clean(fit.stderr[k])
        joint[name] = entry
    table["joint_fit"] = joint
    if inputs:
        table["inputs"] = {f"f/{float(k):g}": str(v) for k, v in inputs.items()}
    if res.notes:
        table["notes"] = list(res.notes)
    return table
