"""The optical centre from contours, and radial profiles (of a flat and of a ratio)
against direct averages."""

import numpy as np
import pytest

from snapcorr.calibrate.flats.radial import estimate_center, estimate_center_rc, radial_profile
from snapcorr.optics import cra_map


def test_center_from_contours_of_a_shifted_fall_off():
    ny, nx = 200, 300
    yy, xx = np.mgrid[:ny, :nx]
    img = 1.0 - 1e-5 * ((xx - 190.4) ** 2 + (yy - 80.7) ** 2)
    (row, col), spread = estimate_center_rc([img])
    assert abs(col - 190.4) < 0.2 and abs(row - 80.7) < 0.2 and spread < 0.5
    # the earlier form gives the same centre x first, and says so
    with pytest.warns(FutureWarning, match="estimate_center gives the optical centre x first"):
        assert estimate_center([img]) == ((col, row), spread)


def test_radial_profile_against_a_direct_average():
    rng = np.random.default_rng(9)
    img = rng.normal(100, 5, (120, 160))
    ok = np.ones(img.shape, bool)
    cra = cra_map(img.shape, 10.0, 21.0, (70.0, 50.0))
    prof = radial_profile(img, ok, cra, bin_deg=0.5)
    sel = (cra >= 2.0) & (cra < 2.5)
    k = np.argmin(np.abs(prof.cra_deg - cra[sel].mean()))
    assert prof.value[k] == pytest.approx(img[sel].mean(), rel=1e-12)
    assert prof.stderr[k] == pytest.approx(img[sel].std(ddof=1) / np.sqrt(sel.sum()), rel=1e-9)
    assert prof.count[k] == sel.sum()


def test_ratio_profile_is_the_ratio_of_bin_sums_with_a_pixelwise_error():
    rng = np.random.default_rng(16)
    num, den = rng.normal(50, 2, (80, 90)), rng.normal(100, 3, (80, 90))
    src = 1 + 0.3 * np.linspace(0, 1, 90)[None, :]  # a source that varies around the ring
    ok = np.ones(num.shape, bool)
    cra = cra_map(num.shape, 20.0, 21.0, (40.0, 40.0))
    prof = radial_profile(num * src, ok, cra, bin_deg=0.5, denominator=den * src)
    sel = (cra >= 1.0) & (cra < 1.5)
    k = np.argmin(np.abs(prof.cra_deg - cra[sel].mean()))
    assert prof.value[k] == pytest.approx((num * src)[sel].sum() / (den * src)[sel].sum())
    q = num[sel] / den[sel]
    assert prof.stderr[k] == pytest.approx(q.std(ddof=1) / np.sqrt(sel.sum()), rel=1e-9)
