"""Lens calibration judged on flats from the independent simulator (tests/oracles/flatsim.py).

The criterion is functional: the calibrated lens must predict the TRUE lens's mean filter
shift (Goossens 2019, Eq. 22; ``mean_shift(..., method="vignetted")``, 1000 nm, n_eff 1.5)
within 0.01 nm (one-circle truth) or 0.02 nm (two circles) at every chief-ray angle of the
field (0 .. its largest angle, where both lenses pass light; ``res.max_cra_deg`` is the same
up to the optical centre it found) and at every f-number of the flats. Where a circle is
identifiable (its onset, Eq. 24-25, inside the field at two or more f-numbers; the onset where
it starts to cut what the pupil and the other circles leave) its P and h must come out within
1 %. A stop-like circle (|h| < 0.05 x, or P within
1 % of a pupil radius R_F with |h| < x / 4) that the truth does not have must never be chosen.

What the flats can tell is limited: no unbiased estimator beats the Cramér-Rao bound
(tests/oracles/cramer_rao.py, written without snapcorr). A tolerance counts as within reach where
``REACH`` standard deviations of the bound's mean shift (largest over f-numbers) fit inside it,
and a circle's 1 % where ``REACH`` of its parameters' do. Within reach the criterion above
holds. Beyond it (a weak circle at 5 % noise per pixel, pixel vignetting at 2 %: no method can
meet the tolerance there) the calibration must say how far it can be trusted instead: its
error stays within ``REACH`` of the standard errors it reports, or within the shift difference
to the richer model it reports it could not rule out; and its standard errors are not smaller
than the bound allows (0.7 of it at least). A true circle may be left out only where its
effect on the shift is under ``DETECT`` of the bound's standard deviations (the model
choice needs about 6 of evidence, and the evidence scatters), and then the error must be no
more than that effect and the reported error bars.

The default run holds a handful of representative cases on 640 x 512 flats whose pixels are
twice the pitch of the user's 1280 x 1024 sensor (the same chief-ray angles; a quarter of the
pixels, so twice the statistical error); the matrix over noise and seeds on the full-size
sensor, and the user's full-size scene, are ``slow``.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, replace

import numpy as np
import pytest
from conftest import PAPER_TRUTH
from cramer_rao import bound, shift_bound_nm
from flatsim import LensTruth, make_flats, mean_shift_nm, relative_illumination

import snapcorr
from snapcorr.calibrate import calibrate_lens

X = 21.0
CWL, N_EFF = 1000.0, 1.5
F_NUMBERS = (2.0, 2.8, 4.0, 5.6, 11.0)
FULL = dict(shape=(1024, 1280), pitch_um=7.1, center_px=(700.0, 480.0))
HALF = dict(shape=(512, 640), pitch_um=14.2, center_px=(350.0, 240.0))  # same angles
QUARTER = dict(shape=(256, 320), pitch_um=28.4, center_px=(174.75, 119.75))

TRUTHS = {
    # the paper's Edmund Optics 16 mm (Goossens 2019, Eq. 31): h < x
    "one_h_lt_x": replace(PAPER_TRUTH, name="one circle, h < x"),
    # h > x: onsets at f/2, 2.8, 4 and 5.6 inside the field
    "one_h_gt_x": LensTruth(X, ((9.5, 26.0),), 0.0, 1.0, name="one circle, h > x"),
    "one_h_gt_x_m": LensTruth(X, ((9.5, 26.0),), 0.06, 1.3, name="one circle, h > x, m > 0"),
    # a weak circle: it cuts only the outer field, at f/2 and f/2.8 (tan CRA 0.23 and 0.28)
    "one_weak": LensTruth(X, ((12.0, 30.0),), 0.06, 1.3, name="one weak circle, h > x"),
    # a front (h < x) and a rear (h > x) circle, each the one that cuts (its effective onset)
    # inside the field at >= 2 f-numbers: the front one at f/2 and f/2.8, the rear one from
    # f/2 to f/5.6 (tan CRA 0.08, 0.21 and 0.21-0.27; the field reaches 0.30)
    "two_front_rear": LensTruth(X, ((6.2, 12.0), (10.0, 30.0)), 0.0, 1.0,
                                name="front and rear circle"),
    # front circle moving against the chief ray (h < 0) and a rear one: they cut opposite sides
    "two_opposite": LensTruth(X, ((6.0, -8.0), (9.5, 30.0)), 0.0, 1.0,
                              name="circles on opposite sides"),
    # the paper's circle plus pixel vignetting (h = x): the paper's circle cuts first (f/2,
    # f/2.8), the pixel's acceptance past tan CRA 0.27-0.29 (f/2-f/4)
    "circle_pixel": LensTruth(X, ((7.4236, 16.991), (8.5, X)), 0.06, 1.3,
                              name="circle plus pixel vignetting"),
    # a circle whose onset lies outside the field at every f-number
    "none_in_field": LensTruth(X, ((12.0, 17.0),), 0.06, 1.3, name="no circle in the field"),
    "no_circle": LensTruth(X, (), 0.0, 1.0, name="no circle at all"),
}


# -- compatibility with the lens API before and after lenses took several circles ----------
def make_lens(truth):
    """The truth as a snapcorr.Lens, or None if this snapcorr cannot hold its circles."""
    try:
        return snapcorr.Lens(truth.exit_pupil_mm, vignetting=truth.circles,
                             magnification=truth.magnification,
                             pupil_magnification=truth.pupil_magnification, name=truth.name)
    except TypeError:  # one-circle Lens(name, x, P, h, m, m_P)
        if len(truth.circles) > 1:
            return None
        P, h = truth.circles[0] if truth.circles else (None, None)
        return snapcorr.Lens(truth.name, truth.exit_pupil_mm, P, h, truth.magnification,
                             truth.pupil_magnification)


def lens_circles(lens):
    v = getattr(lens, "vignetting", None)
    if v is not None and not isinstance(v, (int, float)):
        return tuple((float(P), float(h)) for P, h in v)
    if lens.has_vignetting:
        return ((float(lens.vignetting_radius_mm), float(lens.vignetting_distance_mm)),)
    return ()


# -- judging one calibration ----------------------------------------------------------------
@dataclass
class Outcome:
    truth: LensTruth
    noise: float
    seed: int
    model: str
    circles: tuple
    max_cra_deg: float
    field_cra_deg: float
    shift_error_nm: float
    worst_at: tuple  # (f-number, CRA) of the largest error
    circle_errors: list  # per identifiable true circle: (P err %, h err %) or None if missed
    center_error_px: float
    pixel_error_nm: float  # the same, pixel by pixel, each lens at its own optical centre
    spurious: list
    res: object
    scene: dict = None
    f_numbers: tuple = F_NUMBERS

    def describe(self):
        errs = ", ".join("missed" if e is None else f"P {e[0]:+.3f} % h {e[1]:+.3f} %"
                         for e in self.circle_errors)
        circ = ", ".join(f"(P {P:.4f}, h {h:.3f})" for P, h in self.circles) or "none"
        return (f"{self.truth.name} {self.truth.circles}, noise {100 * self.noise:g} %, seed "
                f"{self.seed}: chose {self.model} -> {circ}; max |shift error| "
                f"{self.shift_error_nm:.4f} nm at f/{self.worst_at[0]:g}, "
                f"{self.worst_at[1]:.2f} deg; identifiable circles: {errs or '-'}; "
                f"spurious: {self.spurious or '-'}; max CRA {self.max_cra_deg:.2f} "
                f"(field {self.field_cra_deg:.2f}); centre off by {self.center_error_px:.2f} "
                f"px; pixel by pixel {self.pixel_error_nm:.4f} nm")


def field_cra_deg(scene, x=X):
    cx, cy = scene["center_px"]
    rows, cols = scene["shape"]
    corners = [(0, 0), (0, rows - 1), (cols - 1, 0), (cols - 1, rows - 1)]
    rho = max(math.hypot(u - cx, v - cy) for u, v in corners) * scene["pitch_um"] * 1e-3
    return math.degrees(math.atan(rho / x))


def effective_onset_tan(truth, f_number, i, t_max=0.6, n=3001):
    """Smallest tan(CRA) where circle ``i`` removes more than 0.1 % of the pupil that the pupil
    and the other circles leave (inf if nowhere up to ``t_max``): a circle hidden behind
    another one has no onset of its own."""
    t = np.linspace(0.0, t_max, n)
    others = LensTruth(truth.exit_pupil_mm,
                       tuple(c for j, c in enumerate(truth.circles) if j != i),
                       truth.magnification, truth.pupil_magnification)
    cut = relative_illumination(others, f_number, t) - relative_illumination(truth, f_number, t)
    k = np.nonzero(cut > 1e-3)[0]
    return float(t[k[0]]) if k.size else np.inf


def identifiable(truth, f_numbers, max_cra_deg):
    """Indices of true circles whose (effective) onset lies inside the field at >= 2
    f-numbers."""
    t_max = math.tan(math.radians(max_cra_deg))
    return [i for i in range(len(truth.circles))
            if sum(effective_onset_tan(truth, f, i) < t_max for f in f_numbers) >= 2]


def spurious_circles(circles, truth, f_numbers):
    """Stop-like circles: |h| < 0.05 x, or P within 1 % of some R_F with |h| < x / 4."""
    x = truth.exit_pupil_mm
    R = [float(truth.pupil_radius_mm(f)) for f in f_numbers]
    out = []
    for P, h in circles:
        near_R = min(abs(P - r) / r for r in R) < 0.01
        if abs(h) < 0.05 * x or (near_R and abs(h) < 0.25 * x):
            out.append((P, h))
    return out


def shift_errors_by_f(truth, lens, f_numbers, max_cra_deg, n=121):
    """At each f-number: the largest |mean-shift error| over 0..max CRA where both lenses pass
    light, and the CRA where it is (0, 0 where neither does). The truth's shift comes from
    snapcorr's closed form where its circles are ordinary ones, else from the simulator's own
    quadrature (``flatsim.mean_shift_nm``)."""
    true_lens = make_lens(truth)
    got_truth = LensTruth(truth.exit_pupil_mm, lens_circles(lens), lens.magnification,
                          lens.pupil_magnification)
    cra = np.linspace(0.0, max_cra_deg, n)
    t = np.tan(np.deg2rad(cra))
    out = []
    for f in f_numbers:
        lit = (relative_illumination(truth, f, t) > 1e-6) & (
            relative_illumination(got_truth, f, t) > 1e-6)
        c = cra[lit]
        if c.size == 0:
            out.append((0.0, 0.0))
            continue
        if true_lens is not None:
            want = snapcorr.mean_shift(CWL, N_EFF, f, c, true_lens, method="vignetted")
        else:
            want = mean_shift_nm(truth, CWL, N_EFF, f, c)
        got = snapcorr.mean_shift(CWL, N_EFF, f, c, lens, method="vignetted")
        err = np.abs(np.asarray(got) - np.asarray(want))
        i = int(np.argmax(err))
        out.append((float(err[i]), float(c[i])))
    return out


def shift_error(truth, lens, f_numbers, max_cra_deg, n=121):
    """Largest |mean-shift error| over 0..max CRA and the f-numbers, and (f-number, CRA)
    where it is."""
    per_f = shift_errors_by_f(truth, lens, f_numbers, max_cra_deg, n)
    k = int(np.argmax([e for e, _ in per_f]))
    return per_f[k][0], (f_numbers[k], per_f[k][1])


def pixel_error(truth, res, scene, f_numbers, step=8):
    """Largest |mean-shift error| over a grid of pixels: the calibrated lens at the chief-ray
    angles of its own optical centre against the true lens at the true ones (NaN if this
    snapcorr cannot hold the truth)."""
    true_lens = make_lens(truth)
    if true_lens is None:
        return np.nan
    rows, cols = scene["shape"]
    yy, xx = np.mgrid[0:rows:step, 0:cols:step]
    k = scene["pitch_um"] * 1e-3 / truth.exit_pupil_mm
    t_true = k * np.hypot(xx - scene["center_px"][0], yy - scene["center_px"][1]).ravel()
    t_cal = k * np.hypot(xx - res.center_rc[1], yy - res.center_rc[0]).ravel()
    got_truth = LensTruth(truth.exit_pupil_mm, lens_circles(res.lens), res.lens.magnification,
                          res.lens.pupil_magnification)
    worst = 0.0
    for f in f_numbers:
        lit = (relative_illumination(truth, f, t_true) > 1e-6) & (
            relative_illumination(got_truth, f, t_cal) > 1e-6)
        if not lit.any():
            continue
        want = snapcorr.mean_shift(CWL, N_EFF, f, np.rad2deg(np.arctan(t_true[lit])),
                                   true_lens, method="vignetted")
        got = snapcorr.mean_shift(CWL, N_EFF, f, np.rad2deg(np.arctan(t_cal[lit])), res.lens,
                                  method="vignetted")
        worst = max(worst, float(np.max(np.abs(np.asarray(got) - np.asarray(want)))))
    return worst


def calibrate(truth, *, noise, seed, scene=HALF, f_numbers=F_NUMBERS, give_dark=True, **kw):
    """Simulate flats, calibrate, judge. ``give_dark``: pass the black level (``dark_dn``) to
    the calibration as a dark frame."""
    flats = make_flats(truth, f_numbers, noise=noise, seed=seed, **scene, **kw)
    dark = kw.get("dark_dn", 0.0)
    res = calibrate_lens(flats, exit_pupil_mm=truth.exit_pupil_mm,
                         pixel_pitch_um=scene["pitch_um"], magnification=truth.magnification,
                         pupil_magnification=truth.pupil_magnification,
                         dark=np.full(scene["shape"], dark) if give_dark and dark else None)
    circles = lens_circles(res.lens)
    max_cra = float(res.max_cra_deg)
    # the field is the truth's: the calibration's max_cra_deg differs from it only through
    # its optical centre (reported, and checked by the pixel-by-pixel error)
    err, at = shift_error(truth, res.lens, f_numbers, field_cra_deg(scene, truth.exit_pupil_mm))
    circle_errors = []
    for i in identifiable(truth, f_numbers, field_cra_deg(scene, truth.exit_pupil_mm)):
        P, h = truth.circles[i]
        best = None
        for Pc, hc in circles:
            e = (100 * (Pc / P - 1), 100 * (hc / h - 1))
            if best is None or max(map(abs, e)) < max(map(abs, best)):
                best = e
        circle_errors.append(best)
    spur = [c for c in spurious_circles(circles, truth, f_numbers)
            if c not in [tuple(t) for t in truth.circles]]
    center = math.hypot(res.center_rc[1] - scene["center_px"][0],
                        res.center_rc[0] - scene["center_px"][1])
    return Outcome(truth, noise, seed, str(res.model), circles, max_cra,
                   field_cra_deg(scene, truth.exit_pupil_mm), err, at, circle_errors, center,
                   pixel_error(truth, res, scene, f_numbers), spur, res, scene,
                   tuple(f_numbers))


#: Standard deviations of the bound that must fit inside a tolerance for it to be in reach.
#: The largest error over the field and the f-numbers can reach the length of the parameter
#: error measured in its own covariance (Mahalanobis), chi-distributed with as many degrees
#: of freedom as the circles have parameters (2-4): 3.5 covers about 99 % of it.
REACH = 3.5


@functools.cache
def _bound(truth, noise, shape, pitch_um, center_px, f_numbers, held=()):
    cov = bound(truth, noise, shape, pitch_um, center_px, f_numbers, step=2, held=held)
    field = field_cra_deg(dict(shape=shape, pitch_um=pitch_um, center_px=center_px),
                          truth.exit_pupil_mm)
    shift = float(np.nanmax(shift_bound_nm(truth, cov, f_numbers, field)))
    values = np.abs(np.ravel(truth.circles))
    return shift, np.sqrt(np.diag(cov)) / values  # nm; relative sd of P1, h1, P2, h2, ...


def cramer_rao(out: Outcome, *, held_pixel=False):
    """The bound's mean-shift sd (nm, largest over f-numbers) and each true circle's largest
    relative sd of P and h, for this outcome's scene and noise. Circles that cut no light in
    the field change neither the flats nor the shift there, and are left out (sd 0); a
    circle the flats cannot pin at all makes both infinite. ``held_pixel``: the bound of an
    estimator that holds a pixel-vignetting circle's h at x (known, not estimated)."""
    truth = out.truth
    t_max = math.tan(math.radians(out.field_cra_deg))
    acting = [i for i in range(len(truth.circles))
              if any(effective_onset_tan(truth, f, i) < t_max for f in out.f_numbers)]
    rel_all = [0.0] * len(truth.circles)
    if not acting:
        return 0.0, rel_all
    reduced = LensTruth(truth.exit_pupil_mm, tuple(truth.circles[i] for i in acting),
                        truth.magnification, truth.pupil_magnification, name=truth.name)
    sc = out.scene or HALF
    try:
        held = tuple(2 * j + 1 for j, (_, h) in enumerate(reduced.circles)
                     if held_pixel and h == reduced.exit_pupil_mm)
        shift, rel = _bound(reduced, out.noise, tuple(sc["shape"]), sc["pitch_um"],
                            tuple(sc["center_px"]), tuple(out.f_numbers), held)
    except np.linalg.LinAlgError:
        return math.inf, [math.inf] * len(truth.circles)
    for j, i in enumerate(acting):
        rel_all[i] = max(rel[2 * j], rel[2 * j + 1])
    return shift, rel_all


