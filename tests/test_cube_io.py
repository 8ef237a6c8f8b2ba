"""Cube files: round trips in every format and dtype, files written by the libraries' own
writers, and bad files refused with a clear error."""

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from snapcorr.cube import make_cube
from snapcorr.cube.io import read_cube, write_cube

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
    assert back.dtype == cube.dtype
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


def test_tiff_written_by_openimageio_is_read(tmp_path):
    import OpenImageIO as oiio

    data = np.random.default_rng(2).integers(0, 60000, (4, 6, 5)).astype(np.uint16)
    path = tmp_path / "plain.tif"
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(6, 4, 5, "uint16"))
    assert out.write_image(data)
    out.close()
    with pytest.raises(ValueError, match="pass wavelength_nm"):
        read_cube(path)
    cube = read_cube(path, wavelength_nm=[500, 550, 600, 650, 700])
    assert_array_equal(cube.values, data)


def test_exr_follows_the_spectral_layout(tmp_path):
    import OpenImageIO as oiio

    path = tmp_path / "r.exr"
    write_cube(_cube(np.float32, name="reflectance"), path)
    spec = oiio.ImageInput.open(str(path)).spec()
    assert spec.getattribute("spectralLayoutVersion") == "1.0"
    assert "T.470,5nm" in spec.channelnames and "T.900,0nm" in spec.channelnames
    write_cube(_cube(np.float32), tmp_path / "e.exr")
    spec = oiio.ImageInput.open(str(tmp_path / "e.exr")).spec()
    assert "S0.650,25nm" in spec.channelnames
    assert spec.getattribute("emissiveUnits") == "W.m^-2.sr^-1"


@pytest.mark.parametrize("ext", [".hdr", ".npy", ".nc", ".zarr"])
def test_chunked_reading_is_lazy_and_equal(tmp_path, ext):
    import dask.array as da

    cube = _cube(np.float32)
    write_cube(cube, tmp_path / f"c{ext}")
    lazy = read_cube(tmp_path / f"c{ext}", chunks={} if ext == ".zarr" else {"y": 2},
                     wavelength_nm=WL if ext == ".npy" else None)
    assert isinstance(lazy.data, da.Array)  # not read into memory first
    assert_array_equal(lazy.values, cube.values)


def test_exr_keeps_band_order_and_widths(tmp_path):
    cube = make_cube(np.arange(3 * 2 * 3, dtype=np.float32).reshape(3, 2, 3),
                     [700.25, 500.5, 600.0], fwhm_nm=[7.0, 5.0, 6.0])
    write_cube(cube, tmp_path / "u.exr")
    back = read_cube(tmp_path / "u.exr")
    assert_array_equal(back.wavelength.values, [700.25, 500.5, 600.0])
    assert_array_equal(back.fwhm.values, [7.0, 5.0, 6.0])
    assert_array_equal(back.values, cube.values)


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


def test_boolean_attributes_survive_netcdf(tmp_path):
    cube = _cube(np.float32)
    cube.attrs["calibrated"] = True
    write_cube(cube, tmp_path / "b.nc")
    assert read_cube(tmp_path / "b.nc").attrs["calibrated"] == 1


def test_writers_protect_existing_files_and_inputs(tmp_path):
    cube = _cube(np.uint16)
    path = write_cube(cube, tmp_path / "c.nc")
    with pytest.raises(FileExistsError):
        write_cube(cube, path)
    with pytest.raises(ValueError, match="also an input"):
        write_cube(cube, path, overwrite=True, inputs=[path])
    write_cube(cube, path, overwrite=True)


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
