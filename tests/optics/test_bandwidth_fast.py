"""The FWHM table and ``response_fwhm``, computed fast (every band's curve and its FFT once per
table, one FFT length for all angles, the kernels of many angles in one pass), against the
straightforward computation written out here: the kernel binned angle by angle as
``kernel_bins`` always did, spread on the grid with ``np.add.at``, and each band's curve
convolved with it by ``np.convolve`` (no FFT), the half maximum read off each curve.

Both must agree to float rounding (1e-6 nm here; they differ by ~1e-12 nm), for lenses without
a circle, with one, with two (cut off inside the tabulated range) and with the Lambertian
pupil, at f/1.4, f/4 and f/11, and for every filter shape.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import PAPER_CIRCLE, PAPER_LENS
from numpy.testing import assert_allclose, assert_array_equal

from snapcorr.optics import FwhmTable, response_fwhm
from snapcorr.optics import bandwidth as bw
from snapcorr.optics.aperture import max_radius_mm, min_radius_mm
from snapcorr.optics.bandwidth import band_profile, kernel_log_variance, refine_nodes
from snapcorr.optics.goossens2019 import _gauss_legendre, kernel, mean_shift_contour
from snapcorr.optics.mean import _geometry
from snapcorr.optics.response import kernel_bins, kernel_bins_batch
from snapcorr.optics.shift import shift_nm

#: A second circle behind the paper's: it cuts the pupil off at 28 deg at f/1.4, 21 deg at
#: f/4 and 18 deg at f/11.
REAR_CIRCLE = (9.0, 30.0)
LENSES = {
    "none": replace(PAPER_LENS, vignetting=()),
    "one": PAPER_LENS,
    "two": replace(PAPER_LENS, vignetting=(PAPER_CIRCLE, REAR_CIRCLE)),
    "lambertian": replace(PAPER_LENS, pupil_radiance="lambertian"),
}
#: Bands of two effective indices (computed in two groups) and several widths.
CWL = np.array([470.0, 560.0, 655.0, 780.0, 900.0])
FWHM = np.array([10.0, 8.0, 12.0, 10.0, 15.0])
N_EFF = np.array([1.7, 1.7, 1.9, 1.7, 1.9])
#: A measured shape: asymmetric, with a shoulder.
_OFF = np.linspace(-25.0, 25.0, 251)
MEASURED = (_OFF, np.exp(-4 * np.log(2) * (_OFF / 9.0) ** 2)
            + 0.4 * np.exp(-4 * np.log(2) * ((_OFF - 6.0) / 5.0) ** 2))
#: On axis, just past the paper circle's onset at f/1.4, inside, near the edge of the usual
#: tables (cut off for two circles at f/11), beyond the two circles' cut-off at f/1.4.
CRAS = np.array([0.0, 0.9, 7.7, 13.1, 19.6, 30.0])
ATOL_NM = 1e-6


# -- the reference: as the code was before, angle by angle, convolution without FFT ------------
def reference_kernel_bins(cwl, n_eff, f_number, cra_deg, lens, step_nm, nodes=6):
    """``kernel_bins`` for one angle as it was written before the batch."""
    x, R, d, P, dv = _geometry(f_number, cra_deg, lens)
    exact = float(mean_shift_contour(cwl, n_eff, x, R, d, P, dv, pupil=lens.pupil_radiance))
    rmin = float(min_radius_mm(R, d, P, dv))
    rmax = float(max_radius_mm(R, d, P, dv))
    lo, hi = (float(shift_nm(cwl, n_eff, np.rad2deg(np.arctan(r / x)))) for r in (rmax, rmin))
    nbins = max(8, int(np.ceil((hi - lo) / step_nm)))
    edges = np.linspace(lo, hi, nbins + 1)
    xi, w = _gauss_legendre(nodes)
    half = 0.5 * np.diff(edges)
    lam = (edges[:-1] + half)[:, None] + half[:, None] * xi
    K = kernel(lam, cwl, n_eff, x, R, d, P, dv)
    if lens.pupil_radiance == "lambertian":
        sin2 = np.clip(n_eff * n_eff * (1.0 - (1.0 + lam / cwl) ** 2), 0.0, 1.0)
        K = K * (1.0 - sin2) ** 2
    mass = (K * w).sum(axis=1) * half
    keep = mass > 0
    if not np.any(keep):
        return np.array([exact]), np.array([1.0])
    mu = (K * lam * w).sum(axis=1)[keep] * half[keep] / mass[keep]
    weights = mass[keep] / mass[keep].sum()
    return mu + (exact - mu @ weights), weights


def _half_maximum_width(ur, R):
    """Width between the outermost half-maximum crossings (linear interpolation); NaN when the
    curve is above half its maximum at an end."""
    half = 0.5 * R.max()
    idx = np.flatnonzero(R >= half)
    i, j = idx[0], idx[-1]
    if i == 0 or j == R.size - 1:
        return np.nan
    left = ur[i - 1] + (half - R[i - 1]) / (R[i] - R[i - 1]) * (ur[i] - ur[i - 1])
    right = ur[j] + (R[j] - half) / (R[j] - R[j + 1]) * (ur[j + 1] - ur[j])
    return np.exp(right) - np.exp(left)


def reference_fwhm(cwl, fwhm, n_eff, f_number, cra_deg, lens, profile):
    """``(n_bands, n_cra)``: each band's curve on the log grid, ``np.convolve``-d with the
    kernel spread on the grid by ``np.add.at``."""
    cwl, fwhm, n_eff = (np.broadcast_to(np.asarray(v, float), np.shape(cwl)) for v in
                        (cwl, fwhm, n_eff))
    rho = fwhm / cwl
    smooth = isinstance(profile, str) and profile != "pi"
    du = float(rho.min()) * (bw.GRID_STEP_FWHM if smooth else bw.GRID_STEP_FWHM_EDGES)
    reach = bw.GRID_HALF_WIDTH_FWHM * float(rho.max())
    u = np.arange(-reach, reach + du, du)
    curves = [band_profile(profile, c, w, n)(c * np.exp(u))
              for c, w, n in zip(cwl, fwhm, n_eff, strict=True)]
    out = np.full((cwl.size, np.size(cra_deg)), np.nan)
    for j, c in enumerate(np.atleast_1d(cra_deg)):
        for n in np.unique(n_eff):
            try:
                mu, w = reference_kernel_bins(1000.0, n, f_number, float(c), lens, 0.005)
            except ValueError:  # cut off: no light
                continue
            la = np.log1p(mu / 1000.0)
            k0 = int(np.floor(la.min() / du))
            pos = la / du - k0
            i = np.floor(pos).astype(int)
            frac = pos - i
            kern = np.zeros(int(i.max()) + 2)
            np.add.at(kern, i, w * (1 - frac))
            np.add.at(kern, i + 1, w * frac)
            ur = u[0] + k0 * du + du * np.arange(u.size + kern.size - 1)
            for b in np.flatnonzero(n_eff == n):
                out[b, j] = cwl[b] * _half_maximum_width(ur, np.convolve(curves[b], kern))
    return out


# -- response_fwhm ------------------------------------------------------------------------------
CASES = [(lens, f, prof) for lens in LENSES for f, prof in
         ((1.4, "gaussian"), (4.0, "airy"), (11.0, "gaussian"))]
CASES += [("one", 1.4, "multi_lorentzian"), ("two", 1.4, "pi"), ("two", 4.0, MEASURED),
          ("lambertian", 1.4, MEASURED), ("none", 4.0, "pi"), ("one", 11.0, "airy")]


@pytest.mark.filterwarnings("ignore::snapcorr.optics.shift.EffectiveIndexWarning")  # at 30 deg
@pytest.mark.parametrize(("lens", "f_number", "profile"), CASES,
                         ids=[f"{c[0]}-f{c[1]:g}-{c[2] if isinstance(c[2], str) else 'measured'}"
                              for c in CASES])
def test_response_fwhm_equals_the_direct_convolution(lens, f_number, profile):
    cras = CRAS[:3] if profile is MEASURED or profile == "pi" else CRAS  # finer grid: slower
    if lens == "two" and f_number == 4.0:
        cras = np.r_[cras, 22.0]  # past its cut-off, between lit angles
    got = response_fwhm(CWL, FWHM, N_EFF, f_number, cras, LENSES[lens], profile=profile)
    want = reference_fwhm(CWL, FWHM, N_EFF, f_number, cras, LENSES[lens], profile)
    assert_array_equal(np.isnan(got), np.isnan(want))  # the same angles without light
    assert np.all(np.isfinite(got[:, cras < 18.0]))
    assert_allclose(got, want, rtol=0, atol=ATOL_NM)


def test_a_cut_off_angle_is_nan_and_the_lit_ones_unchanged():
    """Angles past the cut-off among lit ones (one pass for the lit ones): NaN there, and
    the others as computed alone."""
    lens, cras = LENSES["two"], np.array([5.0, 29.0, 12.0, 40.0, 89.0])
    got = response_fwhm(CWL, FWHM, N_EFF, 1.4, cras, lens)
    assert_array_equal(np.isnan(got[0]), [False, True, False, True, True])
    alone = np.column_stack([response_fwhm(CWL, FWHM, N_EFF, 1.4, [c], lens)[:, 0]
                             for c in cras])
    assert_allclose(got, alone, rtol=0, atol=1e-9)


def test_the_variance_method_is_unchanged():
    cras = np.array([0.0, 10.0, 30.0])
    got = response_fwhm(CWL, FWHM, N_EFF, 1.4, cras, LENSES["two"], method="variance")
    fwhm0 = np.array([bw._own_fwhm("gaussian", c, w, n) for c, w, n in zip(CWL, FWHM, N_EFF,
                                                                            strict=True)])
    for j, c in enumerate(cras):
        for b in range(CWL.size):
            try:
                mu, w = reference_kernel_bins(1000.0, N_EFF[b], 1.4, c, LENSES["two"], 0.005)
            except ValueError:
                assert np.isnan(got[b, j])
                continue
            la = np.log1p(mu / 1000.0)
            var = w @ (la - la @ w) ** 2 * CWL[b] ** 2
            assert abs(got[b, j] - np.sqrt(fwhm0[b] ** 2 + 8 * np.log(2) * var)) < ATOL_NM


# -- the kernels ----------------------------------------------------------------------------------
@pytest.mark.parametrize("lens", list(LENSES))
@pytest.mark.parametrize("f_number", [1.4, 4.0, 11.0])
def test_kernel_bins_in_one_pass_equal_angle_by_angle(lens, f_number):
    lens = LENSES[lens]
    cras = np.r_[np.linspace(0.0, 20.0, 9), np.minimum(lens.onset_cra_deg(f_number), 10) + 0.05]
    cras = cras[lens.relative_illumination(f_number, cras) > 0]
    batch = kernel_bins_batch(1000.0, 1.8, f_number, cras, lens, step_nm=0.005)
    for c, (mu, w) in zip(cras, batch, strict=True):
        for want_mu, want_w in (reference_kernel_bins(1000.0, 1.8, f_number, c, lens, 0.005),
                                kernel_bins(1000.0, 1.8, f_number, c, lens, step_nm=0.005)):
            assert mu.shape == want_mu.shape
            assert_allclose(mu, want_mu, rtol=0, atol=1e-11)  # nm
            assert_allclose(w, want_w, rtol=1e-12, atol=1e-16)


def test_kernel_log_variance_equals_angle_by_angle():
    lens, cras = LENSES["two"], np.array([0.0, 3.0, 17.0, 29.0, 35.0])
    got = kernel_log_variance(1.7, 1.4, cras, lens)
    for c, v in zip(cras, got, strict=True):
        try:
            mu, w = reference_kernel_bins(1000.0, 1.7, 1.4, c, lens, 0.05)
        except ValueError:
            assert np.isnan(v)
            continue
        la = np.log1p(mu / 1000.0)
        assert v == pytest.approx(w @ (la - la @ w) ** 2, rel=1e-10)


# -- the table ------------------------------------------------------------------------------------
TABLES = [("one", 1.4, "gaussian", 12.0), ("two", 4.0, "airy", 17.0),
          ("lambertian", 11.0, "gaussian", 16.0)]


@pytest.fixture(scope="module", params=TABLES, ids=[f"{t[0]}-f{t[1]:g}" for t in TABLES])
def tables(request):
    lens, f_number, profile, cra_max = request.param
    lens = LENSES[lens]
    table = FwhmTable.build(CWL, FWHM, N_EFF, f_number, lens, cra_max_deg=cra_max,
                            profile=profile, tolerance_nm=0.01)
    return table, lens, f_number, profile, cra_max


def test_the_table_has_the_reference_nodes_and_values(tables):
    """The same nodes (the refinement decides alike) and the same values as a table built on
    the reference."""
    table, lens, f_number, profile, cra_max = tables

    def at(c):
        return reference_fwhm(CWL, FWHM, N_EFF, f_number, c, lens, profile)

    nodes, values = refine_nodes(at, f_number, lens, cra_max_deg=cra_max, tolerance=0.01,
                                 what="the FWHM table")
    assert_array_equal(table.cra_deg, nodes)
    assert_allclose(table.fwhm_nm, values, rtol=0, atol=ATOL_NM)


def test_the_table_interpolates_within_its_tolerance(tables):
    table, lens, f_number, profile, cra_max = tables
    cra = np.random.default_rng(11).uniform(0.0, cra_max, 25)
    direct = response_fwhm(CWL, FWHM, N_EFF, f_number, cra, lens, profile=profile)
    assert np.max(np.abs(table(cra) - direct.T)) <= table.tolerance_nm


def test_the_bands_curves_are_computed_once_per_table(monkeypatch):
    calls = []
    real = bw.band_profile

    def counted(*args):
        calls.append(args[1])
        return real(*args)

    monkeypatch.setattr(bw, "band_profile", counted)
    table = FwhmTable.build(CWL, FWHM, N_EFF, 4.0, LENSES["one"], cra_max_deg=10.0)
    assert table.cra_deg.size > 2 * 9  # asked at two rounds of angles at least
    assert len(calls) == CWL.size
