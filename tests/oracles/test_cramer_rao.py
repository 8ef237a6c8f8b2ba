"""The Cramér-Rao bound of tests/oracles/cramer_rao.py checked by evidence independent of its
formula.

* Brute force: on a tiny sensor the Fisher matrix of the full per-pixel Gaussian likelihood
  of the flats, every nuisance (each pixel's gain, each exposure, the centre) an explicit
  parameter, its Jacobian by finite differences of make_flats' noiseless signal evaluated pixel
  by pixel, inverted directly.
* Monte Carlo: maximum-likelihood fits of one circle to many noisy flats reach the bound,
  and so does the spread of their mean filter shifts.
* Scaling: the bound's standard deviations are proportional to the noise and to
  ``1 / sqrt(pixels)``.
"""

from __future__ import annotations

import numpy as np
import pytest
from calibrate.lens.test_calibration_circles import F_NUMBERS, FULL, TRUTHS, field_cra_deg
from cramer_rao import bound, fisher, parameter_names, shift_bound_nm
from flatsim import LensTruth, cra_map_deg, make_flats, mean_shift_nm, relative_illumination
from scipy.optimize import least_squares

LEVEL_DN = 45000.0  # make_flats' level_dn
LIT_MIN = 0.05  # cramer_rao's default lit fraction


