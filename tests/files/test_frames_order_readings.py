"""Frame names read two ways: an exponent or a letter between digits, a point before digits
with one more name, a '+' sign, a suffix or a case apart, and numbers too large to build."""

from __future__ import annotations

import itertools
import time

import numpy as np
import pytest

from snapcorr.cube import read_frames
from snapcorr.files.frames import natural_order


def _save(folder, names):
    import tifffile

    for k, name in enumerate(names):
        frame = np.full((8, 8), 200 + k, np.uint16)
        if name.lower().endswith((".tif", ".tiff")):
            tifffile.imwrite(folder / name, frame)
        else:
            np.save(folder / name, frame)


def test_a_huge_exponent_in_a_frame_name_is_one_line(tmp_path, cli):
    """f1e99999999999999999999.npy beside f2.npy stopped `stream` with a traceback
    (decimal.InvalidOperation): the exponent was built as a number."""
    frames = tmp_path / "frames"
    frames.mkdir()
    _save(frames, ["f1e99999999999999999999.npy", "f2.npy"])
    np.save(tmp_path / "d.npy", np.full((8, 8), 100, np.uint16))
    np.save(tmp_path / "w.npy", np.full((8, 8), 900, np.uint16))
    rc, out, err = cli("stream", "frames", "--dark", "d.npy", "--white", "w.npy", "--sensor",
                       "mosaic_4x4_vis", "--sensor-origin-px", "0,0", "--out", "o.zarr",
                       cwd=tmp_path)
    assert rc == 1 and not out and err.count("\n") == 1 and "Traceback" not in err, err
    assert "'f1e99999999999999999999.npy'" in err and "exponent" in err, err
    assert not (tmp_path / "o.zarr").exists()


@pytest.mark.parametrize("names", [
    ["f1e99999999999999999999", "f2"],          # past any decimal's exponent
    ["f1e" + "9" * 5000, "f2"],                 # past any int's digits
])
def test_numbers_too_large_to_build_are_refused_in_one_line(names):
    with pytest.raises(ValueError) as err:
        natural_order(names)
    assert "exponent" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("names", [
    ["f1e-99999999999999999999", "f2"],         # one order either way: taken
    ["t1e99999999999999999999_f1", "t1e99999999999999999999_f2",
     "t1e99999999999999999999_f10"],
    ["t1e99999999999999999999_f1", "t1e99999999999999999999_f2",
     "t1.5e99999999999999999999_f1", "t2e99999999999999999999_f1"],
])
def test_large_exponents_of_one_order_either_way_are_compared_exactly(names):
    """Both readings agree; the values, never built, are compared exactly."""
    for shuffled in itertools.permutations(names):
        assert natural_order(list(shuffled)) == names


def test_the_work_on_a_long_run_of_digits_is_bounded():
    """A name of 20 000 digits took seconds (a chain of points searched again from every
    digit); it is read once."""
    names = ["a" + "1" * 20_000, "a" + "1" * 19_999 + "2", "b"]
    start = time.perf_counter()
    assert natural_order(names[::-1]) == names
    assert time.perf_counter() - start < 3


@pytest.mark.parametrize("names", [
    ["a1.tif", "a01.npy", "a2.npy"],   # a1 and a01: refused with one suffix, not with two
    ["f1e1.npy", "f10.tif"],
    ["a1.tif", "a1.0.npy"],
])
def test_names_of_one_number_but_different_suffixes_are_refused(names):
    for shuffled in itertools.permutations(names):
        with pytest.raises(ValueError, match="same number"):
            natural_order(list(shuffled))


def test_the_suffix_is_not_compared():
    """a1-.npy came before a1.tif ('-' before '.'): the suffix took part in the order."""
    assert natural_order(["a1-.npy", "a1.tif"]) == ["a1.tif", "a1-.npy"]


