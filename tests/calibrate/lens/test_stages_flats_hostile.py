"""Flats that are not light as measured: a clipped plateau (a float flat, a camera of fewer
bits than its file) found and taken as saturation, and a flat of no numbers said so. Flats
from ``tests/oracles/flatsim.py`` (shares no code with snapcorr)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from flatsim import make_flats

from calibrate.pupil.test_locate import CENTER, PAPER, PITCH_UM, SHAPE
from snapcorr.calibrate import calibrate_lens


@pytest.fixture(scope="module")
def flats():
    return make_flats(PAPER, (1.4, 2.0, 2.8, 4.0, 8.0), shape=SHAPE, pitch_um=PITCH_UM,
                      center_px=CENTER, noise=0.005, seed=1)


def _calibrate(flats):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return calibrate_lens(flats, pixel_pitch_um=PITCH_UM, exit_pupil_mm=PAPER.exit_pupil_mm,
                              magnification=PAPER.magnification,
                              pupil_magnification=PAPER.pupil_magnification, max_circles=1)


def test_a_clipped_float_flat_is_masked_where_it_is_clipped(flats):
    """The f/1.4 flat (float, no saturation given) clipped at 80 % of its top: a plateau of
    pixels at exactly its largest value. Fitted as light, it gave P and h 120 of their errors
    off; now the plateau is saturation, said in the notes, and P and h are the lens's."""
    clipped = dict(flats)
    top = 0.8 * float(clipped[1.4].max())
    clipped[1.4] = np.minimum(clipped[1.4].astype(float), top)
    assert (clipped[1.4] == top).mean() > 0.01
    got = _calibrate(clipped)
    said = [n for n in got.notes if "a clipped plateau" in n]
    assert len(said) == 1 and said[0].startswith("f/1.4: "), got.notes
    (P, h), = got.lens.vignetting
    (P_true, h_true), = PAPER.circles
    assert abs(P / P_true - 1) < 0.01 and abs(h / h_true - 1) < 0.01, (P, h)


def test_the_top_of_a_rounded_fall_off_is_no_plateau():
    """A smooth fall-off rounded to whole numbers has about as many pixels at its top value
    as at the next; a float flat's repeated top value, and one held by few pixels, neither."""
    from snapcorr.calibrate.lens.stages import clipped_level

    yy, xx = np.mgrid[:200, :200]
    smooth = np.round(4000 - 0.05 * ((yy - 100.3) ** 2 + (xx - 99.6) ** 2))
    assert clipped_level(smooth) is None
    assert clipped_level(np.minimum(smooth, 3900)) == 3900
    noisy = np.random.default_rng(2).normal(smooth, 20)
    assert clipped_level(noisy) is None and clipped_level(np.round(noisy)) is None
    assert clipped_level(np.minimum(noisy, 3900)) == 3900


def test_a_flat_of_no_numbers_is_said_so(flats):
    """An all-NaN flat was said to hold "values at or below 0"."""
    bad = dict(flats)
    bad[2.0] = np.full(bad[2.0].shape, np.nan)
    with pytest.raises(ValueError, match=r"the flat at f/2 holds no number in 100 % of its "
                       r"pixels \(NaN or infinite\)"):
        _calibrate(bad)


@pytest.mark.parametrize("share", [1.0, 0.98])
def test_a_flat_saturated_whole_or_nearly_is_refused_as_saturated(flats, share):
    """A flat of one value in every pixel (65535: the exposure far too long) was calibrated,
    with only a note that no model described the flats; one 98 % saturated was said to be
    "saturated, dead or non-finite". Both are refused, saying how much is saturated."""
    bad = dict(flats)
    f2 = bad[2.0].astype(float)
    if share == 1.0:
        bad[2.0] = np.full(f2.shape, 65535, np.uint16)
    else:
        scale = 65535 / np.quantile(f2, 1 - share)
        bad[2.0] = np.minimum(f2 * scale, 65535).astype(np.uint16)
    assert abs(float(np.mean(bad[2.0] == 65535)) - share) < 0.01
    said = ("one value, 65535, in every pixel: saturated whole" if share == 1.0 else
            f"{round(100 * share)} % saturated, at or above 65535")
    with pytest.raises(ValueError, match=rf"the flat at f/2 has only \d+ % usable pixels "
                       rf"\({said}"):
        _calibrate(bad)
