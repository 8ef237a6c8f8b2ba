"""A Zarr store lacking chunks: zarr reads each as the array's fill value, which for integers
(and floats filled with a number) is a valid value, so the store is refused; a fill value that
reads as missing (NaN, a boolean mask's false) is not, and snapcorr's own stores are whole.
A netCDF-4 file whose chunks were never written (HDF5 reads them as the fill value) likewise."""

from __future__ import annotations

import shutil
import warnings

import dask.array as da
import numpy as np
import pytest
import xarray as xr
import zarr

from snapcorr.cube import make_cube, read_cube, read_dataset, write_cube, write_dataset
from snapcorr.files.frames import read_frames

WL = [500.0, 550.0, 600.0]



def _raw_store(tmp_path, name="zraw.zarr"):
    rng = np.random.default_rng(0)
    raw = make_cube(rng.integers(1000, 2000, (64, 64, 3)).astype(np.uint16), WL)
    path = tmp_path / name
    raw.to_dataset(name="raw").to_zarr(path, consolidated=False,
                                       encoding={"raw": {"chunks": (16, 64, 3)}})
    return path


def test_a_cube_lacking_a_chunk_is_refused(tmp_path):
    path = _raw_store(tmp_path)
    chunk = path / "raw" / "c" / "2" / "0" / "0"
    assert chunk.is_file()  # the Zarr 3 layout this test relies on
    chunk.unlink()
    with pytest.raises(ValueError, match=r"zraw\.zarr: variable 'raw' lacks 1 of its 4 chunks"
                                         r".*fill value 0"):
        read_cube(path)
    with pytest.raises(ValueError, match="lacks 1 of its 4 chunks"):
        read_cube(path, chunks={})
    with pytest.raises(ValueError, match="lacks 1 of its 4 chunks"):
        read_dataset(path)


def test_flatfield_of_a_cube_lacking_a_chunk_is_an_error(tmp_path, capsys):
    from snapcorr.cli import main

    path = _raw_store(tmp_path)
    (path / "raw" / "c" / "2" / "0" / "0").unlink()
    write_cube(make_cube(np.full((64, 64, 3), 100, np.uint16), WL), tmp_path / "d.hdr")
    write_cube(make_cube(np.full((64, 64, 3), 3000, np.uint16), WL), tmp_path / "w.hdr")
    out = tmp_path / "ff.nc"
    assert main(["flatfield", str(path), "--dark", str(tmp_path / "d.hdr"), "--white",
                 str(tmp_path / "w.hdr"), "--out", str(out)]) != 0
    assert "variable 'raw' lacks 1 of its 4 chunks" in capsys.readouterr().err
    assert not out.exists()


def _frames_store(tmp_path):
    rng = np.random.default_rng(1)
    path = tmp_path / "zfr.zarr"
    xr.Dataset({"frames": (("frame", "y", "x"),
                           rng.integers(1000, 2000, (3, 8, 8)).astype(np.uint16))}).to_zarr(
        path, consolidated=False, encoding={"frames": {"chunks": (1, 8, 8)}})
    return path


def test_frames_lacking_a_chunk_are_refused(tmp_path):
    path = _frames_store(tmp_path)
    shutil.rmtree(path / "frames" / "c" / "1")
    with pytest.raises(ValueError, match=r"variable 'frames' lacks 1 of its 3 chunks"):
        read_frames(path)


def test_stream_of_frames_lacking_a_chunk_is_an_error(tmp_path, capsys):
    from snapcorr.cli import main

    path = _frames_store(tmp_path)
    shutil.rmtree(path / "frames" / "c" / "1")
    np.save(tmp_path / "d.npy", np.full((8, 8), 100, np.uint16))
    np.save(tmp_path / "w.npy", np.full((8, 8), 3000, np.uint16))
    out = tmp_path / "o.zarr"
    assert main(["stream", str(path), "--dark", str(tmp_path / "d.npy"), "--white",
                 str(tmp_path / "w.npy"), "--sensor", "mosaic_4x4_vis", "--sensor-origin-px",
                 "0,0", "--out", str(out)]) != 0
    assert "variable 'frames' lacks 1 of its 3 chunks" in capsys.readouterr().err
    assert not out.exists()


def test_a_plain_zarr_array_of_frames_lacking_a_chunk_is_refused(tmp_path):
    path = tmp_path / "plain.zarr"
    arr = zarr.create_array(str(path), shape=(3, 8, 8), chunks=(1, 8, 8), dtype="uint16")
    arr[:] = 7
    shutil.rmtree(path / "c" / "2")
    with pytest.raises(ValueError, match=r"plain\.zarr: variable 'the array' lacks 1 of its 3"):
        read_frames(path)


