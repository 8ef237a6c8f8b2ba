"""A vendor file's tile, sensor size, grid, peaks and numbers that would size an allocation or
break later, refused where the vendor file is read."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from vendorfiles import imec_4x4, write_newer, write_older

from snapcorr.cube import Sensor


def _refused(path, words):
    with pytest.raises(ValueError, match=words) as info:
        Sensor.load(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path.name}: "), message


def test_a_tile_of_1e18_bands_is_refused_by_counting_the_bands_first(tmp_path):
    """A tile of 1e5 x 1e5 on a sensor as large: comparing the band indices with
    ``range(tile bands)`` built a list of 1e10 numbers (a MemoryError) before any count; a
    tile of 1e9 x 1e9 on a sensor of 1e12 px is refused by the sensor's size first."""
    fx = dataclasses.replace(imec_4x4(), tile=(10**5, 10**5), size=(10**5, 10**5),
                             area=(0, 0, 10**5, 10**5))
    _refused(write_newer(tmp_path / "tile.xml", fx), r"lists bands \[0, 1, 2, 3, 4, 5\]\.\.\. "
                                                     r"\(16\), but a 10000000000-band tile")
    fx = dataclasses.replace(imec_4x4(), tile=(10**9, 10**9), size=(10**12, 10**12),
                             area=(0, 0, 10**12, 10**12))
    _refused(write_newer(tmp_path / "tile2.xml", fx), "is 1000000000000 px; no sensor")


@pytest.mark.parametrize("writer", [write_newer, write_older])
def test_a_sensor_larger_than_any_is_refused(tmp_path, writer):
    fx = dataclasses.replace(imec_4x4(), size=(10**8, 10**8), area=(0, 0, 1088, 2048))
    _refused(writer(tmp_path / "big.xml", fx), r"sensor_info/(height_px|height)> is 100000000 px")
    with pytest.raises(ValueError, match="size_px"):
        Sensor(name="big", layout="snapscan", cwl_nm=[500.0, 600.0], fwhm_nm=[10.0, 10.0],
               pixel_pitch_um=5.5, n_eff=1.7, size_px=(10**8, 2048))


def test_one_tiny_grid_step_at_a_peak_does_not_license_a_tiny_width(tmp_path):
    """A grid with one step of 1e-9 nm where a peak of 2e-9 nm FWHM sits: the local step
    allowed it, and the centres' fine grid then asked for 26 TiB."""
    fx = imec_4x4()
    at = fx.peaks[0][0][0]
    grid = np.unique(np.r_[fx.grid, at - 1e-9, at])
    curves = np.array([np.interp(grid, fx.grid, c) for c in fx.curves])
    peaks = [list(p) for p in fx.peaks]
    peaks[0] = [(at, 2e-9, 0.5)]
    fx = dataclasses.replace(fx, grid=grid, curves=curves, peaks=peaks)
    _refused(write_newer(tmp_path / "step.xml", fx), r"fwhm_nm> is 2e-09 nm, narrower than the "
                                                     r"response grid's 1 nm step")


@pytest.mark.parametrize("writer", [write_newer, write_older])
def test_a_band_whose_peaks_lie_outside_the_grid_is_refused(tmp_path, writer):
    fx = imec_4x4()
    peaks = [list(p) for p in fx.peaks]
    peaks[2] = [(5000.0, 8.0, 0.5)]
    path = writer(tmp_path / "out.xml", dataclasses.replace(fx, peaks=peaks))
    _refused(path, r"band 2: its peaks \(5000 nm\) all lie outside the response grid "
                   r"\(400-1000 nm\)")


@pytest.mark.parametrize("writer", [write_newer, write_older])
def test_a_virtual_band_outside_the_grid_is_refused(tmp_path, writer):
    fx = imec_4x4()
    name, kind, wl, fw, coeffs = fx.matrices[-1]
    wl = wl.copy()
    wl[5] = 5000.0
    fx = dataclasses.replace(fx, matrices=[*fx.matrices[:-1], (name, kind, wl, fw, coeffs)])
    _refused(writer(tmp_path / "vb.xml", fx), "has a virtual band at 5000 nm, outside the "
                                              "responses' 400-1000 nm")


def test_an_older_grid_of_a_picometre_span_is_refused(tmp_path):
    """601 samples 1e-12 nm apart: the whole grid at 400 nm, every band's peak outside."""
    path = write_older(tmp_path / "pico.xml", imec_4x4(), replace={
        "<measurement_resolution_nm>1.0</measurement_resolution_nm>":
        "<measurement_resolution_nm>1e-12</measurement_resolution_nm>"})
    _refused(path, "outside the response grid")


