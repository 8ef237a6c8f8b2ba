"""uint16 packing in one pass: the codes a file stores are those xarray's own CF encoding gives
the same values, and a CF reader gets back the values within the stated packing error."""

from __future__ import annotations

import dask.array as da
import numpy as np
import pytest
import xarray as xr

from snapcorr.files import write_dataset
from snapcorr.files._packing import pack_uint16
from snapcorr.files.datasets import (
    HDF5_MAX_CHUNK_BYTES,
    PACKED_FILL,
    PACKED_TOP,
    RATIO_PACK_RANGE,
    _hdf5_chunks,
)

LO, HI = RATIO_PACK_RANGE
SCALE, OFFSET = np.float32((HI - LO) / PACKED_TOP), np.float32(LO)


def _values(rng, shape, dtype=np.float32):
    v = rng.uniform(-0.8, 3.9, shape).astype(dtype)  # some beyond the range on both sides
    v.reshape(-1)[rng.choice(v.size, v.size // 50, replace=False)] = np.nan
    # exact half steps: rounding half to even, as xarray does
    v.reshape(-1)[:6] = OFFSET + (np.arange(6) + 0.5).astype(dtype) * dtype(SCALE)
    return v


def _xarray_codes(v):
    """xarray's own CF encoding of ``v`` clipped to the range, as writing did before."""
    coding = {"dtype": "uint16", "scale_factor": SCALE, "add_offset": OFFSET,
              "_FillValue": np.uint16(PACKED_FILL)}
    clipped = np.clip(v, LO, HI)
    return xr.conventions.encode_cf_variable(
        xr.Variable(("y", "x", "band"), clipped, encoding=coding)).values


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_one_pass_codes_are_xarrays_codes(dtype):
    v = _values(np.random.default_rng(1), (40, 30, 5), dtype)
    codes = pack_uint16(np.clip(v, LO, HI), OFFSET, SCALE, PACKED_TOP, PACKED_FILL)
    assert codes.dtype == np.uint16
    np.testing.assert_array_equal(codes, _xarray_codes(v))
    assert (codes[np.isnan(v)] == PACKED_FILL).all() and codes[~np.isnan(v)].max() <= PACKED_TOP
    # unclipped values land at the range's ends, never wrap around
    raw = pack_uint16(v, OFFSET, SCALE, PACKED_TOP, PACKED_FILL)
    np.testing.assert_array_equal(raw, codes)


@pytest.mark.parametrize("suffix", [".zarr", ".nc"])
@pytest.mark.parametrize("chunked", [False, True])
def test_packed_file_reads_back_the_values(tmp_path, suffix, chunked):
    v = _values(np.random.default_rng(2), (48, 32, 6))
    data = da.from_array(v, chunks=(16, 32, 6)) if chunked else v
    ds = xr.Dataset({"reflectance": (("y", "x", "band"), data, {"units": "1"})},
                    coords={"wavelength": ("band", np.linspace(500, 600, 6), {"units": "nm"})})
    path = write_dataset(ds, tmp_path / f"r{suffix}", dtype="uint16")
    engine = "zarr" if suffix == ".zarr" else "h5netcdf"
    with xr.open_dataset(path, engine=engine, mask_and_scale=True) as back:
        got = back["reflectance"].values
        error = float(back["reflectance"].attrs["packing_error"])
    with xr.open_dataset(path, engine=engine, mask_and_scale=False) as raw:
        stored = raw["reflectance"].values
    assert stored.dtype == np.uint16
    np.testing.assert_array_equal(stored, _xarray_codes(v))  # the values stored before
    want = np.clip(v, LO, HI)  # independent of the packing: the values, clipped
    assert np.array_equal(np.isnan(got), np.isnan(v))
    ok = ~np.isnan(v)
    assert np.abs(got[ok] - want[ok]).max() <= error
    assert float(SCALE) / 2 <= error < 1.1 * float(SCALE) / 2  # half a step, as stated


def _starts(blocks):
    return np.cumsum((0, *blocks[:-1]))


@pytest.mark.parametrize("blocks", [(5, 10, 10, 3), (10, 5, 5, 3), (4, 4, 4), (7,), (6, 9, 2)])
def test_compressed_netcdf_chunks_are_filled_whole_by_uneven_blocks(tmp_path, blocks):
    """Every dask block of a stream starts on a chunk boundary, where the blocks allow it
    (uneven blocks are what a stream of 5 then 10 frames a pass gives); the data are the same
    whatever the chunks."""
    n = sum(blocks)
    data = da.from_array(np.arange(n * 6 * 4, dtype=np.float32).reshape(n, 6, 4),
                         chunks=(blocks, 6, 4))
    var = xr.DataArray(data, dims=("frame", "y", "x"))
    chunk = _hdf5_chunks(var)["chunksizes"][0]
    # brute force: the largest size every block start is a multiple of, if not too small
    best = max(c for c in range(1, blocks[0] + 1) if all(s % c == 0 for s in _starts(blocks)))
    assert chunk == (best if 2 * best >= blocks[0] else blocks[0])
    write_dataset(xr.Dataset({"reflectance": var}), tmp_path / "s.nc")
    with xr.open_dataset(tmp_path / "s.nc", engine="h5netcdf") as back:
        np.testing.assert_array_equal(back["reflectance"].values, data.compute())
        assert back["reflectance"].encoding["chunksizes"][0] == chunk


def test_one_huge_block_is_stored_in_chunks_hdf5_accepts():
    """A whole 100-frame stream in one dask block (14 GiB of float32) would ask HDF5 for one
    chunk of that size, which it refuses over 4 GiB: the chunk is cut to at most the limit."""
    data = da.zeros((100, 1088, 2048, 16), dtype=np.float32, chunks=-1)
    var = xr.DataArray(data, dims=("frame", "y", "x", "band"))
    sizes = _hdf5_chunks(var)["chunksizes"]
    assert np.prod(sizes) * 4 <= HDF5_MAX_CHUNK_BYTES < 4 * 2**30
    assert all(1 <= c <= n for c, n in zip(sizes, var.shape, strict=True))
    assert np.prod(sizes) * 4 > HDF5_MAX_CHUNK_BYTES / 2**4  # not cut more than it must
