"""A vendor mosaic's bands in order of wavelength in every cube, the vendor's band number kept
as a coordinate, and everything that indexes bands by tile position (tiles, demosaicking, the
vendor's matrix, a cube in the old tile order) unchanged by the reordering. The frames come
from a simulator written here: each band's known value placed at its tile position as the
vendor's file numbers them (band ``i`` at row ``i // 4``, column ``i % 4``)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from vendorfiles import imec_4x4, write_newer

from snapcorr.correct import virtual_bands
from snapcorr.cube import Sensor, demosaic, flatfield, mosaic_to_cube, write_dataset
from snapcorr.cube.demosaicking import demosaic_array
from snapcorr.cube.vendor_xml import read_vendor_file

TILE = 4


@pytest.fixture(scope="module")
def vendor(tmp_path_factory):
    """A vendor file of the real 4x4 VIS responses, whose bands are not in wavelength order
    in the file; its bands' main peaks and matrices as the file gives them."""
    fx = imec_4x4()
    path = write_newer(tmp_path_factory.mktemp("v") / "s.xml", fx)
    cal = read_vendor_file(path)
    file_cwl = np.array([p.wavelength_nm for p in cal.responses.main_peaks()])
    assert np.any(np.diff(file_cwl) < 0)  # the file's order zigzags
    return Sensor.load(path), cal, file_cwl


def _frame(values_by_file_band, ny, nx):
    """A raw mosaic frame: tile (ty, tx) holds ``values_by_file_band[ty, tx, i]`` at the
    position the file gives band ``i``."""
    frame = np.empty((ny * TILE, nx * TILE))
    for i in range(TILE * TILE):
        frame[i // TILE::TILE, i % TILE::TILE] = values_by_file_band[:, :, i]
    return frame


def test_cubes_list_bands_by_wavelength_with_the_vendors_numbers(vendor, tmp_path):
    sensor, _, file_cwl = vendor
    rng = np.random.default_rng(0)
    truth = rng.uniform(0.1, 0.9, (5, 6, 16))  # per tile, the file's band order
    raw = _frame(truth, 5, 6)
    tiles = mosaic_to_cube(raw, sensor, sensor_origin_px=sensor.tile_origin_px)
    frame = xr.DataArray(raw, dims=("y", "x"))
    v = tiles["vendor_band"].values
    assert np.all(np.diff(tiles["wavelength"].values) > 0)  # plots left to right
    np.testing.assert_array_equal(tiles["wavelength"].values, file_cwl[v])
    np.testing.assert_array_equal(tiles.values, truth[:, :, v])  # each band its own values
    for ext in (".nc", ".zarr"):  # and a reader that is not snapcorr's sees the same
        ds = flatfield(frame, xr.zeros_like(frame), xr.ones_like(frame))
        cube = demosaic(ds, sensor, "bilinear", sensor_origin_px=sensor.tile_origin_px)
        out = write_dataset(cube, tmp_path / f"d{ext}")
        with xr.open_dataset(out, engine="zarr" if ext == ".zarr" else "h5netcdf") as back:
            assert np.all(np.diff(back["wavelength"].values) > 0)
            np.testing.assert_array_equal(back["vendor_band"].values, v)


def test_demosaicking_is_the_same_in_either_order(vendor):
    sensor, _, _ = vendor
    rng = np.random.default_rng(1)
    frame = _frame(rng.uniform(0.1, 0.9, (6, 8, 16)), 6, 8)
    cube = demosaic(xr.DataArray(frame, dims=("y", "x")), sensor, "ri",
                    sensor_origin_px=sensor.tile_origin_px)
    # the numpy core with the bands where the file puts them, in the file's order
    y0, x0 = np.arange(16) // TILE, np.arange(16) % TILE
    by_file = demosaic_array(frame, y0, x0, TILE, TILE, "ri")
    np.testing.assert_allclose(cube.values, by_file[:, :, sensor.vendor_band], rtol=0,
                               atol=1e-6)


def test_the_vendor_matrix_gives_the_same_virtual_bands(vendor):
    sensor, cal, _ = vendor
    rng = np.random.default_rng(2)
    truth = rng.uniform(0.1, 0.9, (4, 5, 16))
    tiles = mosaic_to_cube(_frame(truth, 4, 5), sensor,
                           sensor_origin_px=sensor.tile_origin_px)
    tiles = tiles.rename("reflectance").assign_attrs(units="1")
    got = virtual_bands(tiles, sensor, "vendor")["virtual"].values
    # the file's reflectance matrix on the file's band order, by hand
    (m,) = [m for m in cal.matrices if m.kind == "reflectance"]
    want = np.einsum("vb,yxb->yxv", m.coefficients, truth)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)


