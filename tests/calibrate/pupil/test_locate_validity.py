"""The note that rays pass the index law's validated angle (40 deg, Goossens 2019 Sec. 2.2)
gives the steepest ray's angle: the ray from the rim of the pupil farthest from the edge's
pixel, found here from ``tests/oracles/spectralsim.py``'s own pupil rays. The chief ray's
angle plus the cone's half-angle overstated it (40.6 deg for 36.9 at 8 mm from the axis
behind a 16 mm exit pupil at f/2) and said so where no ray passes 40 deg."""

from __future__ import annotations

import math
import re

import pytest
import spectralsim as sim

from calibrate.pupil.test_locate import PLAIN, as_lens
from snapcorr.calibrate.pupil import locate as loc


@pytest.mark.parametrize("d_mm", [6.0, 8.0, 10.0, 12.0])
def test_the_steepest_ray_is_the_one_from_the_pupils_far_rim(d_mm):
    q, _ = sim._sin2_phi(PLAIN, 2.0, d_mm)
    steepest = math.degrees(math.asin(math.sqrt(q.max())))
    cone = math.radians(float(as_lens(PLAIN).cone_angle_deg(2.0)))
    notes = [n for n in loc._validity_notes(d_mm, PLAIN.exit_pupil_mm, cone, 1.0, 1000)
             if n.startswith("rays reach the filters")]
    assert bool(notes) == (steepest > loc.AOI_VALIDITY_DEG), (d_mm, steepest, notes)
    if notes:
        said = float(re.search(r"up to ([\d.]+) deg", notes[0])[1])
        assert said == pytest.approx(steepest, abs=0.1)
