"""The newcomer's path on whole sensor frames: `snapcorr flatfield --demosaic` of a whole
2048 x 1088 frame to zarr, then `snapcorr correct` zarr to zarr, plainly and with virtual
bands (these need a vendor calibration file: the imec 5x5 sensor's, on its whole frame too).
Each result must read back with its dims, wavelengths, provenance and the data it keeps."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from conftest import run_cli

from snapcorr.cube import Sensor, read_dataset
from snapcorr.data import mosaic_frames, sensor_path

pytestmark = pytest.mark.examples

LENS = "edmund_optics_16mm"


def _run(*args):
    code, out, err = run_cli(*args, "--quiet")
    assert code == 0, err
    assert "Traceback" not in err and "safe_chunks" not in err
    return out


def _flatfield_whole_frame(d, sensor_name, method):
    """Whole frames of a bundled sensor flat-fielded and demosaicked to ``ff.zarr``; the
    result read back, and the pixel flat field computed here."""
    raw, dark, white = mosaic_frames(sensor_name)
    assert raw.shape == (1088, 2048)
    for name, frame in (("raw", raw), ("dark", dark), ("white", white)):
        np.save(d / f"{name}.npy", frame)
    _run("flatfield", d / "raw.npy", "--dark", d / "dark.npy", "--white", d / "white.npy",
         "--sensor", sensor_name, "--demosaic", method, "--out", d / "ff.zarr")
    ff = read_dataset(d / "ff.zarr")
    pixel = (raw.astype(np.float64) - dark) / (white.astype(np.float64) - dark)
    return ff, raw, pixel


def _check_correction(d, out, ff, sensor):
    """``out``, corrected from ``ff.zarr``, as a newcomer would look at it."""
    ds = read_dataset(out)
    plain = xr.open_zarr(out)  # another program's reading: every stored variable there
    assert {"reflectance", "mask", "cra_deg"} <= set(plain.variables)
    cube = ds["reflectance"]
    assert cube.dims == ("y", "x", "band") and cube.shape == ff["reflectance"].shape
    np.testing.assert_allclose(ds["wavelength"].values, sensor.cwl_nm)
    assert np.all(np.diff(ds["wavelength"].values) > 0)  # bands in order of wavelength
    wc = ds["wavelength_corrected"]
    assert wc.dims == cube.dims
    assert ds.attrs["cube_file"] == str(d / "ff.zarr") and ds.attrs["lens_file"] == LENS
    assert ds.attrs["f_number"] == 2.8 and "snapcorr_version" in ds.attrs
    rows = slice(500, 540)  # a band of rows across the field, read back, equal to the input's
    np.testing.assert_array_equal(cube.isel(y=rows).values,
                                  ff["reflectance"].isel(y=rows).values)
    np.testing.assert_array_equal(ds["sensor_row"].values, ff["sensor_row"].values)
    corner, centre = wc.isel(y=0, x=0).values, wc.isel(y=cube.sizes["y"] // 2,
                                                       x=cube.sizes["x"] // 2).values
    # the field's corner sees the filters more obliquely than its centre: shorter wavelengths
    assert np.all(corner < centre)
    assert np.all(np.abs(centre - ds["wavelength"].values) < 0.02 * ds["wavelength"].values)
    return ds


def test_whole_4x4_frame_to_zarr_and_corrected_zarr_to_zarr(tmp_path):
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    ff, raw, pixel = _flatfield_whole_frame(tmp_path, "mosaic_4x4_vis", "ri")
    cube = ff["reflectance"]
    assert cube.dims == ("y", "x", "band") and cube.shape == (1088, 2048, 16)
    np.testing.assert_allclose(ff["wavelength"].values, sensor.cwl_nm)
    assert ff.attrs["raw_file"] == str(tmp_path / "raw.npy")
    assert ff.attrs["demosaic_method"] == "ri"
    np.testing.assert_array_equal(ff["raw"].values, raw)  # the raw frame kept, as it was
    # each band, at the pixels that measured it, near the flat field computed here
    for b, (r, c) in enumerate(np.asarray(sensor.band_offset)):
        got = cube.isel(band=b).values[r::4, c::4]
        np.testing.assert_allclose(np.median(got), np.median(pixel[r::4, c::4]), rtol=0.01)
    _run("correct", tmp_path / "ff.zarr", "--lens", LENS, "--sensor", "mosaic_4x4_vis",
         "--f-number", "2.8", "--out", tmp_path / "corr.zarr")
    _check_correction(tmp_path, tmp_path / "corr.zarr", ff, sensor)


def test_whole_imec_frame_to_zarr_and_virtual_bands_zarr_to_zarr(tmp_path):
    sensor = Sensor.load(sensor_path("imec_5x5_nir"))
    ff, _, _ = _flatfield_whole_frame(tmp_path, "imec_5x5_nir", "bilinear")
    r0, c0, n_rows, n_cols = sensor.filter_area_px
    # cut to the vendor file's filter area (rows 3-1082, columns 0-2044)
    assert ff["reflectance"].shape == (n_rows, n_cols, 25)
    assert int(ff["sensor_row"].min()) == r0 and int(ff["sensor_col"].min()) == c0
    _run("correct", tmp_path / "ff.zarr", "--lens", LENS, "--sensor", "imec_5x5_nir",
         "--f-number", "2.8", "--virtual-bands", "vendor", "--out", tmp_path / "virt.zarr")
    ds = _check_correction(tmp_path, tmp_path / "virt.zarr", ff, sensor)
    v = ds["virtual"]
    assert v.dims == ("y", "x", "virtual_band") and v.attrs["units"] == "1"
    assert v.sizes["virtual_band"] == 25 and {"virtual_matrix", "virtual_stderr"} <= set(ds)
    assert np.all(np.diff(ds["virtual_wavelength"].values) > 0)
    assert np.isfinite(v.isel(y=slice(500, 520)).values).mean() > 0.99
