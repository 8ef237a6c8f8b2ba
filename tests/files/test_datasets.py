"""uint16 packing in one pass: the codes a file stores are those xarray's own CF encoding gives
the same values, and a CF reader gets back the values within the stated packing error."""

from __future__ import annotations

import dask.array as da
import numpy as np
import pytest
import xarray as xr

from snapcorr.files import write_dataset
from snapcorr.files._packing import pack_uint16
from snapcorr.files.datasets import PACKED_FILL, PACKED_TOP, RATIO_PACK_RANGE

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
