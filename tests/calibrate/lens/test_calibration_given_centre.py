"""A centre given to the lens calibration that the flats' own contours place elsewhere is said
in the notes: 5 px off, the joint fit took three circles where the lens has one and blamed the
misfit on the light. Flats from ``tests/oracles/flatsim.py`` (shares no code with snapcorr)."""

from __future__ import annotations

import warnings

import pytest
from flatsim import make_flats

from calibrate.pupil.test_locate import CENTER, PAPER, PITCH_UM, SHAPE
from snapcorr.calibrate import calibrate_lens

ROW, COL = CENTER[1], CENTER[0]


@pytest.fixture(scope="module")
def flats():
    return make_flats(PAPER, (1.4, 2.0, 2.8, 4.0, 8.0), shape=SHAPE, pitch_um=PITCH_UM,
                      center_px=CENTER, noise=0.005, seed=1)


def _notes(flats, center):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got = calibrate_lens(flats, pixel_pitch_um=PITCH_UM, exit_pupil_mm=PAPER.exit_pupil_mm,
                             magnification=PAPER.magnification,
                             pupil_magnification=PAPER.pupil_magnification, center_rc=center,
                             max_circles=1)
    return [n for n in got.notes if "contours place the optical centre" in n]


def test_a_given_centre_the_flats_place_elsewhere_is_said(flats):
    said = _notes(flats, (ROW + 5.0, COL))
    assert len(said) == 1 and said[0].startswith(
        "the flats' contours place the optical centre at row 61.6, col 82.3, 5.0 px from the "
        "one given"), said


@pytest.mark.parametrize("off", [(0.0, 0.0), (1.0, 1.0)])
def test_a_given_centre_the_flats_agree_with_is_not_doubted(flats, off):
    assert not _notes(flats, (ROW + off[0], COL + off[1]))


@pytest.mark.parametrize("given", [(200.0, 300.0), (ROW + 40.0, COL - 50.0)])
def test_a_given_centre_the_flats_contradict_and_misfit_is_refused(flats, given):
    """A centre far from the one the flats show (outside them, or inside 64 px off): the
    fit about it misfits grossly (reduced chi2 57-161 on another simulator's flats), and the
    lens it gave (two circles of 50 mm, or none up to 62 deg) was written as the lens's."""
    with pytest.raises(ValueError, match=r"the optical centre given \(row .*\) is not the "
                       r"flats': their contours place it at row 61\.6, col 82\.3, .*reduced "
                       r"chi2 .*: check center_rc="):
        _notes(flats, given)
