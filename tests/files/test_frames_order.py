"""Frames in the order they were taken: names compared with their numbers as numbers,
decimals and signs included, and a refusal where two names cannot be ordered."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from snapcorr.cube import read_frames
from snapcorr.files.frames import FRAME_ORDER, natural_order

ORDERED = [
    ["t0.25.npy", "t0.5.npy", "t0.75.npy", "t1.npy"],  # decimal times
    ["frame-1.tif", "frame-2.tif", "frame-10.tif"],  # '-' in every name: a separator
    ["z-1.tif", "z-0.5.tif", "z+0.tif", "z+0.5.tif", "z2.tif"],  # signs where names differ
    ["2026-11-30T23-59-59.9.tif", "2026-12-01T00-00-00.1.tif", "2026-12-01T10-15-30.tif"],
    ["a.tif", "B.tif", "c9.tif", "c10.tif", "c10.5.tif"],
    ["run2_f0009.npy", "run2_f0010.npy", "run10_f0001.npy"],
]


@pytest.mark.parametrize("names", ORDERED, ids=[n[0] for n in ORDERED])
def test_every_shuffle_comes_back_in_the_order_taken(names):
    for shuffled in itertools.islice(itertools.permutations(names), 24):
        assert natural_order(list(shuffled)) == names


def test_the_order_is_that_of_the_numbers_for_any_decimal_times():
    """Against the order of the times themselves, for times written as %g writes them."""
    rng = np.random.default_rng(3)
    times = np.unique([round(t, d) for t, d in zip(rng.uniform(-50, 50, 40),
                                                   rng.integers(0, 4, 40), strict=True)])
    names = [f"t{t:g}.npy" for t in times]  # t-0.5, t0.25, t12 ...
    assert natural_order(list(rng.permutation(names))) == names


@pytest.mark.parametrize("names", [["f1.npy", "f01.npy"], ["t0.5.tif", "t0.50.tif"]])
def test_names_of_equal_numbers_are_refused(names):
    with pytest.raises(ValueError, match="order is ambiguous"):
        natural_order(names)


def test_a_folder_streams_in_that_order_and_says_so(tmp_path):
    times = [0.25, 0.5, 0.75, 1.0]
    for t in reversed(times):  # written in another order than taken
        np.save(tmp_path / f"t{t:g}.npy", np.full((4, 4), t, np.float32))
    frames = read_frames(tmp_path)
    assert frames.attrs["frame_files"] == ["t0.25.npy", "t0.5.npy", "t0.75.npy", "t1.npy"]
    assert frames.attrs["frame_order"] == FRAME_ORDER
    np.testing.assert_array_equal(frames.values[:, 0, 0], times)
