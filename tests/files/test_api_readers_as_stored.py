"""Readers give the numbers as stored, or refuse: TIFF bit depths and colour models that
OpenImageIO would convert, a description naming another dtype, OpenEXR integer channels beside
float ones, ENVI headers whose comments hide a repeated key, two data files for one header,
netCDF-3 files; and references of a snapshot cube that no positions describe."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from snapcorr.cube import read_cube


def _twelve_bit_tiff(path, values):
    """A one-row, 12-bit, uncompressed grey TIFF written byte by byte (no library writes
    one): the samples packed most significant bit first."""
    bits = "".join(f"{v:012b}" for v in values)
    bits += "0" * (-len(bits) % 8)
    data = int(bits, 2).to_bytes(len(bits) // 8, "big")
    tags = [(256, 3, 1, len(values)), (257, 3, 1, 1), (258, 3, 1, 12), (259, 3, 1, 1),
            (262, 3, 1, 1), (273, 4, 1, 8), (277, 3, 1, 1), (278, 3, 1, 1),
            (279, 4, 1, len(data))]
    ifd = struct.pack("<H", len(tags)) + b"".join(
        struct.pack("<HHII", *t) if t[1] == 4 else struct.pack("<HHIHH", *t, 0) for t in tags)
    path.write_bytes(b"II*\0" + struct.pack("<I", 8 + len(data)) + data + ifd + b"\0" * 4)


def test_a_twelve_bit_tiff_is_refused_not_rescaled(tmp_path):
    _twelve_bit_tiff(tmp_path / "b12.tif", [1, 100, 1000, 4095])
    with pytest.raises(ValueError, match="12-bit samples"):
        read_cube(tmp_path / "b12.tif", wavelength_nm=[550.0])


@pytest.mark.parametrize("kind", ["one_bit", "min_is_white", "cmyk", "palette"])
def test_tiffs_that_would_be_converted_are_refused(tmp_path, kind):
    import tifffile
    from PIL import Image

    path = tmp_path / f"{kind}.tif"
    if kind == "one_bit":
        Image.fromarray(np.array([[0, 1, 0, 1]], bool)).save(path)
        match = "1-bit"
    elif kind == "min_is_white":
        tifffile.imwrite(path, np.array([[0, 10, 200, 255]], np.uint8),
                         photometric="miniswhite")
        match = "min-is-white"
    elif kind == "cmyk":
        Image.fromarray(np.array([[[10, 20, 30, 40]]], np.uint8), "CMYK").save(path)
        match = "CMYK"
    else:
        im = Image.fromarray(np.array([[0, 1, 2, 3]], np.uint8), "P")
        im.putpalette([0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 255])
        im.save(path)
        match = "palette"
    with pytest.raises(ValueError, match=match):
        read_cube(path, wavelength_nm=[500.0, 550.0, 600.0])


def test_grey_and_plain_channel_tiffs_still_read_as_stored(tmp_path):
    import tifffile

    a = (np.arange(24).reshape(2, 3, 4) * 997).astype(np.uint16)
    tifffile.imwrite(tmp_path / "c.tif", a, photometric="minisblack", planarconfig="contig")
    np.testing.assert_array_equal(
        read_cube(tmp_path / "c.tif", wavelength_nm=[500.0, 550.0, 600.0, 650.0]).values, a)


def test_a_description_naming_another_dtype_is_refused(tmp_path):
    """tifffile keeps a description it is given: a cube re-saved in another type under the
    old description must not be cast to the old type (300 as uint8 is 44)."""
    import tifffile

    path = tmp_path / "c.tif"
    tifffile.imwrite(path, np.full((1, 2, 3), 300, np.uint16), photometric="minisblack",
                     planarconfig="contig", metadata={"dtype": "uint8"})
    with pytest.raises(ValueError, match="says uint8 but the file stores uint16"):
        read_cube(path, wavelength_nm=[500.0, 550.0, 600.0])


def test_an_exr_uint_channel_beside_a_float_one_is_read_as_stored(tmp_path):
    import OpenImageIO as oiio

    path = tmp_path / "mix.exr"
    spec = oiio.ImageSpec(2, 1, 2, "float")
    spec.channelnames = ("band1", "band2")
    spec.channelformats = (oiio.TypeDesc("uint"), oiio.TypeDesc("float"))
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    big = 4294967295.0  # OpenImageIO stores a float as uint normalised to [0, 1]
    out.write_image(np.array([[[1000 / big, 0.5], [3000000000 / big, 0.25]]]))
    out.close()
    inp = oiio.ImageInput.open(str(path))
    stored = np.asarray(inp.read_image(0, 0, 0, 1, "uint")).ravel()
    inp.close()
    got = read_cube(path, wavelength_nm=[500.0, 600.0]).values
    np.testing.assert_array_equal(got[0, :, 0], stored)
    np.testing.assert_array_equal(got[0, :, 1], [0.5, 0.25])


def _envi(tmp_path, name="d", data=None):
    import spectral.io.envi as envi

    data = (np.arange(8, dtype=np.uint16) * 100).reshape(2, 2, 2) if data is None else data
    envi.save_image(str(tmp_path / f"{name}.hdr"), data, dtype=np.uint16, ext=".raw",
                    force=True, metadata={"wavelength": [500, 600], "wavelength units": "nm"})
    return data


def test_a_comment_with_a_brace_does_not_hide_a_repeated_key(tmp_path):
    """Comment lines are skipped as Spectral Python skips them: a ``{`` in one does not open a
    value that would swallow the keys after it."""
    _envi(tmp_path)
    hdr = tmp_path / "d.hdr"
    text = hdr.read_text().replace("byte order = 0",
                                   "; lab notes {see book\nbyte order = 0\nbyte order = 1")
    hdr.write_text(text)
    with pytest.raises(ValueError, match="'byte order' more than once"):
        read_cube(hdr)


def test_a_comment_with_a_brace_alone_is_harmless(tmp_path):
    data = _envi(tmp_path)
    hdr = tmp_path / "d.hdr"
    hdr.write_text(hdr.read_text().replace("byte order = 0", "; notes {see book\nbyte order = 0"))
    np.testing.assert_array_equal(read_cube(hdr).values, data)


def test_two_data_files_for_one_header_are_refused_and_each_reads_by_name(tmp_path):
    data = _envi(tmp_path, "e")
    stale = np.full(data.shape, 7, np.uint16)
    (tmp_path / "e.img").write_bytes(stale.transpose(2, 0, 1).tobytes())  # same size, bsq
    with pytest.raises(ValueError, match=r"more than one data file .*e\.img, e\.raw"):
        read_cube(tmp_path / "e.hdr")
    np.testing.assert_array_equal(read_cube(tmp_path / "e.raw").values, data)
    np.testing.assert_array_equal(read_cube(tmp_path / "e.img").values, stale)


def test_a_netcdf3_file_is_read_as_stored(tmp_path):
    import xarray as xr

    a = (np.arange(24).reshape(2, 3, 4) * 7).astype(np.int16)
    xr.DataArray(a, dims=("y", "x", "band"), name="radiance",
                 coords={"wavelength": ("band", [500.0, 600.0, 700.0, 800.0])}).to_netcdf(
        tmp_path / "n3.nc", engine="scipy")
    for chunks in (None, "rows"):
        got = read_cube(tmp_path / "n3.nc", chunks=chunks)
        assert got.dtype == np.int16
        np.testing.assert_array_equal(got.values, a)


def test_a_snapshot_white_one_row_short_is_refused_without_positions(tmp_path, cli):
    """Bare arrays cut from a mosaic camera's cube carry no positions; the sensor's layout
    still says it is a snapshot, which has no scan axis to average a strip along."""
    from snapcorr.cube import Sensor, mosaic_to_cube
    from snapcorr.data import mosaic_frames, sensor_path

    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    raw, dark, white = mosaic_frames("mosaic_4x4_vis")

    def cube(frame):
        return mosaic_to_cube(frame[100:164, 200:264], sensor, sensor_origin_px=(100, 200)).values

    np.save(tmp_path / "raw.npy", cube(raw))
    np.save(tmp_path / "dark.npy", cube(dark))
    np.save(tmp_path / "white.npy", cube(white)[:15])
    res = cli("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy",
              "--sensor", "mosaic_4x4_vis", "--out", "m.nc", cwd=tmp_path)
    assert res.returncode == 1 and "a snapshot has no scan axis" in res.stderr, res.stderr
    assert not (tmp_path / "m.nc").exists()


def test_a_two_dimensional_array_is_explained_in_command_line_terms(tmp_path, cli):
    np.save(tmp_path / "f.npy", np.ones((12, 10), np.uint16))
    res = cli("budget", "--sensor", "snapscan_vnir", "--lens", "edmund_optics_16mm",
              "--f-number", "2", "--source", "cube", "--cube", "f.npy", cwd=tmp_path)
    assert res.returncode == 1 and "read_frame" not in res.stderr
    assert "--sensor" in res.stderr and "Traceback" not in res.stderr


@pytest.mark.parametrize("ext", [".tif", ".exr"])
def test_half_floats_with_nan_keep_their_described_type(tmp_path, ext):
    """OpenImageIO gives half floats as float32; the description's float16 converts back
    exactly, NaN included."""
    from snapcorr.cube import make_cube, write_cube

    a = np.linspace(0, 1, 24, dtype=np.float16).reshape(3, 4, 2)
    a[1, 1, 1] = np.nan
    write_cube(make_cube(a, [500.0, 600.0]), tmp_path / f"h{ext}")
    got = read_cube(tmp_path / f"h{ext}")
    assert got.dtype == np.float16
    np.testing.assert_array_equal(got.values, a)


def test_a_file_from_another_sensor_is_refused_by_its_band_count(tmp_path, cli):
    """A file carrying its own wavelengths wins over the sensor's only where they agree in
    number: a 6-band file under a 150-band sensor is refused, not read as it is."""
    from snapcorr.cube import make_cube, write_cube

    write_cube(make_cube(np.ones((4, 5, 6), np.float32), np.linspace(500, 600, 6)),
               tmp_path / "six.nc")
    with pytest.raises(ValueError, match="6 bands but wavelength_nm gives 16"):
        read_cube(tmp_path / "six.nc", wavelength_nm=np.linspace(400, 500, 16))
    res = cli("flatfield", "six.nc", "--dark", "six.nc", "--white", "six.nc",
              "--sensor", "snapscan_vnir", "--out", "ff.nc", cwd=tmp_path)
    assert res.returncode == 1 and "but the --sensor has 150" in res.stderr, res.stderr
