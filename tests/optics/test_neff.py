"""Effective index: fitted from centre wavelengths, checked on a real thin-film stack (tmm)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import minimize_scalar

from snapcorr import Lens, mean_shift
from snapcorr.optics import tilted_cwl_nm
from snapcorr.optics.neff import fit_n_eff
from snapcorr.optics.response import kernel_bins
from snapcorr.optics.shift import aoi_from_shift_deg

tmm = pytest.importorskip("tmm")

N_H, N_L, DESIGN = 2.3, 1.46, 700.0


def _stack(spacer):
    qH, qL = DESIGN / (4 * N_H), DESIGN / (4 * N_L)
    n, d = [1.0], [np.inf]
    for _ in range(4):
        n += [N_H, N_L]
        d += [qH, qL]
    if spacer == "2H":
        n, d = [*n, N_H], [*d, 2 * qH]
    else:  # H 2L H
        n, d = [*n, N_H, N_L, N_H], [*d, qH, 2 * qL, qH]
    for _ in range(4):
        n += [N_L, N_H]
        d += [qL, qH]
    return [*n, 1.52], [*d, np.inf]


def _T(spacer, lam, aoi_deg):
    """Unpolarised transmission: the mean of s and p (transfer-matrix method)."""
    n, d = _stack(spacer)
    th = np.deg2rad(aoi_deg)
    return 0.5 * (tmm.coh_tmm("s", n, d, th, lam)["T"] + tmm.coh_tmm("p", n, d, th, lam)["T"])


def _peak(spacer, aoi_deg):
    guess = DESIGN * np.sqrt(1 - (np.sin(np.deg2rad(aoi_deg)) / 1.75) ** 2)
    lam = np.arange(guess - 12, guess + 6, 0.25)
    i = int(np.argmax([_T(spacer, v, aoi_deg) for v in lam]))
    res = minimize_scalar(
        lambda v: -_T(spacer, v, aoi_deg),
        method="bounded",
        bounds=(lam[i] - 0.25, lam[i] + 0.25),
        options={"xatol": 1e-6},
    )
    return res.x


def test_fit_recovers_synthetic_index():
    theta = np.arange(0, 31, 5.0)
    lam = tilted_cwl_nm(812.0, 1.93, theta)
    fit = fit_n_eff(theta, lam + np.random.default_rng(0).normal(0, 0.01, theta.size))
    assert_allclose([fit.n_eff, fit.cwl_nm], [1.93, 812.0], rtol=2e-3)
    assert fit.n_eff_stderr < 0.01


@pytest.mark.parametrize("spacer", ["2H", "H2LH"])
def test_effective_index_law_reproduces_tmm_peaks(spacer):
    theta = np.arange(0, 30.1, 2.5)
    peaks = np.array([_peak(spacer, t) for t in theta])
    fit = fit_n_eff(theta, peaks)
    # High-index spacer -> higher n_eff than the low-index one.
    assert (1.75 < fit.n_eff < 1.95) if spacer == "2H" else (1.55 < fit.n_eff < 1.75)
    assert np.max(np.abs(fit.residuals_nm)) < 0.1


def test_kernel_mean_tracks_centroid_not_peak():
    """Behind f/1.4 at CRA 15 deg the cone-averaged tmm filter's centroid and FWHM midpoint
    move by the kernel mean; its peak lags far behind (it stays with the on-axis rays)."""
    theta = np.arange(0, 30.1, 5.0)
    n_eff = fit_n_eff(theta, [_peak("2H", t) for t in theta]).n_eff
    lens = Lens(21.0, name="ideal")
    f, cra = 1.4, 15.0
    mu, w = kernel_bins(DESIGN, n_eff, f, cra, lens, step_nm=1.0)
    aoi = aoi_from_shift_deg(np.clip(mu, None, 0), DESIGN, n_eff)
    expected = float(mean_shift(DESIGN, n_eff, f, cra, lens, method="ideal"))  # -11.83 nm
    lam = np.arange(640.0, 740.0, 0.25)
    avg = sum(wk * np.array([_T("2H", v, a) for v in lam]) for wk, a in zip(w, aoi, strict=True))
    base = np.array([_T("2H", v, 0.0) for v in lam])

    def centroid(t, center):
        # Airy-like tails: compare centroids over equal +-30 nm windows about each centre.
        m = np.abs(lam - center) < 30
        return np.trapezoid(lam[m] * t[m], lam[m]) / np.trapezoid(t[m], lam[m])

    shift = centroid(avg, DESIGN + expected) - centroid(base, DESIGN)
    assert abs(shift - expected) < 0.02  # measured: 0.002 nm
    half = lam[avg >= avg.max() / 2]
    assert abs(0.5 * (half[0] + half[-1]) - DESIGN - expected) < 0.5  # measured: 0.27 nm
    peak_shift = lam[np.argmax(avg)] - DESIGN
    assert abs(peak_shift - expected) > 5.0  # measured: the peak moved only 3.7 nm
