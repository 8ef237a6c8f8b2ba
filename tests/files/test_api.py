"""Cube files: round trips in every format and dtype, files written by the libraries' own
writers, and bad files refused with a clear error. What one format family alone does is
checked in its own file (test_images.py, test_npy.py, test_attrs.py)."""

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from numpy.testing import assert_allclose, assert_array_equal

from snapcorr.cube import make_cube, read_frame
from snapcorr.cube.model import with_positions
from snapcorr.files.api import read_cube, write_cube, write_dataset
from snapcorr.files.toml import write_toml

REPO = Path(__file__).resolve().parents[2]

WL = np.array([470.5, 500.0, 650.25, 900.0])
DTYPES = [np.uint8, np.uint16, np.int16, np.int32, np.uint32, np.float16, np.float32,
          np.float64]


def _cube(dtype, name="radiance"):
    rng = np.random.default_rng(7)
    data = rng.uniform(0, 250, (5, 7, WL.size)).astype(dtype)
    return make_cube(data, WL, fwhm_nm=[10.0, 11.0, 12.0, 13.0], attrs={"f_number": 2.8},
                     name=name)


@pytest.mark.parametrize("dtype", DTYPES, ids=lambda d: np.dtype(d).name)
@pytest.mark.parametrize("ext", [".hdr", ".tif", ".exr", ".nc", ".zarr", ".npy"])
def test_round_trip_is_lossless(tmp_path, ext, dtype):
    cube = _cube(dtype)
    path = tmp_path / f"cube{ext}"
    unsupported = {".exr": (np.float64, np.int32, np.uint32), ".hdr": (np.float16,),
                   ".tif": (np.int32, np.uint32)}  # each refused with a clear error
    if np.dtype(dtype) in unsupported.get(ext, ()):
        with pytest.raises(ValueError, match="convert"):
            write_cube(cube, path)
        assert not list(tmp_path.iterdir())  # nothing left behind
        return
    write_cube(cube, path)
    back = read_cube(path, wavelength_nm=WL if ext == ".npy" else None)
    # netCDF has no 16-bit float: float16 is kept as float32, every value exactly
    widened = ext == ".nc" and np.dtype(dtype) == np.float16
    assert back.dtype == (np.float32 if widened else cube.dtype)
    assert_array_equal(back.values, cube.values)
    assert_array_equal(back.wavelength.values, WL)
    if ext != ".npy":
        assert_array_equal(back.fwhm.values, cube.fwhm.values)
    if ext not in (".hdr", ".npy"):
        assert back.attrs["f_number"] == 2.8
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp files


@pytest.mark.parametrize("ext", ["", ".img"])
@pytest.mark.parametrize("interleave", ["bsq", "bil", "bip"])
def test_envi_written_by_spectral_python_is_read(tmp_path, interleave, ext):
    from spectral.io import envi

    data = np.random.default_rng(1).integers(0, 4096, (6, 5, 4)).astype(np.uint16)
    hdr = tmp_path / "scene.hdr"
    envi.save_image(str(hdr), data, interleave=interleave, ext=ext,
                    metadata={"wavelength": [0.5, 0.6, 0.7, 0.8], "wavelength units":
                              "Micrometers", "fwhm": [0.01] * 4})
    cube = read_cube(hdr if not ext else tmp_path / f"scene{ext}")  # header or data file
    assert_array_equal(cube.values, data)
    assert_array_equal(cube.wavelength.values, [500.0, 600.0, 700.0, 800.0])
    assert_array_equal(cube.fwhm.values, 10.0)


@pytest.mark.parametrize("ext", [".hdr", ".npy", ".nc", ".zarr"])
def test_chunked_reading_is_lazy_and_equal(tmp_path, ext):
    import dask.array as da

    cube = _cube(np.float32)
    write_cube(cube, tmp_path / f"c{ext}")
    lazy = read_cube(tmp_path / f"c{ext}", chunks={} if ext == ".zarr" else {"y": 2},
                     wavelength_nm=WL if ext == ".npy" else None)
    assert isinstance(lazy.data, da.Array)  # not read into memory first
    assert_array_equal(lazy.values, cube.values)


