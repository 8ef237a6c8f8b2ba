"""The onset of optical vignetting located in a radial profile."""

import numpy as np
from conftest import PAPER_LENS as PAPER

from snapcorr.calibrate.flats.onsets import detect_onset


def test_detect_onset_on_an_exact_ratio_profile():
    # the exact area ratio of the paper's lens at f/2 against f/8, no noise
    theta = np.arange(0.05, 20.0, 0.1)
    ratio = PAPER.relative_illumination(2.0, theta) / PAPER.relative_illumination(8.0, theta)
    o = detect_onset(theta, ratio, np.full(theta.size, 1e-4))
    assert o.found and abs(o.cra_deg - PAPER.onset_cra_deg(2.0)) < 0.3
    flat = detect_onset(theta, np.ones_like(theta), np.full(theta.size, 1e-4))
    assert not flat.found and np.isnan(flat.cra_deg)
