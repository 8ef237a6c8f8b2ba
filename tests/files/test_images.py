"""TIFF and OpenEXR cubes and frames: files OpenImageIO, tifffile and PIL wrote read back as
they stored them (pages, channels, alpha, the channels' order), what snapcorr writes read by
OpenImageIO and tifffile (the spectral layout of Fichet et al. 2021, the JSON description),
and layouts that cannot be told refused."""

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from snapcorr.cube import make_cube, read_frame
from snapcorr.files import read_cube, write_cube

WL = np.array([470.5, 500.0, 650.25, 900.0])


def _cube(dtype, name="radiance"):
    rng = np.random.default_rng(7)
    data = rng.uniform(0, 250, (5, 7, WL.size)).astype(dtype)
    return make_cube(data, WL, fwhm_nm=[10.0, 11.0, 12.0, 13.0], attrs={"f_number": 2.8},
                     name=name)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_a_tiff_snapcorr_writes_is_what_tifffile_reads(tmp_path, dtype):
    """One page, a channel per band (contiguous), the values as they are, and the cube's
    metadata as JSON in the image description. (Integers only: the floating-point predictor
    OpenImageIO writes floats with needs imagecodecs to be read by tifffile.)"""
    import tifffile

    cube = _cube(dtype)
    write_cube(cube, tmp_path / "c.tif")
    with tifffile.TiffFile(tmp_path / "c.tif") as tif:
        assert len(tif.pages) == 1
        page = tif.pages[0]
        assert_array_equal(page.asarray(), cube.values)
        meta = json.loads(page.description)
    assert meta["written_by"].startswith("snapcorr")
    assert_array_equal(meta["wavelength_nm"], WL)
    assert_array_equal(meta["fwhm_nm"], [10.0, 11.0, 12.0, 13.0])


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


def test_exr_keeps_band_order_and_widths(tmp_path):
    cube = make_cube(np.arange(3 * 2 * 3, dtype=np.float32).reshape(3, 2, 3),
                     [700.25, 500.5, 600.0], fwhm_nm=[7.0, 5.0, 6.0])
    write_cube(cube, tmp_path / "u.exr")
    back = read_cube(tmp_path / "u.exr")
    assert_array_equal(back.wavelength.values, [700.25, 500.5, 600.0])
    assert_array_equal(back.fwhm.values, [7.0, 5.0, 6.0])
    assert_array_equal(back.values, cube.values)


def _pages(path, pages, nchannels=1):
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    specs = []
    for p in pages:
        spec = oiio.ImageSpec(p.shape[1], p.shape[0], nchannels, "uint16")
        specs.append(spec)
    assert out.open(str(path), specs)
    for i, p in enumerate(pages):
        if i:
            assert out.open(str(path), specs[i], "AppendSubimage")
        assert out.write_image(np.ascontiguousarray(p.reshape(p.shape[0], p.shape[1], -1)))
    out.close()


def test_multipage_tiff_is_one_band_per_page_for_cubes_and_flats(tmp_path):
    from snapcorr.calibrate import read_flat

    rng = np.random.default_rng(4)
    pages = [rng.integers(0, 4000, (6, 9)).astype(np.uint16) for _ in range(3)]
    _pages(tmp_path / "p.tif", pages)
    cube = read_cube(tmp_path / "p.tif", wavelength_nm=[500, 600, 700])
    assert_array_equal(cube.values, np.stack(pages, axis=2))
    image, info = read_flat(tmp_path / "p.tif")
    assert info == {"bands": 3, "saturation": 65535}
    assert_allclose(image, np.mean(np.stack(pages, axis=2), axis=2, dtype=np.float64))
    with pytest.raises(ValueError, match="holds 3 bands"):
        read_frame(tmp_path / "p.tif")
    _pages(tmp_path / "sizes.tif", [pages[0], pages[1][:5]])
    with pytest.raises(ValueError, match=r"every page .* must match"):
        read_cube(tmp_path / "sizes.tif", wavelength_nm=[500, 600])
    _pages(tmp_path / "rgb.tif", [np.ones((4, 5, 3), np.uint16)] * 2, nchannels=3)
    with pytest.raises(ValueError, match="page 1 has 3 channels"):
        read_flat(tmp_path / "rgb.tif")


def test_an_unassociated_alpha_leaves_the_other_bands_as_stored(tmp_path):
    """PIL writes RGBA (and LA) TIFFs with an unassociated alpha; OpenImageIO by default
    multiplies every other channel by it. The bands come back as stored."""
    from PIL import Image

    from snapcorr.cube import read_frame

    a = np.zeros((4, 5, 4), np.uint8)
    a[..., 0], a[..., 1], a[..., 2], a[..., 3] = 200, 100, 50, 128
    Image.fromarray(a, "RGBA").save(tmp_path / "rgba.tif")
    cube = read_cube(tmp_path / "rgba.tif", wavelength_nm=[500.0, 600.0, 700.0, 800.0])
    np.testing.assert_array_equal(cube.values, a)
    Image.fromarray(a[..., [0, 3]], "LA").save(tmp_path / "la.tif")
    frame = read_frame(tmp_path / "la.tif")
    np.testing.assert_array_equal(np.asarray(frame.values), a[..., 0])


def _exr(path, names):
    import OpenImageIO as oiio

    img = np.zeros((3, 4, len(names)), np.float32)
    img[...] = np.arange(len(names), dtype=np.float32)  # each channel holds its written index
    spec = oiio.ImageSpec(4, 3, len(names), "float")
    spec.channelnames = tuple(names)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_image(img)
    out.close()