def test_envi_units_ignore_value_and_byte_order(tmp_path):
    from spectral.io import envi

    data = np.arange(2 * 3 * 2, dtype=">i2").reshape(2, 3, 2)
    hdr = tmp_path / "be.hdr"
    envi.save_image(str(hdr), data, dtype=">i2", byteorder="big", ext=".img",
                    metadata={"wavelength": [0.5, 0.6], "wavelength units": "um",
                              "data ignore value": 5})
    cube = read_cube(hdr)
    assert cube.dtype == np.int16 and cube.dtype.byteorder in ("=", "|")
    assert_array_equal(cube.values, data.astype(np.int16))
    assert_array_equal(cube.wavelength.values, [500.0, 600.0])
    assert cube.attrs["data_ignore_value"] == 5.0
    hdr.write_text(hdr.read_text().replace("wavelength units = um", "wavelength units = Index"))
    with pytest.raises(ValueError, match="not a length"):
        read_cube(hdr)


def test_envi_writer_guards_its_data_file(tmp_path):
    cube = _cube(np.uint16)
    (tmp_path / "out.raw").write_text("precious")
    with pytest.raises(FileExistsError, match=r"out\.raw"):
        write_cube(cube, tmp_path / "out.hdr")
    assert (tmp_path / "out.raw").read_text() == "precious"
    write_cube(cube, tmp_path / "scene.hdr")
    with pytest.raises(ValueError, match="also an input"):
        write_cube(cube, tmp_path / "scene.hdr", overwrite=True, inputs=[tmp_path / "scene.raw"])


def test_writers_protect_existing_files_and_inputs(tmp_path):
    cube = _cube(np.uint16)
    path = write_cube(cube, tmp_path / "c.nc")
    with pytest.raises(FileExistsError):
        write_cube(cube, path)
    with pytest.raises(ValueError, match="also an input"):
        write_cube(cube, path, overwrite=True, inputs=[path])
    write_cube(cube, path, overwrite=True)


@pytest.mark.parametrize("ext", [".hdr", ".tif", ".exr", ".nc", ".zarr", ".npy"])
def test_writers_refuse_a_folder_that_does_not_exist(tmp_path, ext):
    """A mistyped folder is not made: the writers refuse it, as the command line does, and
    leave nothing behind."""
    cube = _cube(np.float32)
    with pytest.raises(ValueError, match="does not exist; create it first"):
        write_cube(cube, tmp_path / "no" / "such" / f"c{ext}")
    with pytest.raises(ValueError, match="does not exist; create it first"):
        write_toml(tmp_path / "missing" / "p.toml", {"a": 1})
    if ext in (".nc", ".zarr"):
        with pytest.raises(ValueError, match="does not exist; create it first"):
            write_dataset(cube.to_dataset(), tmp_path / "gone" / f"d{ext}")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def _envi(tmp_path, shape=(6, 5, 4)):
    write_cube(make_cube(np.ones(shape, np.uint16), np.linspace(500, 800, shape[2])),
               tmp_path / "e.hdr", overwrite=True)
    return tmp_path / "e.hdr", tmp_path / "e.raw"