#: A true circle whose effect on the mean shift is under this many of the bound's standard
#: deviations may be left out. The model choice asks for a floored BIC gain of 10 beyond the
#: penalty of two parameters, sqrt(2 ln(1e5) + 10) = 5.8 standard deviations of evidence with
#: the 1e5 blocks of the user's sensor, and the evidence scatters by one either way: a
#: circle 9 from nothing is missed about once in a thousand.
DETECT = 9.0


@functools.cache
def circle_effect_nm(truth, i, max_cra_deg, f_numbers):
    """Largest change of the mean shift over the field and the f-numbers that removing true
    circle ``i`` makes (flatsim's quadrature)."""
    without = LensTruth(truth.exit_pupil_mm, truth.circles[:i] + truth.circles[i + 1:],
                        truth.magnification, truth.pupil_magnification)
    cra = np.linspace(0.0, max_cra_deg, 61)
    worst = 0.0
    for f in f_numbers:
        d = np.abs(mean_shift_nm(truth, CWL, N_EFF, f, cra)
                   - mean_shift_nm(without, CWL, N_EFF, f, cra))
        worst = max(worst, float(np.nanmax(d, initial=0.0)))
    return worst


def check(out: Outcome):
    tol = 0.01 if len(out.truth.circles) <= 1 else 0.02
    msg = out.describe()
    assert not out.spurious, "stop-like circle chosen: " + msg
    sd_bound, rel_bound = cramer_rao(out)
    msg += f"; Cramér-Rao shift sd {sd_bound:.4f} nm"
    reported = float(np.nanmax(out.res.shift_stderr_nm, initial=0.0))
    left_out = len(out.truth.circles) - len(out.circles)
    if left_out > 0:  # only circles the noise can hide, and the error no more than theirs
        effects = sorted(circle_effect_nm(out.truth, i, out.field_cra_deg, out.f_numbers)
                         for i in range(len(out.truth.circles)))[:left_out]
        msg += (f"; left out circle(s) of effect {np.round(effects, 4)} nm, reported sd "
                f"{reported:.4f} nm")
        assert all(e <= DETECT * sd_bound for e in effects), "a clear circle missed: " + msg
        assert out.shift_error_nm <= sum(effects) + REACH * reported, msg
        return
    if REACH * sd_bound <= tol:
        assert out.shift_error_nm <= tol, msg
    else:  # beyond the flats' information: the calibration's own error bars must cover it
        rival = float(np.nanmax(out.res.shift_difference_nm, initial=0.0))
        msg += f"; reported sd {reported:.4f} nm, rival model {rival:.4f} nm"
        assert reported >= 0.7 * sd_bound, "claims more than the flats hold: " + msg
        assert (out.shift_error_nm <= REACH * reported
                or out.shift_error_nm <= 1.5 * rival), msg
    identifiable_circles = identifiable(out.truth, out.f_numbers, out.field_cra_deg)
    for e, i in zip(out.circle_errors, identifiable_circles, strict=True):
        if REACH * 100 * rel_bound[i] <= 1.0:
            assert e is not None and abs(e[0]) <= 1.0 and abs(e[1]) <= 1.0, msg