def test_exr_channels_come_back_in_the_bands_order_or_are_refused(tmp_path):
    """OpenEXR keeps channels sorted by name: band1, band10, band11, band2, ... came back in
    that order with the wavelengths assigned to it. Numbered channels are put in their
    numbers' order; names that say no order are refused."""
    _exr(tmp_path / "b.exr", [f"band{i + 1}" for i in range(12)])
    cube = read_cube(tmp_path / "b.exr", wavelength_nm=500.0 + 10 * np.arange(12))
    np.testing.assert_array_equal(cube.values[0, 0], np.arange(12))
    _exr(tmp_path / "c.exr", ["red", "green", "blue"])
    with pytest.raises(ValueError, match="do not say the bands' order"):
        read_cube(tmp_path / "c.exr", wavelength_nm=[600.0, 550.0, 450.0])


@pytest.mark.filterwarnings("ignore:<tifffile.TiffWriter.write> data with shape")
def test_a_tifffile_array_whose_band_axis_cannot_be_told_is_refused(tmp_path):
    """tifffile stores a (4, 5, 6) array as 4 planes of 5 x 6 and records the shape it was
    given; read by the file's layout it came back as 5 x 6 pixels of 4 bands, although the
    writer meant 4 x 5 pixels of 6. Contiguous samples read as written."""
    import tifffile

    a = np.arange(4 * 5 * 6, dtype=np.uint16).reshape(4, 5, 6)
    tifffile.imwrite(tmp_path / "planes.tif", a)
    with pytest.raises(ValueError, match=r"shape \(4, 5, 6\) and stored it as 4 planes"):
        read_cube(tmp_path / "planes.tif", wavelength_nm=500.0 + 10 * np.arange(4))
    tifffile.imwrite(tmp_path / "pages.tif", a, photometric="minisblack")  # 4 pages of 5 x 6
    with pytest.raises(ValueError, match=r"shape \(4, 5, 6\) and stored it as 4 planes"):
        read_cube(tmp_path / "pages.tif", wavelength_nm=500.0 + 10 * np.arange(4))
    tifffile.imwrite(tmp_path / "contig.tif", a, photometric="minisblack",
                     planarconfig="contig")
    cube = read_cube(tmp_path / "contig.tif", wavelength_nm=500.0 + 10 * np.arange(6))
    assert_array_equal(cube.values, a)


@pytest.mark.parametrize("number", ["9" * 250, "0", "0,0", "5", "99999999"],
                         ids=["250-digits", "0", "0,0", "5", "1e8"])
def test_an_exr_channel_whose_number_is_no_wavelength_is_refused(tmp_path, number):
    """A channel's name is the band's wavelength: 250 digits (1e250 nm), 0 or 5 nm were taken
    as wavelengths; refused, naming the file and the channel."""
    _exr(tmp_path / "w.exr", [f"S0.{number}nm", "S0.500nm"])
    with pytest.raises(ValueError, match=r"w\.exr: channel 'S0\.[0-9,]{1,8}.*no wavelength"):
        read_cube(tmp_path / "w.exr")


def test_a_channel_number_beyond_a_float_is_refused():
    """400 digits parse as infinity (OpenEXR cuts names at 255 characters, other layouts do
    not): refused as no wavelength, as 0 is."""
    from snapcorr.files.images import _channel_wavelengths

    for text in ("9" * 400, "0", "nan", "inf"):
        with pytest.raises(ValueError, match=r"c\.tif: channel .* no wavelength"):
            _channel_wavelengths("c.tif", [f"{text}nm"], [text])
    assert_array_equal(_channel_wavelengths("c.tif", ["500nm"], ["500"]), [500.0])


def test_a_description_whose_wavelengths_are_no_numbers_is_refused(tmp_path):
    """The JSON description's wavelength_nm as strings ("1e999": infinity) were cast to
    floats unchecked."""
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(4, 3, 2, "float")
    spec.attribute("ImageDescription", json.dumps({"wavelength_nm": ["1e999", "500"]}))
    out = oiio.ImageOutput.create(str(tmp_path / "d.tif"))
    assert out.open(str(tmp_path / "d.tif"), spec)
    assert out.write_image(np.ones((3, 4, 2), np.float32))
    out.close()
    with pytest.raises(ValueError, match=r"d\.tif: the description's wavelength_nm must be "
                                         "finite"):
        read_cube(tmp_path / "d.tif")


@pytest.mark.parametrize("odd", ["S0." + "9" * 300 + "nm", "S0.500", "T.abcnm"],
                         ids=["cut-at-255", "no-unit", "letters"])
def test_a_spectral_channel_that_gives_no_wavelength_is_refused_not_dropped(tmp_path, odd):
    """A channel named as a band (S0., T.) whose wavelength is lost (OpenEXR cuts a 300-digit
    name at 255 characters, leaving no 'nm') was dropped without a word beside the bands
    that parse: the cube lost a band. Refused, naming it; other channels (R, G, B) are still
    left out."""
    _exr(tmp_path / "w.exr", [odd, "S0.500nm", "S0.600nm"])
    with pytest.raises(ValueError, match=r"w\.exr: channel 'S0\.|w\.exr: channel 'T\."):
        read_cube(tmp_path / "w.exr")
    _exr(tmp_path / "rgb.exr", ["S0.500nm", "S0.600nm", "R"])
    assert_array_equal(read_cube(tmp_path / "rgb.exr").wavelength, [500.0, 600.0])
