"""The optical centre's two checks: a given centre against the cubes, and a found one.

The cubes are made by ``tests/oracles/spectralsim.py`` (shares no code with snapcorr). The
given centre's rule is restated here from its definition (the cubes' centre and its errors by
the public :func:`estimate_target_center_rc`, more than 20 standard errors and a quarter of
the cubes' diagonal away, inside their field's inner part), so the check that skips the
errors where they cannot matter is judged against the rule, not against itself.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import spectralsim as sim
from flatsim import LensTruth

from calibrate.pupil.test_locate import CENTER, CWL, as_lens, cubes, sensor
from snapcorr.calibrate import locate_pupil
from snapcorr.calibrate.pupil import target as tg
from snapcorr.correct.geometry import cube_positions
from snapcorr.cube import make_cube

ROW, COL = CENTER[1], CENTER[0]


def _rule(data, s, lens, center):
    """The given centre's check as defined, from the full estimate: True where it doubts."""
    cube = data[min(data)]
    rows, cols = cube_positions(cube, s, lens)
    img = np.asarray(cube.transpose("y", "x", "band").values, float)
    found, err = tg.estimate_target_center_rc(lambda b: img[:, :, b], s.n_bands, rows, cols)
    for v, at in zip(found, (rows, cols), strict=True):
        lo, hi = at.min(), at.max()
        if not lo + 0.1 * (hi - lo) <= v <= hi - 0.1 * (hi - lo):
            return False
    d = np.subtract(center, found)
    span = np.hypot(np.ptp(rows), np.ptp(cols))
    return bool(np.hypot(*(d / np.asarray(err))) > 20 and np.hypot(*d) > 0.25 * span)


def test_the_given_centre_is_doubted_as_its_rule_says_and_its_errors_found_only_when_far(
        monkeypatch):
    """Centres near (no error needed), just inside and just outside a quarter of the
    diagonal (51 px here), far, and off the sensor: each doubted exactly where the rule
    says; the jackknife (seconds a centre) runs only for the centres beyond the quarter."""
    data = cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5)
    s, lens = sensor(), as_lens(LensTruth(16.0, (), 0.0, 1.0))
    runs = []
    jackknife = tg._jackknife_err
    monkeypatch.setattr(tg, "_jackknife_err", lambda *a, **k: runs.append(1) or jackknife(
        *a, **k))
    quarter = 0.25 * np.hypot(127, 159)
    said = {}
    for name, c in {"same": (ROW, COL), "near": (ROW + 3.0, COL - 2.0),
                    "inside the quarter": (ROW + quarter - 2.0, COL),
                    "beyond the quarter": (ROW + quarter + 2.0, COL),
                    "far": (ROW + 40.0, COL - 60.0), "off": (500.0, 500.0)}.items():
        rule = _rule(data, s, lens, c)
        runs.clear()
        said[name] = tg.check_given_center(data, s, lens, None, c) is not None
        assert said[name] == rule, name
        assert bool(runs) == (name in ("beyond the quarter", "far", "off")), name
    assert said == {"same": False, "near": False, "inside the quarter": False,
                    "beyond the quarter": True, "far": True, "off": True}


def test_where_the_centre_came_from_is_checked():
    data = cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5)
    with pytest.raises(ValueError, match="center_from must be one of 'given', 'flats', got "
                                         "'lens'"):
        tg.check_given_center(data, sensor(), None, None, (ROW, COL), "lens")


@pytest.mark.parametrize("whose, said", [
    ("given", r"the optical centre given \(row 500, col 500\).* leave it out to use the one "
              "found"),
    ("flats", r"the flats' optical centre \(row 500, col 500\).* the flats and the target "
              r"cubes do not agree on the axis")])
def test_a_refused_centre_is_named_for_where_it_came_from(whose, said):
    """A centre off the cubes' axis, fitted about with a misfit: the refusal names the user's
    centre or the flats', and gives the advice true for each (the flats' user gave none)."""
    data = cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5)
    with pytest.raises(ValueError, match=said):
        locate_pupil(data, sensor(), lens=as_lens(LensTruth(16.0, (), 0.0, 1.0)),
                     center_rc=(500.0, 500.0), target_spectrum=sim.colour_filter, n_bins=16,
                     center_from=whose)


def _one_way_cube(seed, kind):
    """A target whose field changes along the rows alone, no optical axis to place: each band
    a ramp over the rows, or a cosine of them (a different slope per band), under noise."""
    rng = np.random.default_rng(seed)
    rr = np.arange(128.0)[:, None, None] / 128
    slope = np.linspace(-0.05, 0.05, CWL.size)[None, None, :]
    field = rr if kind == "ramp" else np.cos(3 * rr)
    return {2.0: make_cube(0.5 + slope * field + rng.normal(0.0, 0.01, (128, 160, CWL.size)),
                           CWL)}


@pytest.mark.parametrize("seed", [0, 1])
def test_a_centre_the_cubes_cannot_place_is_refused_naming_the_way_out(seed):
    """Cubes that change along one direction only: the centre found runs off the sensor
    (rows beyond +-2800 on a 128-row sensor, +- 5 px to 14000 px); it is refused, naming
    center_rc= (--center on the command line), before anything is fitted about it (the ramp
    by its errors, with or without a sensor size; the cosine, whose errors are small, by its
    place off the sensor)."""
    s = sensor()
    sized = dataclasses.replace(s, size_px=(128, 160))
    for kind, sen, why in (("ramp", s, "more than 0.25 of the cubes' diagonal"),
                           ("ramp", sized, "more than 0.25 of the sensor's diagonal"),
                           ("cos", sized, "outside the 128 x 160 px sensor by more than 3 of "
                                          "its standard errors")):
        with pytest.raises(ValueError, match=r"the f/2 cube cannot place the optical centre: "
                                             rf"it finds row .*{why} .* give the centre "
                                             r"\(center_rc=\)"):
            locate_pupil(_one_way_cube(seed, kind), sen, target_spectrum=sim.colour_filter,
                         n_bins=16)


