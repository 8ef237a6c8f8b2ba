"""Frame names compared by their numbers exactly: numbers a float cannot tell apart, a comma
read two ways, the same number written twice, and a stream that is not there."""

from __future__ import annotations

import random

import pytest

from snapcorr.files.frames import natural_order


@pytest.mark.parametrize("ordered", [
    ["f_1733112345123456789", "f_1733112345123456790", "f_1733112345123456791"],
    ["a" + "1" * 400, "a" + "1" * 399 + "2"],
    ["exp_1e-3_f1", "exp_1e-3_f2", "exp_2.5E-3_f1"],  # exponents of one order as letters too
    ["t0,25", "t0,50", "t0,75", "t1,00"],  # a decimal comma of one length: either reading
    ["t0,5", "t1", "t1,5", "t2"],
])
def test_numbers_in_names_are_compared_exactly(ordered):
    rng = random.Random(3)
    for _ in range(5):
        names = list(ordered)
        rng.shuffle(names)
        assert natural_order(names) == ordered


def test_a_comma_read_two_ways_is_refused():
    """t0,5 t0,25 t1: as a decimal comma 0.25 < 0.5, as a separator 5 < 25."""
    with pytest.raises(ValueError, match="decimal comma or a separator"):
        natural_order(["t0,5", "t0,25", "t1"])


def test_a_comma_that_may_separate_thousands_is_refused_where_the_orders_differ():
    """t1,000 t2,000 t999 streamed as 1,000; 2,000; 999: read as thousands, 999 is first.
    Where both readings give one order (every name with its comma, or commas of other
    widths) the names are taken."""
    with pytest.raises(ValueError, match="decimal comma or a thousands separator"):
        natural_order(["t1,000", "t2,000", "t999"])
    assert natural_order(["t3,500", "t1,000", "t2,000"]) == ["t1,000", "t2,000", "t3,500"]
    assert natural_order(["t1,5", "t0,5", "t2"]) == ["t0,5", "t1,5", "t2"]


def test_the_same_number_written_twice_is_still_refused():
    for names in (["f1", "f1.0"], ["f1e3", "f1000"], ["t0,5", "t0.5"]):
        with pytest.raises(ValueError, match="same number"):
            natural_order(names)


def test_a_stream_that_is_not_there_is_said_to_be_missing(tmp_path):
    from snapcorr.cube import read_frames

    with pytest.raises(FileNotFoundError, match="no such file or folder of frames"):
        read_frames(tmp_path / "frames")


@pytest.mark.parametrize("per", [1.5, True, 0, "2"])
def test_frames_per_chunk_is_a_whole_number(tmp_path, per):
    """read_frames(frames_per_chunk=1.5) cut it to 1, and True was taken as 1."""
    import numpy as np

    from snapcorr.cube import read_frames

    np.save(tmp_path / "s.npy", np.zeros((3, 4, 4), np.uint16))
    with pytest.raises(ValueError, match="frames_per_chunk must be a whole number >= 1"):
        read_frames(tmp_path / "s.npy", frames_per_chunk=per)