def test_bad_files_give_clear_errors(tmp_path):
    hdr, raw = _envi(tmp_path)
    raw.write_bytes(raw.read_bytes()[:-10])
    with pytest.raises(ValueError, match="truncated"):
        read_cube(hdr)
    hdr, raw = _envi(tmp_path)
    hdr.write_text(hdr.read_text().replace("bands = 4", "bands = 5"))
    with pytest.raises(ValueError, match="bytes"):
        read_cube(hdr)
    hdr, raw = _envi(tmp_path)
    text = hdr.read_text()
    start = text.index("wavelength = {")
    end = text.index("}", start)
    hdr.write_text(text[:start] + "wavelength = {500, 600}" + text[end + 1:])
    with pytest.raises(ValueError, match="4 bands but 2 wavelengths"):
        read_cube(hdr)
    with pytest.raises(ValueError, match="unknown cube format"):
        read_cube(tmp_path / "cube.xyz")
    with pytest.raises(FileNotFoundError):
        read_cube(tmp_path / "missing.nc")
    (tmp_path / "junk.tif").write_bytes(b"not a tiff at all")
    with pytest.raises(ValueError, match="cannot read"):
        read_cube(tmp_path / "junk.tif")
    np.save(tmp_path / "flat.npy", np.zeros((3, 4)))
    with pytest.raises(ValueError, match="2-D"):
        read_cube(tmp_path / "flat.npy", wavelength_nm=[500])
    (tmp_path / "bad.hdr").write_text("not an envi header\n")
    with pytest.raises(ValueError, match="cannot read"):
        read_cube(tmp_path / "bad.hdr")
    hdr, raw = _envi(tmp_path)
    raw.unlink()
    with pytest.raises(ValueError, match="cannot read"):
        read_cube(hdr)


# -- sensor positions survive every format ---------------------------------------------------

FORMATS_ALL = [".hdr", ".tif", ".exr", ".nc", ".zarr", ".npy"]


def _mosaic_cube():
    from snapcorr.cube import Sensor, mosaic_to_cube

    sensor = Sensor.load(REPO / "calibration" / "sensors" / "mosaic_4x4_vis.toml")
    frame = np.random.default_rng(3).integers(0, 4096, (32, 48)).astype(np.uint16)
    return mosaic_to_cube(frame, sensor, sensor_origin_px=(8, 12))


def _snapscan_crop():
    """A crop of a Snapscan cube: every band of a pixel at one sensor position."""
    cube = _cube(np.float32)
    ny, nx, nb = cube.shape
    rows = np.repeat((100 + np.arange(ny))[:, None], nb, axis=1)
    cols = np.repeat((40 + np.arange(nx))[:, None], nb, axis=1)
    return with_positions(cube, rows, cols)  # with their CF attributes, as readers give them


def _irregular():
    cube = _cube(np.float32)
    rng = np.random.default_rng(5)
    return with_positions(cube, rng.integers(0, 2048, (5, 4)), rng.integers(0, 2048, (7, 4)))


@pytest.mark.parametrize("ext", FORMATS_ALL)
@pytest.mark.parametrize("make", [_mosaic_cube, _snapscan_crop, _irregular],
                         ids=["mosaic", "snapscan-crop", "irregular"])
def test_sensor_positions_round_trip_exactly(tmp_path, ext, make):
    cube = make()
    path = write_cube(cube, tmp_path / f"c{ext}")
    back = read_cube(path)  # no wavelength_nm: every file snapcorr writes carries them
    for name in ("sensor_row", "sensor_col"):
        xr.testing.assert_identical(back[name], cube[name])
        assert back[name].dtype == np.int64
    assert_array_equal(back.values, cube.values)
    assert_array_equal(back.wavelength.values, cube.wavelength.values)
    assert back.name == cube.name


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
@pytest.mark.parametrize("make", [_mosaic_cube, _snapscan_crop], ids=["mosaic", "snapscan-crop"])
def test_chunked_cubes_with_positions_are_written_like_any_other(tmp_path, ext, make):
    """A dask-backed cube is written in a second pass after its coordinates; that pass once
    gave zarr the positions' encoding again ("variable 'sensor_col' already exists")."""
    from snapcorr.cube import read_dataset, write_dataset

    cube = make().chunk({"y": 2})
    write_cube(cube, tmp_path / f"c{ext}")
    write_dataset(cube.to_dataset(name="reflectance"), tmp_path / f"d{ext}")
    for back in (read_cube(tmp_path / f"c{ext}"), read_dataset(tmp_path / f"d{ext}")):
        for name in ("sensor_row", "sensor_col", "wavelength"):
            assert name in back.coords  # still coordinates, not data variables
            assert_array_equal(back[name].values, cube[name].values)
        values = back.values if isinstance(back, xr.DataArray) else back["reflectance"].values
        assert_array_equal(values, cube.values)


