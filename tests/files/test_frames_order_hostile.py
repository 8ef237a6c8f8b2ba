"""Frame names whose order the numbers in them do not settle alone: digits joined by several
points, digits after a point with none before it, a sign in names of different forms, digits
of other scripts, one frame saved in two formats, and hidden files beside the frames."""

from __future__ import annotations

import functools
import itertools
import re
import unicodedata

import numpy as np
import pytest

from snapcorr.cube import read_frames
from snapcorr.files.frames import natural_order


@pytest.mark.parametrize("names", [
    ["cap_12.5.3.npy", "cap_12.10.3.npy"],      # 12:05:03 and 12:10:03, unpadded
    ["v1.9.0.tif", "v1.10.0.tif"],              # versions
])
def test_digits_joined_by_points_of_different_widths_are_refused(names):
    """Read as decimals, 12.10 came before 12.5: the later time streamed first."""
    with pytest.raises(ValueError, match="digits joined by several points"):
        natural_order(names)


@pytest.mark.parametrize("names", [
    ["cap_09.59.59.npy", "cap_12.05.03.npy", "cap_12.10.03.npy"],  # padded: one order
    ["x12.09.4.npy", "x12.10.3.npy", "x12.11.3.npy"],
])
def test_digits_joined_by_points_of_one_width_keep_their_order(names):
    for shuffled in itertools.permutations(names):
        assert natural_order(list(shuffled)) == names


def test_a_sign_in_names_of_different_forms_is_refused_where_the_readings_differ():
    """``x-1``, ``x0``, ``x1_2``: the sign was ignored (the names differ in form) and x-1
    streamed last; as a sign it is first. The two readings differ: refused."""
    with pytest.raises(ValueError, match="may be its sign or a separator"):
        natural_order(["x-1.npy", "x1_2.npy", "x0.npy"])
    # where both readings give one order, it is kept
    assert natural_order(["z1_b.npy", "z-1.npy", "z0.npy"]) == ["z-1.npy", "z0.npy", "z1_b.npy"]


def test_digits_of_other_scripts_are_numbers():
    """Full-width digits were compared as text: a full-width ten came before a nine."""
    ten, nine = "t\uff11\uff10.npy", "t\uff19.npy"  # full width
    assert natural_order([ten, nine]) == [nine, ten]
    twelve, three = "t\u0661\u0662.npy", "t\u0663.npy"  # Arabic-Indic
    assert natural_order([twelve, three]) == [three, twelve]
    with pytest.raises(ValueError, match="how their characters are written"):
        natural_order(["t1.npy", "t\uff11.npy"])  # one number written twice


def test_one_frame_in_two_formats_is_refused(tmp_path):
    """f1.npy beside f1.tif was streamed as two frames taken."""
    import tifffile

    for k in (1, 2):
        np.save(tmp_path / f"f{k}.npy", np.full((4, 4), k, np.uint16))
    tifffile.imwrite(tmp_path / "F1.TIF", np.full((4, 4), 1, np.uint16))
    with pytest.raises(ValueError, match=r"F1\.TIF and f1\.npy .* differ only in their suffix "
                                         "and case"):
        read_frames(tmp_path)


@pytest.mark.parametrize("names, pair", [
    (["t.5.npy", "t.25.npy", "t1.npy"], ("t1.npy", "t.25.npy")),  # 0.5, 0.25, 1 or 5, 25, 1
    (["t.5.npy", "t0.25.npy", "t1.npy"], ("t1.npy", "t.5.npy")),
    (["img.1.tif", "img.2.tif", "img.15.tif"], ("img.2.tif", "img.15.tif")),  # 0.15 or 15
])
def test_digits_after_a_point_alone_read_two_ways_are_refused(names, pair):
    """t.5, t.25, t1 streamed as t1, t.5, t.25 (read as 5 and 25 after a separator) while
    t0.5 is read as a decimal; where reading the point as a decimal point orders them
    otherwise, they are refused, the two frames named."""
    for shuffled in itertools.permutations(names):
        with pytest.raises(ValueError, match=rf"frames '{re.escape(pair[0])}' and "
                                             rf"'{re.escape(pair[1])}': digits after a point "
                                             "with no digit before it"):
            natural_order(list(shuffled))


@pytest.mark.parametrize("names", [
    ["f.001.npy", "f.002.npy", "f.010.npy"],  # as many digits: one order either way
    ["a.5.npy", "b.25.npy"],
    # .1 and .10 are one decimal: these are numbers after a separator, the one reading left
    ["img.1.tif", "img.2.tif", "img.9.tif", "img.10.tif", "img.11.tif"],
])
def test_digits_after_a_point_alone_read_one_way_keep_their_order(names):
    for shuffled in itertools.permutations(names):
        assert natural_order(list(shuffled)) == names


def test_hidden_files_in_a_folder_of_frames_are_left_out(tmp_path):
    """A hidden .t0.npy (a copy's, a viewer's) was streamed as the first frame."""
    for k, name in enumerate([".t0.npy", "t1.npy", "t2.npy", "._t3.npy"]):
        np.save(tmp_path / name, np.full((4, 4), k, np.float32))
    frames = read_frames(tmp_path)
    assert frames.attrs["frame_files"] == ["t1.npy", "t2.npy"]
    assert "hidden files (names starting with '.') left out" in frames.attrs["frame_order"]
    np.testing.assert_array_equal(frames.values[:, 0, 0], [1, 2])


def test_letters_written_in_either_unicode_form_order_as_one():
    """``scène2`` written as ``e`` and an accent (as macOS names files), beside ``scène1`` and
    ``scène3`` written with one character, streamed first; a zero-width space and a ligature
    moved names after others. Compared as the letters they show."""
    nfc, nfd = (functools.partial(unicodedata.normalize, f) for f in ("NFC", "NFD"))
    for names in ([nfc("scène3"), nfd("scène2"), nfc("scène1")],
                  ["t2", "t\u200b1", "t3"], ["file3", "\ufb01le1", "file2"]):
        got = natural_order(names)
        assert [n[-1] for n in got] == ["1", "2", "3"], got
    with pytest.raises(ValueError, match="differ only in how their characters are written"):
        natural_order([nfc("scène1"), nfd("scène1")])
