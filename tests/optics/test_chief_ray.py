"""The chief-ray angle of a pixel (Goossens 2019 Eq. 8) against the geometry of the ray written
out in three dimensions."""

import math

import numpy as np
import pytest

from snapcorr.optics import cra_deg, cra_map, pixel_cra_deg
from snapcorr.optics.chief_ray import image_shape, pixel_tangents

ROW, COL = 7.25, 19.5  # an off-centre optical centre in a 20 x 30 image


def own_cra_deg(i, j, shape, pitch_um, x_mm, center=None):
    """Chief-ray angle of pixel (row i, column j), Goossens 2019 Eq. (8), by hand."""
    ny, nx = shape
    cx, cy = center if center is not None else ((nx - 1) / 2, (ny - 1) / 2)
    d_mm = pitch_um / 1000 * math.sqrt((j - cx) ** 2 + (i - cy) ** 2)
    return math.degrees(math.atan(d_mm / x_mm))


def test_pixel_cra_deg_takes_row_first_and_cra_deg_is_deprecated():
    rows, cols = np.arange(20)[:, None], np.arange(30)[None, :]
    new = pixel_cra_deg(rows, cols, (ROW, COL), 22.0, 21.0)
    with pytest.warns(FutureWarning, match="pixel_cra_deg"):
        old = cra_deg(rows, cols, (COL, ROW), 22.0, 21.0)
    np.testing.assert_array_equal(new, old)
    # against the geometry written out here: tan(CRA) = d / x
    d_mm = np.hypot(rows - ROW, cols - COL) * 22.0e-3
    np.testing.assert_allclose(new, np.rad2deg(np.arctan(d_mm / 21.0)), rtol=1e-12)


def _angle_to_the_pupil_centre_deg(y_mm, x_mm, exit_pupil_mm):
    """The angle between the sensor's normal and the ray from a pixel at (x, y, 0) to the exit
    pupil's centre at (0, 0, exit_pupil_mm), from the dot product of the two vectors."""
    v = np.stack(np.broadcast_arrays(-x_mm, -y_mm, np.full_like(x_mm, exit_pupil_mm)), -1)
    cos = v[..., 2] / np.linalg.norm(v, axis=-1)
    return np.rad2deg(np.arccos(np.clip(cos, -1, 1)))


@pytest.mark.parametrize(("pitch_um", "x_mm"), [(5.5, 21.0), (22.0, 9.0), (3.45, 60.0)])
def test_cra_map_is_the_angle_of_the_ray_to_the_pupil_centre(pitch_um, x_mm):
    shape = (41, 57)
    cra = cra_map(shape, pitch_um, x_mm, center_rc=(ROW, COL))
    i, j = np.indices(shape, dtype=float)
    ref = _angle_to_the_pupil_centre_deg((i - ROW) * pitch_um * 1e-3,
                                         (j - COL) * pitch_um * 1e-3, x_mm)
    np.testing.assert_allclose(cra, ref, atol=1e-9)
    # the default centre is the image's middle, and the map is symmetric about it
    mid = cra_map(shape, pitch_um, x_mm)
    np.testing.assert_allclose(mid, mid[::-1, ::-1], atol=1e-12)
    assert mid[20, 28] == 0.0


def test_pixel_tangents_are_the_signed_components_of_the_map():
    tx, ty = pixel_tangents((20, 30), 22.0, 21.0, center_rc=(ROW, COL))
    assert tx.shape == (30,) and ty.shape == (20,)
    assert tx[0] < 0 < tx[-1] and ty[0] < 0 < ty[-1]
    np.testing.assert_allclose(tx, (np.arange(30) - COL) * 22e-3 / 21.0, rtol=1e-12)
    np.testing.assert_allclose(np.rad2deg(np.arctan(np.hypot(ty[:, None], tx[None, :]))),
                               cra_map((20, 30), 22.0, 21.0, center_rc=(ROW, COL)),
                               rtol=1e-12)


@pytest.mark.parametrize("shape", [(0, 5), (3,), (2.5, 4), "ab", None, (-1, 3)])
def test_a_bad_shape_is_refused_clearly(shape):
    with pytest.raises(ValueError, match="two positive integers"):
        image_shape(shape)


@pytest.mark.parametrize("kw", [dict(pixel_pitch_um=0.0), dict(exit_pupil_mm=-21.0),
                                dict(exit_pupil_mm=np.nan)])
def test_a_bad_pitch_or_pupil_distance_is_refused(kw):
    args = dict(pixel_pitch_um=5.5, exit_pupil_mm=21.0) | kw
    with pytest.raises(ValueError, match=next(iter(kw))):
        pixel_cra_deg(3, 4, (0, 0), **args)


@pytest.mark.parametrize("center", [None, (10.0, 3.0), (4.25, -7.5), (100.0, 40.0)])
def test_cra_map_matches_hand_arithmetic(center):
    shape = (13, 17)
    cra = cra_map(shape, 250.0, 21.0, center)
    assert cra.shape == shape and cra.dtype == np.float64
    for i in range(shape[0]):
        for j in range(shape[1]):
            assert cra[i, j] == pytest.approx(own_cra_deg(i, j, shape, 250.0, 21.0, center),
                                              abs=1e-12)


def test_cra_map_is_zero_at_an_integer_center_and_symmetric_about_the_image_center():
    cra = cra_map((7, 9), 5.5, 21.0, center_px=(4, 3))
    assert cra[3, 4] == 0.0
    sym = cra_map((6, 8), 5.5, 21.0)
    np.testing.assert_array_equal(sym, sym[::-1, ::-1])
    np.testing.assert_array_equal(sym, sym[:, ::-1])
