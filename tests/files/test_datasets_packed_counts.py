"""A camera's numbers are read as stored: netCDF and Zarr frames or cubes of integers that
carry CF packing or fill values (which xarray applies on reading) are refused where they
hold counts; packed physical values are unpacked, as the file means."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from snapcorr.cube import read_cube, read_frame, read_frames

COUNTS = np.arange(2 * 8 * 8, dtype=np.uint16).reshape(2, 8, 8) * 7


def _write(path, data, dims, packing, attrs=None):
    """Integers stored as they are, the packing written as the variable's attributes (as a
    camera's own software would write them), which xarray applies when it reads."""
    ds = xr.DataArray(data, dims=dims, name="frames",
                      attrs={**(attrs or {}), **packing}).to_dataset()
    if path.suffix == ".nc":
        ds.to_netcdf(path, engine="h5netcdf")
    else:
        ds.to_zarr(path, consolidated=False)
    return path


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
@pytest.mark.parametrize("encoding, said", [
    ({"scale_factor": 0.5}, "scale_factor 0.5"),
    ({"add_offset": 10.0}, "add_offset 10.0"),
    ({"missing_value": np.uint16(7)}, "missing_value"),
])
def test_packed_or_filled_frames_are_refused_not_unpacked(tmp_path, suffix, encoding, said):
    stream = _write(tmp_path / f"s{suffix}", COUNTS, ("frame", "y", "x"), encoding)
    with pytest.raises(ValueError, match=rf"frames is stored as uint16 with {said}.*camera's "
                                         "numbers would not be read as they are"):
        read_frames(stream)
    frame = _write(tmp_path / f"f{suffix}", COUNTS[0], ("y", "x"), encoding)
    for read in (read_frame, read_cube):
        with pytest.raises(ValueError, match=said):
            read(frame) if read is read_frame else read(frame, wavelength_nm=[550.0])


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_plain_integer_frames_read_exactly_as_stored(tmp_path, suffix):
    stream = _write(tmp_path / f"s{suffix}", COUNTS, ("frame", "y", "x"), {})
    got = read_frames(stream)
    assert got.dtype == np.uint16
    np.testing.assert_array_equal(got.values, COUNTS)


def test_packed_physical_values_are_unpacked(tmp_path):
    """Reflectance packed in uint16 (units 1) means the unpacked values."""
    path = _write(tmp_path / "r.nc", COUNTS[0], ("y", "x"), {"scale_factor": 1 / 1000},
                  attrs={"units": "1"})
    cube = read_cube(path, wavelength_nm=[550.0])
    np.testing.assert_allclose(cube.values[..., 0], COUNTS[0] / 1000, rtol=1e-6)


def test_the_command_line_says_so_in_one_line(tmp_path, cli):
    stream = _write(tmp_path / "s.zarr", COUNTS, ("frame", "y", "x"),
                    {"scale_factor": 2.0})
    ref = _write(tmp_path / "w.nc", COUNTS[0], ("y", "x"), {})
    code, _, err = cli("stream", str(stream), "--dark", str(ref), "--white", str(ref),
                         "--sensor", "mosaic_4x4_vis", "--sensor-origin-px", "0,0",
                         "--out", str(tmp_path / "o.zarr"))
    assert code == 1 and "scale_factor 2.0" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
