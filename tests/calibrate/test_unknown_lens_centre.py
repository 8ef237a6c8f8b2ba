"""The flats' optical centre handed to the target's fit (``calibrate_with_target``): a
refusal names it as the flats', and one check of it serves every fit of the target.

Flats from ``tests/oracles/flatsim.py``, cubes from ``tests/oracles/spectralsim.py`` (neither
shares code with snapcorr); the cubes' axis is put 60 px from the flats' where they must
disagree."""

from __future__ import annotations

import pytest
from flatsim import make_flats

from calibrate.pupil.test_locate import CENTER, PAPER, PITCH_UM, SHAPE, cubes, sensor
from snapcorr.calibrate import calibrate_with_target

ELSEWHERE = (CENTER[0] - 40.0, CENTER[1] + 45.0)  # (column, row), 60 px from the flats' axis


def _run(cube_center=CENTER, **kw):
    flats = make_flats(PAPER, (1.4, 2.0, 2.8, 4.0, 8.0), shape=SHAPE, pitch_um=PITCH_UM,
                       center_px=CENTER, noise=0.005, seed=1)
    return calibrate_with_target(
        flats, cubes("colour_filter", "paper", (2.0, 8.0), noise=0.002, seed=101,
                     center=cube_center), sensor(), pixel_pitch_um=PITCH_UM, max_circles=1,
        **kw)


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_the_flats_centre_the_cubes_contradict_is_refused_as_the_flats():
    """The user gave no centre: the refusal names the flats' and does not advise leaving
    out a centre never given."""
    with pytest.raises(ValueError) as got:
        _run(ELSEWHERE, magnification=PAPER.magnification,
             pupil_magnification=PAPER.pupil_magnification)
    said = str(got.value)
    assert said.startswith("the flats' optical centre (row 61.")
    assert "the flats and the target cubes do not agree on the axis" in said
    assert "leave it out" not in said and "centre given" not in said


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_every_fit_of_the_target_about_the_flats_centre_shares_one_check(monkeypatch):
    """The magnifications assumed: the target is fitted again at other ratios, every fit
    about the flats' centre; the cubes re-estimate the centre once for each centre (the
    flats', and the two moved by its errors to carry them into x's)."""
    import snapcorr.calibrate.pupil.locate as loc

    calls, fits = [], []
    check, locate = loc.check_given_center, loc._checked_locate
    monkeypatch.setattr(loc, "check_given_center", lambda *a: calls.append(a[4]) or check(*a))
    monkeypatch.setattr(loc, "_checked_locate", lambda *a, **k: fits.append(1) or locate(
        *a, **k))
    with pytest.warns(UserWarning):
        got = _run()
    assert len(fits) >= 2 and len(calls) == len(set(calls)) <= 3
    assert all(abs(c[0] - calls[0][0]) + abs(c[1] - calls[0][1]) < 1.0 for c in calls)
    assert got.pupil.center_source.startswith("the flats' (joint fit, +- 0.")
    # the flats' centre is measured: its errors reach x's (here little, about the middle)
    record = got.pupil.lens.calibration["center_error"]
    assert record["center_stderr_px"] == [pytest.approx(e, rel=1e-2) for e in (
        got.calibration.fits[got.calibration.model].stderr["center_row_px"],
        got.calibration.fits[got.calibration.model].stderr["center_col_px"])]


@pytest.mark.slow
def test_a_crop_by_the_axis_carries_the_flats_centre_error_into_x():
    """Flats and cubes of a 70 x 90 crop with the axis by its corner: the flats place the
    centre to 0.1 px, which moves x by 0.02 mm; left out, x was 4.6 of its errors off (seed
    0). With it, x within 3 of its errors in each of two seeds, and the note says whose."""
    from calibrate.test_unknown_lens import TRUTH

    for seed in (0, 1):
        flats = {f: v[:70, :90] for f, v in make_flats(
            PAPER, (1.4, 2.0, 2.8, 4.0, 8.0), shape=SHAPE, pitch_um=PITCH_UM,
            center_px=CENTER, noise=0.005, seed=seed).items()}
        data = {f: c.isel(y=slice(0, 70), x=slice(0, 90)) for f, c in cubes(
            "colour_filter", "paper", (2.0, 8.0), noise=0.002, seed=100 + seed).items()}
        got = calibrate_with_target(flats, data, sensor(), pixel_pitch_um=PITCH_UM,
                                    fit_n_eff=True, magnification=PAPER.magnification,
                                    pupil_magnification=PAPER.pupil_magnification,
                                    max_circles=1, sensor_origin_px=(0, 0))
        i = got.names.index("exit_pupil_mm")
        assert abs(got.values[i] - TRUTH["exit_pupil_mm"]) < 3 * got.stderr[i], got.summary()
        assert got.pupil.lens.calibration["center_error"]["carried"].startswith("yes")
        assert any(n.startswith("the flats' optical centre was found to")
                   for n in got.pupil.notes)
