"""Per-pixel corrected wavelengths (Goossens 2019 Eq. 8, 23), checked from outside; where
each pixel sits, and its chief-ray angle, in test_geometry.py."""

import dask.array as da
import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_LENS, brute_force_mean

from snapcorr import Lens, mean_shift
from snapcorr.correct import correct_cube
from snapcorr.correct.resample import resample_to_nominal
from snapcorr.cube import Sensor, make_cube, mosaic_to_cube
from snapcorr.data import sensor_path
from snapcorr.optics import choose_model

PAPER = PAPER_LENS
H_GE_X = Lens(21.0, [(6.5, 27.0)], 0.06, 1.3, name="long tube")


def _sensor(n=6, pitch=40.0, n_eff=1.7):
    return Sensor("test", "snapscan", pitch, np.linspace(500, 900, n), 10.0, n_eff)


def _cube(sensor, ny=40, nx=50, seed=0):
    data = np.random.default_rng(seed).random((ny, nx, sensor.n_bands)).astype(np.float32)
    return make_cube(data, sensor.cwl_nm)


@pytest.mark.parametrize("lens", [PAPER, H_GE_X], ids=["h<x", "h>=x"])
def test_corrected_wavelengths_match_brute_force_pupil_integration(lens):
    s = _sensor(n=4, pitch=80.0, n_eff=[1.7, 1.7, 2.0, 2.0])
    cube = _cube(s, ny=60, nx=70)
    f = 1.4
    ds = correct_cube(cube, s, f, lens, center_px=(-10.0, 5.0), tolerance_nm=0.01)
    assert ds.attrs["method"] == "vignetted"
    R = float(lens.exit_pupil_radius_mm(f))
    x = lens.exit_pupil_mm
    rng = np.random.default_rng(1)
    for _ in range(4):
        yy, xx, b = rng.integers(0, 60), rng.integers(0, 70), rng.integers(0, 4)
        t = np.hypot(xx + 10.0, yy - 5.0) * 0.080 / x
        bf, _ = brute_force_mean(s.cwl_nm[b], s.n_eff[b], x, R, x * t,
                                     lens.vignetting[0][0],
                                     lens.vignetting[0][1] * t, N=1200)
        got = float(ds["wavelength_corrected"].values[yy, xx, b])
        cra = float(ds["cra_deg"].values[yy, xx])
        exact = s.cwl_nm[b] + float(mean_shift(s.cwl_nm[b], s.n_eff[b], f, cra, lens,
                                               method="vignetted"))
        assert abs(got - exact) < 0.01 + 1e-4  # the tolerance asked for + float32
        # tolerance + the brute-force grid's own error + float32 rounding of ~900 nm
        assert abs(got - (s.cwl_nm[b] + bf)) < 0.01 + 0.01 + 1e-4, (yy, xx, b)


def test_output_keeps_the_cube_and_records_provenance():
    s = _sensor()
    cube = _cube(s)
    ds = correct_cube(cube, s, 2.8, PAPER)
    kept = ds[cube.name].drop_vars(["wavelength_corrected", "fwhm_corrected"])
    xr.testing.assert_equal(kept, cube)  # values and coordinates unchanged
    assert kept.attrs == {**cube.attrs, "long_name": "radiance"}  # CF name added, nothing lost
    assert cube.attrs == {} and "wavelength_corrected" not in cube.coords  # input untouched
    # the corrected wavelengths: a lazy coordinate over a per-pixel scale, not a second cube
    assert "wavelength_corrected" in ds.coords
    assert isinstance(ds["wavelength_corrected"].data, da.Array)
    assert ds["wavelength_scale"].shape == (40, 50, 1)
    assert ds["wavelength_scale"].nbytes < cube.nbytes / 2
    np.testing.assert_array_equal(
        ds["wavelength_corrected"].values,
        (np.asarray(s.cwl_nm) * ds["wavelength_scale"].values).astype(np.float32))
    for key in ("lens", "sensor", "f_number", "method", "method_reason", "tolerance_nm",
                "snapcorr_version", "optical_center_px", "optical_center_source"):
        assert key in ds.attrs
    assert ds["wavelength_corrected"].dtype == np.float32
    assert ds["wavelength_corrected"].attrs["units"] == "nm"


def test_auto_picks_the_cheapest_model_that_meets_the_tolerance():
    cwl, n = np.array([500.0, 900.0]), np.array([1.7, 1.7])
    # below the onset at f/8 (19.95 deg): no vignetting model needed
    m, why = choose_model(cwl, n, 8.0, 10.0, PAPER, tolerance_nm=0.01)
    assert m in ("asymptotic", "ideal") and "below the onset" in why
    m, _ = choose_model(cwl, n, 1.4, 10.0, PAPER, tolerance_nm=0.01)
    assert m == "vignetted"
    # a nearly collimated beam on axis: nothing moves by more than the tolerance
    m, _ = choose_model(cwl, n, 500.0, 0.01, PAPER, tolerance_nm=0.01)
    assert m == "none"
    # and the choice is right: its error against the exact model is within the tolerance
    s = _sensor(pitch=40.0)
    cube = _cube(s)
    auto = correct_cube(cube, s, 8.0, PAPER, tolerance_nm=0.01)
    exact = correct_cube(cube, s, 8.0, PAPER, method="vignetted", tolerance_nm=1e-4)
    diff = np.abs(auto["wavelength_corrected"].values.astype(float)
                  - exact["wavelength_corrected"].values.astype(float))
    assert diff.max() < 0.01 + 1e-4