# -- the simulator and the package agree on the truth ---------------------------------------
@pytest.mark.parametrize("key", ["one_h_lt_x", "one_h_gt_x_m", "two_front_rear",
                                 "circle_pixel"])
def test_truths_mean_shift_agrees_with_the_independent_quadrature(key):
    truth = TRUTHS[key]
    lens = make_lens(truth)
    if lens is None:
        pytest.skip("this snapcorr.Lens holds one vignetting circle only")
    cra = np.linspace(0, 18, 37)
    for f in F_NUMBERS:
        lit = relative_illumination(truth, f, np.tan(np.deg2rad(cra))) > 1e-3
        want = mean_shift_nm(truth, CWL, N_EFF, f, cra[lit])
        got = snapcorr.mean_shift(CWL, N_EFF, f, cra[lit], lens, method="vignetted")
        np.testing.assert_allclose(got, want, atol=1e-6, err_msg=f"{key} f/{f}")


def test_field_covers_the_onsets():
    """The scenes are built so that the circles named identifiable are so."""
    fmax = field_cra_deg(HALF)
    assert fmax == pytest.approx(field_cra_deg(FULL), abs=0.05)
    assert identifiable(TRUTHS["one_h_lt_x"], F_NUMBERS, fmax) == [0]
    assert identifiable(TRUTHS["one_h_gt_x"], F_NUMBERS, fmax) == [0]
    assert identifiable(TRUTHS["two_front_rear"], F_NUMBERS, fmax) == [0, 1]
    assert identifiable(TRUTHS["circle_pixel"], F_NUMBERS, fmax) == [0, 1]
    assert identifiable(TRUTHS["two_opposite"], F_NUMBERS, fmax) == [0, 1]
    assert identifiable(TRUTHS["one_weak"], F_NUMBERS, fmax) == [0]
    assert identifiable(TRUTHS["none_in_field"], F_NUMBERS, fmax) == []