def test_a_float_cube_filled_with_a_number_lacking_a_chunk_is_refused(tmp_path):
    cube = make_cube(np.full((64, 64, 3), 0.5, np.float32), WL, name="reflectance",
                     attrs={"units": "1"})
    path = tmp_path / "f.zarr"
    cube.to_dataset().to_zarr(path, consolidated=False, encoding={
        "reflectance": {"chunks": (16, 64, 3), "fill_value": 0.0}})
    assert zarr.open_array(str(path / "reflectance"), mode="r").fill_value == 0
    (path / "reflectance" / "c" / "0" / "0" / "0").unlink()
    with pytest.raises(ValueError, match="variable 'reflectance' lacks 1 of its 4 chunks"):
        read_cube(path)


def test_a_float_cube_filled_with_nan_lacking_a_chunk_reads_as_missing(tmp_path):
    cube = make_cube(np.full((64, 64, 3), 0.5, np.float32), WL, name="reflectance",
                     attrs={"units": "1"})
    path = tmp_path / "f.zarr"
    cube.to_dataset().to_zarr(path, consolidated=False,
                              encoding={"reflectance": {"chunks": (16, 64, 3)}})
    (path / "reflectance" / "c" / "0" / "0" / "0").unlink()
    values = read_cube(path).values
    assert np.isnan(values[:16]).all() and (values[16:] == 0.5).all()


def test_a_mask_without_its_all_false_chunks_is_read(tmp_path):
    """snapcorr leaves out a mask's all-false chunks (zarr's own check kept for booleans)."""
    cube = make_cube(da.from_array(np.full((64, 64, 3), 0.5, np.float32), chunks=(16, 64, 3)),
                     WL, name="reflectance", attrs={"units": "1"})
    mask = np.zeros((64, 64, 3), bool)
    mask[40, 3, 1] = True
    ds = cube.to_dataset()
    ds["mask"] = (cube.dims, da.from_array(mask, chunks=(16, 64, 3)))
    path = tmp_path / "r.zarr"
    write_dataset(ds, path)
    stored = zarr.open_array(str(path / "mask"), mode="r")
    assert stored.nchunks_initialized < stored.nchunks  # chunks left out
    back = read_dataset(path)
    np.testing.assert_array_equal(back["mask"].values, mask)
    read_cube(path)


def test_a_cube_with_a_chunk_of_zeros_is_written_whole(tmp_path):
    """Integer chunks holding only the fill value are stored, also when the cube keeps the
    compression of the store it was read from (left out, they could not be told from lost
    ones)."""
    a = np.full((64, 64, 3), 1500, np.uint16)
    a[:16] = 0
    cube = make_cube(da.from_array(a, chunks=(16, 64, 3)), WL)
    write_cube(cube, tmp_path / "a.zarr")
    again = read_cube(tmp_path / "a.zarr", chunks={})
    assert again.encoding.get("compressors")  # its own compression, kept when written again
    write_cube(again, tmp_path / "b.zarr")
    for name in ("a.zarr", "b.zarr"):
        stored = zarr.open_array(str(tmp_path / name / "raw"), mode="r")
        assert stored.nchunks_initialized == stored.nchunks == 4
        np.testing.assert_array_equal(read_cube(tmp_path / name).values, a)


@pytest.mark.parametrize("dtype", [None, "float16", "uint16"])
def test_results_of_every_storage_type_read_back(tmp_path, dtype):
    values = np.full((32, 8, 3), 0.25, np.float32)
    values[:8] = 0.0  # a chunk of zeros: uint16 codes and float16 values of its fill value
    cube = make_cube(da.from_array(values, chunks=(8, 8, 3)), WL, name="reflectance",
                     attrs={"units": "1"})
    ds = cube.to_dataset()
    ds["raw"] = (cube.dims, da.from_array(np.zeros((32, 8, 3), np.uint16), chunks=(8, 8, 3)),
                 {"units": "count"})
    ds["mask"] = (cube.dims, np.zeros((32, 8, 3), bool))
    ds["n_masked"] = np.int64(0)
    path = tmp_path / "r.zarr"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_dataset(ds, path, dtype=dtype)
    back = read_dataset(path)
    np.testing.assert_allclose(back["reflectance"].values, values, atol=1e-4)
    assert int(back["n_masked"]) == 0 and not back["mask"].values.any()
    read_cube(path)
    for name in ("reflectance", "raw", "n_masked"):
        stored = zarr.open_array(str(path / name), mode="r")
        assert stored.nchunks_initialized == stored.nchunks, name