def test_a_cube_in_the_old_tile_order_is_corrected_as_one_in_order(vendor, edmund):
    from dataclasses import replace

    from snapcorr.correct import correct_cube

    sensor, _, _ = vendor
    sensor = replace(sensor, n_eff=(1.7,) * 16)
    rng = np.random.default_rng(3)
    truth = rng.uniform(0.1, 0.9, (6, 7, 16))
    tiles = mosaic_to_cube(_frame(truth, 6, 7), sensor,
                           sensor_origin_px=sensor.tile_origin_px)
    tiles = tiles.rename("reflectance").assign_attrs(units="1")
    back = np.argsort(sensor.vendor_band)
    old = tiles.isel(band=back)  # as files written in the tile order hold it
    assert np.any(np.diff(old["wavelength"].values) < 0)
    a = correct_cube(tiles, sensor, 2.0, edmund, resample=True, fwhm=False)
    b = correct_cube(old, sensor, 2.0, edmund, resample=True, fwhm=False)
    np.testing.assert_array_equal(a["resampled"].values, b["resampled"].values)
    np.testing.assert_array_equal(a["wavelength_corrected"].values,
                                  b["wavelength_corrected"].values)


def test_a_sensor_written_out_reads_back_the_same(vendor, tmp_path):
    from dataclasses import replace

    sensor, _, _ = vendor
    n_eff = tuple(1.6 + 0.01 * i for i in range(16))  # one per band, in wavelength order
    mine = replace(sensor, n_eff=n_eff)
    mine.save(tmp_path / "s.toml")
    # the TOML lists them as the vendor's file numbers the bands
    again = Sensor.load(tmp_path / "s.toml")
    assert again.n_eff == n_eff and again.vendor_band == sensor.vendor_band
    plain = Sensor("p", "mosaic", 5.5, [600.0, 500.0, 550.0, 520.0], 10.0, 1.7,
                   mosaic_shape=(2, 2), band_offset=[(0, 0), (0, 1), (1, 0), (1, 1)])
    assert plain.cwl_nm == (500.0, 520.0, 550.0, 600.0)
    assert plain.band_offset == ((0, 1), (1, 1), (1, 0), (0, 0))
    assert plain.vendor_band == (1, 3, 2, 0)
    assert Sensor.from_dict(plain.to_dict()) == plain


@pytest.mark.parametrize("tile_order", [True, False])
def test_a_band_off_in_a_cube_of_either_order_is_said_by_how_much(vendor, tile_order):
    """One band 0.5 nm off in a cube in the tile's order was said to differ by up to 197 nm
    (the wavelengths compared as given, against the sensor's in wavelength order)."""
    sensor, _, _ = vendor
    tiles = mosaic_to_cube(_frame(np.ones((2, 2, 16)), 2, 2), sensor,
                           sensor_origin_px=sensor.tile_origin_px)
    cube = tiles.isel(band=np.argsort(sensor.vendor_band)) if tile_order else tiles
    wl = cube["wavelength"].values.copy()
    wl[3] += 0.5
    with pytest.raises(ValueError, match=r"differ from the sensor .* \(by up to 0\.5 nm\)"):
        sensor.check_cube(cube.assign_coords(wavelength=("band", wl)))