# -- default run: a handful of representative cases -----------------------------------------
@pytest.mark.parametrize("key, noise, seed", [
    # one circle with h < x runs by default in test_reported_shift_error_is_never_below_the_bound
    # and in tests/calibrate/lens/test_calibration.py (the paper's lens); two circles in
    # test_predictive_refit.py (2 % noise), circle + pixel vignetting in
    # test_standard_errors_reach_the_cramer_rao_bound
    pytest.param("one_h_lt_x", 0.005, 0, marks=pytest.mark.slow),
    ("one_weak", 0.005, 0),
    pytest.param("two_front_rear", 0.005, 0, marks=pytest.mark.slow),
    pytest.param("circle_pixel", 0.005, 0, marks=pytest.mark.slow),
    ("none_in_field", 0.02, 0),
])
def test_calibration_predicts_the_true_shift(key, noise, seed):
    check(calibrate(TRUTHS[key], noise=noise, seed=seed))


@pytest.mark.parametrize("key", ["one_h_gt_x", pytest.param("one_h_gt_x_m",
                                                             marks=pytest.mark.slow)])
def test_users_scene_chooses_no_stop_like_circle(key):
    """The user's report: one circle with h > x, f/2-f/11, 0.5 % noise, off-centre axis.

    Run on the half-size sensor of the same angles; the full 1280 x 1024 scene is in the slow
    set."""
    out = calibrate(TRUTHS[key], noise=0.005, seed=0)
    assert not out.spurious, out.describe()
    assert len(out.circles) == 1, out.describe()
    check(out)


