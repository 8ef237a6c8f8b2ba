"""TOML documents: read with clear errors, written with snapcorr's mark."""

import pytest

from snapcorr.files.marks import written_by_snapcorr
from snapcorr.files.toml import read_toml, write_toml


def test_a_written_document_reads_back_and_carries_the_mark(tmp_path):
    path = write_toml(tmp_path / "lens.toml", {"lens": {"name": "a", "f_mm": 12.5}})
    assert read_toml(path, "lens", "lens")["lens"] == {"name": "a", "f_mm": 12.5}
    assert written_by_snapcorr(path) == (True, "")


def test_a_copy_under_another_name_is_not_snapcorrs(tmp_path):
    path = write_toml(tmp_path / "lens.toml", {"lens": {"name": "a"}})
    copy = tmp_path / "other.toml"
    copy.write_bytes(path.read_bytes())
    ours, found = written_by_snapcorr(copy)
    assert not ours and "copied or saved under this name" in found


def test_an_existing_file_needs_overwrite(tmp_path):
    path = write_toml(tmp_path / "lens.toml", {"lens": {}})
    with pytest.raises(FileExistsError):
        write_toml(path, {"lens": {}})
    write_toml(path, {"lens": {"name": "b"}}, overwrite=True)
    assert read_toml(path, "lens", "lens")["lens"] == {"name": "b"}


def test_an_unknown_table_is_refused(tmp_path):
    path = tmp_path / "lens.toml"
    path.write_text("[lens]\n[[vignetting]]\nr = 1\n")
    with pytest.raises(ValueError, match=r"\[\[lens.vignetting\]\]"):
        read_toml(path, "lens", "lens")
