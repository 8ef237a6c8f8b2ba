"""The bundled lenses and sensors, found by name; a file is always itself."""

import pytest

from snapcorr import data
from snapcorr._bundled import (
    bundled_folder,
    bundled_path,
    calibration_dir,
    input_path,
    profile_path,
)


def test_a_bundled_profile_is_found_by_its_name_or_stem():
    assert bundled_path("lens", "edmund_optics_16mm") == data.lens_path()
    assert bundled_path("sensor", "snapscan_vnir.toml") == data.sensor_path("snapscan_vnir")
    assert bundled_path("lens", data.lens_path()) == data.lens_path()  # a path: its stem


@pytest.mark.parametrize("name", ["nope", "../lenses/edmund_optics_16mm", ".", ""])
def test_an_unknown_name_lists_the_bundled_ones(name):
    with pytest.raises(FileNotFoundError, match=r"no bundled lens named .*; bundled lenses: "
                       r"\[.*'edmund_optics_16mm'"):
        bundled_path("lens", name)


def test_a_file_is_itself_and_a_name_is_bundled(tmp_path):
    assert profile_path("lens", tmp_path / "mine.toml") == tmp_path / "mine.toml"  # need not exist
    assert profile_path("sensor", "camera.XML").name == "camera.XML"
    (tmp_path / "plain").write_text("")
    assert profile_path("lens", tmp_path / "plain") == tmp_path / "plain"  # exists
    assert profile_path("sensor", "imec_5x5_nir") == data.sensor_path("imec_5x5_nir")
    with pytest.raises(FileNotFoundError, match=r"no bundled sensor named 'camera\.xm'"):
        profile_path("sensor", "camera.xm")


def test_an_input_by_name_is_its_bundled_file(tmp_path):
    assert input_path("edmund_optics_16mm") == data.lens_path()
    assert input_path("mosaic_4x4_vis") == data.sensor_path("mosaic_4x4_vis")
    assert input_path("no_such_profile") == input_path("no_such_profile").__class__(
        "no_such_profile")
    assert input_path(tmp_path / "x.nc") == tmp_path / "x.nc"
    assert bundled_folder() is not None and bundled_folder().samefile(calibration_dir())