def test_optical_center_of_a_lens_without_a_circle():
    """No circle in the field: the centre comes from the flats' natural (cos^4) fall-off, which
    an integrating sphere leaves intact; a centre off by pixels moves every pixel's chief-ray
    angle, and with it the shift the profile predicts."""
    out = calibrate(TRUTHS["no_circle"], noise=0.005, seed=0)
    assert out.model == "none" and not out.circles, out.describe()
    assert out.center_error_px < 1.0, out.describe()
    assert out.pixel_error_nm < 0.01, out.describe()


def test_users_scene_with_a_black_level_left_in_chooses_no_stop_like_circle():
    """The user's scene with a black level of 200 DN (13 % of the f/11 signal) that nobody
    subtracted: the ratios are then off, but no circle that does not move may explain it."""
    out = calibrate(TRUTHS["one_h_gt_x_m"], noise=0.005, seed=0, dark_dn=200.0,
                    give_dark=False)
    assert not out.spurious, out.describe()


@pytest.mark.slow
@pytest.mark.parametrize("key", ["one_h_gt_x", "one_h_gt_x_m"])
@pytest.mark.parametrize("dark", [200.0, 800.0])
def test_users_scene_black_level(key, dark):
    out = calibrate(TRUTHS[key], noise=0.005, seed=0, dark_dn=dark, give_dark=False)
    assert not out.spurious, out.describe()
    check(calibrate(TRUTHS[key], noise=0.005, seed=0, dark_dn=dark, give_dark=True))