def test_a_centre_the_cubes_place_is_kept():
    """An ordinary target on a sensor of known size: its centre found and fitted about."""
    data = cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5)
    got = locate_pupil(data, dataclasses.replace(sensor(), size_px=(128, 160)),
                       target_spectrum=sim.colour_filter, n_bins=16, magnification=0.0,
                       pupil_magnification=1.0)
    assert got.center_source.startswith("found from the f/2 cube")
    assert np.hypot(got.center_rc[0] - ROW, got.center_rc[1] - COL) < 1.0


def test_a_found_centre_is_refused_by_its_errors_or_its_place_off_the_sensor():
    """The rule at its edges, on numbers: errors above a quarter of the diagonal, or a centre
    outside the sensor by more than 3 of its errors; a centre beyond the cubes' crop but on
    the sensor, or just off it within its errors, is kept."""
    s = sensor()
    sized = dataclasses.replace(s, size_px=(1000, 2000))
    rows, cols = np.arange(100.0, 164.0)[:, None], np.arange(300.0, 380.0)[:, None]
    quarter = 0.25 * np.hypot(1000, 2000)
    keep = [((500.0, 1000.0), (3.0, 3.0)),  # outside the crop, on the sensor
            ((-10.0, 1000.0), (4.0, 4.0)),  # 9.5 px off the sensor, within 3 errors
            ((500.0, 1000.0), (0.7 * quarter, 0.7 * quarter))]  # 0.99 of the quarter
    refuse = [((500.0, 1000.0), (0.8 * quarter, 0.7 * quarter)),
              ((-20.0, 1000.0), (4.0, 4.0)),
              ((500.0, 2100.0), (10.0, 10.0)),
              ((500.0, 1000.0), (np.inf, np.inf))]
    for c, e in keep:
        tg.check_found_center(c, e, rows, cols, sized, 2.0)
    for c, e in refuse:
        with pytest.raises(ValueError, match="cannot place the optical centre"):
            tg.check_found_center(c, e, rows, cols, sized, 2.0)
    # without a sensor size, the quarter is the cubes' (a crop's centre may lie beyond it)
    tg.check_found_center((500.0, 1000.0), (3.0, 3.0), rows, cols, s, 2.0)
    with pytest.raises(ValueError, match=r"more than 0.25 of the cubes' diagonal \(101 px\)"):
        tg.check_found_center((130.0, 340.0), (20.0, 20.0), rows, cols, s, 2.0)


def test_a_given_centre_a_few_pixels_off_is_refused_or_its_difference_is_in_the_errors():
    """Centres 2-20 px off, inside the quarter diagonal the first check leaves alone, biased
    x by 3 to tens of its errors at reduced chi-squares of 1.04-45, written without a word.
    Where the fit about the centre the cubes place lowers chi-square beyond its spread (10,
    20 px) the centre is refused; where it does not (2, 5 px: chi-square's level hardly
    tells) the two fits' difference is in x's error, which then covers x's error. The true
    centre is kept as it is."""
    data = cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5)
    kw = {"lens": as_lens(LensTruth(16.0, (), 0.0, 1.0)), "target_spectrum": sim.colour_filter,
          "n_bins": 16}
    for d in (10.0, 20.0):
        given = (ROW + 0.6 * d, COL - 0.8 * d)
        assert tg.check_given_center(data, sensor(), kw["lens"], None, given) is None
        with pytest.raises(ValueError, match=r"the optical centre given \(row .*\) fits the "
                                             r"cubes clearly worse than the centre the f/2 cube "
                                             r"places \(row 61\.\d, col 82\.\d\): chi-square "
                                             r"higher by \d+"):
            locate_pupil(data, sensor(), center_rc=given, **kw)
    for d in (2.0, 5.0):
        got = locate_pupil(data, sensor(), center_rc=(ROW + 0.6 * d, COL - 0.8 * d), **kw)
        assert got.center_source == "given"
        assert abs(got.exit_pupil_mm - 16.0) < 2 * got.exit_pupil_stderr_mm
        assert any("lies far from the one the cubes place" in n for n in got.notes)
        assert got.lens.calibration["center_error"]["carried"].startswith("yes")
    got = locate_pupil(data, sensor(), center_rc=(ROW, COL), **kw)
    assert "center_error" not in got.lens.calibration and got.exit_pupil_stderr_mm < 0.007


def test_a_crop_beside_the_axis_keeps_its_true_centre_when_the_cubes_are_compared(monkeypatch):
    """A crop beside the axis places the centre poorly itself: with the comparison made
    whatever the distance, the true centre it is given is kept."""
    import snapcorr.calibrate.pupil.locate as loc

    data = cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5)
    crop = {f: c.isel(y=slice(0, 36), x=slice(0, 44)) for f, c in data.items()}
    compared = []
    real = loc._checked_locate
    monkeypatch.setattr(loc, "CENTER_COMPARED_SIGMAS", 0.0)
    monkeypatch.setattr(loc, "CENTER_COMPARED_PX", 0.0)
    monkeypatch.setattr(loc, "_checked_locate", lambda **k: compared.append(k["center_rc"])
                        or real(**k))
    got = locate_pupil(crop, sensor(), center_rc=(ROW, COL),
                       lens=as_lens(LensTruth(16.0, (), 0.0, 1.0)),
                       target_spectrum=sim.colour_filter, n_bins=16)
    assert len(compared) == 2 and got.center_source == "given", compared