def test_a_negative_quantum_efficiency_is_refused(tmp_path):
    fx = imec_4x4()
    peaks = [list(p) for p in fx.peaks]
    peaks[1] = [(peaks[1][0][0], 8.0, -0.3)]
    _refused(write_newer(tmp_path / "qe.xml", dataclasses.replace(fx, peaks=peaks)),
             "QE -0.3: a quantum efficiency is not negative")


def test_numbers_with_underscores_are_not_numbers(tmp_path):
    """Python's float() reads '1_0' as 10; a calibration file never writes it so."""
    fx = imec_4x4()
    first = repr(float(fx.curves[0][0]))
    path = write_newer(tmp_path / "us.xml", fx, replace={
        f'<response values="{first} ': '<response values="1_0 '})
    _refused(path, "holds '1_0', not a number")
    path = write_newer(tmp_path / "us2.xml", fx, replace={"<pixel_pitch_um>5.5<":
                                                          "<pixel_pitch_um>5_5<"})
    _refused(path, "pixel_pitch_um> must be a number, got '5_5'")


def test_a_response_of_subnormal_numbers_is_nowhere_positive(tmp_path):
    fx = imec_4x4()
    curves = fx.curves.copy()
    curves[4] = 1e-320
    _refused(write_newer(tmp_path / "sub.xml", dataclasses.replace(fx, curves=curves)),
             "band\\[4\\]/response> is nowhere positive")


@pytest.mark.parametrize("writer", [write_newer, write_older])
@pytest.mark.parametrize(("value", "words"), [
    (1e300, r"the responses reach 1e\+300, beyond 1e\+100: their squares and products "
            "overflow"),
    (1e101, r"reach 1e\+101"),
    (0.5, r"band 3's response is the same at every wavelength of the grid \(0\.5\): a "
          "filter's response has a peak"),
])
def test_a_response_too_large_or_without_a_peak_is_refused(tmp_path, writer, value, words):
    """One band's response 1e300 at every sample was read (a warning of overflow, then that
    band's corrected width 267 nm in a harmonised cube); a flat one has no filter's peak."""
    fx = imec_4x4()
    curves = fx.curves.copy()
    curves[3] = value
    _refused(writer(tmp_path / "big.xml", dataclasses.replace(fx, curves=curves)), words)
    curves[3] = fx.curves[3] * 1e90  # large, but a response: read
    Sensor.load(writer(tmp_path / "ok.xml", dataclasses.replace(fx, curves=curves)))


@pytest.mark.parametrize("writer", [write_newer, write_older])
def test_a_peak_wider_than_the_whole_grid_is_refused(tmp_path, writer):
    """A FWHM of 1e300 nm was accepted and shown as the band's width by ``snapcorr sensor``:
    no curve on a 400-1000 nm grid shows a band so wide."""
    fx = imec_4x4()
    peaks = [list(p) for p in fx.peaks]
    peaks[2] = [(peaks[2][0][0], 1e300, 0.5)]
    path = writer(tmp_path / "wide.xml", dataclasses.replace(fx, peaks=peaks))
    _refused(path, r"band\[2\]/peaks/peak\[0\]/fwhm_nm> is 1e\+300 nm, wider than the whole "
                   r"response grid \(400-1000 nm\)")


def test_filter_responses_refuse_a_peak_wider_than_their_grid():
    from snapcorr.cube.responses import FilterResponses, Peak

    grid = np.arange(400.0, 1001.0)
    curve = np.exp(-0.5 * ((grid - 700.0) / 5.0) ** 2)
    FilterResponses(grid, [curve], np.ones(grid.size), [[Peak(700.0, 600.0, 1.0)]])  # the span
    with pytest.raises(ValueError, match="wider than the whole grid"):
        FilterResponses(grid, [curve], np.ones(grid.size), [[Peak(700.0, 601.0, 1.0)]])


@pytest.mark.parametrize("writer, old, new", [
    (write_newer, "<bit_depth>10</bit_depth>", "<bit_depth>{}</bit_depth>"),
    (write_older, "<pixel_pitch>", "<input_bpp>{}</input_bpp><pixel_pitch>"),
])
@pytest.mark.parametrize("bits", [33, 64, 100000])
def test_a_bit_depth_beyond_any_cameras_names_the_file_and_element(tmp_path, writer, old, new,
                                                                    bits):
    """The sensor refused it as 'bit_depth must be ... 1-32', naming neither the file nor the
    element; the reader now says where."""
    path = writer(tmp_path / "bits.xml", imec_4x4(), replace={old: new.format(bits)})
    tag = "bit_depth" if writer is write_newer else "input_bpp"
    _refused(path, rf"<sensor_info/{tag}> is {bits}: no camera's codes have more than 32 bits")


