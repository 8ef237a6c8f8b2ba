"""Where each pixel and band sits on the sensor, and its chief-ray angle (Goossens 2019, Eq. 8)
worked out by hand: a given centre, the lens calibration's (carried over through millimetres),
a mosaic's bands each at its own place, crops placed by their origin, and refusals."""

import dataclasses
import warnings
from dataclasses import replace

import numpy as np
import pytest
from conftest import PAPER_LENS

from snapcorr.correct import PlacementError, correct_cube
from snapcorr.correct.geometry import cube_cra, cube_cra_deg, optical_center, optical_center_rc
from snapcorr.correct.plan import CorrectionPlan
from snapcorr.cube import Sensor, make_cube, mosaic_to_cube
from snapcorr.data import sensor_path

PAPER = PAPER_LENS


def _sensor(n=6, pitch=40.0, n_eff=1.7):
    return Sensor("test", "snapscan", pitch, np.linspace(500, 900, n), 10.0, n_eff)


def _cube(sensor, ny=40, nx=50, seed=0):
    data = np.random.default_rng(seed).random((ny, nx, sensor.n_bands)).astype(np.float32)
    return make_cube(data, sensor.cwl_nm)


def test_cra_map_by_hand():
    s = _sensor(pitch=40.0)
    cube = _cube(s)
    cra, center, source = cube_cra(cube, s, PAPER, center_rc=(-5.0, 10.0))
    assert source == "given" and cra.shape == (40, 50, 1) and center == (-5.0, 10.0)
    y, x = 33, 47
    d_mm = np.hypot(x - 10.0, y + 5.0) * 0.040
    assert cra[y, x, 0] == pytest.approx(np.degrees(np.arctan(d_mm / 21.0)), rel=1e-12)
    # default: the centre of the area the cube covers
    _, center, source = cube_cra(cube, s, PAPER)
    assert center == (19.5, 24.5) and source == "image centre"


def test_center_from_the_lens_calibration_only_for_the_same_pitch():
    s = _sensor(pitch=40.0)
    cube = _cube(s)
    lens = replace(PAPER_LENS, name="cal",
                   calibration={"center_px": [3.0, 4.0], "pixel_pitch_um": 40.0})
    assert cube_cra(cube, s, lens)[1:] == ((4.0, 3.0), "lens calibration")
    other = replace(PAPER_LENS, name="cal",
                    calibration={"center_px": [3.0, 4.0], "pixel_pitch_um": 5.5})
    # another pitch and no image size to match the areas: refused, never the image centre
    with pytest.raises(PlacementError, match=r"center_rc= \(row, col\)"):
        cube_cra(cube, s, other)


def test_mosaic_bands_get_their_own_positions():
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    raw = np.arange(16 * 24, dtype=np.float32).reshape(16, 24)
    cube = mosaic_to_cube(raw, sensor, sensor_origin_px=(40, 80))
    cra = cube_cra(cube, sensor, PAPER, center_rc=(0.0, 0.0)).cra_deg
    assert cra.shape == (4, 6, sensor.n_bands)
    b = 5
    row = cube["sensor_row"].values[2, b]
    col = cube["sensor_col"].values[3, b]
    d = np.hypot(row, col) * sensor.pixel_pitch_um * 1e-3
    assert cra[2, 3, b] == pytest.approx(np.degrees(np.arctan(d / 21.0)), rel=1e-12)


def test_the_largest_angle_without_the_map_is_the_maps_largest():
    """``correct_cube`` starts its width table from the field's largest CRA before the map is
    made: the same number, bit for bit, for a centre inside, at the edge of and outside the
    image, a crop placed on the sensor, a mosaic (each band at its own place) and one pixel,
    and what correct_cube records is the map's largest."""
    from snapcorr.correct.geometry import _largest_cra_deg

    s = _sensor(pitch=40.0)
    cube = _cube(s)
    mosaic_sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    mosaic = mosaic_to_cube(np.arange(16 * 24, dtype=np.float32).reshape(16, 24),
                            mosaic_sensor, sensor_origin_px=(40, 80))
    rng = np.random.default_rng(3)
    cases = [(cube, s, None, None), (cube, s, (10.0, -5.0), None), (cube, s, (49.0, 39.0), None),
             (cube, s, (-300.5, 1200.25), None), (cube, s, None, (500, 700)),
             (cube.isel(y=[7], x=[3]), s, (7.0, 3.0), None),
             (mosaic, mosaic_sensor, (0.0, 0.0), None), (mosaic, mosaic_sensor, None, None)]
    cases += [(cube, s, tuple(rng.uniform(-60, 110, 2)), None) for _ in range(20)]
    for c, sensor, center, origin in cases:
        cra = cube_cra(c, sensor, PAPER, center_rc=center, sensor_origin_px=origin).cra_deg
        assert _largest_cra_deg(c, sensor, PAPER, center, origin) == float(cra.max())
    ds = correct_cube(cube, s, 2.8, PAPER, center_rc=(60.0, -3.0))
    assert ds.attrs["cra_max_deg"] == float(ds["cra_deg"].max())


