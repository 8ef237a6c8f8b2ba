"""The virtual-band options are checked for the sensor before any work or write, with the
option's name in the one-line error: repeated or non-nm wavelengths, widths the responses'
grid cannot resolve, bands beyond the grid; and options the chosen method does not use are
refused, not ignored."""

from __future__ import annotations

import numpy as np
import pytest

import snapcorr.data
from snapcorr.correct.virtual import check_virtual_options, virtual_targets
from snapcorr.cube import Sensor

NIR = Sensor.load(snapcorr.data.sensor_path("imec_5x5_nir"))


@pytest.mark.parametrize("wl, fwhm, words", [
    ([700.0, 700.0], None, "virtual_wavelengths_nm repeats"),
    ([0.7, 0.8], None, "virtual_wavelengths_nm must be in nanometres"),
    ([700.0, 710.0], 0.001, "virtual_fwhm_nm 0.001 nm at 700 nm is narrower than the "
                            "responses' grid resolves"),
    ([405.0], 10.0, "reaches beyond the responses' grid"),
    ([300.0], None, "virtual_wavelengths_nm must lie inside it"),  # the centre is outside
    ([700.0], 1e6, "virtual_fwhm_nm must be narrower"),  # the centre inside, the width not
    ([700.0], -3.0, "virtual_fwhm_nm"),
    (np.linspace(600.0, 870.0, 602), 15.0, "virtual_wavelengths_nm gives 602 bands, more than "
                                           "the 601 samples"),
])
def test_targets_that_cannot_be_estimated_are_refused(wl, fwhm, words):
    with pytest.raises(ValueError, match=words):
        virtual_targets(NIR, wl, fwhm)


def test_the_defaults_and_good_targets_pass():
    wl, fw = virtual_targets(NIR)
    np.testing.assert_array_equal(wl, NIR.matrices[0].wavelength_nm)
    wl, fw = virtual_targets(NIR, [650.0, 700.0], 2.0)  # two grid steps: the narrowest
    np.testing.assert_array_equal(fw, [2.0, 2.0])


@pytest.fixture(scope="module")
def tile_cube(tmp_path_factory):
    from snapcorr.cube import flatfield, mosaic_to_cube, write_dataset

    d = tmp_path_factory.mktemp("virtual")
    frames = snapcorr.data.mosaic_frames("imec_5x5_nir")
    tiles = [mosaic_to_cube(f[100:200, 400:500], NIR, sensor_origin_px=(100, 400)) for f in frames]
    write_dataset(flatfield(*tiles, saturation=NIR.full_scale_dn), d / "ff.nc")
    return d


@pytest.mark.parametrize("extra, words", [
    (["--virtual-wavelengths", "700,700"], "--virtual-wavelengths repeats [700.0] nm"),
    (["--virtual-fwhm-nm", "0.001"], "--virtual-fwhm-nm 0.001 nm at"),
    # 100,001 bands asked 109 s and 3.3 GB for a 20 x 20 crop, 900,001 a 4 GiB matrix
    (["--virtual-wavelengths=600:870:0.0027"], "--virtual-wavelengths gives 100,001 bands, "
                                               "more than the 601 samples of the responses'"),
])
@pytest.mark.parametrize("out", ["o.nc", "o.hdr"])
def test_the_command_line_names_the_option_and_writes_nothing(tile_cube, cli, extra, words,
                                                              out):
    code, _, err = cli("correct", "ff.nc", "--sensor", "imec_5x5_nir", "--lens",
                       "edmund_optics_16mm", "--f-number", "2.8", "--virtual-bands", "fitted",
                       *extra, "--out", out, cwd=tile_cube)
    assert code == 1 and len(err.strip().splitlines()) == 1, err
    assert words in err
    assert sorted(p.name for p in tile_cube.iterdir()) == ["ff.nc"]


@pytest.mark.parametrize(("method", "kw", "words"), [
    (None, {"wavelengths_nm": [700.0, 750.0]}, "virtual_wavelengths_nm= goes with "
                                               "virtual_bands=; give the method too"),
    (None, {"fwhm_nm": 10.0}, "virtual_fwhm_nm= goes with virtual_bands="),
    ("vendor", {"wavelengths_nm": [700.0, 750.0]}, "virtual_wavelengths_nm= goes with "
                                                   "virtual_bands='fitted' or 'angle-aware'"),
    ("fitted", {"matrix": "custom"}, "virtual_matrix= goes with virtual_bands='vendor'"),
    ("angle-aware", {"matrix": "custom"}, "the angle-aware method fits its own matrix"),
])
def test_an_option_the_method_does_not_use_is_refused(method, kw, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)")):
        check_virtual_options(method, **kw)


def test_the_options_each_method_uses_are_taken():
    check_virtual_options(None)
    check_virtual_options("vendor", matrix="custom")
    check_virtual_options("fitted", wavelengths_nm=[700.0], fwhm_nm=12.0)


def test_correct_cube_and_process_stream_refuse_them_before_any_work():
    """correct_cube(virtual_bands='vendor', virtual_wavelengths_nm=...) returned the vendor's
    bands; process_stream took virtual_wavelengths_nm without virtual_bands."""
    from snapcorr.correct import correct_cube
    from snapcorr.pipeline import process_stream

    with pytest.raises(ValueError, match="virtual_wavelengths_nm= goes with"):
        correct_cube(None, None, None, 2.0, virtual_bands="vendor",
                     virtual_wavelengths_nm=[700.0, 750.0])
    with pytest.raises(ValueError, match="virtual_wavelengths_nm= goes with virtual_bands="):
        process_stream(None, None, None, None, virtual_wavelengths_nm=[700.0, 700.0])