def test_dask_cube_gives_identical_results():
    s = _sensor()
    cube = _cube(s)
    a = correct_cube(cube, s, 1.4, PAPER, resample=True)
    b = correct_cube(cube.chunk({"y": 16, "x": 20}), s, 1.4, PAPER, resample=True)
    assert b["wavelength_corrected"].chunks is not None
    xr.testing.assert_identical(a.compute(), b.compute())


def test_resampling_against_numpy_interp_marks_extrapolation():
    s = _sensor(n=12)
    cube = _cube(s)
    ds = correct_cube(cube, s, 1.4, PAPER, resample=True)
    lam = ds["wavelength_corrected"].values
    out = ds["resampled"].values
    for yy, xx in ((0, 0), (20, 25), (39, 49)):
        ref = np.interp(s.cwl_nm, lam[yy, xx].astype(float), cube.values[yy, xx],
                        left=np.nan, right=np.nan)
        np.testing.assert_allclose(out[yy, xx], ref, atol=1e-5, equal_nan=True)
        assert np.isnan(out[yy, xx, -1])  # shifted to the blue: the reddest band is past
    with pytest.raises(ValueError, match="increasing"):
        resample_to_nominal(np.zeros((1, 1, 2)), np.ones((1, 1, 1)), [0, 0], [2.0, 1.0])


@pytest.mark.parametrize("change, message", [
    ({"f_number": 0.0}, "f_number"),
    ({"f_number": float("nan")}, "f_number"),
    ({"method": "magic"}, "method"),
    ({"tolerance_nm": 0.0}, "tolerance"),
    ({"center_px": (1e5, 0.0)}, "cuts off the whole pupil"),
])
def test_bad_arguments_are_clear_errors(change, message):
    s = _sensor()
    kw = {"f_number": 2.0, **change}
    f = kw.pop("f_number")
    with pytest.raises(ValueError, match=message):
        correct_cube(_cube(s), s, f, PAPER, **kw)


def test_band_count_and_wavelengths_must_match_the_sensor():
    s = _sensor(n=6)
    with pytest.raises(ValueError, match="bands"):
        correct_cube(_cube(_sensor(n=5)), s, 2.0, PAPER)
    shifted = make_cube(_cube(s).values, np.asarray(s.cwl_nm) + 3.0)
    with pytest.raises(ValueError, match="wavelengths differ"):
        correct_cube(shifted, s, 2.0, PAPER)


def test_uniform_grid_fast_path_equals_the_general_pass():
    rng = np.random.default_rng(3)
    data = rng.random((7, 9, 20)).astype(np.float32)
    cwl = np.linspace(450.0, 950.0, 20)
    scale = 1.0 - 0.03 * rng.random((7, 9, 1))
    fast = resample_to_nominal(data, scale, np.zeros(20, int), cwl)  # float32: fast path
    general = resample_to_nominal(data.astype(np.float64), scale, np.zeros(20, int), cwl)
    # the fast path works in float32: the fractional band index is good to ~1e-6 x nb
    np.testing.assert_allclose(fast, general, atol=1e-5, equal_nan=True)
    assert np.array_equal(np.isnan(fast), np.isnan(general))


def test_every_variable_and_coordinate_of_a_result_has_cf_units_and_long_name(tmp_path):
    from snapcorr.cube import flatfield, read_dataset, write_dataset

    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    frame = np.random.default_rng(3).uniform(500, 900, (16, 24)).astype(np.float32)
    raw = mosaic_to_cube(frame, sensor, sensor_origin_px=(40, 80))
    dark, white = (mosaic_to_cube(frame * 0 + v, sensor, sensor_origin_px=(40, 80))
                   for v in (100, 1e3))
    ff = flatfield(raw, dark, white)
    ds = correct_cube(ff["reflectance"], sensor, 1.4, PAPER, resample=True, mask=ff["mask"])
    for name, result in (("ff", ff), ("c", ds)):
        for path in (tmp_path / f"{name}.nc", tmp_path / f"{name}.zarr"):
            write_dataset(result, path)
            back = read_dataset(path)
            for v in back.variables:
                if v in ("y", "x", "band", "scale"):
                    continue  # bare dimensions without values of their own
                assert "long_name" in back[v].attrs and "units" in back[v].attrs, (path, v)


@pytest.mark.parametrize("what", ["resample", "harmonise"])
def test_a_one_band_cube_cannot_be_resampled_or_harmonised(what):
    """A one-band --resample said the wavelengths must be "increasing"."""
    sensor = Sensor("one", "snapscan", 5.5, [600.0], 10.0, 1.7)
    cube = make_cube(np.ones((4, 5, 1)), [600.0])
    with pytest.raises(ValueError, match=f"one-band cube has none: leave out {what}=True"):
        correct_cube(cube, sensor, 2.0, Lens(21.0, ()), **{what: True})
