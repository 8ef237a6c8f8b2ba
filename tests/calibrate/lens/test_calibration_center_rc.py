"""The lens calibration takes the optical centre row first and records it so: the x-first
keyword of 0.1 keeps its meaning and warns (snapcorr/_coords.py)."""

import warnings

import numpy as np
import pytest
from conftest import PAPER_LENS

from snapcorr.calibrate import calibrate_lens
from snapcorr.simulate import flat_frame

ROW, COL = 7.25, 19.5

@pytest.mark.slow
def test_the_lens_calibration_takes_and_gives_the_centre_row_first():
    """calibrate_lens: center_rc given is kept and recorded row first (x first beside it, as
    0.1 read it); the x-first keyword gives the same profile and warns; snapcorr's own calls
    raise no FutureWarning."""
    rng = np.random.default_rng(2)
    flats = {f: flat_frame((64, 96), 88.0, f, PAPER_LENS, center_rc=(ROW + 20, COL + 40),
                           rng=rng) for f in (1.4, 2.8, 8.0)}
    kw = dict(exit_pupil_mm=21.0, pixel_pitch_um=88.0, magnification=0.06,
              pupil_magnification=1.3, max_circles=1, method="joint")
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)
        new = calibrate_lens(flats, center_rc=(ROW + 20, COL + 40), **kw)
    assert new.center_rc == (ROW + 20, COL + 40) and new.center_source == "given"
    cal = new.lens.calibration
    assert cal["center_rc"] == [ROW + 20, COL + 40] and cal["center_px"] == [COL + 40, ROW + 20]
    assert cal["joint_fit"]["one"]["center_row_px"] == ROW + 20
    assert cal["joint_fit"]["one"]["center_col_px"] == COL + 40
    with pytest.warns(FutureWarning, match="center_px is the old x-first form"):
        old = calibrate_lens(flats, center_px=(COL + 40, ROW + 20), **kw)
    assert old.lens.vignetting == new.lens.vignetting
    assert {k: v for k, v in old.lens.calibration.items() if k != "date"} == \
        {k: v for k, v in cal.items() if k != "date"}
    with pytest.warns(FutureWarning, match="LensCalibration.center_px gives the optical "
                                           "centre x first"):
        assert old.center_px == (COL + 40, ROW + 20)
    with pytest.raises(TypeError, match="give the optical centre once"):
        calibrate_lens(flats, center_rc=(1, 2), center_px=(2, 1), **kw)
