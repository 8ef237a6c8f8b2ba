"""One pipeline (snapcorr.pipeline): a frame through the steps of PIPELINE_STEPS is what the
steps give one by one, and reading a frame or cube with its origin gives the file's values at
the sensor positions the origin names."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from snapcorr import data
from snapcorr.cube import (
    Sensor,
    demosaic,
    flatfield,
    make_cube,
    mosaic_to_cube,
    read_cube,
    write_dataset,
)
from snapcorr.cube.flatfield import check_masked
from snapcorr.cube.io import BLOCK_BYTES
from snapcorr.optics import Lens
from snapcorr.pipeline import (
    PIPELINE_STEPS,
    process_frame,
    process_stream,
    read_cube_or_frame,
    read_mosaic_frame,
    tile_rows,
    with_transmittance,
)

ORIGIN = (300, 500)
CROP = (slice(300, 340), slice(500, 550))


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    sensor = Sensor.load(data.sensor_path("imec_5x5_nir"))
    raw, dark, white = data.mosaic_frames("imec_5x5_nir", seed=1)
    folder = tmp_path_factory.mktemp("frames")
    paths = {}
    for name, frame in (("raw", raw), ("dark", dark), ("white", white)):
        paths[name] = folder / f"{name}.npy"
        np.save(paths[name], np.asarray(frame)[CROP])
    return sensor, paths


def test_the_steps_are_flat_field_demosaic_correct_virtual_bands():
    assert list(PIPELINE_STEPS) == ["flat-field", "demosaic", "correct", "virtual bands"]
    assert all(callable(step) for step in PIPELINE_STEPS.values())


def test_a_frame_is_what_the_steps_give_one_by_one(frames):
    sensor, paths = frames
    raw, dark, white = (read_mosaic_frame(paths[k], sensor) for k in ("raw", "dark", "white"))
    steps = []
    got = process_frame(raw, [dark], [white], sensor, demosaic_method="bilinear",
                        sensor_origin_px=ORIGIN, saturation=1023, filter_white=white,
                        on_step=steps.append)
    assert steps == ["flat-field", "demosaic"]
    ff = flatfield(raw, [dark], [white], saturation=1023, dtype="float32")
    check_masked(ff)
    want = demosaic(ff, sensor, "bilinear", sensor_origin_px=ORIGIN)
    tr = demosaic(flatfield(white, [dark], [white], saturation=1023, name="transmittance",
                            dtype="float32"), sensor, "bilinear", sensor_origin_px=ORIGIN)
    with_transmittance(want, tr)
    assert set(got.variables) == set(want.variables)
    for name in want.variables:
        assert np.array_equal(got[name].values, want[name].values, equal_nan=True), name


def test_a_frame_corrected_is_the_cube_corrected(frames):
    from snapcorr.correct import correct_cube

    sensor, paths = frames
    lens = Lens.load(data.lens_path())
    raw, dark, white = (read_mosaic_frame(paths[k], sensor) for k in ("raw", "dark", "white"))
    got = process_frame(raw, dark, white, sensor, demosaic_method="bilinear",
                        sensor_origin_px=ORIGIN, saturation=1023, lens=lens, f_number=2.8,
                        resample=True, virtual_bands="vendor")
    ds = process_frame(raw, dark, white, sensor, demosaic_method="bilinear",
                       sensor_origin_px=ORIGIN, saturation=1023)
    want = correct_cube(ds["reflectance"], sensor, 2.8, lens, resample=True,
                        virtual_bands="vendor")
    for name in ("resampled", "virtual", "wavelength_corrected", "cra_deg"):
        assert np.array_equal(got[name].values, want[name].values, equal_nan=True), name
    assert got.attrs["method"] == want.attrs["method"]
    with pytest.raises(ValueError, match="both a lens and an f-number"):
        process_frame(raw, dark, white, sensor, lens=lens)


def test_a_frame_or_cube_is_read_with_the_positions_its_origin_names(frames, tmp_path):
    sensor, paths = frames
    got = read_cube_or_frame(paths["raw"], sensor, ORIGIN)
    want = mosaic_to_cube(np.load(paths["raw"]), sensor, sensor_origin_px=ORIGIN)
    assert np.array_equal(got.values, want.values)
    rows, cols = sensor.mosaic_shape
    assert int(got["sensor_row"].min()) == ORIGIN[0]
    assert int(got["sensor_col"].min()) == ORIGIN[1]
    assert got.sizes["y"] == (CROP[0].stop - CROP[0].start) // rows
    assert got.sizes["band"] == rows * cols
    cube = make_cube(np.random.default_rng(0).random((6, 7, 3)).astype(np.float32),
                     [500.0, 600.0, 700.0])
    path = tmp_path / "cube.nc"
    write_dataset(cube.to_dataset(name="radiance"), path)
    got, mask = read_cube_or_frame(path, with_mask=True)
    assert np.array_equal(got.values, read_cube(path).values)
    assert np.array_equal(got.values, cube.values) and mask is None


def test_an_origin_the_file_contradicts_is_refused(tmp_path):
    sensor = Sensor("t", "snapscan", 5.5, [500.0, 600.0, 700.0], 10.0, 1.7)
    cube = make_cube(np.ones((4, 5, 3), np.float32), sensor.cwl_nm)
    path = tmp_path / "placed.nc"
    write_dataset(read_cube_or_frame(_written(cube, tmp_path), sensor, (10, 20))
                  .to_dataset(name="radiance"), path)
    assert int(read_cube_or_frame(path, sensor, (10, 20))["sensor_row"].min()) == 10
    with pytest.raises(ValueError, match=r"sensor_origin_px \(11, 20\) disagrees .* row 10, "
                                         r"col 20.*leave it out"):
        read_cube_or_frame(path, sensor, (11, 20))


def _written(cube, folder):
    path = folder / "plain.nc"
    write_dataset(cube.to_dataset(name="radiance"), path)
    return path


def test_mosaic_frames_are_read_in_whole_tiles_and_checked_for_size(frames):
    sensor, paths = frames
    frame = read_mosaic_frame(paths["raw"], sensor)
    n = tile_rows(frame, sensor)
    tile = sensor.mosaic_shape[0]
    assert n % tile == 0 and (n == tile or n * frame.sizes["x"] * 4 <= BLOCK_BYTES)
    assert (n + tile) * frame.sizes["x"] * 4 > BLOCK_BYTES
    assert np.array_equal(frame.values, np.load(paths["raw"]))
    with pytest.raises(ValueError, match=r"--dark .*dark.npy is 40 x 50 px but the raw frame "
                                         r"3 x 4"):
        read_mosaic_frame(paths["dark"], sensor, what="--dark", shape=(3, 4))


def test_with_transmittance_adds_the_filters_three_variables():
    ds = xr.Dataset({"reflectance": ("x", np.ones(3))})
    tr = xr.Dataset({"transmittance": ("x", np.full(3, 0.5)), "raw": ("x", np.arange(3.0)),
                     "mask": ("x", np.array([False, True, False]))})
    out = with_transmittance(ds, tr, "fw.npy")
    assert out is ds and ds.attrs["filter_white_file"] == "fw.npy"
    assert np.array_equal(ds["transmittance"], [0.5] * 3)
    assert np.array_equal(ds["filter_white_raw"], [0, 1, 2])
    assert np.array_equal(ds["transmittance_mask"], [False, True, False])
    assert "not meaningful" in ds["transmittance_mask"].attrs["long_name"]


class _Untouchable:
    """A white or a dark that fails the moment anything reads it."""

    def __array__(self, *args, **kwargs):
        raise AssertionError("read before the sensor was checked")

    def __getattr__(self, name):
        raise AssertionError(f"read ({name}) before the sensor was checked")


def test_a_stream_of_another_layout_is_refused_before_anything_is_read():
    scanner = Sensor("scanner", "snapscan", 5.5, np.linspace(500, 900, 5), 10.0, 1.7)
    frames = xr.DataArray(np.ones((3, 8, 8), np.float32), dims=("frame", "y", "x"))
    with pytest.raises(ValueError, match="sensor 'scanner' is not a mosaic"):
        process_stream(frames, _Untouchable(), _Untouchable(), scanner)


@pytest.mark.parametrize("sensor", [None, "imec_5x5_nir.toml", object()])
def test_a_stream_with_no_sensor_object_is_refused_by_name(sensor):
    frames = xr.DataArray(np.ones((3, 8, 8), np.float32), dims=("frame", "y", "x"))
    with pytest.raises(ValueError, match="is not a mosaic"):
        process_stream(frames, _Untouchable(), _Untouchable(), sensor)


def test_a_stream_takes_the_optical_centre_row_first(frames):
    sensor, paths = frames
    lens = Lens.load(data.lens_path())
    raw, dark, white = (read_mosaic_frame(paths[k], sensor) for k in ("raw", "dark", "white"))
    stream = xr.concat([raw, raw], "frame").transpose("frame", "y", "x")
    center = (412.5, 1190.0)  # (row, col): not the sensor's middle, and not symmetric
    got = process_stream(stream, dark, white, sensor, demosaic_method="bilinear",
                         sensor_origin_px=ORIGIN, saturation=1023, lens=lens, f_number=2.8,
                         center_rc=center)
    assert got.attrs["optical_center_rc"] == list(center)
    with pytest.warns(FutureWarning, match="center_rc"):
        old = process_stream(stream, dark, white, sensor, demosaic_method="bilinear",
                             sensor_origin_px=ORIGIN, saturation=1023, lens=lens,
                             f_number=2.8, center_px=center[::-1])
    assert np.array_equal(old["wavelength_corrected"].values,
                          got["wavelength_corrected"].values, equal_nan=True)


def test_a_cube_in_falling_wavelength_order_is_placed_band_by_band(tmp_path):
    """A cube listing the mosaic's bands from red to blue, placed by an origin: each band gets
    its own tile position (the 470 nm band the sensor's first), and the correction takes it.
    Before, the positions went to the file's order and were then reordered with the bands:
    the first band was said to sit at row 3, column 3 and the origin refused."""
    import xarray as xr

    from snapcorr import Lens
    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor
    from snapcorr.pipeline import read_cube_or_frame

    sensor = Sensor.load("mosaic_4x4_vis")
    wl = np.asarray(sensor.cwl_nm, float)[::-1]
    xr.Dataset({"reflectance": (("y", "x", "band"), np.ones((4, 5, wl.size), "float32"))},
               coords={"wavelength": ("band", wl)}).to_netcdf(tmp_path / "rev.nc")
    cube = read_cube_or_frame(tmp_path / "rev.nc", sensor, (8, 12))
    np.testing.assert_array_equal(cube["wavelength"].values, sensor.cwl_nm)
    offsets = sensor.band_offsets_at((8, 12))
    for b in range(wl.size):
        assert int(cube["sensor_row"].values[0, b]) == 8 + offsets[b][0]
        assert int(cube["sensor_col"].values[0, b]) == 12 + offsets[b][1]
    correct_cube(cube, sensor, 2.0, Lens.load("edmund_optics_16mm"))