# -- crops, mosaics without positions, centres on another pixel grid -------------------------

FULL = Sensor("full", "snapscan", 5.5, np.linspace(500, 900, 3), 10.0, 1.7, size_px=(2048, 2048))


def _by_hand(rows, cols, row, col, pitch_mm=5.5e-3, x_mm=21.0):
    """Eq. 8 on the grid rows x cols (sensor pixels): tan CRA = distance * pitch / x, the
    centre at (row, col)."""
    d = np.hypot(np.asarray(rows, float)[:, None] - row, np.asarray(cols, float)[None, :] - col)
    return np.degrees(np.arctan(d * pitch_mm / x_mm))


def test_a_crop_of_unknown_place_is_refused_and_placed_by_its_origin():
    crop = _cube(FULL, ny=256, nx=256)
    with pytest.raises(PlacementError, match="sensor_origin_px="):
        correct_cube(crop, FULL, 2.8, PAPER)
    cra, center, source = cube_cra(crop, FULL, PAPER, sensor_origin_px=(1500, 100))
    assert source == "sensor centre" and center == (1023.5, 1023.5)
    expected = _by_hand(1500 + np.arange(256.0), 100 + np.arange(256.0), 1023.5, 1023.5)
    np.testing.assert_allclose(cra[:, :, 0], expected, rtol=1e-12)
    # the full frame needs no origin; the crop's angles are the full frame's at that place
    full = cube_cra(_cube(FULL, ny=2048, nx=2048), FULL, PAPER).cra_deg
    np.testing.assert_allclose(cra[:, :, 0], full[1500:1756, 100:356, 0], rtol=1e-12)
    ds = correct_cube(crop, FULL, 2.8, PAPER, sensor_origin_px=(1500, 100))
    assert float(ds["cra_deg"].max()) == pytest.approx(expected.max(), rel=1e-12)


def test_an_origin_that_contradicts_the_cube_is_refused():
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    cube = mosaic_to_cube(np.zeros((16, 24), np.float32), sensor, sensor_origin_px=(40, 80))
    cube_cra(cube, sensor, PAPER, sensor_origin_px=(40, 80))  # agrees: fine
    with pytest.raises(PlacementError, match="first pixel"):
        cube_cra(cube, sensor, PAPER, sensor_origin_px=(0, 0))


def test_a_mosaic_cube_without_positions_is_refused_not_put_at_one_place():
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    bare = make_cube(np.zeros((4, 6, 16), np.float32), sensor.cwl_nm)
    with pytest.raises(PlacementError, match="no sensor positions"):
        correct_cube(bare, sensor, 1.4, PAPER)
    # with the tile origin stated, the bands get the tile layout's positions
    placed = mosaic_to_cube(np.zeros((16, 24), np.float32), sensor, sensor_origin_px=(40, 80))
    np.testing.assert_array_equal(
        cube_cra(bare, sensor, PAPER, sensor_origin_px=(40, 80)).cra_deg,
        cube_cra(placed, sensor, PAPER).cra_deg)


def test_the_calibrated_center_is_carried_to_binned_pixels_through_millimetres():
    cal = {"center_px": [1047.3, 998.6], "pixel_pitch_um": 5.5, "image_size_px": [2048, 2048]}
    lens = replace(PAPER_LENS, name="cal", calibration=cal)
    binned = Sensor("binned", "snapscan", 11.0, FULL.cwl_nm, 10.0, 1.7, size_px=(1024, 1024))
    cra, (row, col), source = cube_cra(_cube(binned, ny=1024, nx=1024), binned, lens)
    # pixel i spans [i, i + 1) pitches: the centre 1047.3 px of 5.5 um is at 5.76290 mm,
    # which is 523.9 px of 11 um counted the same way (523.9 + 0.5 = 5.7629 / 0.011)
    assert (row, col) == pytest.approx((5.49505 / 0.011 - 0.5, 5.7629 / 0.011 - 0.5), abs=1e-9)
    assert "converted" in source
    # the same sensor point keeps its angle: binned pixel (300, 700) covers full pixels
    # 600-601 x 1400-1401, whose centre is at 600.5 x 1400.5 full pixels
    full = _by_hand(np.array([600.5]), np.array([1400.5]), 998.6, 1047.3)[0, 0]
    assert cra[300, 700, 0] == pytest.approx(full, rel=1e-12)
    # a sensor of another physical size: the areas cannot be matched
    other = Sensor("other", "snapscan", 11.0, FULL.cwl_nm, 10.0, 1.7, size_px=(1000, 1024))
    with pytest.raises(PlacementError, match=r"center_rc= \(row, col\)"):
        cube_cra(_cube(other, ny=1000, nx=1024), other, lens)
    # ... also at the same pitch: a smaller sensor is not the calibration's pixel grid
    small = Sensor("small", "snapscan", 5.5, FULL.cwl_nm, 10.0, 1.7, size_px=(1024, 1024))
    with pytest.raises(PlacementError, match=r"center_rc= \(row, col\)"):
        cube_cra(_cube(small, ny=1024, nx=1024), small, lens)
    # a crop of the calibrated sensor (placed by its origin) keeps the calibrated centre
    cra, center, _ = cube_cra(_cube(FULL, ny=64, nx=64), FULL, lens,
                              sensor_origin_px=(900, 1000))
    assert center == (998.6, 1047.3)
    assert cra[0, 0, 0] == pytest.approx(_by_hand(np.array([900.0]), np.array([1000.0]),
                                                  998.6, 1047.3)[0, 0], rel=1e-12)


