"""A lens with any number of vignetting circles, checked against a brute force written here.

The geometry (lengths in mm, in the exit-pupil plane at distance x from the sensor): the exit
pupil is the disc of radius R about the axis; a pixel at chief-ray angle CRA has its foot at
``d = x tan(CRA)`` on a radial line; circle i is the disc of radius P_i centred at
``h_i tan(CRA)`` on the same line. Light reaches the pixel through the intersection of all
discs; a ray through the point p meets the filter at ``tan(phi) = |p - foot| / x`` and shifts
its central wavelength by ``-cwl (1 - sqrt(1 - sin^2(phi) / n^2))``. The mean shift is the area
average of that over the intersection.

The reference below (``brute_mean``) knows nothing of snapcorr: all discs are centred on one
line, so the intersection is symmetric about it and its cross-section at abscissa u is the
chord ``|v| <= c(u) = min_k sqrt(r_k^2 - (u - a_k)^2)``. Between the points where the active
disc changes (the radical lines of pairs of discs) c(u) is smooth; the square-root ends of the
intersection are removed by ``u = u0 + (u1 - u0) (1 - cos t) / 2``. Gauss-Legendre in t and
across the chord then converge geometrically, to far below the 2e-4 nm asked of it
(``test_brute_force_has_converged``).

``tests/data/one_circle_reference.npz`` holds numbers of the one-circle lens from before the
lens took several circles (``tests/data/make_one_circle_reference.py``).
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import PAPER_CIRCLE, PAPER_M, PAPER_M_P, PAPER_X_MM

import snapcorr
from snapcorr import Lens, mean_shift
from snapcorr.optics import filter_response, kernel

pytestmark = pytest.mark.filterwarnings("ignore::snapcorr.EffectiveIndexWarning")

DATA = Path(__file__).resolve().parents[1] / "data"

# ------------------------------------------------------------------------------------------
# The brute force
# ------------------------------------------------------------------------------------------


def _gl(n, lo, hi):
    xi, w = np.polynomial.legendre.leggauss(n)
    return lo + (hi - lo) * (xi + 1.0) / 2.0, w * (hi - lo) / 2.0


def shift_of_tan2(s, cwl, n):
    """The tilt shift for ``tan^2(phi) = s``: ``-cwl (1 - sqrt(1 - sin^2(phi) / n^2))``."""
    q = s / (1.0 + s) / (n * n)
    return -cwl * q / (1.0 + np.sqrt(1.0 - q))


def discs_on_axis(R, circles, tan_cra):
    """(centre on the radial line, radius) of the pupil and of every circle ((P, h), ...)."""
    return [(0.0, R)] + [(h * tan_cra, P) for P, h in circles]


def _breakpoints(discs):
    lo = max(a - r for a, r in discs)
    hi = min(a + r for a, r in discs)
    if not hi > lo:
        return []
    pts = {lo, hi}
    for (a1, r1), (a2, r2) in itertools.combinations(discs, 2):
        if a1 != a2:  # where the two half-chords are equal: the radical line
            u = (r1 * r1 - r2 * r2 + a2 * a2 - a1 * a1) / (2.0 * (a2 - a1))
            if lo < u < hi:
                pts.add(u)
    return sorted(pts)


def half_chord(u, discs):
    c2 = np.min([(r - (u - a)) * (r + (u - a)) for a, r in discs], axis=0)
    return np.sqrt(np.clip(c2, 0.0, None))


def brute_area_and_integral(discs, func, nu=64, nv=48):
    """``(area, integral of func(u, v) dA)`` over the intersection of discs centred on the
    u axis; ``func`` even in v."""
    pts = _breakpoints(discs)
    t, wt = _gl(nu, 0.0, np.pi)
    xi, wv = _gl(nv, 0.0, 1.0)
    area = integral = 0.0
    for u0, u1 in itertools.pairwise(pts):
        u = u0 + (u1 - u0) * (1.0 - np.cos(t)) / 2.0
        du = (u1 - u0) / 2.0 * np.sin(t) * wt
        c = half_chord(u, discs)
        v = c[:, None] * xi
        area += 2.0 * np.sum(du * c)
        integral += 2.0 * np.sum(du[:, None] * c[:, None] * wv * func(u[:, None], v))
    return area, integral


def brute_area(R, circles, cra_deg, **kw):
    discs = discs_on_axis(R, circles, math.tan(math.radians(cra_deg)))
    return brute_area_and_integral(discs, lambda u, v: 0.0 * u, **kw)[0]


def brute_mean(cwl, n, x, R, circles, cra_deg, **kw):
    """Area-averaged shift (nm) over the pupil and all circles, and the area (mm^2)."""
    t = math.tan(math.radians(cra_deg))
    d = x * t
    area, integral = brute_area_and_integral(
        discs_on_axis(R, circles, t),
        lambda u, v: shift_of_tan2(((u - d) ** 2 + v * v) / (x * x), cwl, n),
        **kw,
    )
    return integral / area, area


def all_circles_cut(R, circles, cra_deg, area):
    """True if leaving out any one circle would let through more light."""
    return all(
        area < brute_area(R, circles[:i] + circles[i + 1 :], cra_deg) * (1 - 1e-3)
        for i in range(len(circles))
    )


def cutoff_deg(R, circles):
    """Closed form of the full cut-off: the intervals [a - r, a + r] on the line stop meeting
    (discs centred on one line meet iff their diameters along it do)."""
    ends = [(0.0, R)] + [(h, P) for P, h in circles]  # (speed of the centre, radius)
    ts = [
        (r1 + r2) / abs(h1 - h2)
        for (h1, r1), (h2, r2) in itertools.combinations(ends, 2)
        if h1 != h2
    ]
    return math.degrees(math.atan(min(ts))) if ts else math.inf


# ------------------------------------------------------------------------------------------
# Lenses and cases
# ------------------------------------------------------------------------------------------

#: name: (x, circles ((P, h), ...), m, mP)
LENSES = {
    "2: 0<h<x, h<0": (21.0, ((8.0, 15.0), (9.0, -10.0)), 0.0, 1.0),
    "2: h=x, h>x": (21.0, ((7.5, 21.0), (12.0, 40.0)), 0.0, 1.0),
    "3: h<0, 0<h<x, h>x, m>0": (25.0, ((9.0, -12.0), (8.5, 17.0), (14.0, 45.0)), 0.06, 1.3),
    "2: stop h=0 (P<R at f<2.1), 0<h<x": (21.0, ((5.0, 0.0), (7.0, 12.0)), 0.0, 1.0),
    "2: P<R, h>x and h<0": (30.0, ((4.0, 50.0), (6.0, -20.0)), 0.0, 1.0),
    "3: h=x, h=0 (P<R at f<1.32), h<0, m>0": (18.0, ((6.0, 18.0), (4.8, 0.0), (7.0, -9.0)), 0.3,
                                             0.7),
    "2: small, early cut-off": (20.0, ((3.0, 25.0), (4.0, -15.0)), 0.0, 1.0),
    "3: same side, taking turns": (22.0, ((6.0, 10.0), (7.0, 14.0), (8.5, 20.0)), 0.1, 1.0),
}


def make_lens(x, circles, m=0.0, mP=1.0):
    return Lens(x, vignetting=circles, magnification=m, pupil_magnification=mP)


def draw_cases(rng, x, circles, m, mP, k, *, near=2, zero=1):
    """``k`` cases (f, cra, cwl, n) below the cut-off, ``near`` of them just below it (first),
    ``zero`` on the axis, the rest anywhere below the cut-off (and below 35 deg)."""
    out = []
    n = rng.uniform(1.4, 2.4)  # one n_eff per lens keeps the "grid" method to one grid
    for _ in range(100_000):
        f = float(np.exp(rng.uniform(np.log(1.2), np.log(22.0))))
        R = x / (2.0 * (1.0 + m / mP) * f)
        top = cutoff_deg(R, circles)
        cwl = rng.uniform(400.0, 1000.0)
        i = len(out)
        if i < near:
            if top >= 35.0:  # no cut-off below 35 deg at this f-number
                continue
            cra = top * (1.0 - 10.0 ** rng.uniform(-5.0, -2.0))
        elif i < near + zero:
            cra = 0.0
        else:
            cra = rng.uniform(0.0, 0.995 * min(top, 35.0))
        out.append((f, cra, cwl, n))
        if len(out) == k:
            return np.array(out)
    raise RuntimeError("no f-number puts the cut-off below 35 deg; ask for near=0")


def case_set(seed, k, **kw):
    rng = np.random.default_rng(seed)
    return {name: draw_cases(rng, *spec, k, **kw) for name, spec in LENSES.items()}


def reference(spec, cases, **kw):
    x, circles, m, mP = spec
    rows = []
    for f, cra, cwl, n in cases:
        R = x / (2.0 * (1.0 + m / mP) * f)
        rows.append(brute_mean(cwl, n, x, R, circles, cra, **kw))
    return np.array(rows).T  # mean (nm), area (mm^2)


@pytest.fixture(scope="module")
def cases():
    """For every lens: cases, the brute-force mean and area."""
    out = {}
    for name, arr in case_set(7, 14).items():
        mean, area = reference(LENSES[name], arr)
        out[name] = (arr, mean, area)
    return out


def shifts(spec, arr, method, **kw):
    lens = make_lens(*spec)
    f, cra, cwl, n = arr.T
    return mean_shift(cwl, n, f, cra, lens, method=method, **kw)


# ------------------------------------------------------------------------------------------
# 1. The reference itself
# ------------------------------------------------------------------------------------------


def test_brute_force_has_converged(cases):
    worst = 0.0
    for name, (arr, mean, area) in cases.items():
        fine_mean, fine_area = reference(LENSES[name], arr, nu=100, nv=72)
        worst = max(worst, np.max(np.abs(fine_mean - mean)))
        np.testing.assert_allclose(fine_area, area, rtol=1e-10, err_msg=name)
    assert worst < 1e-8  # nm, against the 2e-4 nm asked


def test_brute_force_knows_the_plain_disc():
    # Mean of Delta over a disc centred on the foot (CRA 0, no circle) in closed form:
    # with s = r^2 / x^2, the mean is (1 / rho^2) int_0^rho^2 Delta(s) ds, integrated here by
    # an independent fine Simpson rule in s.
    x, R, cwl, n = 20.0, 7.0, 700.0, 1.7
    got, area = brute_mean(cwl, n, x, R, (), 0.0)
    s = np.linspace(0.0, (R / x) ** 2, 20001)
    y = shift_of_tan2(s, cwl, n)
    h = s[1] - s[0]
    simpson = h / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())
    assert abs(got - simpson / s[-1]) < 1e-10
    assert abs(area - np.pi * R * R) < 1e-11
    # A lune of two discs: area of the lens-shaped overlap in closed form.
    r1, r2, dist = 5.0, 4.0, 6.0
    a1 = r1 * r1 * math.acos((dist**2 + r1**2 - r2**2) / (2 * dist * r1))
    a2 = r2 * r2 * math.acos((dist**2 + r2**2 - r1**2) / (2 * dist * r2))
    a3 = 0.5 * math.sqrt((-dist + r1 + r2) * (dist + r1 - r2) * (dist - r1 + r2) * (dist + r1 + r2))
    got = brute_area_and_integral([(0.0, r1), (dist, r2)], lambda u, v: 0.0 * u)[0]
    assert abs(got - (a1 + a2 - a3)) < 1e-12


# ------------------------------------------------------------------------------------------
# 2. mean_shift against the brute force
# ------------------------------------------------------------------------------------------


def _max_error(cases, method, **kw):
    errors = {}
    for name, (arr, mean, _) in cases.items():
        errors[name] = float(np.max(np.abs(shifts(LENSES[name], arr, method, **kw) - mean)))
    return errors


def test_vignetted_is_the_area_average_over_all_circles(cases):
    errors = _max_error(cases, "vignetted")
    assert max(errors.values()) <= 0.002, errors  # nm; expected far better


@pytest.mark.parametrize(
    ("method", "atol"),
    [
        ("table", 1.1e-3),
        ("auto", 1.1e-3),
        pytest.param("grid", 1.1e-3, marks=pytest.mark.slow),  # a grid per lens: seconds each
    ],
)
def test_fast_methods_meet_their_tolerance(cases, method, atol):
    errors = _max_error(cases, method, tolerance_nm=1e-3)
    assert max(errors.values()) <= atol, errors


def test_riemann_is_within_its_step(cases):
    # The paper's 0.01 nm left Riemann sum (App. B); slivers near the full cut-off are narrower
    # than its step, so those are left out.
    errors = {}
    for name, (arr, mean, _) in cases.items():
        keep = slice(2, None)  # draw_cases puts the near-cut-off cases first
        got = shifts(LENSES[name], arr[keep], "riemann")
        errors[name] = float(np.max(np.abs(got - mean[keep])))
    assert max(errors.values()) <= 0.01, errors


def test_the_cases_cover_every_kind_of_circle(cases):
    hs = {h / x for x, circles, _, _ in LENSES.values() for _, h in circles}
    assert min(hs) < 0 and 0 in hs and any(0 < h < 1 for h in hs) and 1 in hs and max(hs) > 1
    assert any(m > 0 for _, _, m, _ in LENSES.values())
    assert any(len(c) == 3 for _, c, _, _ in LENSES.values())
    on_axis_cut = near_cut = on_axis = 0
    for name, (arr, _, area) in cases.items():
        x, circles, m, mP = LENSES[name]
        R = x / (2.0 * (1.0 + m / mP) * arr[:, 0])
        on_axis_cut += np.sum(R > min(P for P, _ in circles))
        near_cut += np.sum(area < 1e-3 * np.pi * R * R)
        on_axis += np.sum(arr[:, 1] == 0)
    assert on_axis_cut >= 5 and near_cut >= 10 and on_axis >= 5


def random_lens(rng):
    """A lens with two or three circles of any kind, for the slow sweep."""
    x = rng.uniform(10.0, 40.0)
    m = 0.0 if rng.random() < 0.5 else rng.uniform(0.0, 0.5)
    mP = 1.0 if rng.random() < 0.5 else rng.uniform(0.5, 2.5)
    r_big = x / (2.0 * (1.0 + m / mP) * 1.2)
    circles = []
    for _ in range(rng.choice([2, 3])):
        kind = rng.choice(["h<0", "h=0", "0<h<x", "h=x", "h>x"])
        h = {"h<0": -x * rng.uniform(0.05, 1.5), "h=0": 0.0, "0<h<x": x * rng.uniform(0.05, 0.97),
             "h=x": x, "h>x": x * rng.uniform(1.03, 3.0)}[kind]
        P = r_big * (rng.uniform(0.2, 1.3) if h == 0 else rng.uniform(0.3, 2.0))
        circles.append((P, h))
    return x, tuple(circles), m, mP


@pytest.mark.slow
def test_random_lenses_against_the_brute_force():
    rng = np.random.default_rng(2019)
    worst = dict.fromkeys(("vignetted", "table", "auto", "ri", "cutoff"), 0.0)
    for _ in range(40):
        spec = random_lens(rng)
        circles = spec[1]
        R_small = spec[0] / (2.0 * (1.0 + spec[2] / spec[3]) * 22.0)
        near = 3 if cutoff_deg(R_small, circles) < 35.0 else 0
        arr = draw_cases(rng, *spec, 20, near=near, zero=1)
        mean, area = reference(spec, arr)
        for method in ("vignetted", "table", "auto"):
            err = np.max(np.abs(shifts(spec, arr, method, tolerance_nm=1e-3) - mean))
            worst[method] = max(worst[method], err)
        lens = make_lens(*spec)
        R = lens.exit_pupil_radius_mm(arr[:, 0])
        ri = lens.relative_illumination(arr[:, 0], arr[:, 1])
        worst["ri"] = max(worst["ri"], np.max(np.abs(ri - area / (np.pi * R * R))))
        cut = np.asarray(lens.cutoff_cra_deg(arr[:, 0]))
        want = np.array([cutoff_deg(r, circles) for r in R])  # inf if no pair ever parts
        same = cut == want
        assert np.all(np.isfinite(cut[~same])) and np.all(np.isfinite(want[~same]))
        err = np.abs(cut[~same] - want[~same]) / want[~same]
        worst["cutoff"] = max(worst["cutoff"], float(np.max(err, initial=0.0)))
    assert worst["vignetted"] <= 0.002, worst
    assert worst["table"] <= 1.1e-3 and worst["auto"] <= 1.1e-3, worst
    assert worst["ri"] <= 1e-11 and worst["cutoff"] <= 1e-12, worst  # cut-off: relative
    print(worst)


def test_cut_off_pupil_raises():
    spec = LENSES["2: small, early cut-off"]
    circles = spec[1]
    lens = make_lens(*spec)
    R = float(lens.exit_pupil_radius_mm(2.0))
    beyond = cutoff_deg(R, circles) * 1.001
    with pytest.raises(snapcorr.PupilCutOffError):
        mean_shift(700.0, 1.7, 2.0, beyond, lens, method="vignetted")


# ------------------------------------------------------------------------------------------
# 3. Relative illumination, onsets and the full cut-off
# ------------------------------------------------------------------------------------------


def test_relative_illumination_is_the_common_area(cases):
    for name, (arr, _, area) in cases.items():
        lens = make_lens(*LENSES[name])
        f, cra = arr[:, 0], arr[:, 1]
        R = lens.exit_pupil_radius_mm(f)
        # Relative, to 1e-9: slivers near the cut-off leave ~1e-6 of the pupil, where a sum of
        # segment areas with alternating signs would lose digits (it did: 7e-7 relative).
        np.testing.assert_allclose(
            lens.relative_illumination(f, cra), area / (np.pi * R * R), rtol=1e-9, atol=1e-16,
            err_msg=name,
        )


def test_radius_and_lens_attributes():
    x, circles, m, mP = LENSES["3: h<0, 0<h<x, h>x, m>0"]
    lens = make_lens(x, circles, m, mP)
    assert lens.has_vignetting
    assert lens.vignetting == tuple((float(P), float(h)) for P, h in circles)
    assert abs(lens.exit_pupil_radius_mm(2.0) - x / (2 * (1 + m / mP) * 2.0)) < 1e-14
    assert not make_lens(x, ()).has_vignetting
    positional = Lens(x, circles, m, mP, name="three circles")
    assert positional.name == "three circles" and positional.vignetting == lens.vignetting
    assert positional.exit_pupil_radius_mm(2.0) == lens.exit_pupil_radius_mm(2.0)


F_NUMBERS = (1.2, 2.0, 4.0, 11.0)


@pytest.mark.parametrize("name", list(LENSES))
def test_onsets_per_circle_and_together(name):
    x, circles, m, mP = LENSES[name]
    lens = make_lens(x, circles, m, mP)
    f = np.array(F_NUMBERS)
    R = lens.exit_pupil_radius_mm(f)
    per = np.asarray(lens.circle_onsets_cra_deg(f))
    assert per.shape == (len(circles), len(f))
    onset = np.asarray(lens.onset_cra_deg(f))
    np.testing.assert_array_equal(onset, per.min(axis=0))
    for j in range(len(f)):
        for i, (P, h) in enumerate(circles):
            on = per[i, j]
            # Circle i alone: whole pupil before its onset, less just after it.
            if P < R[j]:
                assert on == 0.0
                assert brute_area(R[j], [(P, h)], 0.0) < np.pi * R[j] ** 2 * (1 - 1e-6)
            elif h == 0:
                assert on == np.inf
                assert brute_area(R[j], [(P, h)], 60.0) == pytest.approx(np.pi * R[j] ** 2,
                                                                          rel=1e-13)
            else:
                eps = 1e-4  # deg
                assert brute_area(R[j], [(P, h)], on - eps) == pytest.approx(
                    np.pi * R[j] ** 2, rel=1e-13)
                assert brute_area(R[j], [(P, h)], on + eps) < np.pi * R[j] ** 2 * (1 - 1e-11)
                # ... and the implementation sees the same through relative_illumination.
                one = make_lens(x, [(P, h)], m, mP)
                assert one.relative_illumination(f[j], on - eps) == pytest.approx(1, abs=1e-13)
        # All circles: the first onset.
        on = onset[j]
        if 0 < on < 89:
            eps = 1e-4
            assert brute_area(R[j], circles, on - eps) == pytest.approx(np.pi * R[j] ** 2,
                                                                         rel=1e-13)
            assert brute_area(R[j], circles, on + eps) < np.pi * R[j] ** 2 * (1 - 1e-11)
            assert lens.relative_illumination(f[j], on + eps) < 1 - 1e-11


@pytest.mark.parametrize("name", list(LENSES))
def test_full_cut_off(name):
    x, circles, m, mP = LENSES[name]
    lens = make_lens(x, circles, m, mP)
    f = np.array(F_NUMBERS)
    cut = np.asarray(lens.cutoff_cra_deg(f))
    R = lens.exit_pupil_radius_mm(f)
    for j in range(len(f)):
        assert cut[j] == pytest.approx(cutoff_deg(R[j], circles), rel=1e-12, abs=0)
        if cut[j] < 89.0:
            eps = 1e-6 * cut[j]
            assert brute_area(R[j], circles, cut[j] * (1 + 1e-9) + eps) == 0.0
            assert brute_area(R[j], circles, cut[j] - eps) > 0.0
            assert lens.relative_illumination(f[j], cut[j] + eps) == 0.0
            assert lens.relative_illumination(f[j], cut[j] - eps) > 0.0


# ------------------------------------------------------------------------------------------
# 4.-5. Kernel and filter response with several circles
# ------------------------------------------------------------------------------------------


def _kernel_breaks(x, discs, d, cwl, n):
    """Shifts where the kernel may have a kink or a square-root end: circles about the foot
    through a crossing of two boundaries or tangent to one."""
    radii = []
    for a, r in discs:
        radii += [abs(a - d) + r, abs(abs(a - d) - r)]
    for (a1, r1), (a2, r2) in itertools.combinations(discs, 2):
        if a1 != a2:
            u = (r1 * r1 - r2 * r2 + a2 * a2 - a1 * a1) / (2.0 * (a2 - a1))
            v2 = r1 * r1 - (u - a1) ** 2
            if v2 >= 0:
                radii.append(math.hypot(u - d, math.sqrt(v2)))
    # The pixel's nearest and farthest points of the intersection bound the kernel.
    pts = _breakpoints(discs)
    u = np.linspace(pts[0], pts[-1], 200001)
    c = half_chord(u, discs)
    rmax = float(np.max(np.hypot(u - d, c)))
    rmin = 0.0 if pts[0] <= d <= pts[-1] else float(np.min(np.abs(u - d)))
    radii = [r for r in radii if rmin < r < rmax] + [rmin, rmax * (1 + 1e-9)]
    lam = shift_of_tan2((np.array(radii) / x) ** 2, cwl, n)
    return np.unique(lam)


KERNEL_CASES = [  # lens, f, cra
    ("2: 0<h<x, h<0", 1.4, 14.0),
    ("3: h<0, 0<h<x, h>x, m>0", 1.2, 14.0),
    ("2: stop h=0 (P<R at f<2.1), 0<h<x", 1.6, 12.0),
    ("3: h=x, h=0 (P<R at f<1.32), h<0, m>0", 1.2, 16.0),
]


@pytest.mark.parametrize(("name", "f", "cra"), KERNEL_CASES)
def test_kernel_integrates_to_one_with_the_brute_force_mean(name, f, cra):
    x, circles, m, mP = LENSES[name]
    lens = make_lens(x, circles, m, mP)
    cwl, n = 700.0, 1.7
    R = float(lens.exit_pupil_radius_mm(f))
    t = math.tan(math.radians(cra))
    d = x * t
    discs = discs_on_axis(R, circles, t)
    expected, area = brute_mean(cwl, n, x, R, circles, cra)
    # A genuine several-circle case: no single circle leaves as little light.
    assert all_circles_cut(R, circles, cra, area)
    P = [p for p, _ in circles]
    dv = [h * t for _, h in circles]
    mass = first = 0.0
    s, ws = _gl(64, 0.0, np.pi)  # per piece; 200 nodes agree to 1e-12
    for l0, l1 in itertools.pairwise(_kernel_breaks(x, discs, d, cwl, n)):
        lam = l0 + (l1 - l0) * (1.0 - np.cos(s)) / 2.0
        w = (l1 - l0) / 2.0 * np.sin(s) * ws
        K = kernel(lam, cwl, n, x, R, d, P, dv)
        mass += np.sum(w * K)
        first += np.sum(w * lam * K)
    assert abs(mass - 1.0) < 1e-9
    assert abs(first / mass - expected) < 1e-8  # nm


def test_filter_response_centroid_moves_by_the_mean():
    name, f, cra = "2: 0<h<x, h<0", 1.4, 16.0
    x, circles, m, mP = LENSES[name]
    lens = make_lens(x, circles, m, mP)
    cwl, n = 700.0, 1.7
    R = float(lens.exit_pupil_radius_mm(f))
    expected, area = brute_mean(cwl, n, x, R, circles, cra)
    assert all_circles_cut(R, circles, cra, area)
    wl = np.arange(640.0, 760.0, 0.01)
    T = np.exp(-0.5 * ((wl - cwl) / 2.0) ** 2)
    out = filter_response(wl, T, cwl_nm=cwl, n_eff=n, f_number=f, cra_deg=cra,
                                   lens=lens, method="kernel")

    def centroid(y):
        return np.sum(wl * y) / np.sum(y)

    assert abs(centroid(out) - centroid(T) - expected) < 1e-6  # nm
    # Against the lens without circles it does move: the check is not blind.
    plain, _ = brute_mean(cwl, n, x, R, (), cra)
    assert abs(plain - expected) > 0.05


# ------------------------------------------------------------------------------------------
# 6. One circle, as before
# ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def one_circle():
    return dict(np.load(DATA / "one_circle_reference.npz"))


def _old_lens(ref, i):
    P, h = ref["P"][i], ref["h"][i]
    circles = () if np.isnan(P) else ((float(P), float(h)),)
    return make_lens(float(ref["x"][i]), circles, float(ref["m"][i]), float(ref["mP"][i]))


def _check_one_circle(ref, rows, methods):
    bad = []
    for i in rows:
        lens = _old_lens(ref, i)
        f, cra, cwl, n = (float(ref[k][i]) for k in ("f", "cra", "cwl", "n"))
        for method in methods:
            got = float(mean_shift(cwl, n, f, cra, lens, method=method, tolerance_nm=1e-3))
            want = ref[f"shift_{method}"][i]
            if not abs(got - want) <= 1e-9:
                bad.append((int(i), method, want, got))
        for key, got in (
            ("relative_illumination", lens.relative_illumination(f, cra)),
            ("onset_cra_deg", lens.onset_cra_deg(f)),
            ("cutoff_cra_deg", lens.cutoff_cra_deg(f)),
        ):
            want = ref[key][i]
            if not (got == want or abs(got - want) <= 1e-12):
                bad.append((int(i), key, want, float(got)))
    return bad


def test_one_circle_as_before(one_circle):
    rows = np.arange(0, one_circle["x"].size, 8)  # every family; the rest in the slow run
    bad = _check_one_circle(one_circle, rows, ("vignetted", "ideal", "asymptotic", "auto",
                                               "table"))
    assert not bad, bad[:10]


@pytest.mark.slow
def test_one_circle_as_before_all_cases(one_circle):
    rows = np.arange(one_circle["x"].size)
    bad = _check_one_circle(one_circle, rows, ("vignetted", "ideal", "asymptotic", "auto",
                                               "table"))
    assert not bad, (len(bad), bad[:10])


# ------------------------------------------------------------------------------------------
# 7. Degenerate circles
# ------------------------------------------------------------------------------------------

ONE = (PAPER_X_MM, (PAPER_CIRCLE,), PAPER_M, PAPER_M_P)  # the paper's Edmund 16 mm lens


def _cra(f):
    x, ((P, h),), m, mP = ONE
    R = x / (2 * (1 + m / mP) * f)
    return np.linspace(0.0, min(34.0, 0.999 * math.degrees(math.atan((P + R) / h))), 35)


def _everything(lens, f, methods=("vignetted", "ideal", "auto", "table")):
    out = {m: mean_shift(700.0, 1.7, f, _cra(f), lens, method=m) for m in methods}
    out["ri"] = lens.relative_illumination(f, _cra(f))
    return out


@pytest.mark.parametrize("f", [1.4, 4.0])
def test_two_identical_circles_are_one(f):
    x, circles, m, mP = ONE
    one, two = make_lens(x, circles, m, mP), make_lens(x, circles * 2, m, mP)
    a, b = _everything(one, f), _everything(two, f)
    for k in a:
        np.testing.assert_allclose(b[k], a[k], rtol=0, atol=1e-9, err_msg=k)
    assert two.onset_cra_deg(f) == pytest.approx(one.onset_cra_deg(f), abs=1e-12)
    assert two.cutoff_cra_deg(f) == pytest.approx(one.cutoff_cra_deg(f), abs=1e-12)


@pytest.mark.parametrize("f", [1.4, 4.0])
@pytest.mark.parametrize("far", [(40.0, 30.0), (40.0, -30.0), (30.0, 0.0), (250.0, 300.0)])
def test_a_circle_that_never_cuts_changes_nothing(f, far):
    x, circles, m, mP = ONE
    lens = make_lens(x, circles, m, mP)
    more = make_lens(x, (*circles, far), m, mP)
    R = float(lens.exit_pupil_radius_mm(f))
    # It never reaches the pupil below 34 deg (nor the first circle while that one is in use).
    P, h = far
    assert abs(h) * math.tan(math.radians(34.0)) + R < P
    a, b = _everything(lens, f), _everything(more, f)
    for k in a:
        np.testing.assert_allclose(b[k], a[k], rtol=0, atol=1e-9, err_msg=k)
    assert more.onset_cra_deg(f) == pytest.approx(lens.onset_cra_deg(f), abs=1e-12)
    # ... and a lens with no circle at all is the ideal one.
    bare, far_only = make_lens(x, (), m, mP), make_lens(x, (far,), m, mP)
    np.testing.assert_allclose(
        mean_shift(700.0, 1.7, f, _cra(f), far_only, method="vignetted"),
        mean_shift(700.0, 1.7, f, _cra(f), bare, method="ideal"), rtol=0, atol=1e-9)
