"""The registry of file formats: every suffix to one format object, and a path's format."""

import pytest

from snapcorr.files.registry import FILE_FORMATS, FORMATS, format_by_suffix, format_of


def test_every_suffix_names_a_registered_format_of_that_suffix():
    for suffix, name in FORMATS.items():
        assert suffix in FILE_FORMATS[name].suffixes
        assert format_by_suffix(suffix.upper()) is FILE_FORMATS[name]


def test_the_suffixes_snapcorr_reads_and_writes():
    assert sorted(FORMATS) == [".exr", ".hdr", ".nc", ".npy", ".tif", ".tiff", ".zarr"]


def test_each_format_names_how_every_target_is_marked(tmp_path):
    for fmt in FILE_FORMATS.values():
        targets = fmt.targets(tmp_path / f"c{fmt.suffixes[0]}")
        assert targets[0] == tmp_path / f"c{fmt.suffixes[0]}"
        assert len(fmt.marked_as) == len(targets), fmt.name
    assert FILE_FORMATS["envi"].targets(tmp_path / "c.hdr")[1] == tmp_path / "c.raw"
    assert FILE_FORMATS["npy"].role(1) == "sidecar"


def test_an_envi_data_file_names_its_header(tmp_path):
    (tmp_path / "c.hdr").write_text("ENVI\n")
    fmt, main, data = format_of(tmp_path / "c.img")
    assert (fmt.name, main, data) == ("envi", tmp_path / "c.hdr", tmp_path / "c.img")
    with pytest.raises(ValueError, match="has no header"):
        format_of(tmp_path / "d.raw")


def test_an_unknown_suffix_is_refused_with_the_known_ones(tmp_path):
    assert format_by_suffix(".png") is None
    with pytest.raises(ValueError, match=r"unknown frame format '\.png'.*\.zarr"):
        format_of(tmp_path / "x.png", "frame")