# -- the centre row first, off the middle of a frame that is not square ----------------------

WIDE = Sensor("wide", "snapscan", 40.0, np.linspace(500, 900, 3), 10.0, 1.7, size_px=(30, 50))


def _brute_force_cra_deg(shape, row, col, pitch_um=40.0, x_mm=21.0):
    """CRA = atan(r * pitch / x) pixel by pixel, r the distance from (row, col): Eq. 8 in
    loops, nothing shared with snapcorr."""
    out = np.empty(shape)
    for i in range(shape[0]):
        for j in range(shape[1]):
            r = ((i - row) ** 2 + (j - col) ** 2) ** 0.5
            out[i, j] = np.degrees(np.arctan(r * pitch_um * 1e-3 / x_mm))
    return out


def test_an_off_centre_centre_on_a_wide_frame_is_a_row_and_a_column():
    cube = _cube(WIDE, ny=30, nx=50)
    row, col = 7.25, 31.5  # row != col, and each outside the other's range of a swap
    cra, center, source = cube_cra(cube, WIDE, PAPER, center_rc=(row, col))
    assert center == (row, col) and source == "given"
    np.testing.assert_allclose(cra[..., 0], _brute_force_cra_deg((30, 50), row, col),
                               rtol=1e-12)
    assert np.unravel_index(np.argmin(cra[..., 0]), (30, 50)) == (7, 31)
    # the swapped centre gives other angles: a swap cannot pass the comparison above
    assert not np.allclose(cra[..., 0], _brute_force_cra_deg((30, 50), col, row))
    # the default, the sensor's centre, is (rows - 1) / 2, (cols - 1) / 2
    cra, center, source = cube_cra(cube, WIDE, PAPER)
    assert center == (14.5, 24.5) and source == "sensor centre"
    np.testing.assert_allclose(cra[..., 0], _brute_force_cra_deg((30, 50), 14.5, 24.5),
                               rtol=1e-12)
    # correct_cube takes it and records it the same way
    ds = correct_cube(cube, WIDE, 2.8, PAPER, center_rc=(row, col))
    assert ds.attrs["optical_center_rc"] == [row, col]
    assert ds.attrs["optical_center_px"] == [col, row]  # the x-first copy for earlier readers
    np.testing.assert_allclose(ds["cra_deg"].values.reshape(30, 50),
                               _brute_force_cra_deg((30, 50), row, col), rtol=1e-6)


def test_the_calibrated_centre_of_a_wide_image_carried_to_binned_pixels_keeps_its_order():
    """A profile of snapcorr 0.1 holds only the x-first ``center_px``; a later one
    ``center_rc`` beside it: both give the same centre, carried through millimetres, row
    first (the image 2048 px wide, 1088 high, recorded as [width, height])."""
    binned = Sensor("binned", "snapscan", 11.0, FULL.cwl_nm, 10.0, 1.7, size_px=(544, 1024))
    cube = _cube(binned, ny=544, nx=1024)
    old = {"center_px": [1100.7, 500.2], "pixel_pitch_um": 5.5, "image_size_px": [2048, 1088]}
    new = {**old, "center_rc": [500.2, 1100.7]}
    want = ((500.2 + 0.5) * 0.5 - 0.5, (1100.7 + 0.5) * 0.5 - 0.5)
    for cal in (old, new):
        lens = replace(PAPER_LENS, name="cal", calibration=cal)
        center, source = optical_center_rc(cube, binned, lens)
        assert center == pytest.approx(want, abs=1e-9) and "converted" in source
        cra = cube_cra(cube, binned, lens).cra_deg
        assert cra[100, 900, 0] == pytest.approx(
            _brute_force_cra_deg((1, 1), want[0] - 100, want[1] - 900, pitch_um=11.0)[0, 0],
            rel=1e-12)