def test_envi_header_stores_positions_compactly_when_they_are_regular(tmp_path):
    write_cube(_mosaic_cube(), tmp_path / "m.hdr")
    text = (tmp_path / "m.hdr").read_text()
    assert "snapcorr sensor row step = 4" in text and "snapcorr sensor col step = 4" in text
    assert "snapcorr sensor row offset = { 8 , 8 , 8 , 8 , 9" in text
    write_cube(_irregular(), tmp_path / "i.hdr")
    text = (tmp_path / "i.hdr").read_text()
    assert "snapcorr sensor row = {" in text and "sensor row offset" not in text


# -- units -----------------------------------------------------------------------------------


@pytest.mark.parametrize("units, scale", [
    ("Nanometers", 1), ("nm", 1), ("Micrometers", 1e-3), ("micrometres", 1e-3),
    ("microns", 1e-3), ("um", 1e-3), ("\u00b5m", 1e-3), ("millimeters", 1e-6), ("mm", 1e-6),
    ("meters", 1e-9), ("metres", 1e-9), ("m", 1e-9), ("Unknown", 1), (None, 1)])
def test_envi_wavelength_units_are_converted_to_nm(tmp_path, units, scale):
    from spectral.io import envi

    meta = {"wavelength": [500 * scale, 600 * scale], "fwhm": [10 * scale, 12 * scale]}
    if units is not None:
        meta["wavelength units"] = units
    envi.save_image(str(tmp_path / "u.hdr"), np.ones((2, 3, 2), np.float32), ext=".raw",
                    metadata=meta)
    cube = read_cube(tmp_path / "u.hdr")
    assert_allclose(cube.wavelength.values, [500.0, 600.0], rtol=0, atol=1e-9)
    assert_allclose(cube.fwhm.values, [10.0, 12.0], rtol=0, atol=1e-9)
    assert cube.wavelength.attrs["units"] == "nm" and cube.fwhm.attrs["units"] == "nm"


def test_micrometres_without_units_are_refused_not_labelled_nm(tmp_path):
    from spectral.io import envi

    envi.save_image(str(tmp_path / "u.hdr"), np.ones((2, 3, 2), np.float32), ext=".raw",
                    metadata={"wavelength": [0.5, 0.6]})
    with pytest.raises(ValueError, match=r"micrometres.*wavelength units") as err:
        read_cube(tmp_path / "u.hdr")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
@pytest.mark.parametrize("units, scale", [("um", 1e-3), ("micrometers", 1e-3), ("nm", 1),
                                          ("m", 1e-9), (None, 1)])
def test_netcdf_and_zarr_wavelength_units_are_converted(tmp_path, ext, units, scale):
    attrs = {} if units is None else {"units": units}
    ds = xr.Dataset({"radiance": (("y", "x", "band"), np.ones((2, 3, 2), np.float32))},
                    coords={"wavelength": ("band", [500 * scale, 600 * scale], attrs),
                            # fwhm without units of its own: in the wavelengths' units
                            "fwhm": ("band", [10 * scale, 12 * scale],
                                     {} if units == "um" else attrs)})
    path = tmp_path / f"u{ext}"
    ds.to_netcdf(path, engine="h5netcdf") if ext == ".nc" else ds.to_zarr(path, consolidated=False)
    cube = read_cube(path)
    assert_allclose(cube.wavelength.values, [500.0, 600.0], rtol=0, atol=1e-9)
    assert_allclose(cube.fwhm.values, [10.0, 12.0], rtol=0, atol=1e-9)
    assert cube.wavelength.attrs["units"] == "nm" and cube.fwhm.attrs["units"] == "nm"


