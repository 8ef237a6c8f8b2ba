"""Sensor descriptions, the cube model, mosaic extraction and flat-fielding (Eq. 29)."""

import dask.array as da
import numpy as np
import pytest
import xarray as xr
from conftest import VENDOR_XML
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from snapcorr.cube import Sensor, flatfield, make_cube, mosaic_to_cube
from snapcorr.cube.model import with_positions
from snapcorr.data import sensor_path

# -- sensors ---------------------------------------------------------------------------------


def test_bundled_sensors():
    scan = Sensor.load(sensor_path("snapscan_vnir"))
    assert scan.layout == "snapscan" and 140 <= scan.n_bands <= 160
    assert scan.cwl_nm[0] == 470 and scan.cwl_nm[-1] == 900
    for name, tile in (("mosaic_4x4_vis", (4, 4)), ("mosaic_5x5_nir", (5, 5))):
        s = Sensor.load(sensor_path(name))
        assert s.layout == "mosaic" and s.mosaic_shape == tile
        assert s.n_bands == tile[0] * tile[1]
    with pytest.raises(FileNotFoundError, match="bundled sensors"):
        sensor_path("nope")


def test_sensor_round_trip_and_scalars(tmp_path):
    s = Sensor("t", "snapscan", 5.5, [500.0, 600.0, 700.0], 10.0, 1.7)
    assert s.fwhm_nm == (10.0, 10.0, 10.0) and s.n_eff == (1.7, 1.7, 1.7)
    path = s.save(tmp_path / "s.toml")
    assert Sensor.load(path) == s
    with pytest.raises(FileExistsError):
        s.save(path)
    sized = Sensor("t", "snapscan", 5.5, [500.0], 10.0, 1.7, size_px=[2048.0, 1088])
    assert sized.size_px == (2048, 1088) and Sensor.load(sized.save(tmp_path / "z.toml")) == sized
    # the corner of a 2048 x 1088 field of 5.5 um pixels: half the diagonal
    assert sized.field_radius_mm == pytest.approx(0.5 * 5.5e-3 * (2048**2 + 1088**2) ** 0.5)
    assert s.field_radius_mm is None


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(layout="pushbroom"), "layout"),
        (dict(pixel_pitch_um=0), "pixel_pitch_um"),
        (dict(cwl_nm=[500.0, -1.0]), "cwl_nm"),
        (dict(fwhm_nm=[10.0, 10.0, 10.0]), "fwhm_nm"),
        (dict(n_eff=1.0), "n_eff"),
        (dict(layout="mosaic"), "mosaic_shape"),
        (dict(layout="mosaic", mosaic_shape=[2, 2], band_offset=[[0, 0], [2, 0]]), "inside"),
        (dict(layout="mosaic", mosaic_shape=[2, 2], band_offset=[[0, 0], [0, 0]]), "share"),
        (dict(layout="mosaic", mosaic_shape=[2, 2], band_offset=[[0, 0]]), "one"),
        (dict(mosaic_shape=[2, 2]), "mosaic"),
        (dict(size_px=[0, 10]), "size_px"),
        (dict(size_px=[10.5, 10]), "size_px"),
        (dict(size_px=[10]), "size_px"),
    ],
)
def test_bad_sensors(kwargs, message):
    base = dict(name="t", layout="snapscan", pixel_pitch_um=5.5, cwl_nm=[500.0, 600.0],
                fwhm_nm=10.0, n_eff=1.7)
    with pytest.raises(ValueError, match=message):
        Sensor(**(base | kwargs))


