"""Every cube to zarr and back, chunked or not: a variable's layout in the file it was read
from (its store chunks) never decides how it is written again."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import xarray as xr

from snapcorr.cube import read_dataset, write_dataset


def _cube(shape, positions):
    ny, nx, nb = shape
    rng = np.random.default_rng(0)
    ds = xr.Dataset({"reflectance": (("y", "x", "band"), rng.random(shape, np.float32),
                                     {"units": "1"}),
                     "mask": (("y", "x", "band"), rng.random(shape) > 0.9)},
                    coords={"wavelength": ("band", np.linspace(470.0, 620.0, nb),
                                           {"units": "nm"})})
    if positions == "per band":  # a mosaic's tile cube or demosaicked cube
        ds = ds.assign_coords(sensor_row=(("y", "band"), np.arange(ny)[:, None] * 4
                                          + np.arange(nb)[None, :] // 4),
                              sensor_col=(("x", "band"), np.arange(nx)[:, None] * 4
                                          + np.arange(nb)[None, :] % 4))
    elif positions == "per pixel":  # a Snapscan crop
        ds = ds.assign_coords(sensor_row=("y", 100 + np.arange(ny)),
                              sensor_col=("x", 50 + np.arange(nx)))
    return ds


CHUNKS = [None, {"y": 25}, {"y": 7, "x": 20}]
ALL = list(itertools.product(["per band", "per pixel", "none"], [".zarr", ".nc"],
                             [".zarr", ".nc"], CHUNKS))
#: The default run: every way a mosaic cube (positions per band, the failing class) leaves a
#: zarr store, and one of each other kind; the whole product with -m slow.
DEFAULT = ([("per band", ".zarr", second, c) for second in (".zarr", ".nc") for c in CHUNKS]
           + [("per band", ".nc", ".zarr", CHUNKS[1]), ("per pixel", ".zarr", ".zarr",
                                                          CHUNKS[2])])
CASES = DEFAULT + [pytest.param(*c, marks=pytest.mark.slow) for c in ALL if c not in DEFAULT]


@pytest.mark.parametrize("positions, first, second, chunks", CASES)
def test_a_cube_read_in_other_blocks_is_written_again(tmp_path, positions, first, second,
                                                      chunks):
    ds = _cube((60, 30, 16), positions)
    a = tmp_path / f"a{first}"
    write_dataset(ds.chunk({"y": 16}), a)  # stored in blocks of rows (zarr)
    read = read_dataset(a, chunks=chunks)
    b = tmp_path / f"b{second}"
    write_dataset(read, b)
    back = read_dataset(b).load()
    xr.testing.assert_equal(back.drop_attrs(), ds.drop_attrs())
