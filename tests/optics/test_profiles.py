import numpy as np
import pytest
from numpy.testing import assert_allclose

from snapcorr.optics import tilted_cwl_nm
from snapcorr.optics.profiles import (
    FILTER_PROFILES,
    FWHM_CUT,
    Airy,
    MultiLorentzian,
    PiShaped,
    Tabulated,
    fwhm_of,
)

LAM = np.linspace(350, 1100, 750001)


@pytest.mark.parametrize(("cwl", "fwhm", "n"), [(700, 10, 1.7), (480, 40, 1.5), (900, 2, 2.1)])
def test_airy_peak_and_width(cwl, fwhm, n):
    a = Airy.from_passband(cwl, fwhm, n_eff=n)
    lam = LAM[np.abs(LAM - cwl) < 3 * fwhm]  # one order of the periodic Airy curve
    t = a(lam)
    assert abs(lam[np.argmax(t)] - cwl) < 0.002
    assert_allclose(fwhm_of(lam, t), fwhm, rtol=2e-4)
    assert_allclose(a.cwl_nm, cwl)
    assert_allclose(a.fwhm_nm, fwhm, rtol=2e-4)


def test_airy_peak_follows_the_effective_index_law():
    # Mishev Eq. 2-3: the Airy maximum moves as lambda_m sqrt(1 - sin^2/n^2) -- found here
    # numerically from the curve, not from Eq. 3.
    a = Airy.from_passband(600, 20, n_eff=1.5)
    lam = LAM[np.abs(LAM - 590) < 30]
    for theta in (5, 10, 15, 18):
        peak = lam[np.argmax(a(lam, theta))]
        assert abs(peak - tilted_cwl_nm(600, 1.5, theta)) < 0.002


def test_multi_lorentzian_is_flittner_slater():
    # Their 10 nm filter: 16 nm FWHM at the centre times 6 nm FWHM at +-4 nm; that product's
    # FWHM is 9.96 nm, so the fitted scale is within 0.5 % of theirs.
    m = MultiLorentzian(700.0, 10.0)
    assert abs(m.scale - 1) < 0.005
    t = m(LAM)
    assert_allclose(fwhm_of(LAM, t), 10.0, rtol=1e-5)
    assert t.max() == pytest.approx(1.0, abs=1e-6)
    assert np.all((t == 0) | (t >= FWHM_CUT))  # cut below 5 % of the peak
    assert t[np.abs(LAM - 700) > 30].max() == 0
    assert_allclose(fwhm_of(LAM, MultiLorentzian(413.0, 15.0)(LAM)), 15.0, rtol=1e-5)


def test_multi_lorentzian_tilt_shifts_it():
    m = MultiLorentzian(700.0, 10.0, n_eff=1.7)
    c0 = np.trapezoid(LAM * m(LAM), LAM) / np.trapezoid(m(LAM), LAM)
    c = np.trapezoid(LAM * m(LAM, 20), LAM) / np.trapezoid(m(LAM, 20), LAM)
    assert_allclose(c - c0, tilted_cwl_nm(700, 1.7, 20) - 700, atol=1e-3)


def test_pi_shape_keeps_integral_transmission():
    # Mishev Eq. 7-8: tau_m(theta) dlambda(theta) = tau_m(0) dlambda(0).
    p = PiShaped(720.0, 40.0, n_eff=1.5, k=2.0, peak=0.8)
    areas = [np.trapezoid(p(LAM, th), LAM) for th in (0, 5, 10, 15, 18)]
    assert_allclose(areas, 0.8 * 40.0, rtol=1e-3)


def test_tabulated_round_trip_and_errors():
    t = Tabulated(LAM[::100], MultiLorentzian(700.0, 10.0)(LAM[::100]))
    assert_allclose(t.cwl_nm, 700.0, atol=0.05)
    assert_allclose(t(LAM[::100]), t.transmission)
    with pytest.raises(ValueError, match="increasing"):
        Tabulated([2.0, 1.0], [0.0, 1.0])


def test_registry_profiles_are_callable():
    for name, make in FILTER_PROFILES.items():
        prof = (
            make(LAM[::1000], np.ones(LAM[::1000].size))
            if name == "tabulated"
            else make(700.0, 10.0)
        )
        out = prof(np.array([650.0, 700.0]), 5.0)
        assert out.shape == (2,) and np.all(np.isfinite(out))