def test_bad_sensor_files(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('[sensor]\nname = "x"\nlayout = "snapscan"\npixel_pitch_um = 5.5\n'
                 "cwl_nm = [500.0]\nfwhm_nm = 10.0\nn_eff = 1.7\ncolour = 3\n")
    with pytest.raises(ValueError, match="unknown key"):
        Sensor.load(p)
    p.write_text('[sensor]\nname = "x"\n')
    with pytest.raises(ValueError, match="missing"):
        Sensor.load(p)


# -- cube model ------------------------------------------------------------------------------


def test_make_cube_and_errors():
    cube = make_cube(np.zeros((2, 3, 4)), [500, 600, 700, 800], fwhm_nm=10, attrs={"f_number": 2})
    assert cube.dims == ("y", "x", "band") and cube.wavelength.attrs["units"] == "nm"
    assert_array_equal(cube.fwhm, 10.0) and cube.attrs["f_number"] == 2
    with pytest.raises(ValueError, match="3 dimensions"):
        make_cube(np.zeros((2, 3)), [500])
    with pytest.raises(ValueError, match="4 bands but 3"):
        make_cube(np.zeros((2, 3, 4)), [500, 600, 700])
    with pytest.raises(ValueError, match="finite"):
        make_cube(np.zeros((2, 3, 2)), [500, np.nan])


# -- mosaics ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["mosaic_4x4_vis", "mosaic_5x5_nir"])
def test_mosaic_extraction_against_a_loop(name):
    s = Sensor.load(sensor_path(name))
    tr, tc = s.mosaic_shape
    raw = np.random.default_rng(1).integers(0, 4096, (3 * tr, 4 * tc)).astype(np.uint16)
    cube = mosaic_to_cube(raw, s, sensor_origin_px=(100, 200))
    assert cube.shape == (3, 4, s.n_bands) and cube.dtype == np.uint16
    for y in range(3):
        for x in range(4):
            for b, (r, c) in enumerate(s.band_offset):
                assert cube.values[y, x, b] == raw[y * tr + r, x * tc + c]
                assert cube.sensor_row.values[y, b] == 100 + y * tr + r
                assert cube.sensor_col.values[x, b] == 200 + x * tc + c
    lazy = mosaic_to_cube(da.from_array(raw, chunks=(tr, 2 * tc)), s, sensor_origin_px=(100, 200))
    assert isinstance(lazy.data, da.Array)
    xr.testing.assert_identical(lazy.compute(), cube)


def test_mosaic_errors():
    s = Sensor.load(sensor_path("mosaic_4x4_vis"))
    with pytest.raises(ValueError, match="origin_px"):  # not the sensor's size, no origin
        mosaic_to_cube(np.zeros((8, 8)), s)
    with pytest.raises(ValueError, match="no whole 4 x 4 tile"):
        mosaic_to_cube(np.zeros((3, 8)), s, sensor_origin_px=(0, 0))
    with pytest.raises(ValueError, match="already split into bands"):
        mosaic_to_cube(np.zeros((8, 8, 16)), s, sensor_origin_px=(0, 0))
    with pytest.raises(ValueError, match="whole numbers"):
        mosaic_to_cube(np.zeros((8, 8)), s, sensor_origin_px=(1.5, 0))
    with pytest.raises(ValueError, match="not a mosaic"):
        mosaic_to_cube(np.zeros((8, 8)), Sensor.load(sensor_path("snapscan_vnir")))


def _tile_position(sensor, row, col):
    """The tile position the sensor's grid gives sensor pixel (row, col): written here from
    the layout's definition, not from snapcorr's window arithmetic."""
    r0, c0 = sensor.filter_area_px[:2] if sensor.filter_area_px else (0, 0)
    return (row - r0) % sensor.mosaic_shape[0], (col - c0) % sensor.mosaic_shape[1]


@pytest.mark.parametrize("origin", [(100, 200), (101, 202), (3, 7), (0, 1)])
@pytest.mark.parametrize("name", ["mosaic_4x4_vis", "mosaic_5x5_nir", "vendor"])
def test_a_frame_may_start_anywhere_and_keeps_the_band_layout(name, origin):
    s = (Sensor.load(VENDOR_XML) if name == "vendor"
         else Sensor.load(sensor_path(name)))
    rows, cols = 23, 37  # not whole tiles either
    r = origin[0] + np.arange(rows)[:, None]
    c = origin[1] + np.arange(cols)[None, :]
    raw = (r * 10_000 + c).astype(np.int64)  # each value says where it was taken
    cube = mosaic_to_cube(raw, s, sensor_origin_px=origin)
    tr, tc = s.mosaic_shape
    lo_r, lo_c, n_r, n_c = cube.attrs["mosaic_area_px"]
    assert cube.shape == (n_r // tr, n_c // tc, s.n_bands)
    assert n_r // tr == (origin[0] + rows - lo_r) // tr and n_c // tc == (
        origin[1] + cols - lo_c) // tc
    for b, off in enumerate(s.band_offset):
        sr = cube.sensor_row.values[:, b]
        sc = cube.sensor_col.values[:, b]
        assert all(_tile_position(s, row, sc[0])[0] == off[0] for row in sr)
        assert all(_tile_position(s, sr[0], col)[1] == off[1] for col in sc)
        assert_array_equal(cube.values[:, :, b], sr[:, None] * 10_000 + sc[None, :])
    # every cube pixel's window holds each band once, inside the frame
    assert cube.sensor_row.values.min() >= max(origin[0], lo_r)
    assert cube.sensor_row.values.max() < origin[0] + rows


def test_a_whole_sensor_frame_is_cut_to_the_vendor_files_filter_area():
    s = Sensor.load(VENDOR_XML)
    assert s.filter_area_px == (3, 0, 1080, 2045)
    raw = np.zeros(s.size_px, np.uint16)
    cube = mosaic_to_cube(raw, s)
    assert cube.shape == (216, 409, 25)
    assert cube.attrs["mosaic_area_px"] == [3, 0, 1080, 2045]
    # the file's band i at tile row i // 5, column i % 5 from the area's corner (row 3); the
    # cube's bands in order of wavelength, each with its file number
    b = s.vendor_band.index(7)
    assert cube.vendor_band.values[b] == 7
    assert cube.sensor_row.values[0, b] == 3 + 1 and cube.sensor_col.values[0, b] == 2
    assert np.all(np.diff(cube.wavelength.values) > 0)
    assert cube.sensor_row.values[-1].max() == 1082 and cube.sensor_col.values[-1].max() == 2044
    lazy = mosaic_to_cube(da.from_array(raw, chunks=(256, -1)), s)
    xr.testing.assert_identical(lazy.compute(), cube)


# -- flat-fielding ---------------------------------------------------------------------------

WL = np.linspace(470.0, 900.0, 5)


def _cube(a):
    return make_cube(a, WL, attrs={"f_number": 2.8})


def test_eq29_against_numpy_and_frame_averaging():
    rng = np.random.default_rng(2)
    raw = rng.uniform(100, 3000, (6, 4, 5)).astype(np.uint16)
    darks = [rng.uniform(40, 60, (6, 4, 5)) for _ in range(3)]
    whites = [rng.uniform(3500, 3600, (6, 4, 5)) for _ in range(2)]
    ds = flatfield(_cube(raw), [_cube(d) for d in darks], [_cube(w) for w in whites],
                   dtype="float64")
    d, w = np.mean(darks, axis=0), np.mean(whites, axis=0)
    assert_allclose(ds.reflectance.values, (raw - d) / (w - d), rtol=1e-12)
    assert ds.reflectance.dtype == np.float64 and int(ds.n_masked) == 0
    assert ds.attrs["dark_frames"] == 3 and ds.attrs["white_frames"] == 2
    assert ds.attrs["f_number"] == 2.8 and "Eq. 29" in ds.attrs["method"]
    assert_array_equal(ds.raw.values, raw)  # the raw data is kept, unchanged


def test_line_scan_white_strip_is_broadcast():
    rng = np.random.default_rng(3)
    raw = rng.uniform(100, 3000, (8, 4, 5))
    strip = rng.uniform(3500, 3600, (2, 4, 5))
    ds = flatfield(_cube(raw), _cube(np.zeros((8, 4, 5))), _cube(strip), dtype="float64")
    assert_allclose(ds.reflectance.values, raw / strip.mean(axis=0), rtol=1e-12)
    with pytest.raises(ValueError, match=r"more rows|has 9 rows"):  # larger: not a strip
        flatfield(_cube(raw), _cube(np.zeros((9, 4, 5))), _cube(strip))


def test_meaningless_pixels_are_masked_not_inf():
    raw = np.full((2, 3, 5), 500.0)
    dark = np.full((2, 3, 5), 50.0)
    white = np.full((2, 3, 5), 3000.0)
    white[0, 0, 0] = 50.0  # white == dark
    white[0, 1, 1] = 40.0  # white < dark
    raw[1, 2, 3] = np.nan
    raw[1, 0, 4] = 4095.0  # saturated
    ds = flatfield(_cube(raw), _cube(dark), _cube(white), saturation=4095)
    bad = [(0, 0, 0), (0, 1, 1), (1, 2, 3), (1, 0, 4)]
    assert int(ds.n_masked) == len(bad)
    for idx in bad:
        assert bool(ds.mask.values[idx]) and np.isnan(ds.reflectance.values[idx])
    assert np.all(np.isfinite(ds.reflectance.values[~ds.mask.values]))
    assert not np.any(np.isinf(ds.reflectance.values))


def test_infinite_saturated_and_missing_values_in_any_frame_are_masked():
    raw = np.full((2, 3, 5), 500.0)
    raw[0, 0, 0] = np.inf
    w1, w2 = np.full((2, 3, 5), 3000.0), np.full((2, 3, 5), 3000.0)
    w1[0, 1, 0] = np.inf
    w1[0, 2, 0] = 4095.0  # saturated in one frame only: the mean (3547.5) hides it
    w2[1, 0, 0] = np.nan  # missing in one frame only: a NaN-skipping mean would hide it
    ds = flatfield(_cube(raw), _cube(np.zeros((2, 3, 5))), [_cube(w1), _cube(w2)],
                   saturation=4095)
    for idx in [(0, 0, 0), (0, 1, 0), (0, 2, 0), (1, 0, 0)]:
        assert bool(ds.mask.values[idx]), idx
    assert int(ds.n_masked) == 4
    assert np.all(np.isfinite(ds.reflectance.values[~ds.mask.values]))
    strip = np.full((3, 3, 5), 3000.0)
    strip[1, 2, 4] = 4095.0  # one saturated row of a line-scan strip masks that column
    ds = flatfield(_cube(np.full((6, 3, 5), 500.0)), _cube(np.zeros((6, 3, 5))),
                   _cube(strip), saturation=4095)
    assert ds.mask.values[:, 2, 4].all() and int(ds.n_masked) == 6


def test_data_ignore_value_is_masked():
    cube = _cube(np.full((2, 3, 5), 500.0))
    cube.values[1, 1, 1] = -9999.0
    cube.attrs["data_ignore_value"] = -9999.0
    ds = flatfield(cube, _cube(np.zeros((2, 3, 5))), _cube(np.ones((2, 3, 5)) * 1000))
    assert bool(ds.mask.values[1, 1, 1]) and int(ds.n_masked) == 1


def test_float_policy_and_shape_errors():
    f32 = _cube(np.ones((2, 3, 5), np.float32))
    assert flatfield(f32, f32 * 0, f32 * 2).reflectance.dtype == np.float32
    with pytest.raises(ValueError, match="x and band must match"):
        flatfield(_cube(np.ones((2, 3, 5))), _cube(np.zeros((2, 4, 5))), _cube(np.ones((2, 3, 5))))
    with pytest.raises(ValueError, match="differ in shape"):
        darks = [_cube(np.zeros((2, 3, 5))), _cube(np.zeros((1, 3, 5)))]
        flatfield(_cube(np.ones((2, 3, 5))), darks, _cube(np.ones((2, 3, 5))))
    other = make_cube(np.ones((2, 3, 5)), WL + 1.0)
    with pytest.raises(ValueError, match="different wavelengths"):
        flatfield(_cube(np.ones((2, 3, 5))), other, _cube(np.ones((2, 3, 5))))
    # every frame of a reference is checked, not only its first
    whites = [_cube(np.ones((2, 3, 5))), make_cube(np.ones((2, 3, 5)), WL + 1.0)]
    with pytest.raises(ValueError, match="white frame 2 of 2 and the cube have different"):
        flatfield(_cube(np.ones((2, 3, 5))), _cube(np.zeros((2, 3, 5))), whites)
    with pytest.raises(TypeError, match="DataArray"):
        flatfield(np.ones((2, 3, 5)), _cube(np.zeros((2, 3, 5))), _cube(np.ones((2, 3, 5))))


def test_numpy_and_dask_give_identical_results():
    rng = np.random.default_rng(4)
    raw = _cube(rng.uniform(0, 4095, (16, 12, 5)))
    dark = _cube(rng.uniform(40, 60, (16, 12, 5)))
    white = _cube(rng.uniform(20, 4095, (1, 12, 5)))  # some white < dark: masked
    eager = flatfield(raw, dark, white, saturation=4000)
    lazy = flatfield(raw.chunk({"y": 5, "x": 4}), dark.chunk({"y": 5}), white,
                     saturation=4000)
    assert isinstance(lazy.reflectance.data, da.Array)
    xr.testing.assert_identical(lazy.compute().drop_attrs(), eager.drop_attrs())


@settings(max_examples=50, deadline=None)
@given(data=st.lists(st.floats(-1e6, 1e6), min_size=30, max_size=30))
def test_unit_flat_and_zero_dark_leave_the_cube_unchanged(data):
    cube = _cube(np.array(data).reshape(2, 3, 5))
    ds = flatfield(cube, _cube(np.zeros((2, 3, 5))), _cube(np.ones((2, 3, 5))), dtype="float64")
    assert_array_equal(ds.reflectance.values, cube.values)
    assert int(ds.n_masked) == 0


def test_float32_by_default_and_float64_on_request():
    rng = np.random.default_rng(5)
    raw = rng.uniform(100, 3000, (4, 3, 5)).astype(np.uint16)
    d, w = np.full((4, 3, 5), 50.0), np.full((4, 3, 5), 3500.0)
    f32 = flatfield(_cube(raw), _cube(d), _cube(w))
    f64 = flatfield(_cube(raw), _cube(d), _cube(w), dtype="float64")
    assert f32.reflectance.dtype == np.float32 and f64.reflectance.dtype == np.float64
    assert_allclose(f32.reflectance.values, (raw - 50.0) / 3450.0, rtol=1e-6)
    with pytest.raises(ValueError, match="float32 or float64"):
        flatfield(_cube(raw), _cube(d), _cube(w), dtype="int16")


@pytest.mark.parametrize("kind", [np.uint32, np.int64, np.float64])
@pytest.mark.parametrize("frames", [False, True])
def test_counts_beyond_float32s_whole_numbers_are_subtracted_exactly(kind, frames):
    """Counts near 4e9 (uint32, int64, or float64 references) with a white 4096 DN above the
    dark: float32 holds whole numbers only to 2**24, and the differences taken in it were up
    to 128 DN (reflectance 0.031) off. They are now taken in float64 and the float32 result
    is k / 4096 to float32's rounding, for cubes and raw frames alike."""
    rng = np.random.default_rng(3)
    shape = (6, 5) if frames else (4, 3, 5)
    k = rng.integers(0, 4097, shape)
    dark = np.full(shape, 4_000_000_000, kind)
    raw, white = (dark + k).astype(kind), (dark + 4096).astype(kind)
    wrap = ((lambda a: xr.DataArray(a, dims=("y", "x"))) if frames else _cube)
    ds = flatfield(wrap(raw), wrap(dark), wrap(white))
    assert ds.reflectance.dtype == np.float32 and ds.raw.dtype == kind
    assert_allclose(ds.reflectance.values, k / 4096.0, rtol=1e-7, atol=0)


@pytest.mark.parametrize("bad", [np.nan, -1.0, 0.0, np.inf])
def test_saturation_must_be_a_positive_number(bad):
    with pytest.raises(ValueError, match="saturation"):
        flatfield(_cube(np.ones((2, 3, 5))), _cube(np.zeros((2, 3, 5))),
                  _cube(np.full((2, 3, 5), 2.0)), saturation=bad)


def test_everything_masked_is_refused_and_mostly_masked_warns():
    from snapcorr.cube.flatfield import MaskedWarning, check_masked

    raw, dark = _cube(np.full((2, 3, 5), 500.0)), _cube(np.full((2, 3, 5), 100.0))
    with pytest.raises(ValueError, match=r"every value .* is masked"):
        flatfield(raw, dark, _cube(np.full((2, 3, 5), 100.0)))  # white == dark everywhere
    with pytest.raises(ValueError, match=r"every value .* is masked"):
        flatfield(_cube(np.full((2, 3, 5), np.nan)), dark, _cube(np.full((2, 3, 5), 900.0)))
    white = np.full((2, 3, 5), 900.0)
    white[:, :, :3] = 50.0  # 3 of 5 bands below the dark: 60 % masked
    with pytest.warns(MaskedWarning, match="60.0 % of the values are masked"):
        flatfield(raw, dark, _cube(white))
    lazy = flatfield(raw.chunk({"y": 1}), dark, _cube(np.full((2, 3, 5), 100.0)))  # not yet
    with pytest.raises(ValueError, match="every value"):
        check_masked(lazy)
    assert check_masked(flatfield(raw.chunk({"y": 1}), dark, _cube(np.full((2, 3, 5), 9e2)))) \
        == (0, 30)


@pytest.mark.parametrize("dtype", [np.complex64, bool])
def test_complex_and_boolean_cubes_are_not_digital_numbers(dtype):
    good = _cube(np.ones((2, 3, 5)))
    bad = xr.DataArray(np.ones((2, 3, 5), dtype), dims=("y", "x", "band"),
                       coords={"wavelength": ("band", WL)})
    with pytest.raises((TypeError, ValueError), match=r"complex|bool"):
        flatfield(bad, good * 0, good * 2)


def test_outputs_carry_cf_units_and_long_names():
    ds = flatfield(_cube(np.full((2, 3, 5), 500.0)), _cube(np.zeros((2, 3, 5))),
                   _cube(np.full((2, 3, 5), 900.0)))
    for v in ("reflectance", "mask"):
        assert ds[v].attrs["units"] == "1" and ds[v].attrs["long_name"]
    assert ds["raw"].attrs["long_name"]
    # each variable says truly where it came from: the raw cube's file, not the dataset's
    raw = _cube(np.full((2, 3, 5), 500.0))
    raw.attrs["source"] = "scene.hdr"
    ds = flatfield(raw, _cube(np.zeros((2, 3, 5))), _cube(np.full((2, 3, 5), 900.0)))
    assert ds["raw"].attrs["source"] == "scene.hdr"
    assert ds["reflectance"].attrs["source"].startswith("(raw - dark) / (white - dark) of "
                                                        "scene.hdr")
    assert "flatfield" in ds.attrs["source"] and "white <= dark" in ds["mask"].attrs["source"]


def _placed(values, row0=0, col0=0, wl=None):
    cube = make_cube(np.asarray(values, float), wl if wl is not None else
                     np.linspace(500.0, 700.0, np.shape(values)[2]))
    ny, nx, nb = cube.shape
    rows = np.repeat(np.arange(row0, row0 + ny)[:, None], nb, axis=1)
    cols = np.repeat(np.arange(col0, col0 + nx)[:, None], nb, axis=1)
    return with_positions(cube, rows, cols)


def test_references_from_another_part_of_the_sensor_are_refused():
    """A dark or white whose recorded positions differ from the cube's was accepted:
    reflectance up to 33 % wrong. The same columns always, the same rows unless a strip."""
    raw = _placed(np.full((6, 4, 3), 500.0), 100, 200)
    dark = _placed(np.zeros((6, 4, 3)), 100, 200)
    with pytest.raises(ValueError, match="other sensor columns than the cube"):
        flatfield(raw, dark, _placed(np.full((6, 4, 3), 1000.0), 100, 240))
    with pytest.raises(ValueError, match="other sensor rows than the cube"):
        flatfield(raw, dark, _placed(np.full((6, 4, 3), 1000.0), 300, 200))
    # a line-scan strip may come from any rows of the scan, never other columns
    ds = flatfield(raw, dark, _placed(np.full((2, 4, 3), 1000.0), 900, 200))
    assert float(ds["reflectance"].mean()) == pytest.approx(0.5)


def test_a_snapshot_has_no_scan_axis_and_references_keep_their_ignore_value():
    """A mosaic white one tile row short was averaged over y as if it were a line-scan strip
    (11.9 % wrong); a reference's ENVI data ignore value was not honoured (0.917 for 0.474)."""
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    rng = np.random.default_rng(0)
    frame = rng.uniform(100, 200, (32, 32))
    raw = mosaic_to_cube(frame, sensor, sensor_origin_px=(64, 64))
    white = mosaic_to_cube(np.full((28, 32), 400.0), sensor, sensor_origin_px=(64, 64))
    dark = mosaic_to_cube(np.zeros((32, 32)), sensor, sensor_origin_px=(64, 64))
    with pytest.raises(ValueError, match="a snapshot has no scan axis"):
        flatfield(raw, dark, white)
    raw = _placed(np.full((4, 3, 2), 500.0))
    white = _placed(np.full((4, 3, 2), 1000.0))
    white[0, 0, 0] = -1.0
    white.attrs["data_ignore_value"] = -1.0
    ds = flatfield(raw, _placed(np.zeros((4, 3, 2))), white)
    assert bool(ds["mask"][0, 0, 0]) and np.isnan(float(ds["reflectance"][0, 0, 0]))
    assert float(ds["reflectance"][1, 1, 1]) == pytest.approx(0.5)


def test_a_frame_reference_keeps_its_ignore_value():
    raw = xr.DataArray(np.full((4, 5), 500.0), dims=("y", "x"))
    white = xr.DataArray(np.full((4, 5), 1000.0), dims=("y", "x"))
    white[1, 1] = -1.0
    white.attrs["data_ignore_value"] = -1.0
    ds = flatfield(raw, xr.DataArray(np.zeros((4, 5)), dims=("y", "x")), white)
    assert bool(ds["mask"][1, 1]) and int(ds["mask"].sum()) == 1
    assert float(ds["reflectance"][0, 0]) == pytest.approx(0.5)
