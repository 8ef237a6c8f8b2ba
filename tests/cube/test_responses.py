"""What a calibration file says of its filters, held and checked: Gaussian responses made
here, each band's main peak the strongest inside the system's pass band (a second order
outside it does not count), read-only copies, equality by value, and files whose curves
cannot be a band's response refused."""

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from snapcorr.cube.responses import (
    NOISE_FRACTION,
    PASSBAND_FRACTION,
    CorrectionMatrix,
    FilterResponses,
    Peak,
)

GRID = np.arange(400.0, 1001.0, 2.0)


def _gauss(centre, fwhm, height=1.0):
    return height * np.exp(-4 * np.log(2) * ((GRID - centre) / fwhm) ** 2)


def _responses(**change):
    """Two bands, the second with a stronger second order at 900 nm, behind a band-pass of
    450-750 nm."""
    curves = np.stack([_gauss(500.0, 12.0, 40.0), _gauss(650.0, 14.0, 30.0)
                       + _gauss(900.0, 20.0, 50.0)])
    system = np.where((GRID >= 450) & (GRID <= 750), 0.9, 0.2)
    peaks = [[Peak(500.0, 12.0, 40.0)], [Peak(650.0, 14.0, 30.0, 1), Peak(900.0, 20.0, 50.0, 2)]]
    kwargs = {"wavelength_nm": GRID, "curves": curves, "system": system, "peaks": peaks,
              "system_name": "band-pass"} | change
    return FilterResponses(**kwargs)


def test_the_main_peak_is_the_strongest_the_system_lets_through():
    r = _responses()
    assert r.n_bands == 2
    assert [p.wavelength_nm for p in r.main_peaks()] == [500.0, 650.0]
    assert 0.2 < PASSBAND_FRACTION * 0.9  # the 900 nm order lies outside the pass band
    # with nothing in front, the stronger order is the main peak
    bare = _responses(system=np.ones(GRID.size))
    assert [p.wavelength_nm for p in bare.main_peaks()] == [500.0, 900.0]


def test_the_arrays_are_read_only_copies_and_equality_is_by_value():
    curves = np.stack([_gauss(500.0, 12.0), _gauss(650.0, 14.0)])
    r = _responses(curves=curves)
    curves[0, :] = 0.0
    assert r.curves[0].max() == pytest.approx(1.0)  # a copy
    with pytest.raises(ValueError, match="read-only"):
        r.curves[0, 0] = 1.0
    assert_array_equal(r.effective, r.curves * r.system)
    again = _responses(curves=np.stack([_gauss(500.0, 12.0), _gauss(650.0, 14.0)]))
    assert again == r and hash(again) == hash(r)
    assert _responses() != r


@pytest.mark.parametrize("change, match", [
    ({"wavelength_nm": GRID[::-1]}, "increasing"),
    ({"curves": np.stack([_gauss(500.0, 12.0), -_gauss(650.0, 14.0)])}, "not negative"),
    ({"curves": np.stack([_gauss(500.0, 12.0), np.zeros(GRID.size)])}, "positive somewhere"),
    ({"peaks": [[Peak(500.0, 1.0, 1.0)], [Peak(650.0, 14.0, 1.0)]]}, "narrower than the grid"),
    ({"peaks": [[Peak(1200.0, 12.0, 1.0)], [Peak(650.0, 14.0, 1.0)]]}, "outside the response"),
    ({"peaks": [[Peak(500.0, 12.0, 1.0)]]}, "at least one peak"),
    ({"curves": np.stack([_gauss(500.0, 12.0), 1.0 * (np.abs(GRID - 650) < 20)]),
      "system": 1.0 * (GRID < 600)}, "zero everywhere through the system"),
])
def test_curves_that_cannot_be_a_bands_response_are_refused(change, match):
    with pytest.raises(ValueError, match=match):
        _responses(**change)


def test_noise_below_zero_is_allowed_up_to_its_fraction():
    small = -0.5 * NOISE_FRACTION * 40.0
    curves = np.stack([_gauss(500.0, 12.0, 40.0) + small, _gauss(650.0, 14.0, 30.0)])
    assert _responses(curves=curves).curves.min() == pytest.approx(small)


def test_a_correction_matrix_turns_bands_into_virtual_bands_as_its_rows_say():
    coefficients = [[1.0, -0.1, 0.0], [0.0, 1.2, -0.3]]
    m = CorrectionMatrix("hsi_reflectance", "reflectance", [510.0, 640.0], np.nan,
                         coefficients)
    assert m.n_virtual == 2 and np.isnan(m.fwhm_nm).all() and m.fwhm_nm.shape == (2,)
    bands = np.array([2.0, 3.0, 5.0])
    np.testing.assert_allclose(m.coefficients @ bands, [2.0 - 0.3, 3.6 - 1.5], rtol=1e-15)
    assert m == CorrectionMatrix("hsi_reflectance", "reflectance", [510.0, 640.0],
                                 [np.nan, np.nan], coefficients)
    with pytest.raises(ValueError, match="type must be one of"):
        CorrectionMatrix("x", "radiance", [510.0, 640.0], 10.0, coefficients)
    with pytest.raises(ValueError, match="one row per"):
        CorrectionMatrix("x", "reflectance", [510.0], 10.0, coefficients)
    with pytest.raises(ValueError, match="widths must be > 0"):
        CorrectionMatrix("x", "reflectance", [510.0, 640.0], [10.0, 0.0], coefficients)