@pytest.mark.parametrize("ext", [".hdr", ".nc"])
def test_unknown_units_are_refused(tmp_path, ext):
    if ext == ".hdr":
        from spectral.io import envi

        envi.save_image(str(tmp_path / "u.hdr"), np.ones((2, 3, 2), np.float32), ext=".raw",
                        metadata={"wavelength": [500, 600], "wavelength units": "furlongs"})
    else:
        xr.Dataset({"radiance": (("y", "x", "band"), np.ones((2, 3, 2), np.float32))},
                   coords={"wavelength": ("band", [500.0, 600.0], {"units": "furlongs"})}
                   ).to_netcdf(tmp_path / "u.nc", engine="h5netcdf")
    with pytest.raises(ValueError, match="'furlongs' are not a length"):
        read_cube(tmp_path / f"u{ext}")
    # wavelengths given by the caller stand in for ones in no length unit
    cube = read_cube(tmp_path / f"u{ext}", wavelength_nm=[510.0, 610.0])
    assert_array_equal(cube.wavelength.values, [510.0, 610.0])


# -- one reader for cubes, flats and frames --------------------------------------------------


def test_flats_read_every_cube_format(tmp_path):
    from snapcorr.calibrate import read_flat

    cube = _cube(np.uint16)
    for ext in FORMATS_ALL:
        write_cube(cube, tmp_path / f"f{ext}")
        image, info = read_flat(tmp_path / f"f{ext}")
        assert info == {"bands": 4, "saturation": 65535}, ext
        assert_allclose(image, cube.values.mean(axis=2, dtype=np.float64))


def _frame_files(tmp_path, frame):
    import OpenImageIO as oiio
    from spectral.io import envi

    np.save(tmp_path / "f2.npy", frame)
    np.save(tmp_path / "f3.npy", frame[:, :, None])
    for ext, typedesc, data in ((".tif", "uint16", frame), (".exr", "float",
                                                            frame.astype(np.float32))):
        out = oiio.ImageOutput.create(str(tmp_path / f"f{ext}"))
        assert out.open(str(tmp_path / f"f{ext}"), oiio.ImageSpec(frame.shape[1],
                                                                 frame.shape[0], 1, typedesc))
        assert out.write_image(np.ascontiguousarray(data[:, :, None]))
        out.close()
    envi.save_image(str(tmp_path / "f.hdr"), frame, dtype=np.uint16, ext=".raw",
                    byteorder="big")
    ds = xr.Dataset({"raw": (("y", "x", "band"), frame[:, :, None])})
    ds.to_netcdf(tmp_path / "f.nc", engine="h5netcdf")
    ds.to_zarr(tmp_path / "f.zarr", consolidated=False)
    return ["f2.npy", "f3.npy", "f.tif", "f.exr", "f.hdr", "f.nc", "f.zarr"]


@pytest.mark.parametrize("chunks", [None, {"y": 4}])
def test_read_frame_from_every_format(tmp_path, chunks):
    import dask.array as da

    frame = np.random.default_rng(8).integers(0, 4096, (10, 7)).astype(np.uint16)
    for name in _frame_files(tmp_path, frame):
        got = read_frame(tmp_path / name, chunks=chunks)
        assert got.dims == ("y", "x") and got.name == "frame", name
        assert isinstance(got.data, da.Array) == (chunks is not None), name
        assert_array_equal(got.values, frame)
    write_cube(_cube(np.uint16), tmp_path / "cube.hdr")
    with pytest.raises(ValueError, match="holds 4 bands; a frame is one 2-D image"):
        read_frame(tmp_path / "cube.hdr")


def _traced_peak(read):
    import tracemalloc

    tracemalloc.start()
    try:
        result = read()
        return result, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("ext", [".hdr", ".npy"])