@pytest.mark.parametrize("writer, tag", [(write_newer, "pixel_pitch_um"),
                                         (write_older, "pixel_pitch")])
@pytest.mark.parametrize("pitch", ["1e300", "0.01", "20000"])
def test_a_pixel_pitch_no_camera_has_names_the_file_and_element(tmp_path, writer, tag, pitch):
    fx = dataclasses.replace(imec_4x4(), pitch=float(pitch))
    _refused(writer(tmp_path / "pitch.xml", fx),
             re.escape(f"<sensor_info/{tag}> = {float(pitch):g} um is no camera's pixel pitch"))


def _real(tmp_path, name, old, new):
    """The real CMV2K file with its first ``old`` replaced by ``new``."""
    from conftest import VENDOR_XML

    text = VENDOR_XML.read_text(encoding="utf-8")
    assert old in text, old
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


@pytest.mark.parametrize(("old", "new", "element"), [
    ('<custom_spectral_correction version="0" nr_elements="25">',
     '<custom_spectral_correction version="0" nr_elements="999999999999">',
     r"virtual_bands/band\[0\]/custom_spectral_correction> states nr_elements=\"999999999999\", "
     r"but <[^>]*/data> holds 25 values"),
    ('<custom_spectral_correction version="0" nr_elements="25">',
     '<custom_spectral_correction version="0" nr_elements="24">', "holds 25 values"),
    ('<response_composition version="0" nr_elements="601">',
     '<response_composition version="0" nr_elements="600">',
     r"bands/band\[0\]/response_composition> states nr_elements=\"600\", but .* 601 values"),
    ('<filter_response version="0" nr_elements="601">',
     '<filter_response version="0" nr_elements="6010">',
     r"rejection_filter/filter_response> states nr_elements=\"6010\", but .* 601 values"),
    ('<filter_response version="0" nr_elements="601">',
     '<filter_response version="0" nr_elements="six">', "not a whole number"),
])
def test_a_stated_count_that_disagrees_with_the_values_is_refused(tmp_path, old, new, element):
    """nr_elements="999999999999" on a row of 25 coefficients was read as if it said 25."""
    _refused(_real(tmp_path, "count.xml", old, new), element)


def test_a_stated_count_is_compared_before_the_values_are_parsed(tmp_path):
    """A stated count that disagrees is refused before any value is read as a number: the
    count, not the word among the values, is what the message says."""
    from conftest import VENDOR_XML

    text = VENDOR_XML.read_text(encoding="utf-8")
    text = text.replace('<custom_spectral_correction version="0" nr_elements="25">\n'
                        '                        <data>',
                        '<custom_spectral_correction version="0" nr_elements="27">\n'
                        '                        <data>word, ', 1)
    assert "<data>word, " in text
    path = tmp_path / "first.xml"
    path.write_text(text, encoding="utf-8")
    _refused(path, r"states nr_elements=\"27\", but .* holds 26 values")


@pytest.mark.parametrize("fwhm", ["1e-300", "1", "1e300"])
def test_an_older_virtual_band_width_the_grid_cannot_make_is_refused(tmp_path, fwhm):
    """<fwhm_virtual_filters_nm>1e-300</...> was read (0 was refused), and the sensor's plot
    then overflowed and drew no Gaussians: the width has the bound a correction's virtual
    width has, two steps of the response grid (2 nm here), and at most the whole grid."""
    path = _real(tmp_path, "fw.xml", "<fwhm_virtual_filters_nm>15<",
                 f"<fwhm_virtual_filters_nm>{fwhm}<")
    _refused(path, re.escape(f"<spectral_correction_info/fwhm_virtual_filters_nm> is "
                             f"{float(fwhm):g} nm"))


def test_an_older_virtual_band_width_of_two_grid_steps_is_read(tmp_path):
    path = _real(tmp_path, "fw.xml", "<fwhm_virtual_filters_nm>15<",
                 "<fwhm_virtual_filters_nm>2<")
    assert np.all(Sensor.load(path).matrices[0].fwhm_nm == 2.0)


