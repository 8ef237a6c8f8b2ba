"""The joint fit holds the optical centre row first, (P, h, row, col), and its earlier x-first
keywords and names keep their meaning, warn, and refuse to be mixed with the new ones.

The ratio images come from the independent simulator's pupil areas
(``tests/oracles/flatsim.py``), about a centre far from the image's middle in a wide image, so
that a swapped row and column would fit far worse (and land far off).
"""

import warnings

import numpy as np
import pytest
from flatsim import LensTruth, relative_illumination

from snapcorr.calibrate.lens.joint_fit import (
    BlockData,
    _block_model,
    fit_model,
    floor_chi2,
    param_names,
)
from snapcorr.calibrate.lens.predictive import compare_estimators, predict_left_out

TRUTH = LensTruth(21.0, [(7.4236, 16.991)])
FS = np.array([1.4, 2.0, 2.8, 8.0])
ROW, COL = 20.3, 71.6  # (row, col) of the optical centre in a 48 x 96 grid of 8-pixel blocks
PITCH_MM, BLOCK = 0.088, 8


@pytest.fixture(scope="module")
def data():
    """Noise-free ratio images q_F = A_F / A_ref of every block, from the simulator."""
    by, bx = np.mgrid[:48, :96]
    c = (BLOCK - 1) / 2.0
    rows, cols = (by * BLOCK + c).ravel() / BLOCK, (bx * BLOCK + c).ravel() / BLOCK
    # block centres in pixels of 88 um, one pixel per block side (block_px 1: the centres)
    xpix, ypix = cols * 1.0, rows * 1.0
    tan = np.hypot(xpix - COL, ypix - ROW) * PITCH_MM / TRUTH.exit_pupil_mm
    ref = relative_illumination(TRUTH, FS[-1], tan)
    q = np.stack([relative_illumination(TRUTH, f, tan) / ref for f in FS[:-1]])
    ok = ref > 0.05
    return BlockData(q=np.where(ok, q, 0.0), sigma=np.where(ok, 1e-3, np.inf) * np.ones_like(q),
                     xpix=xpix, ypix=ypix, R_mm=TRUTH.pupil_radius_mm(FS[:-1]),
                     R_ref_mm=float(TRUTH.pupil_radius_mm(FS[-1])), pitch_mm=PITCH_MM,
                     x_mm=TRUTH.exit_pupil_mm)


def test_the_vector_and_its_names_are_row_first():
    assert param_names("one") == ["P_mm", "h_mm", "center_row_px", "center_col_px"]
    assert param_names("two")[2:4] == ["center_row_px", "center_col_px"]


def test_the_fitted_centre_is_row_first_and_right(data):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new form: no warning at all
        fit = fit_model(data, "one", [[7.0, 18.0, ROW + 2.0, COL - 3.0]])
    assert fit.names == ("P_mm", "h_mm", "center_row_px", "center_col_px")
    assert fit.params["center_row_px"] == pytest.approx(ROW, abs=1e-3)
    assert fit.params["center_col_px"] == pytest.approx(COL, abs=1e-3)
    assert fit.params["P_mm"] == pytest.approx(7.4236, rel=1e-4)
    assert fit.params["h_mm"] == pytest.approx(16.991, rel=1e-4)
    # the covariance follows the names: the centre's two variances at 2 and 3
    cov = np.asarray(fit.covariance)
    assert cov[2, 2] == pytest.approx(fit.stderr["center_row_px"] ** 2, rel=1e-9)
    assert cov[3, 3] == pytest.approx(fit.stderr["center_col_px"] ** 2, rel=1e-9)
    # the earlier names read the same values, and warn
    with pytest.warns(FutureWarning, match="'cx_px' is the earlier name of 'center_col_px'"):
        assert fit.params["cx_px"] == fit.params["center_col_px"]
    with pytest.warns(FutureWarning, match="'cy_px'"):
        assert fit.stderr["cy_px"] == fit.stderr["center_row_px"]
    with pytest.warns(FutureWarning):
        assert fit.params.get("cy_px") == fit.params["center_row_px"]
    assert fit.params.get("nothing") is None
    with pytest.raises(KeyError):
        fit.params["cz_px"]


def test_a_swapped_centre_is_a_bad_model(data):
    # the same model about (col, row) instead of (row, col) misses the data by far
    p = [7.4236, 16.991, ROW, COL]
    good = _block_model(data, "one", p, (ROW, COL))
    swapped = _block_model(data, "one", p, (COL, ROW))
    ok = np.isfinite(data.sigma)
    assert np.max(np.abs(good - data.q)[ok]) < 1e-4
    assert np.max(np.abs(swapped - data.q)[ok]) > 0.1


def test_the_x_first_keyword_keeps_its_meaning_and_warns(data):
    start = [[7.0, 18.0, ROW, COL]]
    new = fit_model(data, "one", start, center_rc=(ROW, COL))
    with pytest.warns(FutureWarning, match=r"center is the old x-first form .* "
                                           r"center_rc=\(20\.3, 71\.6\)"):
        old = fit_model(data, "one", start, center=(COL, ROW))
    assert old.params == new.params and old.chi2 == new.chi2
    assert new.stderr["center_row_px"] == 0.0 and new.params["center_row_px"] == ROW
    with pytest.raises(TypeError, match="give the optical centre once"):
        fit_model(data, "one", start, center=(COL, ROW), center_rc=(ROW, COL))
    with pytest.warns(FutureWarning, match="center is the old x-first form"):
        assert floor_chi2(data, new, 1e-3, center=(COL, ROW)) == \
            floor_chi2(data, new, 1e-3, center_rc=(ROW, COL))


def test_prediction_takes_the_centre_row_first(data):
    fit = fit_model(data, "one", [[7.0, 18.0, ROW, COL]], center_rc=(ROW, COL))
    p = [fit.params[k] for k in fit.names]
    new = predict_left_out(data, "one", p, (ROW, COL), 0)
    with pytest.warns(FutureWarning, match="center is the old x-first form"):
        old = predict_left_out(data, "one", p, center=(COL, ROW), k=0)
    assert new == old
    swapped = predict_left_out(data, "one", p, (COL, ROW), 0)
    assert swapped[0] > 100 * max(new[0], 1.0)


def test_the_comparison_of_estimators_takes_its_centres_row_first(data):
    fit = fit_model(data, "one", [[7.0, 18.0, ROW, COL]], center_rc=(ROW, COL))

    def solver(_):
        return (7.4236, 16.991)

    new = compare_estimators(data, FS, fit, solver, (ROW, COL), fix_center_rc=(ROW, COL))
    with pytest.warns(FutureWarning) as got:
        old = compare_estimators(data, FS, fit, solver, center=(COL, ROW),
                                 fix_center=(COL, ROW))
    assert {str(w.message).split(" is ")[0] for w in got} == {"center", "fix_center"}
    assert new[0].chi2 == old[0].chi2 and new[1].chi2 == old[1].chi2
    assert new[0].chi2  # the flats left out were predicted