def scene(factor):
    """The FULL scene's field of view on a sensor ``factor`` times coarser in each direction."""
    (rows, cols), (cx, cy) = FULL["shape"], FULL["center_px"]
    return dict(shape=(rows // factor, cols // factor), pitch_um=FULL["pitch_um"] * factor,
                center_px=((cx + 0.5) / factor - 0.5, (cy + 0.5) / factor - 0.5))


def with_circles(truth, values):
    """The lens with its circles' (P1, h1, P2, h2, ...) replaced by ``values``."""
    v = [float(a) for a in values]
    return LensTruth(truth.exit_pupil_mm, tuple(zip(v[0::2], v[1::2], strict=True)),
                     truth.magnification, truth.pupil_magnification)


def circle_values(truth):
    return np.array([v for circle in truth.circles for v in circle], float)


def whitened_eigenvalues(cov, ref):
    """Eigenvalues of ``ref^-1/2 cov ref^-T/2``: all 1 when ``cov == ref``."""
    L = np.linalg.cholesky(ref)
    M = np.linalg.solve(L, np.linalg.solve(L, cov).T)
    return np.linalg.eigvalsh(0.5 * (M + M.T))


# -- brute force ------------------------------------------------------------------------------
def clean_signal(truth, f_numbers, scn, center_px, exposures):
    """make_flats' noiseless signal, shape (flats, pixels), every pixel's area computed directly.

    ``level_dn * e_F * (R_F / R_min)^2 * A_F(CRA) * cos^4(CRA)`` with unit gains and source.
    """
    cra, tan = cra_map_deg(scn["shape"], scn["pitch_um"], center_px, truth.exit_pupil_mm)
    cos4 = np.cos(np.deg2rad(cra)) ** 4
    r_min = float(truth.pupil_radius_mm(min(f_numbers)))
    return np.stack([
        (LEVEL_DN * e * (float(truth.pupil_radius_mm(f)) / r_min) ** 2
         * relative_illumination(truth, f, tan) * cos4).ravel()
        for f, e in zip(f_numbers, exposures, strict=True)])


def brute_force_bound(truth, f_numbers, scn, noise):
    """Circles' block of the inverse of the full Fisher matrix, and the forward model's error.

    Parameters: the circles, the centre, the log exposures of all flats but the last, and a
    gain per pixel (1 at the truth). The data ``y ~ N(s, (noise s)^2)`` independently per
    lit measurement (relative illumination above ``LIT_MIN``), so the Fisher matrix is
    ``J^T S^-1 J + 1/2 tr(S^-1 dS S^-1 dS) = (1 / noise^2 + 2) (J / s)^T (J / s)``.
    """
    fs = [float(f) for f in f_numbers]
    _, clean, exposures = make_flats(truth, fs, noise=noise, return_truth_maps=True, **scn)
    e = np.array([exposures[f] for f in fs])
    center = np.array(scn["center_px"], float)
    circ = circle_values(truth)
    nc = circ.size
    signal = clean_signal(truth, fs, scn, center, e)
    model_error = max(float(np.max(np.abs(signal[j] / clean[f].ravel() - 1.0)))
                      for j, f in enumerate(fs))

    def model(theta):
        lens = with_circles(truth, theta[:nc])
        exps = np.append(np.exp(theta[nc + 2:]), e[-1])
        return clean_signal(lens, fs, scn, theta[nc:nc + 2], exps).ravel()

    theta = np.concatenate([circ, center, np.log(e[:-1])])
    steps = np.concatenate([1e-5 * np.abs(circ), [1e-4, 1e-4], np.full(len(fs) - 1, 1e-5)])
    cols = []
    for q, dq in enumerate(steps):
        up, down = theta.copy(), theta.copy()
        up[q] += dq
        down[q] -= dq
        cols.append((model(up) - model(down)) / (2.0 * dq))
    n_pix = signal.shape[1]
    gains = np.zeros((len(fs) * n_pix, n_pix))  # d s / d G_pixel = s
    for j in range(len(fs)):
        gains[j * n_pix + np.arange(n_pix), np.arange(n_pix)] = signal[j]
    J = np.column_stack([*cols, gains])

    _, tan = cra_map_deg(scn["shape"], scn["pitch_um"], center, truth.exit_pupil_mm)
    lit = np.concatenate([(relative_illumination(truth, f, tan) > LIT_MIN).ravel() for f in fs])
    G = J[lit] / signal.ravel()[lit, None]
    G = G[:, np.any(G != 0.0, axis=0)]  # a pixel lit in no flat has no gain to estimate
    F = (1.0 / noise**2 + 2.0) * G.T @ G
    return np.linalg.inv(F)[:nc, :nc], model_error


@pytest.mark.parametrize("key", ["one_h_lt_x", "two_front_rear", "circle_pixel"])
def test_bound_is_the_inverse_of_the_full_fisher_matrix(key):
    truth, fs, noise, scn = TRUTHS[key], (2.0, 2.8, 4.0), 0.01, scene(40)
    want, model_error = brute_force_bound(truth, fs, scn, noise)
    assert model_error < 1e-5, f"{key}: the test's forward model is off make_flats' by " \
                               f"{model_error:.2e}"
    got = bound(truth, noise, f_numbers=fs, **scn)
    ev = whitened_eigenvalues(want, got)
    sd_ratio = np.sqrt(np.diag(want) / np.diag(got))
    assert np.all(np.abs(ev - 1.0) < 0.01), (
        f"{key} on {scn['shape']}: brute-force covariance / bound has eigenvalues {ev}, "
        f"sd ratios {sd_ratio}")


def test_names_and_shape():
    truth = TRUTHS["two_front_rear"]
    F, names = fisher(truth, 0.01, f_numbers=F_NUMBERS, step=4, **scene(8))
    assert names == parameter_names(truth, F_NUMBERS)
    assert names[:6] == ["P1", "h1", "P2", "h2", "cx", "cy"], names
    assert len(names) == 4 + 2 + len(F_NUMBERS) - 1 and F.shape == (len(names),) * 2
    assert np.allclose(F, F.T) and np.all(np.linalg.eigvalsh(F) > 0), "F is not positive"


# -- Monte Carlo ------------------------------------------------------------------------------
class ProfiledFit:
    """Maximum-likelihood fit of (P, h, cx, cy) of a one-circle lens to log flats.

    Residuals ``ln I - ln A_F(t(cx, cy); P, h)`` over the lit measurements (relative
    illumination of the truth above ``LIT_MIN``), projected orthogonally to a log gain per
    pixel and a log exposure per flat: both nuisances profiled out in closed form. ``A_F`` is
    tabulated over tan(CRA) and interpolated to the pixels.
    """

    def __init__(self, truth, f_numbers, scn, n_table=384):
        self.truth, self.fs = truth, [float(f) for f in f_numbers]
        rows, cols = scn["shape"]
        yy, xx = np.mgrid[0:rows, 0:cols]
        self.x, self.y = xx.ravel().astype(float), yy.ravel().astype(float)
        self.k = scn["pitch_um"] * 1e-3 / truth.exit_pupil_mm
        t = self.tan(*scn["center_px"])
        self.grid = np.linspace(0.0, 1.05 * float(t.max()), n_table)
        self.lit = np.stack([relative_illumination(truth, f, t) > LIT_MIN for f in self.fs])
        self.count = np.maximum(self.lit.sum(axis=0), 1)
        unit = np.eye(len(self.fs))
        E = np.stack([self._centerd(np.repeat(unit[j][:, None], t.size, axis=1))[self.lit]
                      for j in range(len(self.fs) - 1)], axis=1)
        self.Q = np.linalg.qr(E)[0]

    def tan(self, cx, cy):
        return self.k * np.hypot(self.x - cx, self.y - cy)

    def _centerd(self, v):
        v = np.where(self.lit, v, 0.0)
        return np.where(self.lit, v - v.sum(axis=0) / self.count, 0.0)

    def project(self, v):
        u = self._centerd(v)[self.lit]
        return u - self.Q @ (self.Q.T @ u)

    def tables(self, P, h):
        lens = with_circles(self.truth, (P, h))
        return [relative_illumination(lens, f, self.grid) for f in self.fs]

    def log_area(self, tables, cx, cy):
        t = self.tan(cx, cy)
        return np.log(np.maximum(np.stack([np.interp(t, self.grid, a) for a in tables]),
                                 1e-300))

    def residuals(self, theta, y):
        return self.project(y - self.log_area(self.tables(*theta[:2]), *theta[2:]))

    def jacobian(self, theta, y):
        tabs = self.tables(*theta[:2])
        base = self.log_area(tabs, *theta[2:])
        cols = []
        for q in range(4):
            dq = 1e-6 * max(abs(theta[q]), 1.0)
            moved = theta.copy()
            moved[q] += dq
            tq = self.tables(*moved[:2]) if q < 2 else tabs
            cols.append(-self.project(self.log_area(tq, *moved[2:]) - base) / dq)
        return np.column_stack(cols)

    def fit(self, flats, start):
        y = np.log(np.maximum(np.stack([flats[f].ravel() for f in self.fs]), 1.0))
        sol = least_squares(self.residuals, np.asarray(start, float), jac=self.jacobian,
                            args=(y,), method="lm", xtol=1e-8, ftol=1e-10)
        assert sol.success, sol.message
        return sol.x


MC_KEY, MC_F_NUMBERS, MC_NOISE, MC_FACTOR, MC_SEEDS = "one_h_gt_x", (2.0, 2.8, 4.0), 0.01, 16, 80


@pytest.fixture(scope="module")
def monte_carlo():
    """(P, h) fitted to flats of MC_SEEDS noise seeds (with a 5 % source non-uniformity)."""
    truth, scn = TRUTHS[MC_KEY], scene(MC_FACTOR)
    fitter = ProfiledFit(truth, MC_F_NUMBERS, scn)
    start = [*truth.circles[0], *scn["center_px"]]
    est = np.array([fitter.fit(make_flats(truth, MC_F_NUMBERS, noise=MC_NOISE, seed=seed,
                                          source_amplitude=0.05, n_table=1024, **scn), start)
                    for seed in range(MC_SEEDS)])
    return truth, scn, est[:, :2]


def test_maximum_likelihood_fits_reach_the_bound(monte_carlo):
    truth, scn, est = monte_carlo
    C = bound(truth, MC_NOISE, f_numbers=MC_F_NUMBERS, **scn)
    err = est - circle_values(truth)
    sample = np.cov(err.T)
    ratio = np.diag(sample) / np.diag(C)
    z_mean = err.mean(axis=0) / np.sqrt(np.diag(C) / len(err))
    ev = whitened_eigenvalues(sample, C)
    what = (f"{len(err)} seeds on {scn['shape']}: sample / bound variances of (P, h) "
            f"{ratio}, whitened eigenvalues {ev}, mean error {z_mean} standard errors")
    assert np.all((ratio > 0.6) & (ratio < 1.6)), what
    assert np.all((ev > 0.5) & (ev < 1.7)), what
    assert np.all(np.abs(z_mean) < 3.5), what


def test_fitted_lenses_mean_shift_spread_reaches_the_shift_bound(monte_carlo):
    truth, scn, est = monte_carlo
    C = bound(truth, MC_NOISE, f_numbers=MC_F_NUMBERS, **scn)
    max_cra, n = field_cra_deg(scn), 21
    want = shift_bound_nm(truth, C, MC_F_NUMBERS, max_cra, n=n)
    cra = np.linspace(0.0, max_cra, n)
    for f, w in zip(MC_F_NUMBERS, want, strict=True):
        shifts = np.array([mean_shift_nm(with_circles(truth, v), 1000.0, 1.5, f, cra)
                           for v in est])
        got = float(np.max(np.std(shifts, axis=0, ddof=1)))
        assert 0.75 < got / w < 1.3, (
            f"f/{f:g}: mean-shift sd of {len(est)} fitted lenses {got:.3e} nm, bound "
            f"{w:.3e} nm")


# -- scaling ----------------------------------------------------------------------------------
def test_bound_scales_with_noise_and_pixels():
    truth = TRUTHS["two_front_rear"]

    def sd(noise, scn, step=1):
        return np.sqrt(np.diag(bound(truth, noise, f_numbers=F_NUMBERS, step=step, **scn)))

    base = sd(0.01, scene(8))
    assert np.allclose(sd(0.04, scene(8)), 4.0 * base, rtol=1e-9, atol=0), "not linear in noise"
    cov = bound(truth, 0.01, f_numbers=F_NUMBERS, **scene(8))
    s1 = shift_bound_nm(truth, cov, F_NUMBERS, field_cra_deg(FULL), n=21)
    s3 = shift_bound_nm(truth, 9.0 * cov, F_NUMBERS, field_cra_deg(FULL), n=21)
    assert np.allclose(s3, 3.0 * s1, rtol=1e-9, atol=0), "shift bound not linear in the sd"
    # every second row and column: a quarter of the pixels, each standing for four
    r_step = sd(0.01, scene(8), step=2) / base
    assert np.all(np.abs(r_step - 1.0) < 0.05), f"step 2 / step 1 sd {r_step}"
    # the same field on a quarter of the pixels: twice the sd
    r_pix = sd(0.01, scene(16)) / base
    assert np.all(np.abs(r_pix / 2.0 - 1.0) < 0.05), f"quarter of the pixels: sd ratio {r_pix}"


def test_more_f_numbers_never_loosen_the_bound():
    truth, scn = TRUTHS["circle_pixel"], scene(8)
    few = bound(truth, 0.01, f_numbers=F_NUMBERS[:3], **scn)
    many = bound(truth, 0.01, f_numbers=F_NUMBERS, **scn)
    ev = whitened_eigenvalues(many, few)
    assert np.all(ev <= 1.0 + 1e-9), f"adding flats raised the bound: eigenvalues {ev}"


@pytest.mark.slow
@pytest.mark.parametrize("key", ["one_h_lt_x", "one_h_gt_x_m", "one_weak", "two_front_rear",
                                 "circle_pixel"])
def test_full_scene_every_second_pixel(key):
    truth = TRUTHS[key]
    full = bound(truth, 0.01, f_numbers=F_NUMBERS, **FULL)
    half = bound(truth, 0.01, f_numbers=F_NUMBERS, step=2, **FULL)
    r = np.sqrt(np.diag(half) / np.diag(full))
    assert np.all(np.abs(r - 1.0) < 0.03), f"{key}: step 2 / step 1 sd {r}"
    s_full = shift_bound_nm(truth, full, F_NUMBERS, field_cra_deg(FULL))
    s_half = shift_bound_nm(truth, half, F_NUMBERS, field_cra_deg(FULL))
    assert np.allclose(s_half, s_full, rtol=0.03, atol=1e-9), f"{key}: {s_half} vs {s_full}"
