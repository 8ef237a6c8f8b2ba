"""A refusal of a given optical centre says where the centre came from, and advises what is
true there: the caller's own (leave it out), or the flats' (``calibrate_with_target``, where
the user gave none). Cubes from ``tests/oracles/spectralsim.py`` (shares no code with
snapcorr), their axis off the centre handed to the fit."""

from __future__ import annotations

import pytest
import spectralsim as sim

from calibrate.pupil.test_locate import PLAIN, as_lens, cubes, sensor
from snapcorr.calibrate import locate_pupil

ROW, COL = 37.25, 81.5
FAR = (ROW + 80.0, COL - 60.0)


def _fit(center_from=None, center=FAR, **kw):
    data = cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5, center=(COL, ROW))
    return locate_pupil(data, sensor(), center_rc=center, lens=as_lens(PLAIN),
                        target_spectrum=sim.colour_filter, n_bins=32,
                        **({} if center_from is None else {"center_from": center_from}), **kw)


def test_a_refused_centre_the_caller_gave_is_called_given_and_may_be_left_out():
    with pytest.raises(ValueError) as got:
        _fit()
    said = str(got.value)
    assert said.startswith("the optical centre given (row 117.25, col 21.5) is ")
    assert said.endswith("or leave it out to use the one found")


def test_a_refused_centre_of_the_flats_is_named_so_with_advice_true_there():
    """The user gave no centre: the refusal names the flats' and does not advise leaving
    out a centre never given."""
    with pytest.raises(ValueError) as got:
        _fit("flats")
    said = str(got.value)
    assert said.startswith("the flats' optical centre (row 117.25, col 21.5) is ")
    assert "from where the f/2 cube places it" in said
    assert "the flats and the target cubes do not agree on the axis" in said
    assert "(center_rc=)" in said
    assert "given" not in said and "leave it out" not in said


def test_one_check_serves_every_fit_about_the_same_centre(monkeypatch):
    """Fits sharing ``center_checks`` check a centre once (the check re-estimates the
    centre: seconds); another centre is checked anew."""
    import snapcorr.calibrate.pupil.locate as loc

    calls = []
    check = loc.check_given_center
    monkeypatch.setattr(loc, "check_given_center",
                        lambda *a: calls.append(a[4]) or check(*a))
    checks = {}
    near = (ROW + 1.0, COL - 1.0)
    for _ in range(2):
        _fit(center=near, center_checks=checks)
    assert calls == [near]
    for _ in range(2):
        with pytest.raises(ValueError, match="the optical centre given"):
            _fit(center_checks=checks)
    assert calls == [near, FAR]


def test_where_the_centre_came_from_is_one_of_two():
    with pytest.raises(ValueError, match="center_from must be one of 'given', 'flats'"):
        _fit("lens")
