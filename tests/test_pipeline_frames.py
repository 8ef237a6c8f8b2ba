"""Raw mosaic frames through the pipeline at full resolution: flat-fielded pixel by pixel,
demosaicked, corrected with each pixel's own chief-ray angle, virtual bands; streams of frames
from .zarr, multi-page TIFF and folders, the same with numpy, dask and dask.distributed; and
the command line (``flatfield --demosaic``, ``stream``)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
import xarray as xr
from numpy.testing import assert_allclose, assert_array_equal

from snapcorr import data
from snapcorr.correct import correct_cube
from snapcorr.cube import (
    Sensor,
    demosaic,
    flatfield,
    mosaic_to_cube,
    read_dataset,
    read_frames,
)
from snapcorr.optics import Lens
from snapcorr.pipeline import process_stream

ORIGIN = (401, 802)  # a region of interest starting off the tile grid
ROI = (64, 96)


@pytest.fixture(scope="module")
def vis():
    return Sensor.load(data.sensor_path("mosaic_4x4_vis"))


@pytest.fixture(scope="module")
def lens():
    return Lens.load(data.lens_path("edmund_optics_16mm"))


def _frames(shape, n=1, seed=0):
    """Raw uint16 frames, their dark and white (DataArrays), and the true reflectance."""
    rng = np.random.default_rng(seed)
    dark = rng.normal(64, 2, shape).astype(np.float32)
    white = rng.normal(3000, 40, shape).astype(np.float32)  # a vignetted, uneven white
    refl = rng.uniform(0.1, 0.9, (n, *shape))
    raw = np.round(dark + refl * (white - dark)).astype(np.uint16)
    da = lambda a: xr.DataArray(a, dims=("y", "x"))  # noqa: E731
    return (xr.DataArray(raw, dims=("frame", "y", "x")), da(dark), da(white))


# -- flat-fielding frames pixel by pixel ---------------------------------------------------------


def test_a_frame_is_flat_fielded_pixel_by_pixel_and_its_mask_reaches_only_its_own_band(vis):
    raw, dark, white = _frames(ROI)
    frame = raw[0].copy()
    frame[10, 21] = 4000  # saturated
    ff = flatfield(frame, dark, white, saturation=3900)
    expected = (frame.values - dark.values) / (white.values - dark.values)
    expected[10, 21] = np.nan
    assert_allclose(ff["reflectance"].values, expected, rtol=1e-6)
    assert ff["mask"].values.sum() == 1 and ff["mask"].values[10, 21]
    assert_array_equal(ff["raw"].values, frame.values)  # kept as read
    ds = demosaic(ff, vis, "ri", sensor_origin_px=ORIGIN)
    cube = ds["reflectance"].values
    assert np.isnan(cube).sum() == 1  # masked, never spread to the neighbours
    yy, xx, bb = np.argwhere(np.isnan(cube))[0]
    assert (yy, xx) == (10, 21)
    # its band is the one the 4x4 tile puts at sensor pixel (411, 823)
    off = vis.band_offsets_at(ORIGIN)
    assert tuple(off[bb] % 4) == (10 % 4, 21 % 4)
    assert_array_equal(ds["mask"].values, np.isnan(cube))
    assert int(ds["n_masked"]) == 1
    assert_array_equal(ds["raw"].values, frame.values)  # the same pixels as the cube
    assert ds.attrs["demosaic_method"] == "ri"


def test_references_of_another_size_are_refused(vis):
    raw, dark, white = _frames(ROI)
    with pytest.raises(ValueError, match="same size and place"):
        flatfield(raw[0], dark[:-4], white)
    with pytest.raises(ValueError, match=r"2-D \(y, x\) frame"):
        flatfield(raw[0], dark.expand_dims("band", 2), white)


# -- correct: each pixel's own chief-ray angle ----------------------------------------------------


def test_correct_gives_every_pixel_of_a_demosaicked_cube_its_own_angle(vis, lens):
    """The corrected wavelength of band b at a pixel equals the one the tile cube gives band b
    at the tile whose sample of b is that pixel: both at the same sensor position."""
    raw, dark, white = _frames((96, 128), seed=3)
    ff = flatfield(raw[0], dark, white)
    full = correct_cube(demosaic(ff, vis, "bilinear", sensor_origin_px=ORIGIN)["reflectance"], vis,
                        1.4, lens)
    tiles = correct_cube(mosaic_to_cube(ff["reflectance"].values, vis, sensor_origin_px=ORIGIN),
                         vis, 1.4, lens)
    wl_full = full["wavelength_corrected"].values
    wl_tile = tiles["wavelength_corrected"].values
    rows_t, cols_t = tiles["sensor_row"].values, tiles["sensor_col"].values
    rows_f, cols_f = full["sensor_row"].values[:, 0], full["sensor_col"].values[:, 0]
    assert_array_equal(full["sensor_row"].values, rows_f[:, None].repeat(16, 1))
    checked = 0
    for b in range(16):
        for ty in (0, 7, 23):
            for tx in (0, 11, 31):
                y = int(np.flatnonzero(rows_f == rows_t[ty, b])[0])
                x = int(np.flatnonzero(cols_f == cols_t[tx, b])[0])
                assert wl_full[y, x, b] == pytest.approx(wl_tile[ty, tx, b], abs=2e-4)
                checked += 1
    assert checked == 16 * 9
    # and within one tile, one band's corrected wavelength differs from pixel to pixel
    assert np.ptp(wl_full[40:44, 0:4, 0]) > 1e-3


def test_virtual_bands_on_a_demosaicked_cube_are_the_matrix_at_every_pixel():
    nir = Sensor.load(data.sensor_path("imec_5x5_nir"))
    rows, cols = 40, 60
    raw, dark, white = _frames((rows, cols), seed=5)
    ds = demosaic(flatfield(raw[0], dark, white), nir, "ppid", sensor_origin_px=(500, 1000))
    cube = ds["reflectance"]
    res = correct_cube(cube, nir, 2.0, Lens.load(data.lens_path("edmund_optics_16mm")),
                       virtual_bands="vendor")
    A = res["virtual_matrix"].values
    assert res["virtual"].shape == (rows, cols, 25)
    ref = np.einsum("vb,yxb->yxv", A, cube.values.astype(float))
    assert_allclose(res["virtual"].values, ref, rtol=1e-5, atol=1e-6)
    assert np.isfinite(res["virtual"].values).all()


# -- streams ------------------------------------------------------------------------------------


def _tiff_pages(path, pages):
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    specs = [oiio.ImageSpec(p.shape[1], p.shape[0], 1, "uint16") for p in pages]
    assert out.open(str(path), specs)
    for i, p in enumerate(pages):
        if i:
            assert out.open(str(path), specs[i], "AppendSubimage")
        assert out.write_image(np.ascontiguousarray(p[:, :, None]))
    out.close()


def test_a_stream_reads_the_same_from_zarr_tiff_and_a_folder(tmp_path):
    import zarr

    raw, _, _ = _frames(ROI, n=4, seed=7)
    stack = raw.values
    zarr.save_array(str(tmp_path / "plain.zarr"), stack)  # no dimension names
    raw.to_dataset(name="frames").to_zarr(tmp_path / "named.zarr", consolidated=False)
    _tiff_pages(tmp_path / "pages.tif", list(stack))
    np.save(tmp_path / "stack.npy", stack)
    np.save(tmp_path / "fortran.npy", np.asfortranarray(stack))
    (tmp_path / "folder").mkdir()
    for i, f in enumerate(stack):  # names in numeric order, not text order
        np.save(tmp_path / "folder" / f"f{[0, 2, 10, 11][i]}.npy", f)
    for src in ("plain.zarr", "named.zarr", "pages.tif", "folder", "stack.npy", "fortran.npy"):
        got = read_frames(tmp_path / src)
        assert got.dims == ("frame", "y", "x") and got.chunks[0] == (1, 1, 1, 1)
        assert_array_equal(got.values, stack, err_msg=src)
    assert read_frames(tmp_path / "folder").attrs["frame_files"] == [
        "f0.npy", "f2.npy", "f10.npy", "f11.npy"]


def test_streams_that_cannot_be_read_are_refused_clearly(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="holds no frame files"):
        read_frames(tmp_path / "empty")
    (tmp_path / "mixed").mkdir()
    np.save(tmp_path / "mixed" / "a.npy", np.zeros((8, 8), np.uint16))
    np.save(tmp_path / "mixed" / "b.npy", np.zeros((8, 12), np.uint16))
    with pytest.raises(ValueError, match="every frame must match"):
        read_frames(tmp_path / "mixed")
    with pytest.raises(ValueError, match="a stream is a DataArray of dims"):
        process_stream(xr.DataArray(np.zeros((8, 8)), dims=("y", "x")), None, None, None)


def test_a_stream_is_the_frames_in_memory_with_numpy_dask_and_distributed(vis, lens):
    raw, dark, white = _frames(ROI, n=3, seed=11)
    raw[1, 5, 5] = 0  # a value below the dark: kept (negative), not masked
    raw[2, 30, 40] = 65535
    kw = dict(demosaic_method="ri", lens=lens, f_number=2.0, sensor_origin_px=ORIGIN,
              saturation=60000, resample=True)
    eager = process_stream(raw, dark, white, vis, **kw)
    lazy = process_stream(raw.chunk({"frame": 1, "y": 24}), dark, white, vis, **kw)
    assert lazy["reflectance"].chunks is not None
    one = [correct_cube(demosaic(flatfield(raw[i], dark, white, saturation=60000), vis, "ri",
                                 sensor_origin_px=ORIGIN)["reflectance"], vis, 2.0, lens,
                        resample=True) for i in range(3)]
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                      dashboard_address=None) as cluster, Client(cluster):
        distributed = lazy.compute()
    for name in ("reflectance", "resampled", "mask"):
        ref = np.stack([o[name].values if name in o else np.isnan(o["reflectance"].values)
                        for o in one])
        for got in (eager, lazy, distributed):
            assert_array_equal(got[name].values, ref, err_msg=name)
    assert_array_equal(eager["wavelength_corrected"].values,
                       one[0]["wavelength_corrected"].values)
    assert int(eager["n_masked"]) == 1 and eager.attrs["flatfield_method"].startswith("Goossens")


# -- the command line ---------------------------------------------------------------------------


@pytest.fixture
def frame_files(tmp_path):
    raw, dark, white = _frames(ROI, n=3, seed=13)
    np.save(tmp_path / "raw.npy", raw.values[0])
    np.save(tmp_path / "dark.npy", dark.values)
    np.save(tmp_path / "white.npy", white.values)
    np.save(tmp_path / "dark_small.npy", dark.values[:-4])
    import zarr

    zarr.save_array(str(tmp_path / "frames.zarr"), raw.values)
    return tmp_path, raw, dark, white


def test_flatfield_demosaic_from_the_command_line(frame_files, cli, vis):
    d, raw, dark, white = frame_files
    res = cli("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
              "mosaic_4x4_vis", "--sensor-origin-px", "401,802", "--demosaic", "ppid", "--out",
              "full.nc", cwd=d)
    assert res.returncode == 0, res.stderr
    assert "demosaicked (ppid) to 64 x 96 x 16" in res.stdout
    ds = read_dataset(d / "full.nc")
    ref = demosaic(flatfield(raw[0], dark, white), vis, "ppid", sensor_origin_px=ORIGIN)
    assert_array_equal(ds["reflectance"].values, ref["reflectance"].values)
    assert_array_equal(ds["raw"].values, raw.values[0])  # the raw data next to the result
    assert ds.attrs["demosaic_method"] == "ppid" and ds.attrs["raw_file"] == "raw.npy"
    assert list(ds.attrs["mosaic_area_px"]) == [401, 802, 64, 96]
    assert_array_equal(ds["sensor_row"].values[:, 3], 401 + np.arange(64))
    out = cli("correct", "full.nc", "--lens", "edmund_optics_16mm", "--sensor",
              "mosaic_4x4_vis", "--f-number", "2", "--out", "corr.nc", cwd=d)
    assert out.returncode == 0, out.stderr


@pytest.mark.parametrize(("args", "message"), [
    (["--demosaic", "ri"], "--demosaic needs a mosaic --sensor"),
    (["--demosaic", "ri", "--sensor", "snapscan_vnir"], "--demosaic needs a mosaic --sensor"),
    (["--demosaic", "cubic", "--sensor", "mosaic_4x4_vis"], "invalid choice"),
    (["--demosaic", "ri", "--sensor", "mosaic_4x4_vis"], "not the sensor's|1088 x 2048"),
    (["--demosaic", "ri", "--sensor", "mosaic_4x4_vis", "--sensor-origin-px", "401,802",
      "--dark", "dark_small.npy"], "same size and place"),
])
def test_flatfield_demosaic_refusals_are_one_line(frame_files, cli, args, message):
    d = frame_files[0]
    base = ["flatfield", "raw.npy", "--white", "white.npy", "--out", "x.nc"]
    if "--dark" not in args:
        base += ["--dark", "dark.npy"]
    res = cli(*base, *args, cwd=d)
    assert res.returncode != 0
    assert re.search(message, res.stderr), res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert not (d / "x.nc").exists()


def test_stream_from_the_command_line(frame_files, cli, vis, lens):
    d, raw, dark, white = frame_files
    res = cli("stream", "frames.zarr", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
              "mosaic_4x4_vis", "--sensor-origin-px", "401,802", "--lens", "edmund_optics_16mm",
              "--f-number", "2", "--out", "s.zarr", cwd=d)
    assert res.returncode == 0, res.stderr
    ds = read_dataset(d / "s.zarr")
    ref = process_stream(raw, dark, white, vis, lens=lens, f_number=2.0, sensor_origin_px=ORIGIN)
    assert_array_equal(ds["reflectance"].values, ref["reflectance"].values)
    assert_array_equal(ds["raw"].values, raw.values)
    assert ds.attrs["frames_file"] == "frames.zarr" and ds.attrs["demosaic_method"] == "ri"
    assert_allclose(ds["wavelength_corrected"].values, ref["wavelength_corrected"].values)
    bad = cli("stream", "frames.zarr", "--dark", "dark.npy", "--white", "white.npy",
              "--sensor", "snapscan_vnir", "--out", "t.zarr", cwd=d)
    assert bad.returncode == 1 and "not a mosaic" in bad.stderr
    half = cli("stream", "frames.zarr", "--dark", "dark.npy", "--white", "white.npy",
               "--sensor", "mosaic_4x4_vis", "--sensor-origin-px", "401,802", "--lens",
               "edmund_optics_16mm", "--out", "t.zarr", cwd=d)
    assert half.returncode == 1 and "both --lens and --f-number" in half.stderr
    again = cli("correct", "s.zarr", "--lens", "edmund_optics_16mm", "--sensor",
                "mosaic_4x4_vis", "--f-number", "2", "--out", "c.nc", cwd=d)
    assert again.returncode == 1 and "holds a stream of cubes" in again.stderr


def test_demosaic_warns_when_a_hole_leaves_other_bands_without_samples(vis):
    raw, dark, white = _frames(ROI, seed=17)
    frame = flatfield(raw[0], dark, white)["reflectance"].values.copy()
    frame[20:34, 30:44] = np.nan  # wider than three tiles
    with pytest.warns(UserWarning, match="hole several tiles wide"):
        demosaic(frame, vis, "bilinear", sensor_origin_px=ORIGIN)
    frame = flatfield(raw[0], dark, white)["reflectance"].values.copy()
    frame[20, 30] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        demosaic(frame, vis, "bilinear", sensor_origin_px=ORIGIN)



# -- what a careful reading found: each checked here -------------------------------------------


def test_the_mask_is_every_nan_of_the_cube_numpy_or_dask(vis):
    raw, dark, white = _frames(ROI, n=2, seed=19)
    raw[1, 20:40, 30:50] = 65535  # a saturated blob of five tiles
    for frames in (raw, raw.chunk({"frame": 1, "y": 32})):
        ff = flatfield(frames, dark, white, saturation=60000)
        for method in ("nearest", "bilinear", "ppid", "ri"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ds = demosaic(ff, vis, method, sensor_origin_px=ORIGIN).compute()
            nan = np.isnan(ds["reflectance"].values)
            assert nan.sum() >= 400  # the blob's own values at least
            assert_array_equal(ds["mask"].values, nan, err_msg=method)
            assert int(ds["n_masked"]) == nan.sum()


def test_a_small_region_of_interest_through_dask_is_the_same_as_in_memory(vis):
    import dask.array as dsk

    for shape in ((4, 96), (35, 200), (200, 20)):
        f = np.random.default_rng(1).uniform(0.1, 1, shape).astype(np.float32)
        for method in ("nearest", "bilinear", "ppid", "ri"):
            a = demosaic(f, vis, method, sensor_origin_px=ORIGIN).values
            b = demosaic(dsk.from_array(f, chunks=(16, 16)), vis, method,
                         sensor_origin_px=ORIGIN).values
            assert_array_equal(a, b, err_msg=f"{shape} {method}")


def test_a_wide_hole_on_the_5x5_sensor_is_the_same_through_dask():
    import dask.array as dsk

    nir = Sensor.load(data.sensor_path("imec_5x5_nir"))
    f = np.random.default_rng(2).uniform(0.1, 1, (300, 400))
    f[100:114, 200:214] = np.nan
    for method in ("nearest", "bilinear", "ppid", "ri"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            a = demosaic(f, nir, method, sensor_origin_px=(500, 1000)).values
            b = demosaic(dsk.from_array(f, chunks=(50, 50)), nir, method,
                         sensor_origin_px=(500, 1000)).values
        assert_array_equal(a, b, err_msg=method)


def test_frames_keep_their_times_and_streams_are_refused_when_empty_or_not_frames(tmp_path, vis,
                                                                                   lens):
    raw, dark, white = _frames(ROI, n=3, seed=23)
    times = np.array(["2026-01-01T00:00:00", "2026-01-01T00:00:01", "2026-01-01T00:00:02"],
                     dtype="datetime64[ns]")
    raw.assign_coords(frame=times).to_dataset(name="frames").to_zarr(
        tmp_path / "timed.zarr", consolidated=False)
    frames = read_frames(tmp_path / "timed.zarr")
    assert_array_equal(frames["frame"].values, times)
    ds = process_stream(frames, dark, white, vis, lens=lens, f_number=2.0, sensor_origin_px=ORIGIN)
    assert_array_equal(ds["reflectance"]["frame"].values, times)
    np.save(tmp_path / "empty.npy", np.zeros((0, 64, 96), np.uint16))
    with pytest.raises(ValueError, match="holds no frame"):
        read_frames(tmp_path / "empty.npy")
    cube = xr.DataArray(np.zeros((4, 8, 8), np.float32), dims=("band", "y", "x"))
    cube.to_dataset(name="radiance").to_zarr(tmp_path / "bands.zarr", consolidated=False)
    with pytest.raises(ValueError, match="a cube's bands are not frames"):
        read_frames(tmp_path / "bands.zarr")
    (tmp_path / "broken").mkdir()
    np.save(tmp_path / "broken" / "f0.npy", raw.values[0])
    (tmp_path / "broken" / "f1.npy").symlink_to(tmp_path / "nowhere.npy")
    with pytest.raises(ValueError, match="not a regular file"):
        read_frames(tmp_path / "broken")
    with pytest.raises(ValueError, match="harmonised spectra are made cube by cube"):
        process_stream(raw, dark, white, vis, lens=lens, f_number=2.0, sensor_origin_px=ORIGIN,
                       method="harmonised")
    ideal = process_stream(raw, dark, white, vis, lens=lens, f_number=2.0, sensor_origin_px=ORIGIN,
                           method="ideal")
    assert ideal.attrs["method"] == "ideal"


def test_stream_refuses_swapped_references_and_an_origin_beyond_the_sensor(frame_files, cli):
    d = frame_files[0]
    swapped = cli("stream", "frames.zarr", "--dark", "white.npy", "--white", "dark.npy",
                  "--sensor", "mosaic_4x4_vis", "--sensor-origin-px", "401,802", "--out",
                  "s.zarr", cwd=d)
    assert swapped.returncode == 1 and "masked by the references alone" in swapped.stderr
    beyond = cli("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy",
                 "--sensor", "mosaic_4x4_vis", "--sensor-origin-px", "5000,9000", "--demosaic",
                 "nearest", "--out", "x.nc", cwd=d)
    assert beyond.returncode == 1 and "beyond the sensor" in beyond.stderr
    assert not (d / "s.zarr").exists() and not (d / "x.nc").exists()


def test_what_a_frame_holds_is_checked(vis):
    f = np.random.default_rng(3).uniform(0.1, 1, ROI)
    f[10, 10] = np.inf  # an infinity is missing, as NaN is
    cube = demosaic(f, vis, "ri", sensor_origin_px=ORIGIN).values
    assert np.isnan(cube).sum() == 1 and np.isfinite(cube).sum() == cube.size - 1
    with pytest.raises(TypeError, match="complex"):
        demosaic(f.astype(complex), vis, "bilinear", sensor_origin_px=ORIGIN)
    counts = np.full(ROI, 2**24 + 1, np.int64)  # float32 would round these
    cube = demosaic(counts, vis, "nearest", sensor_origin_px=ORIGIN)
    assert cube.dtype == np.float64 and (cube.values == 2**24 + 1).all()
    with pytest.raises(ValueError, match=r"use cube.transpose"):
        flatfield(xr.DataArray(np.ones((4, *ROI)), dims=("band", "y", "x")),
                  np.zeros(ROI), np.ones(ROI))


def test_the_command_line_offers_every_method():
    from snapcorr.cli import build_parser
    from snapcorr.cube import DEMOSAIC_METHODS

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name in ("flatfield", "stream"):
        opt = next(a for a in sub.choices[name]._actions if a.dest == "demosaic")
        assert list(opt.choices) == list(DEMOSAIC_METHODS)


def test_flatfield_demosaic_with_a_filter_white(frame_files, cli, vis):
    d, raw, dark, white = frame_files
    np.save(d / "fw.npy", raw.values[1])
    res = cli("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
              "mosaic_4x4_vis", "--sensor-origin-px", "401,802", "--demosaic", "bilinear",
              "--filter-white", "fw.npy", "--out", "tr.zarr", cwd=d)
    assert res.returncode == 0, res.stderr
    ds = read_dataset(d / "tr.zarr")
    ref = demosaic(flatfield(raw[1], dark, white, name="transmittance"), vis, "bilinear",
                   sensor_origin_px=ORIGIN)
    assert_array_equal(ds["transmittance"].values, ref["transmittance"].values)
    assert_array_equal(ds["filter_white_raw"].values, raw.values[1])
    assert ds.attrs["filter_white_file"] == "fw.npy"


def test_second_reading_refusals_and_what_files_hold(tmp_path, vis, lens):
    raw, dark, white = _frames(ROI, n=2, seed=29)
    nearly = dark.copy()
    nearly[7, 7] = white[7, 7] + 1  # swapped, but for one pixel
    with pytest.raises(ValueError, match="masked by the references alone"):
        flatfield(raw, white, nearly)
    with pytest.raises(ValueError, match="demosaic_method"):
        process_stream(raw, dark, white, vis, method="nearest", sensor_origin_px=ORIGIN)
    with pytest.raises(ValueError, match="holds no frame"):
        process_stream(raw[:0], dark, white, vis, sensor_origin_px=ORIGIN)
    # the writing instruction computed_with stays out of files, from memory or from dask
    from snapcorr.cube import write_dataset

    for ds, name in ((demosaic(flatfield(raw[0], dark, white), vis, "bilinear",
                               sensor_origin_px=ORIGIN), "mem.nc"),
                     (process_stream(raw.chunk({"frame": 1}), dark, white, vis,
                                     sensor_origin_px=ORIGIN), "lazy.zarr")):
        write_dataset(ds, tmp_path / name)
        back = read_dataset(tmp_path / name)
        assert all("computed_with" not in back[v].attrs for v in back.data_vars), name
        assert_array_equal(back["mask"].values, np.isnan(back["reflectance"].values))
    # a snapcorr stream's own output reads back as its raw frames; other 3-D variables beside
    # a stack of frames do not stop it
    assert_array_equal(read_frames(tmp_path / "lazy.zarr").values, raw.values)
    xr.Dataset({"frames": raw, "lut": (("gain", "adc", "k"), np.zeros((2, 3, 4)))}).to_netcdf(
        tmp_path / "aux.nc", engine="h5netcdf")
    assert_array_equal(read_frames(tmp_path / "aux.nc").values, raw.values)


def test_snapcorr_cube_loads_without_numba_and_the_reach_follows_the_window():
    import subprocess
    import sys

    code = "import sys, snapcorr.cube; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
    from snapcorr.cube.demosaicking import DEMOSAIC_REACH_TILES
    from snapcorr.cube.msfa import monno2017

    assert DEMOSAIC_REACH_TILES["ri"] == DEMOSAIC_REACH_TILES["ppid"] + 2 * monno2017.RADIUS


def test_a_frame_larger_than_the_sensor_is_refused_before_any_work(tmp_path):
    """A 4096 x 4096 white for a 2048 x 1088 sensor (sensor --phase-from): 19 s and 700 MB
    of work, then "cannot tell the phase"."""
    from snapcorr.cube import Sensor
    from snapcorr.pipeline import read_mosaic_frame

    sensor = Sensor.load("mosaic_4x4_vis")
    rows, cols = sensor.size_px
    np.save(tmp_path / "big.npy", np.zeros((rows + 4, cols), np.uint16))
    with pytest.raises(ValueError, match=rf"--white .*big\.npy is {rows + 4} x {cols} px, "
                       rf"larger than the sensor .*\({rows} x {cols} px\): not a raw frame"):
        read_mosaic_frame(tmp_path / "big.npy", sensor, what="--white")
    np.save(tmp_path / "ok.npy", np.zeros((rows, cols), np.uint16))
    assert read_mosaic_frame(tmp_path / "ok.npy", sensor).shape == (rows, cols)