def test_a_newer_virtual_band_width_the_grid_cannot_make_is_refused(tmp_path):
    fx = imec_4x4()
    name, kind, wl, fw, coeffs = fx.matrices[-1]
    fw = np.array(fw, float)
    fw[3] = 1e-300
    fx = dataclasses.replace(fx, matrices=[*fx.matrices[:-1], (name, kind, wl, fw, coeffs)])
    _refused(write_newer(tmp_path / "fw.xml", fx),
             r"virtual_band\[3\]/fwhm_nm> is 1e-300 nm at .* narrower than the responses' grid")


@pytest.mark.parametrize("writer", [write_newer, write_older])
def test_two_bands_of_one_peak_are_refused_naming_the_file(tmp_path, writer):
    """Two bands whose measured responses peak at one wavelength: 'cwl_nm repeats [622.5]
    nm' named neither the file nor where the wavelengths came from."""
    fx = imec_4x4()
    curves = fx.curves.copy()
    curves[1] = curves[0]
    peaks = [list(p) for p in fx.peaks]
    peaks[1] = list(peaks[0])
    _refused(writer(tmp_path / "twice.xml", dataclasses.replace(fx, curves=curves, peaks=peaks)),
             r"cwl_nm repeats \[[\d.]+\] nm; .* \(the bands' main peaks, read from their "
             r"measured responses\)")


@pytest.mark.parametrize(("old", "new", "words"), [
    ("<pattern_width>5</pattern_width>", "<pattern_width>5</pattern_width>"
     "<pattern_width>4</pattern_width>", r"<filter_info/pattern_width> appears 2 times"),
    ('<sensor_info version="0">', '<sensor_info version="0"><width>1024</width></sensor_info>'
     '<sensor_info version="0">', r"<sensor_calibration/sensor_info> appears 2 times"),
    ("<wavelength_nm>608.2067</wavelength_nm>", "<wavelength_nm>608.2067</wavelength_nm>"
     "<wavelength_nm>700</wavelength_nm>", r"virtual_bands/band\[0\]/wavelength_nm> appears 2"),
    ("<type>bandpass_600xi-875eo</type>", "<type>bandpass_600xi-875eo</type><type>none</type>",
     r"<filter_info/rejection_filter/type> appears 2 times"),
    ('<spectral_correction_info version="1">', '<spectral_correction_info version="1">'
     '</spectral_correction_info><spectral_correction_info version="1">',
     r"<spectral_correction_info> appears 2 times"),
    ("<bands>", "<bands></bands><bands>", r"<filter_info/bands> appears 2 times"),
])
def test_an_element_stated_twice_is_refused_naming_it(tmp_path, old, new, words):
    """Two values of one element (a second pattern width, sensor block, band wavelength,
    band-pass type, correction block or band list) were read as the first, silently."""
    _refused(_real(tmp_path, "twice.xml", old, new), words)


def test_a_message_names_the_element_as_the_file_spells_it(tmp_path):
    """The older variant's band-pass counts its samples in <nr_data_points>: a count of 1e10
    there was refused naming <nr_measurements>, which that element has not got."""
    _refused(_real(tmp_path, "count.xml", "<nr_data_points>601</nr_data_points>",
                   "<nr_data_points>10000000000</nr_data_points>"),
             r"<filter_info/rejection_filter/nr_data_points> is 10000000000: more samples")
    _refused(_real(tmp_path, "word.xml", "<nr_data_points>601</nr_data_points>",
                   "<nr_data_points>six</nr_data_points>"),
             r"<filter_info/rejection_filter/nr_data_points> must be a number")


@pytest.mark.parametrize(("value", "refused"), [("1e300", True), ("-1e31", True), ("1e29", False)])
def test_a_correction_coefficient_that_overflows_is_refused(tmp_path, value, refused):
    """A virtual band's coefficient of 1e300 was read; the vendor bands were then inf at every
    pixel with only numpy's "overflow encountered in cast"."""
    path = _real(tmp_path, "coef.xml", "<data>0.006918495,", f"<data>{value},")
    if refused:
        _refused(path, r"matrix 'custom': a coefficient is .*, beyond 1e\+30: applied to a "
                       "band's values it overflows")
    else:
        Sensor.load(path)


def test_a_peak_listed_twice_in_one_band_is_refused(tmp_path):
    """The same peak twice in a band was read as a band of two peaks."""
    peak = ('<peak version="0" order="1">\n                        <wavelength_nm>'
            '614.9032232924481</wavelength_nm>')
    path = _real(tmp_path, "peak2.xml", peak, peak.replace("<peak ", '<peak order="1" ', 0)
                 + '\n<fwhm_nm>6.589033018692362</fwhm_nm><QE>56.59</QE></peak>' + peak)
    _refused(path, r"band\[0\]/peaks> lists the peak at 614\.903 nm twice")
