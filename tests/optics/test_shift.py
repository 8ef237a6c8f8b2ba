"""The effective-index shift law, Goossens Eq. 3 = Rienstra Eq. 3 = Mishev Eq. 3."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from snapcorr.optics import EffectiveIndexWarning, aoi_from_shift_deg, shift_nm, tilted_cwl_nm
from snapcorr.optics.profiles import PiShaped

# Mishev & Bakalova Table 2 (n = 1.5), rounded to 1 nm.
THETA = [0, 5, 10, 15, 18]
TABLE2 = {
    480: [480, 479, 477, 473, 470],
    540: [540, 539, 536, 532, 528],
    600: [600, 599, 596, 591, 587],
    660: [660, 659, 656, 650, 646],
    720: [720, 719, 715, 709, 705],
    840: [840, 839, 834, 827, 822],
}
WIDTH = {40: [40, 40.6, 42.6, 46.2, 49.5], 100: [100, 101.5, 106.5, 115.5, 123.6]}


@pytest.mark.parametrize("cwl", sorted(TABLE2))
def test_mishev_table2_peaks(cwl):
    got = tilted_cwl_nm(cwl, 1.5, THETA)
    assert_allclose(got, TABLE2[cwl], atol=0.5 + 1e-9)  # the table is rounded to 1 nm


@pytest.mark.parametrize("w0", sorted(WIDTH))
def test_mishev_table2_widths(w0):
    got = PiShaped(600.0, w0, n_eff=1.5, k=2.0).width_nm(THETA)
    # Printed to 0.1 nm, but two entries (49.5 and 106.5) are 0.06 and 0.08 nm above the
    # paper's own formula w0 / cos(2 theta) (49.44, 106.42): allow 0.1 nm.
    assert_allclose(got, WIDTH[w0], atol=0.1)


def test_same_law_as_rienstra_form():
    # Rienstra Eq. 3: lambda = lambda_0 cos(asin(sin(theta) / n_eff)), written independently.
    theta = np.linspace(0, 40, 81)
    for n in (1.4, 1.775, 2.037, 2.4):
        ref = 700 * np.cos(np.arcsin(np.sin(np.deg2rad(theta)) / n)) - 700
        assert_allclose(shift_nm(700, n, theta), ref, rtol=1e-12, atol=1e-12)


def test_inverse_round_trip():
    theta = np.linspace(0, 40, 41)
    assert_allclose(aoi_from_shift_deg(shift_nm(850, 1.9, theta), 850, 1.9), theta, atol=1e-9)


def test_small_angle_accuracy_no_cancellation():
    # 1 - sqrt(1 - q) ~ q/2 for tiny q: computed without cancellation.
    q_exact = (np.sin(np.deg2rad(1e-6)) / 1.7) ** 2
    assert_allclose(shift_nm(700, 1.7, 1e-6), -700 * q_exact / 2, rtol=1e-10)


def test_broadcasting_shapes_agree():
    theta = np.linspace(0, 25, 6)
    flat = shift_nm(700, 1.7, theta)
    assert_allclose(shift_nm(700, 1.7, theta.reshape(2, 3)), flat.reshape(2, 3))
    assert_allclose([shift_nm(700, 1.7, t) for t in theta], flat)


@pytest.mark.parametrize("n", [1.0, 0.9, np.nan, np.inf])
def test_bad_index(n):
    with pytest.raises(ValueError, match="n_eff"):
        shift_nm(700, n, 10)


@pytest.mark.parametrize("aoi", [90, 120, np.nan])
def test_bad_angle(aoi):
    with pytest.raises(ValueError, match="angle of incidence"):
        shift_nm(700, 1.7, aoi)


def test_beyond_validity_warns_but_answers():
    with pytest.warns(EffectiveIndexWarning, match="40"):
        v = shift_nm(700, 1.7, 45)
    assert np.isfinite(v)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        shift_nm(700, 1.7, 40)
