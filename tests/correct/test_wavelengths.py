"""The corrected wavelengths' model (snapcorr.correct.wavelengths): the relative shift by each
model, and the model chosen."""

import numpy as np
import pytest
from conftest import PAPER_LENS

from snapcorr import mean_shift
from snapcorr.correct import relative_shift
from snapcorr.correct.wavelengths import _field_max_deg

CRA = np.linspace(0.0, 15.0, 7)


def test_no_model_shifts_nothing_and_the_asymptotic_one_is_eq_6():
    kw = {"tolerance_nm": 0.01, "cwl_max_nm": 900.0}
    assert np.array_equal(relative_shift(1.7, 2.8, CRA, PAPER_LENS, model="none", **kw),
                          np.zeros(CRA.shape))
    got = relative_shift(1.7, 2.8, CRA, PAPER_LENS, model="asymptotic", **kw)
    np.testing.assert_allclose(got, mean_shift(1.0, 1.7, 2.8, CRA, PAPER_LENS,
                                               method="asymptotic"))
    assert np.all(got[1:] < 0)


def test_the_exact_models_are_within_the_tolerance_of_the_exact_shift():
    kw = {"tolerance_nm": 0.01, "cwl_max_nm": 900.0}
    for model, method in (("ideal", "ideal"), ("vignetted", "vignetted")):
        got = relative_shift(1.7, 2.8, CRA, PAPER_LENS, model=model, **kw) * 900.0
        want = mean_shift(900.0, 1.7, 2.8, CRA, PAPER_LENS, method=method)
        np.testing.assert_allclose(got, want, atol=0.011)
    with pytest.raises(ValueError, match="model"):
        relative_shift(1.7, 2.8, CRA, PAPER_LENS, model="exact", **kw)


def test_a_field_beyond_the_lens_cutoff_is_refused():
    cutoff = float(PAPER_LENS.cutoff_cra_deg(2.8))
    assert _field_max_deg(cutoff - 1.0, 2.8, PAPER_LENS) == cutoff - 1.0
    with pytest.raises(ValueError, match="cuts off the whole pupil"):
        _field_max_deg(cutoff + 0.1, 2.8, PAPER_LENS)