def test_a_zarr_2_cube_lacking_a_chunk_is_refused(tmp_path):
    rng = np.random.default_rng(2)
    raw = make_cube(rng.integers(1000, 2000, (64, 64, 3)).astype(np.uint16), WL)
    path = tmp_path / "v2.zarr"
    raw.to_dataset(name="raw").to_zarr(path, consolidated=False, zarr_format=2,
                                       encoding={"raw": {"chunks": (16, 64, 3)}})
    (path / "raw" / "1.0.0").unlink()
    with pytest.raises(ValueError, match="variable 'raw' lacks 1 of its 4 chunks"):
        read_cube(path)


def test_a_sharded_cube_lacking_a_shard_is_refused(tmp_path):
    rng = np.random.default_rng(3)
    raw = make_cube(rng.integers(1000, 2000, (64, 64, 3)).astype(np.uint16), WL)
    path = tmp_path / "sh.zarr"
    raw.to_dataset(name="raw").to_zarr(path, consolidated=False, encoding={
        "raw": {"chunks": (8, 64, 3), "shards": (16, 64, 3)}})
    (path / "raw" / "c" / "3" / "0" / "0").unlink()
    with pytest.raises(ValueError, match="variable 'raw' lacks 2 of its 8 chunks"):
        read_cube(path)


def _partial_netcdf(path, contiguous=False, fill=None):
    """A netCDF-4 file whose raw cube has its last 16 rows never written (all of it, not
    chunked), as a writer stopped part way leaves it."""
    import h5netcdf

    with h5netcdf.File(path, "w") as f:
        f.dimensions = {"y": 64, "x": 64, "band": 3}
        wl = f.create_variable("wavelength", ("band",), "f8")
        wl[:] = WL
        wl.attrs["units"] = "nm"
        kw = {} if contiguous else {"chunks": (16, 64, 3)}
        if fill is not None:
            kw["fillvalue"] = fill
        raw = f.create_variable("raw", ("y", "x", "band"), "u2", **kw)
        raw.attrs["units"] = "count"
        if not contiguous:
            raw[:48] = 1500
    return path


def test_a_netcdf_cube_with_chunks_never_written_is_refused(tmp_path):
    path = _partial_netcdf(tmp_path / "part.nc")
    with pytest.raises(ValueError, match=r"part\.nc: variable 'raw' lacks 1 of its 4 chunks, "
                                         r"never written.*fill value 0"):
        read_cube(path)
    with pytest.raises(ValueError, match="lacks 1 of its 4 chunks"):
        read_dataset(path)
    path = _partial_netcdf(tmp_path / "empty.nc", contiguous=True)
    with pytest.raises(ValueError, match="variable 'raw' lacks 1 of its 1 chunks"):
        read_cube(path)


def test_netcdf_chunks_never_written_that_read_as_missing_are_accepted(tmp_path):
    """A CF _FillValue: xarray reads the chunks never written as NaN (missing, not wrong)."""
    import h5py

    path = _partial_netcdf(tmp_path / "part.nc", fill=65535)
    with h5py.File(path, "a") as f:
        f["raw"].attrs["_FillValue"] = np.uint16(65535)
    back = read_dataset(path)
    assert np.isnan(back["raw"].values[48:]).all() and (back["raw"].values[:48] == 1500).all()


def test_a_netcdf_result_with_a_chunk_of_zeros_reads_back(tmp_path):
    a = np.full((64, 64, 3), 1500, np.uint16)
    a[:16] = 0
    write_cube(make_cube(da.from_array(a, chunks=(16, 64, 3)), WL), tmp_path / "a.nc")
    np.testing.assert_array_equal(read_cube(tmp_path / "a.nc").values, a)
    values = np.zeros((32, 8, 3), np.float32)
    ds = make_cube(da.from_array(values, chunks=(8, 8, 3)), WL, name="reflectance",
                   attrs={"units": "1"}).to_dataset()
    for dtype in (None, "uint16"):
        write_dataset(ds, tmp_path / f"r{dtype}.nc", dtype=dtype)
        np.testing.assert_allclose(read_dataset(tmp_path / f"r{dtype}.nc")["reflectance"],
                                   values, atol=1e-4)