# -- slow: the full matrix and the user's full-size scene -----------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("key", ["one_h_gt_x", "one_h_gt_x_m"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_users_full_size_scene(key, seed):
    out = calibrate(TRUTHS[key], noise=0.005, seed=seed, scene=FULL)
    assert not out.spurious, out.describe()
    assert len(out.circles) == 1, out.describe()
    check(out)


@pytest.mark.slow
@pytest.mark.parametrize("noise", [0.005, 0.01, 0.02, 0.05, 0.1])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("key", list(TRUTHS))
def test_matrix(key, noise, seed):
    """On the user's full 1280 x 1024 sensor: the precision a calibration can reach grows with
    the number of pixels, so the criterion is judged on the pixels the user has."""
    check(calibrate(TRUTHS[key], noise=noise, seed=seed, scene=FULL))


@pytest.mark.slow
@pytest.mark.parametrize("key", ["one_h_lt_x", "two_front_rear"])
def test_with_source_non_uniformity_dark_and_poisson(key):
    out = calibrate(TRUTHS[key], noise=0.005, seed=5, source_amplitude=0.05, dark_dn=64.0,
                    poisson_gain=2.0)
    check(out)


# -- standard errors: z-scores over seeds ----------------------------------------------------
def fitted_with_stderr(res):
    """[(P, sP, h, sh), ...] of the chosen joint-fit model, or None if not exposed."""
    fit = getattr(res, "fits", {}).get(getattr(res, "model", None))
    if fit is None or not getattr(fit, "stderr", None):
        return None
    out = {}
    for k, v in fit.params.items():
        m = re.fullmatch(r"([Ph])(\d*)_mm", k)
        if m and k in fit.stderr:
            out.setdefault(m.group(2) or "1", {})[m.group(1)] = (v, fit.stderr[k])
    circles = [out[i] for i in sorted(out) if {"P", "h"} <= set(out[i])]
    return [(c["P"][0], c["P"][1], c["h"][0], c["h"][1]) for c in circles] or None


