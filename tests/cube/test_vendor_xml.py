"""The vendor's sensor calibration file: a real one (older variant), fixtures of both variants
written from their description, sensor TOMLs that name a file, and malformed or hostile files
refused in one line."""

import numpy as np
import pytest
from conftest import VENDOR_XML
from mosaicsim import read_older
from numpy.testing import assert_array_equal
from vendorfiles import imec_4x4, write_newer, write_older

from snapcorr.cube import Sensor
from snapcorr.cube.vendor_xml import read_vendor_file


def test_the_real_older_file_reads_as_its_elements_say():
    cal = read_vendor_file(VENDOR_XML)
    plain = read_older(VENDOR_XML)  # the standard library, element by element
    curves, bp, coeffs = plain.curves, plain.bandpass, plain.coefficients
    wl, peaks = plain.virtual_nm, plain.peaks_nm
    assert cal.variant == "older"
    assert cal.size_px == (1088, 2048) and cal.pixel_pitch_um is None  # the file says 0
    assert cal.filter_area_px == (3, 0, 1080, 2045) and cal.mosaic_shape == (5, 5)
    assert_array_equal(cal.responses.wavelength_nm, np.arange(400.0, 1001.0))
    assert_array_equal(cal.responses.curves, curves)  # values as written, none altered
    assert_array_equal(cal.responses.system, bp)
    assert cal.responses.system.min() < 0  # the measured band-pass's noise is kept as it is
    (m,) = cal.matrices
    assert (m.name, m.kind) == ("custom", "irradiance")
    assert_array_equal(m.coefficients, coeffs)
    assert_array_equal(m.wavelength_nm, wl)
    assert np.all(m.fwhm_nm == 15.0)
    assert m.coefficients[0, 11] == 9.6813e-005  # the file's "9.6813e-005"
    sensor = Sensor.load(VENDOR_XML)
    # the bands in order of wavelength, each with its number in the file
    v = list(sensor.vendor_band)
    assert sorted(v) == list(range(25)) and np.all(np.diff(sensor.cwl_nm) > 0)
    assert sensor.cwl_nm == tuple(np.asarray(peaks)[v]) and sensor.n_eff is None
    assert sensor.band_offset[v.index(7)] == (1, 2) and sensor.profile == "measured"
    assert_array_equal(sensor.matrices[0].coefficients, coeffs[:, v])
    assert_array_equal(sensor.responses.curves, curves[v])
    # why it is an irradiance matrix: it turns the measured responses (band-pass included)
    # into single peaks of about 1 at its virtual bands, and its rows do not sum to 1 (a
    # matrix for flat-fielded values would leave a flat spectrum flat)
    virtual = coeffs @ (curves * bp)
    assert np.all(np.abs(np.argmax(virtual, axis=1) + 400 - wl) <= 5)
    assert np.all((virtual.max(axis=1) > 0.7) & (virtual.max(axis=1) < 1.8))
    assert np.all(np.abs(coeffs.sum(axis=1)) < 0.1)


@pytest.mark.parametrize("write", [write_newer, write_older], ids=["newer", "older"])
def test_both_variants_give_back_what_was_written(tmp_path, write):
    fx = imec_4x4()
    fx.area = (2, 1, 1084, 2044)
    sensor = Sensor.load(write(tmp_path / "s.xml", fx))
    r = sensor.responses
    v = list(sensor.vendor_band)  # the bands in order of wavelength: the file's numbers
    assert_array_equal(r.wavelength_nm, fx.grid)
    assert_array_equal(r.curves, fx.curves[v])
    bp = np.interp(fx.grid, fx.components[0][1], fx.components[0][2])
    np.testing.assert_allclose(r.system, bp, rtol=0, atol=1e-15)
    assert sensor.filter_area_px == (2, 1, 1084, 2044) and sensor.tile_origin_px == (2, 1)
    assert sensor.size_px == (1088, 2048) and sensor.pixel_pitch_um == 5.5
    assert sensor.band_offset[v.index(6)] == (1, 2)
    assert sensor.cwl_nm == tuple(fx.peaks[i][0][0] for i in v)
    # band 3's second peak (the leak) lies outside the band-pass: its main peak is the first
    assert sensor.cwl_nm[v.index(3)] == fx.peaks[3][0][0]
    names = [m.name for m in sensor.matrices]
    if write is write_newer:
        assert names == ["hsi_reflectance", "hsi_irradiance"]
        assert [m.kind for m in sensor.matrices] == ["reflectance", "irradiance"]
        for m, (_, _, wl, fw, coeffs) in zip(sensor.matrices, fx.matrices, strict=True):
            assert_array_equal(m.coefficients, coeffs[:, v])
            assert_array_equal(m.wavelength_nm, wl)
            assert_array_equal(m.fwhm_nm, fw)
    else:
        assert names == ["custom"] and sensor.matrices[0].kind == "irradiance"
        assert_array_equal(sensor.matrices[0].coefficients, fx.matrices[-1][4][:, v])