def test_the_copy_a_refusal_advises_reads_chunks_left_out_as_their_fill_value(tmp_path):
    """A store whose writer left out its chunks of zeros (Zarr's default, and snapcorr's
    writer before it wrote every chunk) is refused; the copy the refusal names, made as it
    says, holds every chunk and reads back with those zeros."""
    import re

    a = np.full((64, 64, 3), 1500, np.uint16)
    a[16:32] = 0
    path = tmp_path / "old.zarr"
    make_cube(a, WL).to_dataset(name="raw").to_zarr(
        path, consolidated=False,
        encoding={"raw": {"chunks": (16, 64, 3), "write_empty_chunks": False}})
    assert not (path / "raw" / "c" / "1" / "0" / "0").exists()  # left out as its writer does
    with pytest.raises(ValueError, match="lacks 1 of its 4 chunks") as err:
        read_cube(path)
    recipe = re.search(r"(xarray\.open_zarr\(store\)\.to_zarr\(copy, [^)]*\))", str(err.value))
    copy = tmp_path / "copy.zarr"
    with warnings.catch_warnings():  # xarray says the store has no consolidated metadata
        warnings.simplefilter("ignore", RuntimeWarning)
        eval(recipe.group(1), {"xarray": xr, "store": str(path), "copy": str(copy)})
    np.testing.assert_array_equal(read_cube(copy).values, a)


def test_a_shard_lacking_one_of_its_chunks_is_refused(tmp_path):
    """A shard file that is there but lacks an inner chunk (its writer left out a chunk of the
    fill value, or stopped part way) read that chunk as 0 DN without a word: the shards'
    files alone were counted."""
    a = np.full((32, 32, 16), 1500, np.uint16)
    a[0:8, 8:16] = 0
    path = tmp_path / "inner.zarr"
    make_cube(a, np.linspace(450.0, 650.0, 16)).to_dataset(name="raw").to_zarr(
        path, consolidated=False, encoding={"raw": {"chunks": (8, 8, 16),
                                                    "shards": (16, 16, 16),
                                                    "write_empty_chunks": False}})
    assert (path / "raw" / "c" / "0" / "0" / "0").is_file()  # the shard is there
    with pytest.raises(ValueError, match="variable 'raw' lacks 1 of its 16 chunks"):
        read_cube(path)


def test_a_shard_at_the_array_edge_counts_only_chunks_inside_it(tmp_path):
    """Shards reaching past the array's end hold no chunk beyond it: a whole store reads."""
    rng = np.random.default_rng(5)
    a = rng.integers(1000, 2000, (40, 24, 3)).astype(np.uint16)
    path = tmp_path / "edge.zarr"
    make_cube(a, WL).to_dataset(name="raw").to_zarr(
        path, consolidated=False, encoding={"raw": {"chunks": (8, 8, 3),
                                                    "shards": (16, 16, 3)}})
    np.testing.assert_array_equal(read_cube(path).values, a)


def test_a_store_declaring_billions_of_chunks_is_refused_at_once(tmp_path):
    """Metadata alone, 200000 x 200000 x 16 in 1 x 1 x 16 chunks (4e10 chunks): the check
    walked every key, minutes before any bound; a grid far beyond the files there is not
    walked."""
    import time

    path = tmp_path / "huge.zarr"
    g = zarr.open_group(str(path), mode="w")
    arr = g.create_array("raw", shape=(200000, 200000, 16), chunks=(1, 1, 16), dtype="uint16",
                         dimension_names=("y", "x", "band"))
    arr[0, 0] = 1
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"variable 'raw' lacks \d+ of its 40000000000 chunks"):
        from snapcorr.files.chunks import _refuse_incomplete_zarr

        _refuse_incomplete_zarr(path)
    assert time.perf_counter() - t0 < 5.0