def zscores(key, noise, seeds, scene=HALF):
    """z-scores of P and h of every true circle over seeds, and the seeds whose chosen model
    left a true circle out (their z-scores would say nothing about the standard errors)."""
    truth = TRUTHS[key]
    z, missed = [], []
    for seed in seeds:
        out = calibrate(truth, noise=noise, seed=seed, scene=scene)
        fitted = fitted_with_stderr(out.res)
        if fitted is None and truth.circles and out.res.model != "none":
            pytest.fail("the calibration exposes no standard errors of P and h")
        if len(fitted or ()) < len(truth.circles):  # a circle (or every circle) left out
            missed.append(out.describe())
            continue
        for P, h in truth.circles:
            Pc, sP, hc, sh = min(fitted, key=lambda c, P=P, h=h: abs(c[0] / P - 1)
                                 + abs(c[2] / h - 1))
            z += [(Pc - P) / sP, (hc - h) / sh]
    return np.asarray(z), missed


@pytest.mark.slow
@pytest.mark.parametrize("key", ["one_h_lt_x", "one_h_gt_x", "one_weak", "two_front_rear",
                                 "circle_pixel"])
def test_standard_errors_are_honest(key):
    """(fitted - true) / stderr of P and h over 10 seeds: RMS between 0.5 and 2 (with 20
    z-scores of unit variance, outside that range by chance < 1e-3). 2 % noise on a quarter
    of the user's pixels. The weak circle and the pixel-vignetting circle are within reach
    (their shift's Cramér-Rao sd well under their effect) only at 0.5 %, on a quarter and on
    half of them: at 2 % on a quarter the weak circle's sd is 0.04 nm and some seeds rightly
    leave it out."""
    noise, scene = {"circle_pixel": (0.005, HALF), "one_weak": (0.005, QUARTER)}.get(
        key, (0.02, QUARTER))
    z, missed = zscores(key, noise, range(10), scene=scene)
    assert not missed, "true circles left out:\n" + "\n".join(missed)
    rms = float(np.sqrt(np.mean(z**2)))
    assert 0.5 <= rms <= 2.0, f"z-scores {np.round(z, 2)}, RMS {rms:.2f}"


# -- efficiency: the reported standard errors against the Cramér-Rao bound -------------------
@pytest.mark.parametrize("key", [
    "circle_pixel", pytest.param("one_h_gt_x_m", marks=pytest.mark.slow),
    pytest.param("one_h_lt_x", marks=pytest.mark.slow),
    pytest.param("one_weak", marks=pytest.mark.slow),
    pytest.param("two_front_rear", marks=pytest.mark.slow)])
def test_standard_errors_reach_the_cramer_rao_bound(key):
    """The calibration's standard error of the mean shift (largest over the field and the
    f-numbers) against the smallest any unbiased estimator can have (tests/oracles/cramer_rao.py):
    within 15 % of it. Dividing every flat by the slowest one, as the paper does, and weighting
    by a read-plus-shot noise line was 1.4-1.55 x the bound on these flats."""
    out = calibrate(TRUTHS[key], noise=0.02, seed=0)
    assert len(out.circles) == len(TRUTHS[key].circles), out.describe()
    # an estimator that holds pixel vignetting's h at x has that estimator's bound
    held = bool(out.res.fits[out.res.model].extra.get("held"))
    assert held == (key == "circle_pixel")
    sd_bound, _ = cramer_rao(out, held_pixel=held)
    # the fit's part: the models the flats cannot rule out add their own (tested below)
    reported = float(np.nanmax(out.res.shift_stderr_fit_nm))
    assert reported / sd_bound == pytest.approx(1.0, abs=0.15), (reported, sd_bound)
    total = np.asarray(out.res.shift_stderr_nm)
    assert np.all(total >= out.res.shift_stderr_fit_nm)


def shift_z(out):
    """The shift's error over its reported standard error, at the f-number where that is
    largest (the largest error over the field there)."""
    res = out.res
    err = np.array([e for e, _ in shift_errors_by_f(
        out.truth, res.lens, res.f_numbers, field_cra_deg(out.scene, out.truth.exit_pupil_mm))])
    k = int(np.nanargmax(res.shift_stderr_nm))
    return float(err[k] / res.shift_stderr_nm[k]), float(err.max())


