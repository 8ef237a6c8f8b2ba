"""The model choice's messages and the calibration summary print criterion values compactly:
a BIC gain of 241884663.9 reads 2.419e+08, not as nine digits and a decimal."""

from types import SimpleNamespace

import numpy as np
import pytest

from snapcorr.calibrate.lens import choice
from snapcorr.calibrate.lens.choice import ModelVerdict, choose
from snapcorr.calibrate.lens.report import summary

BIG = 241884663.9


@pytest.fixture
def rules(monkeypatch):
    """Every circle identifiable and a lens per fit; the shift difference and its error set
    by the test (the rules themselves are tested in test_model_choice.py)."""
    got = {"diff": np.array([0.2, 0.3]), "sd": np.array([1e-6, 1e-6])}
    monkeypatch.setattr(choice, "check_circles", lambda *a, **k: [])
    monkeypatch.setattr(choice, "lens_of", lambda fit, base: fit)
    monkeypatch.setattr(choice, "shift_difference_nm", lambda *a, **k: got["diff"])
    monkeypatch.setattr(choice, "shift_stderr_nm", lambda *a, **k: got["sd"])
    return got


def _choose(bic):
    fits = {m: SimpleNamespace(reduced_chi2=1.0) for m in bic}
    return choose(fits, bic, None, [2.0, 4.0], 15.0)


def _compact(text):
    """No number in ``text`` printed with more than five digits in a row."""
    run = 0
    for ch in text:
        run = run + 1 if ch.isdigit() else 0
        assert run <= 5, text


def test_a_large_bic_gain_is_printed_compactly(rules):
    model, verdicts = _choose({"one": BIG, "two": 0.0})
    assert model == "two"
    why = verdicts["two"].why
    assert "BIC gain 2.419e+08 over one" in why, why
    assert "(3e+05 standard errors)" in why, why  # 0.3 nm over 1e-6 nm
    _compact(why)


def test_a_large_bic_loss_is_printed_compactly(rules):
    model, verdicts = _choose({"one": 0.0, "two": BIG})
    assert model == "one"
    why = verdicts["two"].why
    assert "(BIC gain -2.419e+08 <= 10)" in why, why
    _compact(why)


def test_small_shift_differences_keep_their_digits(rules):
    rules["diff"] = np.array([1.234e-7, 2.5e-8])
    model, verdicts = _choose({"one": BIG, "two": 0.0})
    assert model == "one"
    why = verdicts["two"].why
    assert "at most 1.234e-07 nm" in why, why  # not 0.0000 nm


def test_summary_prints_bic_and_chi2_compactly():
    fit = SimpleNamespace(names=["P_mm"], params={"P_mm": 9.5}, stderr={"P_mm": 0.01},
                          reduced_chi2=123456789.0)
    pred = SimpleNamespace(chi2={2.0: 987654321.0}, total=1987654321.0, n={2.0: 40})
    res = SimpleNamespace(
        center_rc=(2.0, 1.0), center_source="given", max_cra_deg=15.0,
        model_onsets_deg=lambda: np.array([np.inf]), f_numbers=np.array([2.0]),
        onsets={"ratio": {}, "model": {}}, onset_check_deg=lambda: None, onset_fits={},
        fits={"one": fit}, verdicts={"one": ModelVerdict("one", True, "the only model tried",
                                                         BIG, fit.reduced_chi2)},
        bic_floor={"one": BIG}, lens=SimpleNamespace(has_vignetting=False), next_best=None,
        shift_stderr_nm=np.array([]), predictive={"joint": pred}, reason="test", notes=[])
    text = summary(res)
    assert "BIC with floor 2.419e+08, reduced chi2 1.235e+08" in text, text
    assert "f/2 9.877e+08 (total 1.988e+09)" in text, text
    _compact(text)