def test_a_main_peak_is_the_strongest_inside_the_pass_band(tmp_path):
    fx = imec_4x4()
    fx.peaks[0] = [(900.0, 30.0, 80.0), (fx.peaks[0][0][0], 8.0, 40.0)]  # stronger, outside
    sensor = Sensor.load(write_newer(tmp_path / "s.xml", fx))
    b = sensor.vendor_band.index(0)
    assert sensor.cwl_nm[b] == fx.peaks[0][1][0] and sensor.fwhm_nm[b] == 8.0


# -- sensor TOMLs naming a vendor file ----------------------------------------------------------


def test_a_toml_names_the_file_and_adds_what_it_lacks(tmp_path):
    (tmp_path / "cal").mkdir()
    xml = write_newer(tmp_path / "cal" / "s.xml", imec_4x4())
    (tmp_path / "s.toml").write_text('[sensor]\nvendor_file = "cal/s.xml"\nname = "mine"\n'
                                     "n_eff = 1.75\npixel_pitch_um = 5.6\n"
                                     "[calibration]\nn_eff = \"guessed\"\n")
    s = Sensor.load(tmp_path / "s.toml")
    plain = Sensor.load(xml)
    assert s.name == "mine" and s.n_eff == (1.75,) * 16 and s.pixel_pitch_um == 5.6
    assert s.responses == plain.responses and s.matrices == plain.matrices
    assert s.cwl_nm == plain.cwl_nm and s.calibration == {"n_eff": "guessed"}
    # written elsewhere, it still names the same file, relative to where it now is
    (tmp_path / "elsewhere").mkdir()
    s.save(tmp_path / "elsewhere" / "t.toml")
    assert Sensor.load(tmp_path / "elsewhere" / "t.toml") == s
    assert "../cal/s.xml" in (tmp_path / "elsewhere" / "t.toml").read_text()


@pytest.mark.parametrize("line, words", [
    ('cwl_nm = [500.0]', "may add or override only"),
    ('vendor_file = 3', "vendor_file must be"),
    ('vendor_file = "missing.xml"', "not found"),
    ('n_eff = "1.7"', "n_eff"),
    ('n_eff = 0.9', "n_eff"),
    ('pixel_pitch_um = -1', "pixel_pitch_um"),
])
def test_a_toml_naming_a_file_is_checked(tmp_path, line, words):
    write_newer(tmp_path / "s.xml", imec_4x4())
    key = line.split(" =")[0]
    body = '[sensor]\nvendor_file = "s.xml"\n' if key != "vendor_file" else "[sensor]\n"
    (tmp_path / "s.toml").write_text(body + line + "\n")
    with pytest.raises((ValueError, FileNotFoundError), match=words):
        Sensor.load(tmp_path / "s.toml")


def test_a_sensor_file_refuses_tables_outside_sensor_and_calibration(tmp_path):
    (tmp_path / "s.toml").write_text('[sensor]\nvendor_file = "s.xml"\n[sensors]\nn_eff = 1.7\n')
    with pytest.raises(ValueError, match=r"unknown top-level.*sensors"):
        Sensor.load(tmp_path / "s.toml")


def test_what_needs_n_eff_or_the_pitch_says_how_to_give_them():
    s = Sensor.load(VENDOR_XML)
    with pytest.raises(ValueError, match=r"n_eff.*snapcorr pupil --fit-n-eff"):
        s.require("n_eff", "the shift")
    with pytest.raises(ValueError, match=r"pixel_pitch_um.*vendor_file"):
        s.require("pixel_pitch_um", "the chief-ray angle")


# -- malformed and hostile files ------------------------------------------------------------------


