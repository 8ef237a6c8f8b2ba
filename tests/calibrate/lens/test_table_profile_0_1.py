"""A lens profile as snapcorr 0.1 wrote it, the optical centre x first, still places the axis.

Release 0.1 recorded the centre only as ``center_px = [cx, cy]`` (column first) and the image
as ``image_size_px = [width, height]``; the joint fit's entries named it ``cx_px``, ``cy_px``.
The text below is such a profile, written by the calibration of release 0.1 (``calibrate_lens``
on simulated flats of 96 x 160 pixels of 88 um, the axis at row 30.6, column 101.3), cut to the
keys a correction reads and the joint fit's record. Every chief-ray angle is checked against
Goossens et al. (2019), Eq. 8, ``d = x tan(CRA)``, worked out here from the pixel's distance to
the centre in millimetres.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from snapcorr import Lens
from snapcorr.correct.geometry import cube_cra
from snapcorr.cube import Sensor, make_cube

PROFILE_0_1 = """\
# written by snapcorr 0.1.0
[lens]
name = "paper lens, 0.1"
exit_pupil_mm = 21.0
magnification = 0.06
pupil_magnification = 1.3

[[lens.vignetting]]
radius_mm = 7.418784105180696
distance_mm = 16.974526652941268

[calibration]
method = "joint"
model = "one"
date = "2026-12-03T08:20:01+00:00"
snapcorr_version = "0.1.0"
f_numbers = [
    1.4,
    2.0,
    2.8,
    4.0,
    8.0,
]
reference_f_number = 8.0
center_px = [
    101.32257067871326,
    30.588553676567386,
]
center_source = "joint fit"
pixel_pitch_um = 88.0
image_size_px = [
    160,
    96,
]
max_cra_deg = 26.7079

[calibration.joint_fit.one]
reduced_chi2 = 1.0172192488010714
converged = true
chosen = true
P_mm = 7.418784105180696
P_stderr_mm = 0.0024466282656496552
h_mm = 16.974526652941268
h_stderr_mm = 0.007002569594905094
cx_px = 101.32257067871326
cx_stderr_px = 0.014863391964511648
cy_px = 30.588553676567386
cy_stderr_px = 0.018280090366126073
"""

ROW, COL = 30.588553676567386, 101.32257067871326  # the centre the profile holds, x first
PITCH_UM, X_MM = 88.0, 21.0
PIXELS = [(0, 0), (95, 159), (30, 101), (80, 10), (5, 150), (95, 0)]


def _sensor(pitch_um, size_px):
    return Sensor("test", "snapscan", pitch_um, np.linspace(500, 900, 3), 10.0, 1.7,
                  size_px=size_px)


def _cube(size_px):
    return make_cube(np.ones((*size_px, 3), np.float32), np.linspace(500, 900, 3))


def _eq8_deg(edge_row_mm, edge_col_mm):
    """Eq. 8 by hand: the pixel centre's distance from the axis, both measured in mm from the
    image's first edge (the axis at (ROW + 0.5, COL + 0.5) pitches of the 0.1 grid)."""
    d_mm = math.hypot(edge_row_mm - (ROW + 0.5) * PITCH_UM * 1e-3,
                      edge_col_mm - (COL + 0.5) * PITCH_UM * 1e-3)
    return math.degrees(math.atan(d_mm / X_MM))


@pytest.fixture
def profile_0_1(tmp_path):
    path = tmp_path / "lens_0_1.toml"
    path.write_text(PROFILE_0_1, encoding="utf-8")
    return Lens.load(path)


def test_a_0_1_profile_loads_with_its_numbers(profile_0_1):
    lens = profile_0_1
    assert lens.exit_pupil_mm == X_MM
    assert lens.vignetting == ((7.418784105180696, 16.974526652941268),)
    assert lens.calibration["center_px"] == [COL, ROW]
    assert "center_rc" not in lens.calibration


def test_a_0_1_profile_places_the_axis_x_first_on_the_same_sensor(profile_0_1):
    cra, center_rc, source = cube_cra(_cube((96, 160)), _sensor(PITCH_UM, (96, 160)),
                                      profile_0_1)
    assert center_rc == (ROW, COL) and source == "lens calibration"
    for i, j in PIXELS:
        want = _eq8_deg((i + 0.5) * PITCH_UM * 1e-3, (j + 0.5) * PITCH_UM * 1e-3)
        assert cra[i, j, 0] == pytest.approx(want, rel=1e-12, abs=1e-12), (i, j)
    # the smallest angle lies at the pixel nearest the axis: row 31, column 101
    assert np.unravel_index(np.argmin(cra[..., 0]), cra.shape[:2]) == (31, 101)


def test_a_0_1_profile_places_the_axis_on_binned_pixels_through_millimetres(profile_0_1):
    # the same image area read out 2 x 2 binned: 48 x 80 pixels of 176 um
    cra, center_rc, source = cube_cra(_cube((48, 80)), _sensor(2 * PITCH_UM, (48, 80)),
                                      profile_0_1)
    assert "converted through mm" in source
    assert center_rc == pytest.approx(((ROW + 0.5) / 2 - 0.5, (COL + 0.5) / 2 - 0.5), rel=1e-12)
    for i, j in [(0, 0), (47, 79), (15, 50), (40, 5)]:
        want = _eq8_deg((i + 0.5) * 2 * PITCH_UM * 1e-3, (j + 0.5) * 2 * PITCH_UM * 1e-3)
        assert cra[i, j, 0] == pytest.approx(want, rel=1e-12, abs=1e-12), (i, j)


def test_the_profile_written_now_gives_the_same_angles(profile_0_1, tmp_path):
    # what the calibration writes today: the centre row first, and x first beside it
    now = replace(profile_0_1, calibration={
        **profile_0_1.calibration, "center_rc": [ROW, COL], "image_shape_px": [96, 160]})
    back = Lens.load(now.save(tmp_path / "lens_now.toml"))
    sensor, cube = _sensor(PITCH_UM, (96, 160)), _cube((96, 160))
    old = cube_cra(cube, sensor, profile_0_1)
    new = cube_cra(cube, sensor, back)
    assert new.center_rc == old.center_rc == (ROW, COL)
    np.testing.assert_array_equal(new.cra_deg, old.cra_deg)
