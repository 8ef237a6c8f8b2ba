"""Magnifications the flats cannot tell: the degeneracy, and the errors that hold it.

Judged on the independent simulator (tests/oracles/flatsim.py: its own area quadrature and
mean-shift integral, no snapcorr code) with the paper's lens, m = 0.06 and m_P = 1.3
(Goossens 2019, Sec. 5).
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
from conftest import PAPER_TRUTH
from flatsim import make_flats, mean_shift_nm, relative_illumination

import snapcorr
from snapcorr.calibrate.lens import calibration
from snapcorr.calibrate.lens import magnification as mag

F_NUMBERS = (1.4, 2.0, 2.8, 4.0, 5.6, 11.0)
SCENE = dict(shape=(256, 320), pitch_um=28.4, center_px=(174.75, 119.75))
CWL, N_EFF = 1000.0, 1.5


def test_flats_cannot_tell_the_magnifications_from_a_scale_of_P_and_h():
    """The simulator's relative illumination of the paper lens equals, at every f-number and
    CRA, that of a lens at m = 0 with P and h scaled by 1 + m / m_P: no number of f-numbers
    pins m / m_P. The mean shift of the two differs (the rays' angles change)."""
    k = 1.0 + PAPER_TRUTH.magnification / PAPER_TRUTH.pupil_magnification
    alias = replace(PAPER_TRUTH, circles=tuple((P * k, h * k) for P, h in PAPER_TRUTH.circles),
                    magnification=0.0, pupil_magnification=1.0)
    tan = np.linspace(0.0, 0.6, 61)
    for f in F_NUMBERS:
        a = relative_illumination(PAPER_TRUTH, f, tan)
        b = relative_illumination(alias, f, tan)
        assert np.max(np.abs(a - b)) < 1e-12
        assert np.ptp(a) > 0.1  # the circle cuts the pupil in this field
    cra = np.linspace(0.0, 25.0, 6)
    d = mean_shift_nm(PAPER_TRUTH, CWL, N_EFF, 1.4, cra) - mean_shift_nm(alias, CWL, N_EFF, 1.4,
                                                                         cra)
    assert np.max(np.abs(d)) > 0.5


@pytest.mark.parametrize("m, mp, lens, want", [
    (None, None, None, ("neither", 0.0, (0.0, 0.1))),
    (0.0, None, None, ("m = 0", 0.0, (0.0, 0.0))),
    (0.06, 1.3, None, ("both", 0.06 / 1.3, (0.06 / 1.3, 0.06 / 1.3))),
    (0.06, None, None, ("m only", 0.06, (0.03, 0.12))),
    (None, 1.3, None, ("m_P only", 0.0, (0.0, 0.1))),
    (None, None, snapcorr.Lens(21.0, (), 0.06, 1.3), ("both", 0.06 / 1.3, (0.06 / 1.3,) * 2)),
    (None, None, snapcorr.Lens(21.0, (), 0.0, 1.0,
                               calibration={"magnification": {"assumed": True}}),
     ("neither", 0.0, (0.0, 0.1))),
])
def test_the_range_judged_follows_what_was_given(m, mp, lens, want):
    given, r, rng = mag.ratio_range(m, mp, lens)
    assert given == want[0] and r == pytest.approx(want[1])
    assert rng == pytest.approx(want[2])


def _true_errors(res):
    """|P - P_true|, |h - h_true| and, per f-number, the largest |mean shift - truth| over the
    field (the simulator's quadrature for the truth)."""
    (P, h), = res.lens.vignetting
    (Pt, ht), = PAPER_TRUTH.circles
    cra = np.linspace(0.0, res.max_cra_deg, 41)
    shift = [np.nanmax(np.abs(
        snapcorr.mean_shift(CWL, N_EFF, f, cra, res.lens, method="vignetted")
        - mean_shift_nm(PAPER_TRUTH, CWL, N_EFF, f, cra))) for f in F_NUMBERS]
    return abs(P - Pt), abs(h - ht), np.array(shift)


@pytest.mark.slow
def test_assumed_magnifications_are_said_and_their_errors_cover_the_truth():
    """Defaults on a lens at 0.06 / 1.3: a warning, the assumption recorded, and errors of
    P, h and the mean shift that cover the true errors (z between 0.5 and 2, not a floor far
    above); the true magnifications given: no warning, the same figures as the calibration
    without this module, to the last digit."""
    flats = make_flats(PAPER_TRUTH, F_NUMBERS, noise=0.005, seed=3, **SCENE)
    kw = dict(exit_pupil_mm=PAPER_TRUTH.exit_pupil_mm, pixel_pitch_um=SCENE["pitch_um"])
    with pytest.warns(mag.MagnificationWarning, match="no magnifications given"):
        res = calibration.calibrate_lens(flats, **kw)
    rec = res.lens.calibration["magnification"]
    assert rec["assumed"] is True and rec["given"] == "neither"
    assert rec["m_over_m_P_range"] == [0.0, 0.1]
    assert any("no magnifications given" in n for n in res.lens.calibration["notes"])
    dP, dh, ds = _true_errors(res)
    assert dP / PAPER_TRUTH.circles[0][0] > 0.04  # the defaults are wrong by 4.6 %
    assert 0.5 < dP / rec["P_stderr_mm"][0] < 2 and 0.5 < dh / rec["h_stderr_mm"][0] < 2
    z = ds / res.shift_stderr_nm
    assert np.all((z > 0.5) & (z < 2)), z
    assert res.lens.calibration["shift_stderr_nm"] == pytest.approx(list(res.shift_stderr_nm))
    assert "magnifications assumed" in res.summary()

    true = dict(magnification=PAPER_TRUTH.magnification,
                pupil_magnification=PAPER_TRUTH.pupil_magnification)
    with warnings.catch_warnings():
        warnings.simplefilter("error", mag.MagnificationWarning)
        got = calibration.calibrate_lens(flats, **kw, **true)
    assert getattr(got, "magnification_spread", None) is None  # given: nothing added
    assert "magnification" not in got.lens.calibration
    assert not any("magnification" in n for n in got.notes)
    assert "magnifications assumed" not in got.summary()


def test_without_vignetting_the_working_f_number_alone_is_in_the_errors():
    """No circle: the flats still cannot tell f_W, and the mean shift of the open pupil
    depends on it; its error is the spread alone, and it covers the true error."""
    truth = replace(PAPER_TRUTH, circles=())
    fs = (1.4, 4.0)
    scene = dict(shape=(96, 120), pitch_um=75.7, center_px=(65.5, 44.9))
    flats = make_flats(truth, fs, noise=0.005, seed=11, **scene)
    with pytest.warns(mag.MagnificationWarning, match="not the flats' noise"):
        res = calibration.calibrate_lens(flats, exit_pupil_mm=truth.exit_pupil_mm,
                                 pixel_pitch_um=scene["pitch_um"], method="joint")
    assert res.model == "none" and not res.lens.vignetting
    cra = np.linspace(0.0, res.max_cra_deg, 21)
    true = np.array([np.max(np.abs(
        snapcorr.mean_shift(CWL, N_EFF, f, cra, res.lens, method="vignetted")
        - mean_shift_nm(truth, CWL, N_EFF, f, cra))) for f in fs])
    z = true / res.shift_stderr_nm
    assert np.all((z > 0.5) & (z < 2)), z
    assert res.lens.calibration["shift_stderr_filter"] == [CWL, N_EFF]
    before = res.shift_stderr_nm.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("error", mag.MagnificationWarning)
        assert mag.account_for_magnifications(res) is res  # once only
    assert np.array_equal(res.shift_stderr_nm, before)
    assert sum("no magnifications given" in n for n in res.notes) == 1