NEWER_BROKEN = [
    (dict(drop=["sensor_info"]), "sensor_info> is missing"),
    (dict(drop=["height_px"]), "height_px> is missing"),
    (dict(drop=["calibration_info"]), "calibration_info> is missing"),
    (dict(drop=["pattern_width"]), "pattern_width> is missing"),
    (dict(drop=["filter_area"]), "filter_area> is missing"),
    (dict(drop=["peaks"]), "peaks> is missing"),
    (dict(drop=["response"]), "response> is missing"),
    (dict(drop=["coefficients"]), "coefficients> is missing"),
    (dict(drop=["band"]), "bands"),  # 15 bands for a 4 x 4 tile
    (dict(replace={"<pattern_width>4": "<pattern_width>5"}), "a 20-band tile"),
    (dict(replace={'<band index="1">': '<band index="0">'}), "band 0 twice"),
    (dict(replace={'<band index="1">': '<band index="one">'}), "whole-number"),
    (dict(replace={'<response values="': '<response values="0.5 '}), "602 values, expected 601"),
    (dict(replace={'<coefficients values="': '<coefficients values="1.0 '}),
     "17 values, expected 16"),
    (dict(replace={'<response values="': '<response values="abc '}), "602 values, expected 601"),
    (dict(replace={'sample_points_nm values="400.0 ': 'sample_points_nm values="abc '}),
     "'abc', not a number"),
    (dict(replace={'sample_points_nm values="400.0 ': 'sample_points_nm values="nan '}),
     "not finite"),
    (dict(replace={"<width_px>2048": "<width_px>wide"}), "width_px> must be a number"),
    (dict(replace={"<height_px>1088": "<height_px>1088.5"}), "whole number"),
    (dict(replace={'sample_points_nm values="400.0 401.0': 'sample_points_nm values="401.0 400.0'}),
     "increasing"),
    (dict(replace={'layout="MOSAIC"': 'layout="TILED"'}), "layout TILED"),
    (dict(extra_zone=True), "2 filter zones"),
    (dict(replace={"<type>reflectance": "<type>radiance"}), "reflectance or irradiance"),
    (dict(replace={"<offset_y>0": "<offset_y>10"}), "extends beyond"),
    (dict(replace={"<wavelength_nm>": "<wavelength_nm>-"}), "not a wavelength"),
]


@pytest.mark.parametrize("how, words", NEWER_BROKEN,
                         ids=[w.replace(" ", "-") for _, w in NEWER_BROKEN])
