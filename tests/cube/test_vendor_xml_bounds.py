"""A vendor file's numbers are bounded before they size anything, and its curves are checked
as curves: hostile files built here, each refused in one line naming the file and element,
in bounded time and memory."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from vendorfiles import imec_4x4, write_newer, write_older

from snapcorr.cube import Sensor


def _refused(path, words):
    with pytest.raises(ValueError, match=words) as info:
        Sensor.load(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path.name}: "), message
    return message


@pytest.mark.parametrize("fwhm", ["1e-4", "1e-6", "1e-300"])
def test_a_peak_narrower_than_the_grid_is_refused_before_it_sizes_a_grid(tmp_path, fwhm):
    fx = imec_4x4()
    first = repr(float(fx.peaks[0][0][1]))
    path = write_newer(tmp_path / "narrow.xml", fx,
                       replace={f"<fwhm_nm>{first}</fwhm_nm>": f"<fwhm_nm>{fwhm}</fwhm_nm>"})
    _refused(path, r"band\[0\]/peaks/peak\[0\]/fwhm_nm> is \S+ nm, narrower than the response "
                   r"grid's 1 nm step")


def test_a_peak_as_wide_as_the_grid_step_is_read():
    """The bound is the grid's step, not more: the real 5x5 file's narrowest band is 3.2 nm
    on a 1 nm grid."""
    from conftest import VENDOR_XML

    fwhm = [p.fwhm_nm for p in Sensor.load(VENDOR_XML).responses.main_peaks()]
    assert min(fwhm) == pytest.approx(3.176, abs=1e-3)


@pytest.mark.parametrize("n", ["1000000000", "1000000000000"])
def test_a_huge_count_is_refused_before_anything_is_allocated(tmp_path, n):
    path = write_older(tmp_path / "count.xml", imec_4x4(),
                       replace={"<nr_measurements>601": f"<nr_measurements>{n}"})
    tracemalloc.start()
    try:
        _refused(path, rf"nr_measurements> is {n}: more samples than the file holds room for")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 50 * path.stat().st_size  # the parsed tree, never an array of n


def test_a_band_of_millions_of_values_is_refused_before_they_are_parsed(tmp_path):
    fx = imec_4x4()
    many = " ".join(["0.5"] * 3_000_000)
    path = write_newer(tmp_path / "big.xml", fx,
                       replace={'<response values="': f'<response values="{many} '})
    size = path.stat().st_size
    tracemalloc.start()
    try:
        _refused(path, r"band\[0\]/response> holds .* MiB of text, more than 601 numbers take")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # the text itself (about the file's size), not three million floats and their strings
    # (about 40 times it)
    assert peak < 4 * size, (peak, size)


def test_a_list_without_a_count_is_bounded_too(tmp_path):
    fx = imec_4x4()
    grid = np.arange(400.0, 400.0 + 0.001 * 200_000, 0.001)  # 200 000 samples
    fx.components[0] = ("bandpass", grid, np.full(grid.size, 0.9))
    path = write_newer(tmp_path / "fine.xml", fx)
    _refused(path, r"optical_component\[0\]/sample_points_nm> holds 200000 values; no "
                   "calibration curve has more than 100000")


@pytest.mark.parametrize("how, words", [
    ("negative", r"band\[0\]/response> is nowhere positive \(largest value -"),
    ("negative band-pass", r"optical_component\[0\]/response> is nowhere positive"),
    ("dip", r"band\[2\]/response> goes down to -5, below -0.01 of its largest value"),
    ("zero", r"optical_component\[0\]/response> is nowhere positive \(largest value 0\)"),
])
def test_curves_that_are_not_responses_are_refused_at_load(tmp_path, how, words):
    fx = imec_4x4()
    grid_bp, bp = fx.components[0][1], fx.components[0][2]
    if how == "negative":  # both negative: their product would look positive
        fx.components[0] = ("bandpass", grid_bp, -bp)
        fx.curves[:] = -fx.curves
    elif how == "negative band-pass":
        fx.components[0] = ("bandpass", grid_bp, -bp)
    elif how == "dip":
        fx.curves[2, 10] = -5.0
    else:
        fx.components[0] = ("bandpass", grid_bp, 0.0 * bp)
    _refused(write_newer(tmp_path / f"{how.replace(' ', '_')}.xml", fx), words)


def test_a_curve_dipping_below_zero_by_noise_is_read(tmp_path):
    fx = imec_4x4()
    grid_bp = fx.components[0][1]
    fx.components[0][2][(grid_bp >= 400) & (grid_bp < 405)] = -0.0008  # as the real 5x5 file
    assert Sensor.load(write_newer(tmp_path / "noisy.xml", fx)).responses.system.min() < 0


def test_values_whose_product_overflows_are_refused(tmp_path):
    fx = imec_4x4()
    fx.curves *= 1e300 / fx.curves.max()
    fx.components[0] = ("bandpass", fx.components[0][1], fx.components[0][2] * 1e300)
    _refused(write_newer(tmp_path / "huge.xml", fx), "overflow")


@pytest.mark.parametrize("index", ["²", "-1", "1.0", "٣x"])
def test_a_band_index_that_is_not_a_whole_number_names_the_element(tmp_path, index):
    path = write_newer(tmp_path / "index.xml", imec_4x4(),
                       replace={'<band index="1">': f'<band index="{index}">'})
    _refused(path, r"a <filter_info/filter_zones/filter_zone/bands/band> has no whole-number "
                   "index attribute")


def test_older_files_are_told_by_their_own_tags(tmp_path):
    path = write_older(tmp_path / "old.xml", imec_4x4(),
                       replace={"<height>1088": "<height>tall"})
    _refused(path, r"<sensor_info/height> must be a number")


@pytest.mark.skipif(not __import__("os").path.exists("/proc/self/mem"), reason="Linux only")
def test_a_path_whose_bytes_cannot_be_read_is_named(tmp_path):
    with pytest.raises(ValueError, match=r"^/proc/self/mem: cannot read it \(Input/output"):
        Sensor.load("/proc/self/mem")  # read as a sensor TOML
    toml = tmp_path / "camera.toml"
    toml.write_text('[sensor]\nvendor_file = "/proc/self/mem"\nn_eff = 1.8\n')
    with pytest.raises(ValueError, match=r"mem: cannot read it \(Input/output error\)"):
        Sensor.load(toml)


@pytest.mark.parametrize("how, words", [("um", "look like micrometres"),
                                        ("repeated", r"repeats \[\d")])
def test_a_matrix_of_wavelengths_that_are_not_nm_is_refused(tmp_path, how, words):
    fx = imec_4x4()
    name, kind, wl, fw, coeffs = fx.matrices[0]
    wl = wl / 1000 if how == "um" else np.r_[wl[0], wl[:-1]]
    fx.matrices[0] = (name, kind, wl, fw, coeffs)
    _refused(write_newer(tmp_path / "wl.xml", fx), f"matrix 'hsi_reflectance'.*{words}")


def test_a_file_far_larger_than_any_calibration_file_is_refused_by_its_size(tmp_path):
    """A 60 MB file was parsed (580 MB, 10 s) before it was refused; one past 16 MiB, here a
    real file padded with a comment, is refused unread, the size and the bound named."""
    fx = imec_4x4()
    path = write_newer(tmp_path / "huge.xml", fx)
    text = path.read_text()
    cut = text.rindex("</sensor_calibration>")
    path.write_text(text[:cut] + "<!--" + "x" * (17 * 2**20) + "-->" + text[cut:])
    tracemalloc.start()
    try:
        message = _refused(path, r"it holds 17\.\d MiB, far more than any sensor calibration "
                                 r"file \(a few MB\): a file larger than 16 MiB is refused")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 2**20, (peak, message)


def test_a_virtual_band_reaching_past_the_grid_is_said_at_load(tmp_path, capsys):
    """A matrix band inside the grid whose width reaches past its edge (465 nm with a FWHM of
    50 nm on a 400-1000 nm grid: 1.5 FWHM below it is 390 nm) was read without a word, and
    refused only by a correction asking for virtual bands. The file is read (its bands and
    responses are sound), saying so, in the command's output as well."""
    from snapcorr.cli import main
    from snapcorr.cube.vendor_xml import VendorFileWarning

    fx = imec_4x4()
    name, kind, wl, fw, coeffs = fx.matrices[0]
    fw = fw.copy()
    fw[0] = 50.0
    assert wl[0] - 1.5 * fw[0] < fx.grid[0] < wl[0]  # the centre inside, the width beyond
    fx.matrices[0] = (name, kind, wl, fw, coeffs)
    path = write_newer(tmp_path / "wide.xml", fx)
    with pytest.warns(VendorFileWarning, match=rf"wide\.xml: .*'hsi_reflectance' has 1 virtual "
                                               rf"band\(s\) whose width reaches beyond the "
                                               rf"responses' 400-1000 nm .*at {wl[0]:g} nm, "
                                               r"FWHM 50 nm"):
        sensor = Sensor.load(path)
    assert sensor.n_bands == 16
    assert main(["sensor", str(path)]) == 0
    assert "whose width reaches beyond" in capsys.readouterr().err