def test_chunked_envi_and_npy_stay_memory_mapped(tmp_path, ext):
    data = np.random.default_rng(9).random((512, 256, 32), dtype=np.float32)  # 16 MiB
    wl = np.linspace(400, 900, 32)
    write_cube(make_cube(data, wl), tmp_path / f"big{ext}")
    names = [f"big{ext}"]
    if ext == ".hdr":  # big-endian too: swapped block by block, never copied whole
        from spectral.io import envi

        envi.save_image(str(tmp_path / "be.hdr"), data, dtype=">f4", byteorder="big",
                        ext=".raw", metadata={"wavelength": wl})
        names.append("be.hdr")
    for name in names:
        block, peak = _traced_peak(lambda name=name: read_cube(tmp_path / name,
                                                               chunks={"y": 32})[:32].values)
        assert peak < 6 * 2**20, f"{name}: {peak / 2**20:.1f} MiB traced for a 16 MiB file"
        assert_array_equal(block, data[:32])
    frame = data[:, :, 0].copy()
    write_cube(make_cube(np.stack([frame] * 32, axis=2), wl), tmp_path / "wide.hdr")
    np.save(tmp_path / "frame.npy", np.tile(frame, (8, 4)))  # 16 MiB
    block, peak = _traced_peak(lambda: read_frame(tmp_path / "frame.npy",
                                                  chunks={"y": 32})[:32].values)
    assert peak < 6 * 2**20 and block.shape == (32, 1024)


def test_zarr_has_consolidated_metadata_and_both_kinds_are_read(tmp_path):
    import warnings

    from snapcorr.cube import read_dataset

    cube = _cube(np.float32)
    write_cube(cube, tmp_path / "c.zarr")
    assert json.loads((tmp_path / "c.zarr" / "zarr.json").read_text())["consolidated_metadata"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        xr.open_zarr(tmp_path / "c.zarr").close()  # default arguments: no warning
        cube.to_dataset().to_zarr(tmp_path / "plain.zarr", consolidated=False)
        for name in ("c.zarr", "plain.zarr"):
            assert_array_equal(read_cube(tmp_path / name).values, cube.values)
            assert_array_equal(read_dataset(tmp_path / name)["radiance"].values, cube.values)


# -- readers never alter values ---------------------------------------------------------------


def _envi_with(tmp_path, extra, name="e"):
    cube = make_cube(np.arange(2 * 3 * 4, dtype=np.uint16).reshape(2, 3, 4) * 100,
                     [500.0, 600.0, 700.0, 800.0])
    hdr = tmp_path / f"{name}.hdr"
    write_cube(cube, hdr)
    hdr.write_text(hdr.read_text() + extra)
    return hdr, cube.values


def test_an_envi_key_given_twice_is_refused(tmp_path):
    """Spectral Python keeps the last of a repeated key, and the data were read scrambled."""
    hdr, _ = _envi_with(tmp_path, "samples = 2\n")
    with pytest.raises(ValueError, match="gives 'samples' more than once"):
        read_cube(hdr)


@pytest.mark.parametrize("chunks", [None, {"y": 1}])
def test_envi_gains_offsets_scale_and_bad_bands_are_applied(tmp_path, chunks):
    """value = (stored * gain + offset) / reflectance scale factor; bbl 0 bands and pixels at
    the data ignore value (in stored units) are NaN. They were ignored."""
    hdr, raw = _envi_with(tmp_path, "data gain values = {2, 2, 3, 3}\ndata offset values = "
                               "{1, 1, 1, 0}\nreflectance scale factor = 10000\n"
                               "bbl = {1, 0, 1, 1}\ndata ignore value = 0\n")
    got = np.asarray(read_cube(hdr, chunks=chunks).values, float)
    want = (raw * np.array([2, 2, 3, 3]) + np.array([1, 1, 1, 0])) / 10000.0
    want[..., 1] = np.nan
    want[raw == 0] = np.nan
    np.testing.assert_allclose(got, want, rtol=1e-6)
    bad, _ = _envi_with(tmp_path, "data gain values = {2, 2}\n", name="bad")
    with pytest.raises(ValueError, match="'data gain values' has 2 values for 4 bands"):
        read_cube(bad)
    # a flat or a frame is used as stored: such a header is refused there, not half applied
    from snapcorr.calibrate import read_flat

    with pytest.raises(ValueError, match="a flat field is used as stored"):
        read_flat(hdr)
    same, _ = _envi_with(tmp_path, "bbl = {1, 1, 1, 1}\ndata gain values = 1\n", name="same")
    assert read_flat(same)[0].shape == (2, 3)  # identity: nothing to apply