def test_a_folder_of_frames_in_two_formats_is_refused(tmp_path):
    """a1.tif, a01.npy, a2.npy streamed as three frames taken, a01.npy first."""
    _save(tmp_path, ["a1.tif", "a01.npy", "a2.npy"])
    with pytest.raises(ValueError, match=r"holds frames of 2 formats \(a01\.npy \(npy\), "
                                         r"a1\.tif \(tiff\)\)"):
        read_frames(tmp_path)


def test_tif_and_tiff_are_one_format_ordered_by_their_stems(tmp_path):
    _save(tmp_path, ["t10.tif", "t2.tiff", "t1.TIF"])  # 200, 201, 202
    frames = read_frames(tmp_path)
    assert frames.attrs["frame_files"] == ["t1.TIF", "t2.tiff", "t10.tif"]
    np.testing.assert_array_equal(frames.values[:, 0, 0], [202, 201, 200])


@pytest.mark.parametrize("names", [
    ["t.5", "t.50", "t.25", "t1"],    # .5 and .50 one decimal: the check was left off
    ["t.5.npy", "t.50.npy", "t1.npy"],
])
def test_a_point_before_digits_read_two_ways_is_refused_beside_one_decimal_twice(names):
    for shuffled in itertools.permutations(names):
        with pytest.raises(ValueError, match="digits after a point with no digit before it"):
            natural_order(list(shuffled))


def test_a_plus_is_a_sign_where_names_differ_by_it():
    """f+1 came after f2 (its '+' was text), while z-0 and z+0 were one number."""
    with pytest.raises(ValueError, match="'f\\+1' and 'f1' have the same number"):
        natural_order(["f+1", "f1", "f2"])
    assert natural_order(["f2", "f+1"]) == ["f+1", "f2"]
    assert natural_order(["f+1", "f-2", "f+0.5"]) == ["f-2", "f+0.5", "f+1"]
    with pytest.raises(ValueError, match="same number"):
        natural_order(["z-0", "z+0"])
    # where every name has it, it is a separator
    assert natural_order(["f+10", "f+2", "f+1"]) == ["f+1", "f+2", "f+10"]


@pytest.mark.parametrize("names", [
    ["id1d2", "id1e2", "id1f2"],          # hexadecimal ids: 1e2 was read as 100, last
    ["exp_1e-3", "exp_1e-2", "exp_1"],    # as exponents one order, as letters another
    ["f1e99999999999999999999.npy", "f2.npy"],
])
def test_an_e_between_digits_read_two_ways_is_refused(names):
    for shuffled in itertools.permutations(names):
        with pytest.raises(ValueError, match="an 'e' between digits may be an exponent"):
            natural_order(list(shuffled))


def test_an_e_between_digits_of_one_order_either_way_is_taken():
    names = ["t1e-3_f1", "t1e-3_f2", "t1e-3_f10", "t2e-3_f1"]
    for shuffled in itertools.permutations(names):
        assert natural_order(list(shuffled)) == names


@pytest.mark.parametrize("names, words", [
    (["F1.npy", "f1.npy", "f2.npy"], r"F1\.npy and f1\.npy in the folder of frames differ "
                                     r"only in case:"),
    (["f1.npy", "f1.tif", "f2.npy"], r"f1\.npy and f1\.tif in the folder of frames differ "
                                     r"only in their suffix:"),
    (["F1.TIF", "f1.npy", "f2.npy"], r"F1\.TIF and f1\.npy in the folder of frames differ "
                                     r"only in their suffix and case:"),
])
def test_one_frame_twice_is_said_to_differ_by_what_it_differs_by(tmp_path, names, words):
    """F1.npy beside f1.npy was said to differ only in its suffix."""
    _save(tmp_path, names)
    with pytest.raises(ValueError, match=words):
        read_frames(tmp_path)


@pytest.mark.parametrize("names, words", [
    (["F1.npy", "f1.npy"], "differ only in case"),
    (["F1.npy", "f1.tif"], "differ only in their suffix and case"),
    (["f1.npy", "f1.npy"], "'f1.npy' is named twice"),
])
def test_names_of_one_stem_are_refused_by_what_they_differ_by(names, words):
    with pytest.raises(ValueError, match=words):
        natural_order(names)
