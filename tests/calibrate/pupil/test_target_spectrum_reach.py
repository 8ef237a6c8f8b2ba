"""A target spectrum given as samples that stops short of where the field's edge moves the
bands is said so: beyond its samples it is held at its end value.

Cubes from ``tests/oracles/spectralsim.py``; where the bands reach is found here from the
simulator's own pupil rays (every ray's incidence angle at the farthest pixel), not from
snapcorr's cone.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
import spectralsim as sim

from calibrate.pupil.test_locate import (
    CENTER,
    CWL,
    FWHM,
    N_EFF,
    PITCH_UM,
    PLAIN,
    SHAPE,
    as_lens,
    cubes,
    sensor,
)
from snapcorr.calibrate import locate_pupil


def _fit(lo_nm):
    wl = np.arange(lo_nm, 900.0, 0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return locate_pupil(cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5),
                            sensor(), lens=as_lens(PLAIN), n_bins=16,
                            target_spectrum=(wl, sim.colour_filter(wl)))


def _reach_nm():
    """The bluest band's blue end (2 FWHM) scaled by the smallest s of any ray at the
    farthest pixel from the axis."""
    rows, cols = SHAPE[0] - 1 - CENTER[1], CENTER[0]
    d = np.hypot(rows, cols) * PITCH_UM * 1e-3
    q, _ = sim._sin2_phi(PLAIN, 2.0, d)
    return (CWL.min() - 2 * FWHM) * np.sqrt(1 - q.max() / N_EFF**2)


@pytest.mark.parametrize("lo_nm", [476.0, 462.0])
def test_a_spectrum_stopping_short_of_the_edge_is_said_with_where_it_should_reach(lo_nm):
    """The bands need 476-872 nm on the axis; the f/2 cube's edge moves them to about 455."""
    got = _fit(lo_nm)
    said = [n for n in got.notes if n.startswith("the target spectrum given starts at")]
    assert len(said) == 1, got.notes
    reach = float(re.search(r"wings reach (\d+) nm", said[0])[1])
    assert reach == pytest.approx(_reach_nm(), abs=2.0)
    assert said[0] in got.lens.calibration.get("notes", []) or said[0] in got.summary()


def test_a_spectrum_reaching_the_edge_or_a_function_is_not_noted():
    assert not any("spectrum given starts" in n for n in _fit(440.0).notes)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got = locate_pupil(cubes("colour_filter", "plain", (2.0,), noise=0.01, seed=5),
                           sensor(), lens=as_lens(PLAIN), n_bins=16,
                           target_spectrum=sim.colour_filter)
    assert not any("spectrum given starts" in n for n in got.notes)
