"""Large variables go to Zarr in chunks of whole rows, whether held in memory or as one block.

Left to zarr, the flat field of a whole 2048 x 1088 x 16 frame was one chunk of 142 MB: every
block a reader took decoded all of it, and ``correct`` from that store peaked at 784 MiB
(404 MiB from the same store in chunks of rows).
"""

import dask.array as da
import numpy as np
import pytest
import xarray as xr
import zarr

from snapcorr.cube import write_dataset
from snapcorr.files.storage import ZARR_ROWS_BYTES, ZARR_WHOLE_BYTES


@pytest.mark.parametrize("lazy", [False, True])
def test_a_large_variable_is_stored_in_chunks_of_rows(tmp_path, lazy):
    shape = (1088, 2048, 5)  # 44.6 MB of float32
    data = np.random.default_rng(0).random(shape, np.float32)
    assert data.nbytes > ZARR_WHOLE_BYTES
    values = da.from_array(data, chunks=shape) if lazy else data  # one block
    ds = xr.Dataset({"reflectance": (("y", "x", "band"), values)})
    write_dataset(ds, tmp_path / "c.zarr")
    arr = zarr.open_group(tmp_path / "c.zarr", mode="r")["reflectance"]
    rows = arr.chunks[0]
    assert arr.chunks[1:] == shape[1:]
    assert 0.5 * ZARR_ROWS_BYTES <= rows * 2048 * 5 * 4 <= ZARR_ROWS_BYTES
    np.testing.assert_array_equal(arr[:], data)