def test_the_x_first_returns_still_work_and_say_what_replaces_them():
    cube = _cube(WIDE, ny=30, nx=50)
    new = cube_cra(cube, WIDE, PAPER, center_rc=(7.25, 31.5))
    with pytest.warns(FutureWarning, match=r"cube_cra_deg gives the optical centre x first.*"
                                           r"removed in snapcorr 0\.3; use cube_cra"):
        cra, center, source = cube_cra_deg(cube, WIDE, PAPER, center_rc=(7.25, 31.5))
    assert center == (31.5, 7.25) and source == "given"
    np.testing.assert_array_equal(cra, new.cra_deg)
    with pytest.warns(FutureWarning, match=r"optical_center gives .* 0\.3; use "
                                           r"optical_center_rc"):
        assert optical_center(cube, WIDE, PAPER) == ((24.5, 14.5), "sensor centre")
    # the x-first centre in its old positional place keeps its meaning
    with pytest.warns(FutureWarning, match="center_px is the old x-first form"), \
            pytest.warns(FutureWarning, match="cube_cra_deg gives"):
        _, center, _ = cube_cra_deg(cube, WIDE, PAPER, (31.5, 7.25))
    assert center == (31.5, 7.25)
    plan = dataclasses.replace(CorrectionPlan(1.4, 1.0, 0.1, "none", "", np.ones(3)),
                               center_rc=(7.25, 31.5))
    with pytest.warns(FutureWarning, match=r"CorrectionPlan\.center gives .* "
                                           r"CorrectionPlan\.center_rc"):
        assert plan.center == (31.5, 7.25)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the row-first forms and snapcorr's own calls: silent
        cube_cra(cube, WIDE, PAPER, center_rc=(7.25, 31.5))
        optical_center_rc(cube, WIDE, PAPER)
        correct_cube(cube, WIDE, 2.8, PAPER, center_rc=(7.25, 31.5))


def test_a_centre_measured_on_cropped_flats_is_placed_by_their_origin():
    """Raw flats of a crop at sensor row 5, column 7 (``calibrate --sensor-origin-px 5,7``):
    the profile's centre is the crop's, and the sensor's is that plus the origin. It was
    refused, the crop's image size not being the sensor's (or, were they alike, taken as the
    sensor's own pixels)."""
    sensor = Sensor("mosaic", "snapscan", 28.4, FULL.cwl_nm, 10.0, 1.7, size_px=(300, 400))
    cal = {"center_rc": [169.75, 112.75], "center_px": [112.75, 169.75],
           "pixel_pitch_um": 28.4, "image_size_px": [320, 256], "sensor_origin_rc": [5, 7]}
    lens = replace(PAPER_LENS, name="cal", calibration=cal)
    cra, center, source = cube_cra(_cube(sensor, ny=300, nx=400), sensor, lens)
    assert center == (174.75, 119.75) and "row 5, column 7" in source
    assert cra[0, 0, 0] == pytest.approx(_by_hand(
        np.array([0.0]), np.array([0.0]), 174.75, 119.75, pitch_mm=28.4e-3,
        x_mm=PAPER_LENS.exit_pupil_mm)[0, 0], rel=1e-12)
    # another pixel grid: the crop's centre cannot be placed
    binned = Sensor("binned", "snapscan", 56.8, FULL.cwl_nm, 10.0, 1.7, size_px=(150, 200))
    with pytest.raises(PlacementError, match="crop"):
        cube_cra(_cube(binned, ny=150, nx=200), binned, lens)
    # a crop that does not fit on this sensor is not placed on it
    beyond = replace(lens, calibration={**cal, "sensor_origin_rc": [50, 90]})
    with pytest.raises(PlacementError, match=r"256 x 320 px crop at sensor row 50, column 90"):
        cube_cra(_cube(sensor, ny=300, nx=400), sensor, beyond)


def test_a_profile_giving_only_image_shape_px_places_the_centre_as_image_size_px_does():
    """image_shape_px (rows, columns) was checked but never read: a profile giving only it was
    said not to record the calibration image's size, and its centre was not carried over."""
    import numpy as np

    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor, make_cube
    from snapcorr.optics import Lens

    sensor = Sensor("s2", "snapscan", 20.0, np.linspace(500, 900, 6), 10.0, 1.7,
                    size_px=(24, 32))
    cube = make_cube(np.random.default_rng(0).random((24, 32, 6)).astype(np.float32),
                     sensor.cwl_nm)
    cra = {}
    for key, value in (("image_shape_px", [48, 64]), ("image_size_px", [64, 48])):
        lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, calibration={
            "pixel_pitch_um": 10.0, "center_rc": [20.0, 24.0], key: value})
        cra[key] = correct_cube(cube, sensor, 2.0, lens)["cra_deg"].values
    np.testing.assert_array_equal(cra["image_shape_px"], cra["image_size_px"])
