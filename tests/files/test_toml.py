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


DEEP = "x = " + "[" * 5000 + "]" * 5000 + "\n"


@pytest.mark.parametrize("body", [
    "[lens]\nexit_pupil_mm = 21.0\n[calibration]\n" + DEEP,  # past the parser's recursion
    "[lens]\nexit_pupil_mm = 21.0\n[calibration]\nx = " + "[" * 40 + "]" * 40 + "\n",
    "[lens]\nexit_pupil_mm = 21.0\n[calibration]\nx = " + "{a = " * 40 + "1" + "}" * 40 + "\n",
], ids=["arrays-5000", "arrays-40", "tables-40"])
def test_a_document_nested_deeper_than_any_is_refused_in_one_line(tmp_path, body):
    """5000 levels of arrays raised a RecursionError from inside the parser; 40 parsed and
    left every later reader of the document to recurse as deep."""
    path = tmp_path / "deep.toml"
    path.write_text(body)
    with pytest.raises(ValueError, match=r"deep\.toml: its arrays or tables nest more than 32 "
                                         "levels deep; a lens profile nests a few"):
        read_toml(path, "lens", "lens profile")


def test_a_lens_file_nesting_as_deep_as_a_real_one_reads(tmp_path):
    path = tmp_path / "ok.toml"
    path.write_text("[lens]\nexit_pupil_mm = 21.0\n[[lens.vignetting]]\nradius_mm = 7.4\n"
                    "distance_mm = 17.0\n[calibration]\nx = " + "[" * 25 + "]" * 25 + "\n")
    assert read_toml(path, "lens", "lens profile")["lens"]["vignetting"][0]["radius_mm"] == 7.4


def test_a_toml_far_larger_than_any_is_refused_by_its_size_unread(tmp_path):
    path = tmp_path / "big.toml"
    path.write_text("[lens]\nexit_pupil_mm = 21.0\n# " + "x" * (5 * 2**20) + "\n")
    with pytest.raises(ValueError, match=r"big\.toml holds 5\.0 MiB; a lens profile is a few kB, "
                                         "and a TOML larger than 4 MiB is refused unread"):
        read_toml(path, "lens", "lens profile")


@pytest.mark.parametrize("kind", ["lens", "sensor"])
def test_every_toml_the_command_line_reads_refuses_deep_nesting_in_one_line(tmp_path, cli,
                                                                           kind):
    from hostile import refused_in_one_line

    head = ("[lens]\nexit_pupil_mm = 21.0\n" if kind == "lens" else
            '[sensor]\nname = "s"\nlayout = "snapscan"\npixel_pitch_um = 5.5\n'
            "size_px = [64, 64]\ncwl_nm = [550.0, 650.0]\nfwhm_nm = 10.0\nn_eff = 1.7\n")
    (tmp_path / "deep.toml").write_text(head + "[calibration]\n" + DEEP)
    args = (("shift", "--lens", "deep.toml", "--f-number", "2", "--cra", "10") if kind == "lens"
            else ("sensor", "deep.toml"))
    err = refused_in_one_line(cli(*args, cwd=tmp_path))
    assert "deep.toml: its arrays or tables nest more than 32 levels" in err


def test_a_table_written_as_an_array_and_a_byte_order_mark(tmp_path):
    """[[sensor]] gave Python's "dictionary update sequence element #0 has length 1"; a
    UTF-8 byte-order mark (some editors write one) gave "Invalid statement" at line 1."""
    from snapcorr.cube import Sensor

    arr = tmp_path / "a.toml"
    arr.write_text('[[sensor]]\nname = "x"\n')
    with pytest.raises(ValueError, match=r"a\.toml: sensor is an array of tables \(\[\[sensor\]\]\)"
                       r"; a sensor description holds one \[sensor\] table"):
        Sensor.load(arr)
    bom = tmp_path / "b.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + b'[sensor]\nname = "b"\nlayout = "snapscan"\n'
                    b"pixel_pitch_um = 5.5\ncwl_nm = [500.0, 600.0]\nfwhm_nm = 10.0\n"
                    b"n_eff = 1.7\n")
    assert Sensor.load(bom).name == "b"


@pytest.mark.parametrize(("text", "words"), [
    ('[lens]\nexit_pupil_mm = 21.0\nname = ["a"]\n', r"\[lens\] name must be text"),
    ('[lens]\nexit_pupil_mm = 21.0\npupil = 3\n', r"\[lens\] pupil must be text"),
])
def test_a_lens_name_that_is_not_text_is_refused(tmp_path, text, words):
    from snapcorr import Lens

    path = tmp_path / "l.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=words):
        Lens.load(path)
