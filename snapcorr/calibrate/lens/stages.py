"""The stages of a lens calibration, each a function of the one before.

:func:`clean_flats` -> :func:`ratio_images` -> :func:`optical_center_rc` ->
:func:`profiles_and_onsets` (and :func:`solve_onsets`, Eq. 26) -> :func:`block_data` ->
:func:`joint_fits`; :mod:`snapcorr.calibrate.lens.choice` then picks the model and
:func:`snapcorr.calibrate.calibrate_lens` strings them together. Every optical centre here
is ``(row, col)``; the x-first keywords of earlier releases (``center_px``, ``center``,
``fix_center``, ``centers``) still work and warn (:func:`snapcorr._coords.accepts_center_rc`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..._coords import accepts_center_rc, called_from_outside, warn_x_first_return
from ..._validation import (
    check_center,  # noqa: F401 (snapcorr.calibrate.stages re-exports it)
    check_center_rc,
)
from ...optics.chief_ray import cra_map
from ...optics.lens import Lens
from ..flats.cleaning import _band_labels, clean_flat, remove_band_gains
from ..flats.onset_fit import OnsetFit, solve_vignetting_circle
from ..flats.onsets import Onset, detect_onset
from ..flats.radial import (
    estimate_center,  # noqa: F401 (re-exported, as above)
    estimate_center_rc,
    radial_profile,
)
from .joint_fit import (
    CIRCLE_MODELS,
    N_CIRCLES,
    BlockData,
    ModelFit,
    block_average,
    block_centroids,
    fit_model,
    floor_chi2,
)

__all__ = [
    "Flats",
    "Ratios",
    "block_data",
    "clean_flats",
    "joint_fits",
    "optical_center",
    "optical_center_rc",
    "pixel_rival",
    "profiles_and_onsets",
    "ratio_images",
    "solve_onsets",
    "without_band_gains",
]

#: Largest side of the block-averaged images used by the joint fit.
FIT_GRID = 160
#: Pixels where the reference flat is below this fraction of its peak are not used (past its
#: own cut-off a ratio is noise over noise).
LIT_FRACTION = 0.05
#: Width of the radial-profile bins, degrees of chief-ray angle.
BIN_DEG = 0.1
#: Largest side of the images the radial profiles are taken from (larger flats are binned).
PROFILE_SIZE = 1024


#: How the note begins that says the flats show no fall-off to find the optical centre by.
NO_FALL_OFF = "no radial fall-off to find the optical centre from"


@dataclass
class Flats:
    """Cleaned flats, sorted by f-number (the last is the reference of the ratios)."""

    f_numbers: np.ndarray
    images: list
    valids: list
    variances: list
    shape: tuple
    notes: list

    @property
    def single(self) -> bool:
        return len(self.images) == 1


@dataclass
class Ratios:
    """Block-averaged flats and their ratios to the reference flat."""

    block: int
    images: list  # block means of every flat
    variances: list
    enough: list  # blocks with enough valid pixels
    bx: np.ndarray  # block centres, full-resolution pixels
    by: np.ndarray
    ratios: list  # one per flat but the reference (the flats themselves for a single one)
    ratio_variances: list
    ratio_ok: list
    ref_peak: float | None
    centroids: list = None  # per flat: (dx, dy, sx, sy) of its valid pixels in each block
    # (the offsets along the columns, x, then the rows, y, as :class:`BlockData` holds them)


def without_band_gains(items, dark, saturation, sensor, origin_px):
    """Raw flats of a snapshot mosaic, dark subtracted, with each flat's band gains divided out
    (:func:`~snapcorr.calibrate.remove_band_gains`).

    Parameters
    ----------
    items : sequence of (float, ndarray)
        ``(f_number, raw frame)`` pairs.
    dark : ndarray, optional
        Dark frame subtracted from every flat before the gains are fitted.
    saturation : float or dict, optional
        Raw value at or above which a pixel is saturated (a dict: per f-number).
    sensor : Sensor
        The mosaic sensor.
    origin_px : (int, int), optional
        Sensor row and column of the frames' first pixel (default: the whole sensor).

    Returns
    -------
    items : list of (float, ndarray)
        The flats, NaN where saturated or carrying no filter.
    gains : dict
        f-number -> each band's gain (mean 1), in the sensor's band order.
    pixel_gains : dict
        f-number -> the gain divided out of each pixel (NaN: no filter), for the noise.
    """
    sat = saturation if isinstance(saturation, dict) else {f: saturation for f, _ in items}
    out, gains, pixel_gains = [], {}, {}
    for f, img in items:
        try:
            flat, gains[f] = remove_band_gains(img, sensor, origin_px=origin_px, dark=dark,
                                               saturation=sat.get(f))
        except ValueError as err:
            raise ValueError(f"the flat at f/{f:g}: {err}") from None
        labels = _band_labels(flat.shape, sensor, origin_px)
        pixel_gains[f] = np.where(labels >= 0, gains[f][np.maximum(labels, 0)], np.nan)
        out.append((f, flat))
    return out, gains, pixel_gains


def _pattern_hint(img, saturation, pixel_gains):
    """Where most pixels were masked only for standing out from their neighbours: a tile
    pattern, the raw frames of a snapshot mosaic whose band gains were not divided out."""
    plain = np.isfinite(img) & (img < saturation if saturation is not None else True)
    if pixel_gains or plain.mean() < 0.5:
        return ""
    return ("; most pixels stand out from their neighbours: if these are raw frames of a "
            "snapshot mosaic, give its sensor (sensor=) so that the band gains are "
            "divided out")


#: A flat whose pixels, grouped by their place in a k x k tile, differ in mean gain by more
#: than this (relative spread of the k*k means, each against its neighbourhood) is a mosaic's
#: raw frame; a sensor's own fixed pattern (PRNU, column gains) is a percent or less.
TILE_SPREAD = 0.05


def _tile_period(image, ok, periods=range(2, 9)):
    """``(k, spread)`` for a flat whose pixels repeat a ``k x k`` tile of gains: the ``k * k``
    positions' mean gains (each pixel over the mean of its 15 x 15 neighbourhood) spread by
    more than :data:`TILE_SPREAD` and by more than 10 times their noise; ``k`` the smallest
    tile with nearly the largest spread (a 4 x 4 tile also shows, less, in 2 x 2 and, as
    much, in 8 x 8). None for a flat without one."""
    import cv2

    img = np.where(ok, image, 0.0).astype(np.float32)
    w = ok.astype(np.float32)
    local = cv2.blur(img, (15, 15)) / np.maximum(cv2.blur(w, (15, 15)), 1e-6)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(ok & (local > 0), img / local, np.nan)
    if np.count_nonzero(np.isfinite(q)) < 64 * 64:
        return None
    found = {}
    for k in periods:
        means, errs = [], []
        for i in range(k):
            for j in range(k):
                v = q[i::k, j::k]
                v = v[np.isfinite(v)]
                if v.size < 16:
                    return None
                means.append(v.mean())
                errs.append(v.std() / np.sqrt(v.size))
        spread = float(np.std(means) / np.mean(means))
        if spread > TILE_SPREAD and spread > 10.0 * float(np.mean(errs)) / np.mean(means):
            found[k] = spread
    if not found:
        return None
    top = max(found.values())
    k = min(k for k, v in found.items() if v > 0.9 * top)
    return k, found[k]


#: A flat's largest value is a clipped plateau where at least this many pixels hold it, and
#: at least :data:`CLIP_RATIO` times as many as hold its next largest value (a smooth fall-off
#: rounded to whole numbers has about as many pixels at its top value as at the next).
CLIP_MIN_PIXELS = 16
CLIP_RATIO = 5.0


def clipped_level(image):
    """The value a flat is clipped at (its largest, held by a plateau of pixels: an ADC's or a
    file's limit, a float flat saturated where no type says where), or None."""
    a = np.asarray(image)
    a = a[np.isfinite(a)] if a.dtype.kind == "f" else a.ravel()
    if a.size < CLIP_MIN_PIXELS:
        return None
    top = a.max()
    at_top = int(np.count_nonzero(a == top))
    if at_top < CLIP_MIN_PIXELS:
        return None
    below = a[a < top]
    if below.size == 0:  # one value everywhere: clipped whole (accepted, such a flat was
        return float(top)  # calibrated with a note that no model described it)
    nxt = int(np.count_nonzero(below == below.max()))
    return float(top) if at_top >= CLIP_RATIO * nxt else None


def _lost_said(img, saturation):
    """What a flat's masked pixels are, for a refusal: most saturated (at which level)?"""
    a = np.asarray(img, float)
    if a.size and np.nanmin(a) == np.nanmax(a):  # no fall-off, no noise: clipped whole?
        return f"one value, {np.nanmax(a):g}, in every pixel: saturated whole or no flat field"
    with np.errstate(invalid="ignore"):
        share = 0.0 if saturation is None else float(np.mean(a >= saturation))
    return (f"{100 * share:.0f} % saturated, at or above {saturation:g}; the rest dead or "
            "non-finite" if share >= 0.5 else "saturated, dead or non-finite")


def clean_flats(items, dark, saturation, pixel_gains=None) -> Flats:
    """Dark-subtract and mask each flat (:func:`~snapcorr.calibrate.clean_flat`); refuse flats
    with too few usable pixels (< 20 %) or no signal.

    Parameters
    ----------
    items : sequence of (float, ndarray)
        ``(f_number, image)`` pairs, 2-D images of one shape, in increasing f-number (the
        last is the reference of the ratios; they are not sorted here).
    dark : ndarray, optional
        Dark frame subtracted from every flat (None: none).
    saturation : float or dict, optional
        Raw value at or above which a pixel is saturated; a dict gives it per f-number
        (missing or None: no saturation test).
    pixel_gains : dict, optional
        f-number -> the gain already divided out of each pixel (a mosaic's band gains,
        :func:`without_band_gains`), for each pixel's noise (:func:`clean_flat`).

    Returns
    -------
    Flats
    """
    sat = saturation if isinstance(saturation, dict) else {f: saturation for f, _ in items}
    notes = []
    images, valids, variances = [], [], []
    for f, img in items:
        clip = clipped_level(img)
        if clip is not None and (sat.get(f) is None or clip < sat[f]):
            count = int(np.count_nonzero(np.asarray(img) == clip))
            notes.append(f"f/{f:g}: {count} pixels hold its largest value, {clip:g}, exactly "
                         "(a clipped plateau: no other value is nearly so common): taken as "
                         "saturated and left out; give saturation= if that is wrong")
            sat = {**sat, f: clip}
        image, ok, var = clean_flat(img, dark=dark, saturation=sat.get(f),
                                    gain=(pixel_gains or {}).get(f))
        lost = 1.0 - ok.mean()
        if lost > 0.05:
            notes.append(f"f/{f:g}: {100 * lost:.1f} % of pixels masked (saturated, dead, hot "
                         "or non-finite)")
        raw = np.asarray(img, float) - (0.0 if dark is None else np.asarray(dark, float))
        with np.errstate(invalid="ignore"):
            lit = np.isfinite(raw) & (raw > 0)  # saturated pixels are lit
        if ok.mean() < 0.2 and lit.mean() < 0.2:  # nothing above its dark: say that
            bad = 1.0 - np.isfinite(raw).mean()
            if bad > 0.8:
                raise ValueError(f"the flat at f/{f:g} holds no number in {100 * bad:.0f} % of "
                                 "its pixels (NaN or infinite"
                                 + (", itself or in the dark" if dark is not None else "")
                                 + "): check the file")
            raise ValueError(f"the flat at f/{f:g} has no signal in {100 * (1 - lit.mean()):.0f} "
                             "% of its pixels (values at or below 0"
                             + (" after the dark" if dark is not None else "")
                             + "): check the file, its sign and the dark frame")
        if ok.mean() < 0.2:
            raise ValueError(f"the flat at f/{f:g} has only {100 * ok.mean():.0f} % usable "
                             f"pixels ({_lost_said(img, sat.get(f))}); lower the exposure or "
                             "check the file" + _pattern_hint(img, sat.get(f), pixel_gains))
        period = None if pixel_gains else _tile_period(image, ok)
        if period is not None:
            k, spread = period
            raise ValueError(f"the flat at f/{f:g} repeats a {k} x {k} pattern of pixel gains "
                             f"(its positions' means differ by {100 * spread:.0f} %): raw "
                             "frames of a snapshot mosaic; give its sensor (sensor=) "
                             "so that the band gains are divided out")
        images.append(image)
        valids.append(ok)
        variances.append(var)
    for (f, _), img, ok in zip(items, images, valids, strict=True):
        top = float(np.percentile(img[ok], 99))
        if not top > 0:
            raise ValueError(f"the flat at f/{f:g} has no signal (99 % of its pixels at or "
                             f"below {top:.4g}"
                             + (" after the dark" if dark is not None else "")
                             + "): check the file, its sign and the dark frame")
    return Flats(np.array([f for f, _ in items]), images, valids, variances,
                 items[0][1].shape, notes)


def ratio_images(flats: Flats) -> Ratios:
    """Block means of every flat and their ratios to the reference (highest f-number), only
    where the reference itself is lit: past its own cut-off a ratio is noise over noise."""
    block = max(1, math.ceil(max(flats.shape) / FIT_GRID))
    bimgs, bvars, bcnt, bx, by = block_average(flats.images, flats.valids, flats.variances,
                                               block)
    enough = [c >= 0.5 * block * block for c in bcnt]
    if flats.single:
        return Ratios(block, bimgs, bvars, enough, bx, by, bimgs, bvars, enough, None,
                      block_centroids(flats.valids, block))
    ref = len(bimgs) - 1
    ref_peak = float(np.nanpercentile(np.where(enough[ref], bimgs[ref], np.nan), 99))
    with np.errstate(invalid="ignore"):
        lit = (bimgs[ref] > LIT_FRACTION * ref_peak) & (bimgs[ref] > 5.0 * np.sqrt(bvars[ref]))
    ratios, rvars, rok = [], [], []
    for i in range(ref):
        with np.errstate(invalid="ignore", divide="ignore"):
            q = bimgs[i] / bimgs[ref]
            v = q * q * (bvars[i] / bimgs[i] ** 2 + bvars[ref] / bimgs[ref] ** 2)
        ratios.append(q)
        rvars.append(v)
        rok.append(enough[i] & enough[ref] & np.isfinite(q) & lit & (v > 0))
    return Ratios(block, bimgs, bvars, enough, bx, by, ratios, rvars, rok, ref_peak,
                  block_centroids(flats.valids, block))


def optical_center_rc(flats: Flats, ratios: Ratios, center_rc=None):
    """The optical centre ``(row, col)`` (pixels), how it was found, and a note if it could
    not be.

    Parameters
    ----------
    flats : Flats
    ratios : Ratios
        The flats' block means and ratios (:func:`ratio_images`); contours are traced in the
        ratios, else in the block means.
    center_rc : (row, col), optional
        A given centre, full-resolution pixels; returned as it is.

    Returns
    -------
    center_rc : (float, float)
        ``(row, col)`` in full-resolution pixels.
    source : {"given", "contours", "image centre"}
    note : str or None
        Set when no fall-off was found and the image centre is used.
    """
    if center_rc is not None:
        return check_center_rc(center_rc), "given", None
    c = None
    if not flats.single:
        c, _ = estimate_center_rc(ratios.ratios, ratios.ratio_ok)
    if c is None:
        c, _ = estimate_center_rc(ratios.images, ratios.enough)
    if c is None:
        shape = flats.shape
        return (((shape[0] - 1) / 2.0, (shape[1] - 1) / 2.0), "image centre",
                NO_FALL_OFF + ": the image centre is used")
    b = ratios.block  # block coordinates -> pixels
    return (c[0] * b + (b - 1) / 2.0, c[1] * b + (b - 1) / 2.0), "contours", None


@accepts_center_rc
def optical_center(flats: Flats, ratios: Ratios, center_px=None, *, center_rc=None):
    """The optical centre x first, ``(cx, cy)``: the earlier form of
    :func:`optical_center_rc`, which gives it row first; removed in snapcorr 0.3.

    Parameters
    ----------
    flats, ratios
        As for :func:`optical_center_rc`.
    center_rc, center_px : (row, col), optional
        A given centre; ``center_px=(cx, cy)``, in its old place, is the deprecated x-first
        form.

    Returns
    -------
    center : (float, float)
        ``(cx, cy)``, x first.
    source, note
        As for :func:`optical_center_rc`.
    """
    if called_from_outside(2):
        warn_x_first_return("optical_center", "optical_center_rc")
    (row, col), source, note = optical_center_rc(flats, ratios, center_rc)
    return (col, row), source, note


@accepts_center_rc(old="center", new="center_rc")
def profiles_and_onsets(flats: Flats, ratios: Ratios, center_rc, base: Lens, pixel_pitch_um,
                        fixed_h=None):
    """Radial profiles of every flat and of every ratio, and the onsets found in them by the
    paper's discontinuity (``"ratio"``) and by the area model per profile (``"model"``).

    Parameters
    ----------
    flats : Flats
    ratios : Ratios
        From :func:`ratio_images` (its reference peak sets which pixels are lit).
    center_rc : (row, col)
        Optical centre, full-resolution pixels (``center=(cx, cy)`` is its deprecated
        x-first form).
    base : Lens
        Its exit-pupil distance turns pixels into chief-ray angles.
    pixel_pitch_um : float
        Pixel pitch, micrometres.
    fixed_h : float, optional
        The circle's ``h`` held fixed in the model-based detection, mm.

    Returns
    -------
    profiles : dict
        f-number -> :class:`~snapcorr.calibrate.RadialProfile` of the flat.
    ratio_profiles : dict
        f-number -> profile of its ratio to the reference flat (empty for a single flat).
    onsets : dict
        ``{"ratio": {f: Onset}, "model": {f: Onset}}``, for every flat but the reference (for
        a single flat: that flat, its profile divided by ``cos^4``).
    max_cra_deg : float
        Largest chief-ray angle on the sensor, degrees.
    """
    shape, x = flats.shape, base.exit_pupil_mm
    # from pixels binned k x k on large sensors (k <= PROFILE_SIZE / side keeps a binned pixel
    # well under a bin's 0.1 deg)
    k = max(1, math.ceil(max(shape) / PROFILE_SIZE))
    if k > 1:
        pimgs, _, pcnt, _, _ = block_average(flats.images, flats.valids, flats.variances, k)
        pvalid = [c >= 0.5 * k * k for c in pcnt]
        pimgs = [np.where(ok, im, 0.0) for im, ok in zip(pimgs, pvalid, strict=True)]
        pcenter = ((center_rc[0] - (k - 1) / 2.0) / k, (center_rc[1] - (k - 1) / 2.0) / k)
    else:
        pimgs, pvalid, pcenter = flats.images, flats.valids, center_rc
    cra = cra_map(pimgs[0].shape, pixel_pitch_um * k, x, center_rc=pcenter)
    full_cra = cra_map(shape, pixel_pitch_um, x, center_rc=center_rc)
    max_cra, min_cra = float(full_cra.max()), float(full_cra.min())
    fs = flats.f_numbers
    profiles = {float(f): radial_profile(pimgs[i], pvalid[i], cra, bin_deg=BIN_DEG)
                for i, f in enumerate(fs)}
    short = [f for f, p in profiles.items() if p.cra_deg.size < 8]
    if short:
        n_bins = profiles[short[0]].cra_deg.size
        r, c = center_rc
        outside = not (-0.5 <= r <= shape[0] - 0.5 and -0.5 <= c <= shape[1] - 0.5)
        raise ValueError(
            f"the flats span only {min_cra:.2f}-{max_cra:.2f} deg of chief-ray angle "
            f"({n_bins} bins of {BIN_DEG} deg) about the optical centre at row {r:g}, column "
            f"{c:g}: too few to see a fall-off; "
            + (f"that centre lies outside the {shape[0]} x {shape[1]} px flats: check it "
               "(center_rc=), " if outside else "check ")
            + "the pixel pitch and the exit-pupil distance, and that the flats hold signal")
    R = base.exit_pupil_radius_mm(fs)
    single = flats.single
    R_ref = None if single else float(R[-1])
    ratio_profiles, onsets = {}, {"ratio": {}, "model": {}}
    for i in range(len(fs) - (0 if single else 1)):
        f = float(fs[i])
        if single:
            prof = profiles[f]
            cos4 = np.cos(np.deg2rad(prof.cra_deg)) ** 4
            onsets["ratio"][f] = detect_onset(prof.cra_deg, prof.value / cos4, prof.stderr / cos4)
        else:
            ref_img = np.where(pimgs[-1] > LIT_FRACTION * ratios.ref_peak, pimgs[-1], 0.0)
            prof = radial_profile(pimgs[i], pvalid[i] & pvalid[-1], cra, bin_deg=BIN_DEG,
                                  denominator=ref_img)
            ratio_profiles[f] = prof
            if np.count_nonzero(np.isfinite(prof.value) & (prof.stderr > 0)) < 8:
                raise ValueError(
                    f"the flat at f/{f:g} divided by the flat at f/{float(fs[-1]):g} leaves no "
                    "profile with a spread to read an onset from (fewer than 8 bins that vary"
                    "): are they the same frames? Each flat must be taken at its own "
                    "f-number")
            onsets["ratio"][f] = detect_onset(prof.cra_deg, prof.value, prof.stderr)
        onsets["model"][f] = _model_onset(prof, float(R[i]), R_ref, x, max_cra,
                                          fixed_h=fixed_h, natural=single,
                                          ray_weight=base.ray_weight)
    return profiles, ratio_profiles, onsets, max_cra


def _model_onset(prof, R_F, R_ref, x, max_cra, fixed_h=None, natural=False, ray_weight="area"):
    """Onset from fitting the vignetted-area ratio to one profile (model-based detection)."""
    tan = np.tan(np.deg2rad(prof.cra_deg))
    ok = prof.stderr > 0
    data = BlockData(q=prof.value[None, ok], sigma=prof.stderr[None, ok], xpix=tan[ok] * x,
                     ypix=np.zeros(ok.sum()), R_mm=np.array([R_F]), R_ref_mm=R_ref,
                     pitch_mm=1.0, x_mm=x, natural=natural, ray_weight=ray_weight)
    starts = [[R_F + h * math.tan(math.radians(th)), h, 0.0, 0.0]
              for h in ((fixed_h,) if fixed_h else (0.5 * x, 0.8 * x, 1.2 * x, 2.0 * x))
              for th in (0.1 * max_cra, 0.4 * max_cra, 0.7 * max_cra)]
    none = fit_model(data, "none", [], center_rc=(0.0, 0.0))
    fit = fit_model(data, "one", starts, center_rc=(0.0, 0.0), fixed_h=fixed_h, keep=3)
    if not fit.success or fit.bic >= none.bic:
        return Onset(float("nan"), float("inf"), False, max_cra)
    P, h = fit.params["P_mm"], fit.params["h_mm"]
    u = max(P - R_F, 0.0) / h
    on = math.degrees(math.atan(u))
    g = np.array([1.0, -u]) / (h * (1 + u * u)) if P > R_F else np.zeros(2)
    var = float(g @ fit.covariance[:2, :2] @ g)
    err = math.degrees(math.sqrt(max(var, 0.0))) if np.isfinite(var) else float("inf")
    if on > max_cra:
        return Onset(float("nan"), float("inf"), False, max_cra)
    return Onset(on, err, True, max_cra)


def solve_onsets(onsets, base: Lens, h_given=None) -> OnsetFit | None:
    """Eq. (26) over the onsets found (None with fewer than two, or one without h).

    Only onsets found at a CRA > 0 with a finite standard error are used.

    Parameters
    ----------
    onsets : dict
        f-number -> :class:`~snapcorr.calibrate.flats.onsets.Onset`.
    base : Lens
        Gives the exit-pupil radius at each f-number (Eq. 27-28).
    h_given : float, optional
        Known ``h``, mm: then each onset gives ``P = R + h tan(onset)`` and ``P`` is their
        weighted mean (one onset suffices).

    Returns
    -------
    OnsetFit or None
    """
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
        sP = float(1.0 / np.sqrt(np.sum(w)))
        return OnsetFit(P, float(h_given), sP, 0.0, P_i - P, np.diag([sP * sP, 0.0]))
    if len(found) < 2:
        return None
    t = np.array([o.cra_deg for _, o in found])
    if np.ptp(t) == 0:
        return None
    try:
        return solve_vignetting_circle(t, base.exit_pupil_radius_mm([f for f, _ in found]),
                                       onset_stderr_deg=[max(o.stderr_deg, 1e-3)
                                                         for _, o in found])
    except ValueError:  # onsets no circle fits (a centre far off): as too few of them
        return None


def block_data(flats: Flats, ratios: Ratios, base: Lens, pixel_pitch_um) -> BlockData:
    """The blocks to fit, ready for :func:`fit_model`: every flat's block means where the
    reference (highest f-number) flat is lit, each block's gain to be solved for; a single
    flat as it is (its fall-off taken as ``cos^4``).

    Parameters
    ----------
    flats : Flats
    ratios : Ratios
        From :func:`ratio_images`.
    base : Lens
        Exit-pupil distance and radius at each f-number.
    pixel_pitch_um : float
        Pixel pitch, micrometres.

    Returns
    -------
    BlockData
        Blocks used by at least two flats, the reference among them.
    """
    R = base.exit_pupil_radius_mm(flats.f_numbers)
    common = dict(pitch_mm=pixel_pitch_um * 1e-3, x_mm=base.exit_pupil_mm,
                  ray_weight=base.ray_weight)
    if flats.single:
        ok = ratios.ratio_ok[0]
        return BlockData(q=ratios.ratios[0][None, ok],
                         sigma=np.sqrt(ratios.ratio_variances[0])[None, ok],
                         xpix=ratios.bx[ok], ypix=ratios.by[ok], R_mm=R, R_ref_mm=None,
                         natural=True, block_px=ratios.block,
                         **{k: ratios.centroids[0][i][None, ok]
                            for i, k in enumerate(("xoff", "yoff", "xsd", "ysd"))},
                         **common)
    imgs = np.stack(ratios.images)
    var = np.stack(ratios.variances)
    with np.errstate(invalid="ignore"):
        used = np.stack(ratios.enough) & np.isfinite(imgs) & (var > 0)
        ref = imgs[-1]
        lit = (ref > LIT_FRACTION * ratios.ref_peak) & (ref > 5.0 * np.sqrt(var[-1]))
    keep = lit & used[-1] & (used.sum(axis=0) >= 2)
    used = used[:, keep]
    return BlockData(q=np.where(used, imgs[:, keep], 0.0),
                     sigma=np.where(used, np.sqrt(np.where(used, var[:, keep], 1.0)), np.inf),
                     xpix=ratios.bx[keep], ypix=ratios.by[keep], R_mm=R, R_ref_mm=None,
                     gains=True, block_px=ratios.block,
                     **{k: np.stack([c[i][keep] for c in ratios.centroids])
                        for i, k in enumerate(("xoff", "yoff", "xsd", "ysd"))},
                     **common)


def _starts_one(onset_fits, R, x, centers_rc, max_cra, h_given):
    starts = []
    for row, col in centers_rc:
        for of in onset_fits:
            if of is not None and of.h_mm > 0 and of.P_mm > 0:
                starts.append([of.P_mm, of.h_mm, row, col])
        for hf in (0.5, 0.8, 1.2, 2.0):
            h = h_given or hf * x
            # the fastest pupil cut from near the axis to the far corner of the field
            for frac in (0.15, 0.3, 0.45, 0.6, 0.75, 0.9):
                th = math.radians(frac * max_cra)
                starts.append([R[0] + h * math.tan(th), h, row, col])
    return starts


def _starts_more(fit: ModelFit, R, x, max_cra):
    """Starts for one more circle, added to the fit so far.

    A circle that cuts nothing in the field has no gradient, and one that cuts much fits worse
    than none, so neither is a useful start. For each distance ``h`` (against the chief ray,
    in front of the pupil, pixel vignetting at ``h = x``, behind it) the start's ``P`` is just
    inside the largest radius that still cuts the light somewhere in the field at some
    f-number: the farthest point of the vignetted pupil from the circle's centre
    (:func:`~snapcorr.optics.discs.extreme_radii`)."""
    from ...optics.discs import extreme_radii
    from .joint_fit import circles_of

    p = [fit.params[k] for k in fit.names]
    circles = circles_of(fit.model, p)
    t = np.linspace(0.0, math.tan(math.radians(max_cra)), 64)[:, None]
    Rs = np.asarray(R, float)[None, :]
    radii = [Rs] + [P for P, _ in circles]
    centers = [0.0 * t] + [h * t for _, h in circles]
    starts = []
    for hf in (-1.0, -0.5, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0):
        h = hf * x
        _, rmax = extreme_radii(h * t, radii, centers)
        P_crit = float(np.max(rmax))
        starts += [[*p, P_crit * (1.0 - d), h] for d in (0.002, 0.01, 0.03, 0.1)]
    return starts


@accepts_center_rc(old="fix_center", new="fix_center_rc")
def pixel_rival(data: BlockData, fit: ModelFit, R, x, max_cra, fix_center_rc=None):
    """The fit's circles and one more at ``h = x``, its P alone fitted: pixel vignetting.

    The pixel's acceptance cone is a circle that moves with the chief ray at the exit pupil's
    own distance, so it costs the flats one parameter, not two. Near the noise that decides:
    a pixel-vignetting circle that moves the mean shift by 0.2 nm at 5 % noise per pixel
    (about 4 Cramér-Rao standard deviations) lowers the chi-square by 15-32, under the
    ``2 ln n`` a free circle pays, and the free fit's P and h wander along the valley of
    onsets they share (or it stops elsewhere); held at ``h = x`` its P comes out within
    0.2 % and the evidence clears one ``ln n``. Where its BIC is lower than the free fit's it
    is the two-circle model (the cheaper of two that fit alike); else it is a rival of the
    model chosen in the error of the shift
    (:func:`~snapcorr.calibrate.lens.choice.model_choice_stderr`).

    Parameters
    ----------
    data : BlockData
        The blocks the joint fits were fitted to (:func:`block_data`).
    fit : ModelFit
        The fit whose circles are kept as starting points (one circle, as a rule).
    R : array
        The exit pupil's radius at each f-number (mm).
    x : float
        The exit pupil's distance (mm): the pixel's circle's h, held.
    max_cra : float
        The largest chief-ray angle in the field (degrees), for the starting points.
    fix_center_rc : (row, col), optional
        The centre, held, as in the other joint fits; None: fitted. ``fix_center=(cx, cy)``
        is its deprecated x-first form.

    Returns
    -------
    ModelFit
        With one circle more than ``fit``; its last h is ``x`` with no standard error.
    """
    n = N_CIRCLES[fit.model] + 1
    starts = [s for s in _starts_more(fit, R, x, max_cra) if s[-1] == x]
    return fit_model(data, CIRCLE_MODELS[n], starts, center_rc=fix_center_rc, keep=1,
                     fixed={f"h{n}_mm": x})


@accepts_center_rc(old="centers", new="centers_rc", many=True)
@accepts_center_rc(old="fix_center", new="fix_center_rc")
def joint_fits(data: BlockData, base: Lens, fs, onset_fits, centers_rc, fix_center_rc, max_cra,
               *, fixed_h=None, max_circles=3, keep_going=None, progress=None, rivals=None):
    """Fit the area model with no circle, then one, two, three circles, each from the last.

    A model with one more circle is fitted only while ``keep_going(fits, bic)`` says the one
    with most circles so far is chosen (one that is not cannot be the base of a better one).

    Parameters
    ----------
    data : BlockData
        From :func:`block_data`; without gains (a single flat) at most one circle is fitted.
    base : Lens
        Exit-pupil distance and radius at each f-number.
    fs : array_like
        f-numbers of the flats, in the order of ``data``.
    onset_fits : iterable of (OnsetFit or None)
        Eq. (26) solutions used as starts for the first circle (those with ``P, h > 0``).
    centers_rc : list of (row, col)
        Starting optical centres, pixels; the first is the no-circle model's (and the one
        its floored criterion is taken at when the centre is fixed). ``centers``, x first,
        is its deprecated form.
    fix_center_rc : (row, col) or None
        Centre held fixed in the fits with circles (the caller passes ``centers_rc[0]``);
        None: fitted. ``fix_center=(cx, cy)`` is its deprecated x-first form.
    max_cra : float
        Largest chief-ray angle of the field, degrees.
    fixed_h : float, optional
        The circle's ``h`` held fixed, mm; then at most one circle is fitted.
    max_circles : int
        Most circles to fit (0-3).
    keep_going : callable, optional
        ``keep_going(fits, bic) -> bool``; None: always go on.
    progress : callable, optional
        ``progress(step)`` before each model is fitted.
    rivals : dict, optional
        Filled, where two circles are fitted, with ``"pixel"``: ``(fit, floored BIC)`` of the
        first circle plus pixel vignetting (:func:`pixel_rival`); or, where that has the
        lower BIC (the free h does not buy its ``ln n``), it becomes the two-circle model
        and the free fit is the rival, ``"free"``.

    Returns
    -------
    fits : dict
        Model name -> :class:`ModelFit`.
    bic : dict
        Model name -> its information criterion with the systematic floor
        (:data:`~snapcorr.calibrate.lens.choice.FLOOR_REL`).
    """
    from .choice import FLOOR_REL

    x = base.exit_pupil_mm
    R = base.exit_pupil_radius_mm(fs)
    fits, bic = {}, {}

    def floored(name, fit):
        c = centers_rc[0] if name == "none" or fix_center_rc is not None else None
        return floor_chi2(data, fit, FLOOR_REL, center_rc=c) + fit.k * math.log(fit.n)

    def add(name, fit):
        fits[name] = fit
        bic[name] = floored(name, fit)

    def step(what):
        if progress is not None:
            progress(what)

    add("none", fit_model(data, "none", [], center_rc=centers_rc[0]))
    if max_circles < 1:
        return fits, bic
    step("joint fit, one circle")
    add("one", fit_model(data, "one", _starts_one(onset_fits, R, x, centers_rc, max_cra,
                                                  fixed_h),
                         center_rc=fix_center_rc, fixed_h=fixed_h))
    single = not data.gains
    for n in range(2, max_circles + 1):
        if single or fixed_h is not None or (keep_going is not None
                                             and not keep_going(fits, bic)):
            break
        prev = fits[CIRCLE_MODELS[n - 1]]
        step(f"joint fit, {n} circles")
        # two runs for a second circle; one for a third, which rarely matters
        add(CIRCLE_MODELS[n], fit_model(data, CIRCLE_MODELS[n], _starts_more(prev, R, x, max_cra),
                                 center_rc=fix_center_rc, keep=2 if n == 2 else 1))
        if n == 2 and rivals is not None:
            pixel = pixel_rival(data, prev, R, x, max_cra, fix_center_rc)
            b = floored(CIRCLE_MODELS[n], pixel)
            if pixel.success and b < bic[CIRCLE_MODELS[n]]:
                # the second circle at h = x fits as well for one parameter less: the two
                # circles are those, and the free h is the rival
                rivals["free"] = (fits[CIRCLE_MODELS[n]], bic[CIRCLE_MODELS[n]])
                fits[CIRCLE_MODELS[n]], bic[CIRCLE_MODELS[n]] = pixel, b
            else:
                rivals["pixel"] = (pixel, b)
    return fits, bic