def test_a_malformed_newer_file_is_refused_in_one_line(tmp_path, how, words):
    fx = imec_4x4()
    path = write_newer(tmp_path / "bad.xml", fx, **how)
    with pytest.raises(ValueError, match=words) as info:
        Sensor.load(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith("bad.xml: ")


OLDER_BROKEN = [
    (dict(drop=["nr_measurements"]), "nr_measurements> is missing"),
    (dict(replace={"<nr_measurements>601": "<nr_measurements>600"}), "600"),
    (dict(replace={"<filter_width>1": "<filter_width>2"}), "several pixels"),
    (dict(replace={'layout="MOSAIC"': 'layout="WEDGE"'}), "layout WEDGE"),
    (dict(drop=["response_composition"]), "response_composition> is missing"),
    (dict(replace={"<filter_response><data>": "<filter_response><data>1.0, "}),
     "holds 602 values"),
    (dict(replace={"<custom_spectral_correction><data>": "<custom_spectral_correction><data>"
                   "1e400, "}), "17 values|not finite"),
]


@pytest.mark.parametrize("how, words", OLDER_BROKEN,
                         ids=[w.split("|")[0].replace(" ", "-") for _, w in OLDER_BROKEN])
def test_a_malformed_older_file_is_refused_in_one_line(tmp_path, how, words):
    path = write_older(tmp_path / "bad.xml", imec_4x4(), **how)
    with pytest.raises(ValueError, match=words) as info:
        Sensor.load(path)
    assert "\n" not in str(info.value)


def test_files_that_are_not_calibration_files(tmp_path):
    (tmp_path / "a.xml").write_text("<lens_profile/>")
    with pytest.raises(ValueError, match="root element <lens_profile>"):
        Sensor.load(tmp_path / "a.xml")
    (tmp_path / "b.xml").write_text("<sensor_calibration><unclosed>")
    with pytest.raises(ValueError, match="not well-formed XML"):
        Sensor.load(tmp_path / "b.xml")
    (tmp_path / "c.xml").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00")
    with pytest.raises(ValueError, match="not well-formed XML"):
        Sensor.load(tmp_path / "c.xml")
    (tmp_path / "d.xml").mkdir()
    with pytest.raises(ValueError, match="is a folder"):
        Sensor.load(tmp_path / "d.xml")
    with pytest.raises(FileNotFoundError, match="not found"):
        Sensor.load(tmp_path / "missing.xml")


def test_entity_expansion_is_refused_not_expanded(tmp_path):
    lol = ('<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol">'
           '<!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">'
           '<!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">]>'
           "<sensor_calibration>&lol3;</sensor_calibration>")
    (tmp_path / "lol.xml").write_text(lol)
    with pytest.raises(ValueError, match=r"refused: it declares entities \(<!ENTITY \.\.\.>\), "
                                         "text the parser would expand in place"):
        Sensor.load(tmp_path / "lol.xml")
    ext = ('<?xml version="1.0"?><!DOCTYPE s [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
           "<sensor_calibration>&x;</sensor_calibration>")
    (tmp_path / "ext.xml").write_text(ext)
    with pytest.raises(ValueError, match=r"refused: it (declares entities|refers to an external)"):
        Sensor.load(tmp_path / "ext.xml")


def test_a_fifo_is_refused_before_it_is_opened(tmp_path):
    import os

    os.mkfifo(tmp_path / "f.xml")
    with pytest.raises(ValueError, match="not a regular file"):
        Sensor.load(tmp_path / "f.xml")


def test_the_sensor_files_documented_in_calibration_readme_load(tmp_path):
    """Every [sensor] TOML block of calibration/README.md, the template included, loads; the
    vendor one names the bundled file."""
    import re

    from conftest import REPO

    text = (REPO / "calibration" / "README.md").read_text()
    blocks = [b for b in re.findall(r"```toml\n(.*?)```", text, re.S) if "[sensor]" in b]
    assert len(blocks) == 2
    for k, block in enumerate(blocks):
        block = block.replace('vendor_file = "', f'vendor_file = "{VENDOR_XML.parent}/')
        (tmp_path / f"s{k}.toml").write_text(block)
        sensor = Sensor.load(tmp_path / f"s{k}.toml")
        assert sensor.n_eff is not None and sensor.pixel_pitch_um == 5.5
    assert sensor.responses is not None and sensor.name == "imec-5x5-nir"


def test_measured_responses_leave_no_room_for_a_second_description(tmp_path):
    import dataclasses

    s = Sensor.load(VENDOR_XML)
    with pytest.raises(ValueError, match="both say what the filters are"):
        dataclasses.replace(s, profile="airy")
    orphan = dataclasses.replace(s, n_eff=1.8, vendor_file=None)
    with pytest.raises(ValueError, match="no vendor file to name"):
        orphan.save(tmp_path / "o.toml")
    fx = imec_4x4()
    fx.curves[5] = 0.0
    with pytest.raises(ValueError, match=r"^dead\.xml: .*band\[5\]/response> is nowhere "
                       "positive"):
        Sensor.load(write_newer(tmp_path / "dead.xml", fx))
    fx.curves[5, fx.grid > 390] = 0.0  # light only where the band-pass passes none
    fx.curves[5, fx.grid > 990] = 1.0
    fx.components[0][2][fx.components[0][1] > 980] = 0.0
    with pytest.raises(ValueError, match=r"^dark\.xml: .*zero everywhere through the system"):
        Sensor.load(write_newer(tmp_path / "dark.xml", fx))


def test_the_exit_pupil_fit_of_measured_responses_needs_an_index_or_two_f_numbers():
    """The fit models measured responses (tests/calibrate/pupil/test_measured_target.py); the index
    it starts from is the sensor's, or, where the file gives none, a typical one, but only where it
    is fitted (two f-numbers, or one that pins it): otherwise x would rest on a guess. The
    precision's prediction models them (tests/calibrate/pupil/test_precision.py) but needs the
    pitch this file gives as 0."""
    import dataclasses

    from conftest import PAPER_LENS

    from snapcorr.calibrate import locate_pupil, pupil_precision

    s = Sensor.load(VENDOR_XML)
    with pytest.raises(ValueError, match="effective index n_eff"):
        locate_pupil({2.0: None}, s, fit_n_eff=False)
    # fitted, one f-number may pin it (tests/calibrate/pupil/test_locate_one_f_number.py):
    # the cubes are read first
    with pytest.raises(TypeError, match=r"the f/2 cube must be a cube .* got NoneType"):
        locate_pupil({2.0: None}, s, fit_n_eff=True)
    with pytest.raises(ValueError, match="pixel pitch, which its file gives as 0"):
        pupil_precision(lambda lam: lam, dataclasses.replace(s, n_eff=1.8), (2.0, 8.0),
                        PAPER_LENS)