def test_a_store_stating_no_fill_value_says_what_a_missing_chunk_reads_as(tmp_path):
    rng = np.random.default_rng(6)
    raw = make_cube(rng.integers(1000, 2000, (64, 64, 3)).astype(np.uint16), WL)
    path = tmp_path / "nofill.zarr"
    g = zarr.open_group(str(path), mode="w", zarr_format=2)
    g.attrs["_ARRAY_DIMENSIONS"] = []
    g.create_array("wavelength", data=np.array(WL))[...] = WL
    g["wavelength"].attrs.update({"_ARRAY_DIMENSIONS": ["band"], "units": "nm"})
    stored = g.create_array("raw", shape=(64, 64, 3), chunks=(16, 64, 3), dtype="uint16",
                            fill_value=None)
    stored[:] = raw.values
    stored.attrs["_ARRAY_DIMENSIONS"] = ["y", "x", "band"]
    assert zarr.open_array(str(path / "raw"), mode="r").fill_value is None
    (path / "raw" / "1.0.0").unlink()
    with pytest.raises(ValueError, match=r"read them as 0 \(it states no fill value\), a valid "
                                         "uint16 value"):
        read_cube(path)


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_consolidated_metadata_left_stale_is_not_believed(tmp_path, zarr_format):
    """A store written with consolidated metadata, then one array grown from 3 frames to 4 by
    a writer that did not consolidate again: the consolidated copy says 3, and the 4th frame
    was streamed away without a word. Each array's own metadata is read."""
    path = tmp_path / "frames.zarr"
    frames = np.arange(3 * 8 * 8, dtype=np.uint16).reshape(3, 8, 8)
    xr.Dataset({"raw": (("frame", "y", "x"), frames)}).to_zarr(
        path, consolidated=True, zarr_format=zarr_format, encoding={"raw": {"chunks": (1, 8, 8)}})
    arr = zarr.open_array(str(path / "raw"), mode="r+")
    arr.resize((4, 8, 8))
    arr[3] = 7
    ds = read_dataset(path)
    assert ds["raw"].shape == (4, 8, 8) and int(ds["raw"][3].max()) == 7
    assert read_frames(path).shape[0] == 4


def test_a_damaged_input_chunk_is_said_of_the_input_not_the_output(tmp_path):
    """One chunk's bytes overwritten in a Blosc-compressed store: computing the output met
    Blosc's "error during blosc decompression: -1", said as "cannot write OUT"."""
    src = tmp_path / "in.zarr"
    cube = make_cube(np.random.default_rng(1).random((32, 16, 3)).astype(np.float32), WL)
    cube.to_dataset(name="reflectance").to_zarr(src, consolidated=False, zarr_format=2,
                                                encoding={"reflectance": {"chunks": (8, 16, 3)}})
    chunk = src / "reflectance" / "1.0.0"
    chunk.write_bytes(chunk.read_bytes()[:16] + b"\x00" * (len(chunk.read_bytes()) - 16))
    ds = read_dataset(src, chunks={"y": 8})
    with pytest.raises(ValueError, match=r"a chunk of the input .*in\.zarr cannot be decoded "
                       r"\(.*\): the store is damaged or truncated; .* Nothing was written to "
                       r".*out\.nc"):
        write_dataset(ds, tmp_path / "out.nc")
    assert not (tmp_path / "out.nc").exists()


@pytest.mark.parametrize("stored", ["float64", "float16"])
def test_a_store_whose_metadata_states_another_type_is_refused_naming_the_variable(
        tmp_path, stored):
    """``data_type`` edited from float32: the chunk's bytes are too few or too many for the
    shape, and zarr failed with numpy's "cannot reshape array of size 2304" wherever the
    values were first computed, naming neither the store nor the variable."""
    import json

    rng = np.random.default_rng(0)
    path = tmp_path / "c.zarr"
    write_cube(make_cube(rng.random((24, 32, 3)).astype(np.float32), WL, name="reflectance"),
               path)
    meta = path / "reflectance" / "zarr.json"
    doc = json.loads(meta.read_text())
    assert doc["data_type"] == "float32"
    doc["data_type"] = stored
    meta.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"c\.zarr: variable 'reflectance': its first chunk "
                       rf"does not hold {stored} values.*metadata does not match its chunks"):
        read_cube(path)
    # a plain array of frames (no xarray names) likewise
    arr = zarr.open_array(str(tmp_path / "frames.zarr"), mode="w", shape=(2, 8, 8),
                          chunks=(1, 8, 8), dtype="uint16")
    arr[:] = 7
    meta = tmp_path / "frames.zarr" / "zarr.json"
    doc = json.loads(meta.read_text())
    doc["data_type"] = "uint8"
    meta.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"the array.*does not hold uint8 values"):
        read_frames(tmp_path / "frames.zarr")


def test_a_chunk_missing_from_a_float_store_snapcorr_wrote_is_refused(tmp_path):
    """A float cube's fill value is NaN, which reads as missing, so a chunk deleted (or its
    keys renamed, a separator edited) read as NaN, silently: snapcorr writes every chunk, so
    in its own stores that is refused."""
    rng = np.random.default_rng(0)
    path = tmp_path / "c.zarr"
    write_cube(make_cube(rng.random((24, 32, 3)).astype(np.float32), WL, name="reflectance"),
               path)
    shutil.rmtree(path / "reflectance" / "c")
    with pytest.raises(ValueError, match=r"variable 'reflectance' lacks 1 of its 1 chunks.*"
                       "missing values where snapcorr, which wrote the store, wrote data"):
        read_cube(path)