def test_a_circle_the_noise_hides_is_in_the_error_bar():
    """At 5 % noise per pixel the pixel-vignetting circle is near the noise: in this seed the
    flats cannot decide between one circle and two, and one is chosen (in five seeds of eight
    two, with the pixel's held at h = x). Its error of the shift (0.2 nm) is then the missing
    circle's, which the fit's own standard error (0.011 nm) knows nothing of: the models the
    rules could not rule out are in the reported error, weighted by their evidence."""
    out = calibrate(TRUTHS["circle_pixel"], noise=0.05, seed=2, scene=HALF)
    assert out.model == "one", out.describe()
    res = out.res
    assert np.nanmax(res.shift_stderr_model_nm) > 5 * np.nanmax(res.shift_stderr_fit_nm)
    z, err = shift_z(out)
    assert err > 0.1 and z < 2.5, (z, err)
    assert "shift_stderr_model_choice_nm" in res.lens.calibration
    # what carries it: the two circles with the pixel's held at h = x, its P pinned (the
    # two-circle model where a free h buys nothing, else a rival)
    pixel = res.rivals["pixel"][0] if "pixel" in res.rivals else res.fits["two"]
    assert pixel.extra["held"] == {"h2_mm": X}
    assert pixel.params["h2_mm"] == X and pixel.params["P2_mm"] == pytest.approx(8.5, rel=0.01)
    assert set(res.lens.calibration["model_choice"]["rivals"]) & {"pixel", "free"}


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_pixel_vignetting_is_the_second_circle_where_a_free_h_buys_nothing():
    """A free second circle's h wanders along the valley of onsets it shares with P: in this
    seed, at 0.5 % noise, it stopped at P 8.63, h 21.46 mm (true 8.5, 21.0) for a shift 0.021
    nm off. Held at h = x it fits the flats as well for one parameter less (a lower BIC), so
    it is the two-circle model, and the free h is the rival in the error bar."""
    out = calibrate(TRUTHS["circle_pixel"], noise=0.005, seed=3, scene=HALF)
    res = out.res
    assert res.method == "joint" and res.model == "two", out.describe()
    assert res.fits["two"].extra["held"] == {"h2_mm": X} and "free" in res.rivals
    P2, h2 = res.lens.vignetting[1]
    assert h2 == X and P2 == pytest.approx(8.5, rel=0.002)
    z, err = shift_z(out)
    assert err < 0.01 and z < 2, (err, z)
    table = res.lens.calibration
    assert table["joint_fit"]["two"]["h2_stderr_mm"] == "held"
    assert table["exit_pupil_scaling"]["dh_dx"][1] == 1.0
    assert any("pixel vignetting, held at h = x" in n for n in table["notes"])
    from snapcorr.calibrate.lens.report import summary

    assert "h2_mm = 21 (held: pixel vignetting, h = x)" in summary(res)


@pytest.mark.slow
@pytest.mark.parametrize(("key", "noise"), [
    (k, n) for k in ("one_h_lt_x", "one_h_gt_x", "two_front_rear", "circle_pixel")
    for n in (0.005, 0.02, 0.05)])
def test_shift_error_bars_cover_over_seeds(key, noise):
    """The shift's errors over its reported standard errors, over 8 seeds: RMS in [0.5, 2]
    for every truth and noise level (``benchmarks/calibration_circles.coverage_sweep``).

    The pixel-vignetting circle at 5 % noise is at the detection limit (its 0.24 nm about 4
    Cramér-Rao standard deviations): most seeds choose one circle, and what covers the
    missing circle is the model with it held at ``h = x`` (one parameter, so its evidence
    clears the criterion where a free second circle's does not): RMS z 8 without it."""
    z = np.array([shift_z(calibrate(TRUTHS[key], noise=noise, seed=s, scene=HALF))[0]
                  for s in range(8)])
    rms = float(np.sqrt(np.mean(z**2)))
    assert 0.5 <= rms <= 2.0, (np.round(z, 2), rms)


@pytest.mark.parametrize("key", ["one_h_lt_x", pytest.param("one_h_gt_x_m",
                                                             marks=pytest.mark.slow)])
def test_reported_shift_error_is_never_below_the_bound(key):
    """At low noise the shift's standard error must not fall below what the flats allow (it
    did, to 0.7 of the bound, when each variance of P and h was scaled on its own to an error
    with a floor); the block model's approximation enters as one correlated direction."""
    out = calibrate(TRUTHS[key], noise=0.005, seed=0, scene=QUARTER)
    sd_bound, _ = cramer_rao(out)
    reported = float(np.nanmax(out.res.shift_stderr_nm))
    assert reported >= 0.95 * sd_bound, (reported, sd_bound)
