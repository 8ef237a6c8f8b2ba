"""Counts and records said exactly: the chunks a huge Zarr grid lacks, and the reading of
frame names as signed numbers."""

from __future__ import annotations

import numpy as np
import pytest
import zarr

from snapcorr.files.chunks import _refuse_incomplete_zarr, _refuse_missing_chunks


def _sparse_store(path, zarr_format):
    """An array of 10**6 x 10**6 in chunks of 1000 x 1000 (10**6 chunks, too many to walk),
    three of them written."""
    g = zarr.open_group(str(path), mode="w", zarr_format=zarr_format)
    arr = g.create_array("raw", shape=(10**6, 10**6), chunks=(1000, 1000), dtype="uint16",
                         fill_value=0)
    arr[0:1000, 0:1000] = 1
    arr[5000:6000, 0:1000] = 2
    arr[0:1000, 7000:8000] = 3
    return g


def test_a_huge_grid_lacking_chunks_says_how_many_exactly(tmp_path):
    """The array's metadata file (zarr.json) was counted as a chunk: one too few said."""
    _sparse_store(tmp_path / "huge.zarr", 3)
    with pytest.raises(ValueError, match=r"variable 'raw' lacks 999997 of its 1000000 chunks"):
        _refuse_incomplete_zarr(tmp_path / "huge.zarr")


def test_a_huge_zarr_2_grid_lacking_chunks_says_how_many_exactly(tmp_path):
    """Zarr 2 keeps .zarray and .zattrs beside the chunks: two too few said."""
    g = _sparse_store(tmp_path / "huge2.zarr", 2)
    with pytest.raises(ValueError, match=r"variable 'raw' lacks 999997 of its 1000000 chunks"):
        _refuse_missing_chunks(tmp_path / "huge2.zarr",
                               [("raw", tmp_path / "huge2.zarr" / "raw", g["raw"])], cf=False)


def test_a_huge_sharded_grid_counts_chunks_inside_the_array(tmp_path):
    """A shard at the array's edge holds only the chunks inside the array; a grid of 10**4
    shards is not walked."""
    g = zarr.open_group(str(tmp_path / "sh.zarr"), mode="w")
    arr = g.create_array("raw", shape=(1500, 10**7), chunks=(500, 1000),
                         shards=(1000, 2000), dtype="uint16")
    arr[1000:1500, 0:2000] = 1  # the edge shard (1, 0): 2 chunks inside the array
    total = 3 * 10**4
    with pytest.raises(ValueError, match=rf"lacks {total - 2} of its {total} chunks"):
        _refuse_incomplete_zarr(tmp_path / "sh.zarr")


def test_a_huge_sharded_grid_counts_the_chunks_a_shard_lacks(tmp_path):
    """A shard holding one of its four chunks was counted whole where the grid is too large
    to walk: three missing chunks left out of the count."""
    g = zarr.open_group(str(tmp_path / "part.zarr"), mode="w")
    arr = g.create_array("raw", shape=(2000, 10**7), chunks=(500, 1000),
                         shards=(1000, 2000), dtype="uint16")
    arr[0:500, 0:1000] = 1  # shard (0, 0): one of its four chunks written
    arr[1000:2000, 2000:4000] = 2  # shard (1, 1): all four
    total = 4 * 10**4
    with pytest.raises(ValueError, match=rf"lacks {total - 5} of its {total} chunks"):
        _refuse_incomplete_zarr(tmp_path / "part.zarr")


def test_the_recorded_frame_order_says_how_signs_are_read(tmp_path):
    """Names of as many numbers whose signs differ (a-1, a-2, a3) are read as signed numbers
    with no comparison of the two readings (as text a3 would come first): the record says the
    readings are compared only where the names hold different counts of numbers."""
    from snapcorr.files.frames import FRAME_ORDER, natural_order, read_frames

    names = ["a-1.npy", "a-2.npy", "a3.npy"]
    for k, n in enumerate(names):
        np.save(tmp_path / n, np.full((2, 2), k, np.float32))
    frames = read_frames(tmp_path)
    assert frames.attrs["frame_files"] == ["a-2.npy", "a-1.npy", "a3.npy"]
    assert natural_order(["a-1", "a-2", "a3"]) == ["a-2", "a-1", "a3"]
    assert natural_order(["a-1_", "a-2_", "a3_"]) == ["a-2_", "a-1_", "a3_"]
    as_separators = sorted(names, key=lambda n: (n[:-5], n))  # 'a' before 'a-'
    assert as_separators[0] == "a3.npy"  # the two readings differ, and the names are taken
    text = frames.attrs["frame_order"]
    assert text == FRAME_ORDER
    assert "where both readings give one order" not in text
    signs = text[text.index("a '-' or '+'"):]
    assert signs.startswith("a '-' or '+' before a number read as its sign where the names "
                            "differ by it at that place, else as part of the text (where the "
                            "names hold different counts of numbers, refused if the two "
                            "readings give different orders; where they hold as many, read so "
                            "without comparing them)")
    with pytest.raises(ValueError, match="in names of different forms the two orders differ"):
        natural_order(["x-1", "x0", "x1_2"])


@pytest.mark.parametrize("chunks", [{"y": 0}, 7, {"y": 1.5}, {"y": True}])
def test_chunks_that_are_no_block_sizes_are_refused_by_name(tmp_path, chunks):
    """read_cube(..., chunks={'y': 0}) was said as "FILE: cannot read it as zarr:
    ZeroDivisionError", blaming the file for the argument."""
    from snapcorr.cube import make_cube, read_cube, write_cube

    write_cube(make_cube(np.ones((4, 4, 2), np.float32), [500.0, 600.0]), tmp_path / "c.zarr")
    with pytest.raises(ValueError, match=r"^chunks"):
        read_cube(tmp_path / "c.zarr", chunks=chunks)
