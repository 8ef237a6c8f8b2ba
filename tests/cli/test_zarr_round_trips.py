"""Every cube to zarr and back, chunked or not, whatever the command: `snapcorr flatfield`
(tile cubes and demosaicked cubes, raw frames in every format), `snapcorr correct` (plain,
``--resample``, ``--method none``, ``--virtual-bands``) and `snapcorr stream`, for a whole
sensor, a crop, a Snapscan-style cube (positions per pixel) and a stream, from and to
``.zarr`` and ``.nc`` stores laid out in small blocks, in one block, or as snapcorr wrote them.

What each result must hold is computed here, not by the package: the flat field pixel by
pixel from the frames, the tile cube by cutting that into tiles, and every run of a command
gives the same numbers whatever the formats and blocks its input came in (compared with the
run from plain arrays). The default run keeps one row of each kind; the whole product is
``-m slow``.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import xarray as xr
from conftest import run_cli

from snapcorr.cube import Sensor, make_cube, read_dataset, write_cube, write_dataset
from snapcorr.data import sensor_path

LENS = "edmund_optics_16mm"
#: The small mosaic sensor's whole frame (rows, columns): mosaic_4x4_vis cut to this size.
SMALL = (48, 64)
#: A crop of the bundled 4x4 sensor, and of the imec 5x5 sensor (its filter area starts at
#: row 3, so a crop's origin there is one the vendor file's phase allows).
CROP_4X4 = ((400, 800), (48, 64))
CROP_IMEC = ((300, 500), (50, 75))
#: The Snapscan-style cube: a crop of the image field, positions per pixel (sensor_row on y).
SCAN = ((1000, 900), (40, 48), 8)

#: How the input of a step is laid out: as snapcorr's previous step wrote it, rewritten in
#: small blocks that split rows, columns and bands, or rewritten as one block per variable.
LAYOUTS = ("native", "blocks", "whole")
BLOCKS = {"y": 5, "x": 7, "band": 6, "frame": 1}


# -- inputs ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A folder with the sensors: the small whole-frame 4x4 mosaic and a small Snapscan."""
    d = tmp_path_factory.mktemp("matrix")
    text = sensor_path("mosaic_4x4_vis").read_text()
    assert "size_px = [1088, 2048]" in text
    (d / "small.toml").write_text(text.replace("size_px = [1088, 2048]",
                                               f"size_px = [{SMALL[0]}, {SMALL[1]}]"))
    Sensor("scan", "snapscan", 5.5, tuple(np.linspace(500.0, 850.0, SCAN[2])), 12.0, 1.7,
           size_px=(2048, 2048)).save(d / "scan.toml")
    return d


#: Where each kind's frames come from: the sensor, the frame size, the origin option.
KINDS = {
    "whole": ("small.toml", SMALL, None),
    "crop": ("mosaic_4x4_vis", CROP_4X4[1], CROP_4X4[0]),
    "imec": ("imec_5x5_nir", CROP_IMEC[1], CROP_IMEC[0]),
    "scan": ("scan.toml", SCAN[1], SCAN[0]),
    "bundled": ("mosaic_4x4_vis", (1088, 2048), None),
}


def _sensor_arg(work, kind):
    name = KINDS[kind][0]
    return str(work / name) if name.endswith(".toml") else name


def _origin_args(kind):
    origin = KINDS[kind][2]
    return ["--sensor-origin-px", f"{origin[0]},{origin[1]}"] if origin else []


def _frames(kind, seed=0, n_frames=None):
    """Raw, dark and white frames (uint16) of a grey-ish scene, reflectance 0.2-0.8 per
    pixel; a Snapscan's are cubes (y, x, band); a stream's raw frames a stack."""
    rng = np.random.default_rng(seed)
    shape = KINDS[kind][1]
    if kind == "scan":
        shape = (*shape, SCAN[2])
    top = 800.0 if kind == "imec" else 3000.0  # the imec sensor's codes are 10-bit
    base = 16.0 if kind == "imec" else 64.0
    white = rng.normal(top, top / 100, shape)
    dark = rng.normal(base, 2.0, shape)
    lead = () if n_frames is None else (n_frames,)
    refl = rng.uniform(0.2, 0.8, lead + shape)
    raw = dark + refl * (white - dark) + rng.normal(0.0, 1.0, lead + shape)
    return [np.clip(np.rint(a), 0, 4095).astype(np.uint16) for a in (raw, dark, white)]


def _write_array(path, name, data, dims, blocks):
    """``data`` as ``path`` (.npy, .zarr, .nc, .tif, .hdr): a store in blocks of ``blocks``
    (by dim) or in one block (None)."""
    suffix = path.suffix
    if suffix == ".npy":
        np.save(path, data)
        return
    if suffix == ".tif":
        import tifffile

        tifffile.imwrite(path, data)
        return
    if suffix == ".hdr":
        wl = np.linspace(500.0, 850.0, SCAN[2])
        write_cube(make_cube(data, wl), path)
        return
    sizes = zip(dims, data.shape, strict=True)
    chunks = data.shape if blocks is None else tuple(min(blocks.get(d, n), n) for d, n in sizes)
    coords = {"wavelength": ("band", np.linspace(500.0, 850.0, SCAN[2]))} \
        if "band" in dims else {}
    ds = xr.Dataset({name: (dims, data)}, coords=coords)
    if suffix == ".zarr":
        ds.to_zarr(path, mode="w", encoding={name: {"chunks": chunks}}, consolidated=False)
    else:
        enc = {} if blocks is None else {"chunksizes": chunks}
        ds.to_netcdf(path, engine="h5netcdf", encoding={name: enc})


def _inputs(d, kind, fmt, blocks, n_frames=None):
    """Raw, dark and white files of ``kind`` in ``d``: the raw one as ``fmt``; the paths."""
    raw, dark, white = _frames(kind, n_frames=n_frames)
    if kind == "scan":
        dims = ("y", "x", "band")
    elif n_frames is not None:
        dims = ("frame", "y", "x")
    else:
        dims = ("y", "x")
    paths = [d / f"raw{fmt}", d / "dark.npy", d / "white.npy"]
    _write_array(paths[0], "frames" if n_frames else "raw", raw, dims, blocks)
    if kind == "scan":  # references in the format a Snapscan gives them: ENVI cubes
        paths[1:] = [d / "dark.hdr", d / "white.hdr"]
    for p, a in zip(paths[1:], (dark, white), strict=True):
        _write_array(p, p.stem, a, dims[-a.ndim:], None)
    return paths, (raw, dark, white)


def _relaid(src, dst, layout):
    """``src`` (a result snapcorr wrote) as ``dst``: as it is (``native``, when the formats
    agree), or rewritten by the library in small blocks or in one block per variable."""
    if layout == "native" and src.suffix == dst.suffix:
        return src
    ds = read_dataset(src, chunks={})
    if dst.suffix in (".hdr", ".tif", ".npy"):  # the cube alone, its positions kept
        write_cube(ds["reflectance"], dst)
        return dst
    if layout == "blocks":
        ds = ds.chunk({k: v for k, v in BLOCKS.items() if k in ds.dims})
    else:
        ds = ds.chunk(-1)
    write_dataset(ds, dst)
    return dst


def _ok(*args, cwd=None):
    code, out, err = run_cli(*args, "--quiet", cwd=cwd)
    assert code == 0, err
    assert "Traceback" not in err and "safe_chunks" not in err and "warning" not in err, err
    return out


def _engine(path):
    return "zarr" if path.suffix == ".zarr" else "h5netcdf"


def _read_back(path):
    """A result read back twice: by snapcorr (derived variables rebuilt) and by xarray alone
    (a store another program opens): both in memory."""
    ds = read_dataset(path).load()
    plain = (xr.open_zarr(path) if path.suffix == ".zarr"
             else xr.open_dataset(path, engine="h5netcdf")).load()
    for name in plain.data_vars:
        if plain[name].encoding.get("dtype") == np.uint16 and ds[name].dtype == np.float32:
            # unpacked in float32 by snapcorr, as netCDF's reader does (xarray alone unpacks
            # Zarr's in float64): the same to float32's rounding at the range's size
            np.testing.assert_allclose(plain[name].values, ds[name].values, rtol=0,
                                       atol=4 * np.finfo(np.float32).eps * 3.5, err_msg=name)
            continue
        np.testing.assert_array_equal(plain[name].values, ds[name].values, err_msg=name)
    return ds


# -- expected values, computed here ----------------------------------------------------------


def _pixel_flatfield(raw, dark, white):
    return (raw.astype(np.float64) - dark) / (white.astype(np.float64) - dark)


def _tile_cube(ff, kind):
    """The tile cube of a pixel flat field: each tile's pixels as its bands, in the sensor's
    band order (row-major in the tile for the 4x4 sensors: also the order of wavelength)."""
    sensor = Sensor.load(_sensor_path(kind))
    tr, tc = sensor.mosaic_shape
    ny, nx = ff.shape[0] // tr, ff.shape[1] // tc
    out = np.empty((ny, nx, len(sensor.cwl_nm)))
    for b, (r, c) in enumerate(np.asarray(sensor.band_offset)):
        out[..., b] = ff[r:ny * tr:tr, c:nx * tc:tc]
    return out


def _sensor_path(kind):
    name = KINDS[kind][0]
    if name == "small.toml":
        return sensor_path("mosaic_4x4_vis")  # the same tile and bands
    return sensor_path(name)


# -- snapcorr flatfield ----------------------------------------------------------------------

FF_KINDS = [("whole", None), ("whole", "bilinear"), ("crop", None), ("crop", "bilinear"),
            ("scan", None)]
FF_INPUTS = [(".zarr", "blocks"), (".zarr", "whole"), (".nc", "blocks"), (".nc", "whole"),
             (".npy", "whole"), (".tif", "whole"), (".hdr", "whole")]
FF_ALL = [(k, dm, f, lay, out) for (k, dm), (f, lay), out
          in itertools.product(FF_KINDS, FF_INPUTS, (".zarr", ".nc"))
          if not (f == ".tif" and k == "scan") and not (f == ".hdr" and k != "scan")]
FF_DEFAULT = [("whole", "bilinear", ".zarr", "blocks", ".zarr"),
              ("crop", None, ".nc", "blocks", ".zarr"),
              ("scan", None, ".zarr", "blocks", ".nc")]
FF_CASES = FF_DEFAULT + [pytest.param(*c, marks=pytest.mark.slow) for c in FF_ALL
                         if c not in FF_DEFAULT] + [
    pytest.param("bundled", None, ".zarr", "blocks", ".zarr", marks=pytest.mark.slow)]


@pytest.mark.parametrize("kind, demosaic, fmt, layout, out", FF_CASES)
def test_flatfield(work, tmp_path, kind, demosaic, fmt, layout, out):
    blocks = {"y": 8, "x": 24, "band": 3} if layout == "blocks" else None
    paths, (raw, dark, white) = _inputs(tmp_path, kind, fmt, blocks)
    result = tmp_path / f"ff{out}"
    _ok("flatfield", *paths[:1], "--dark", paths[1], "--white", paths[2], "--sensor",
        _sensor_arg(work, kind), *_origin_args(kind),
        *(["--demosaic", demosaic] if demosaic else []), "--out", result)
    ds = _read_back(result)
    ff = _pixel_flatfield(raw, dark, white)
    cube = ds["reflectance"]
    assert cube.dims == ("y", "x", "band") and cube.attrs["units"] == "1"
    assert ds.attrs["raw_file"] == str(paths[0])
    assert {"sensor_row", "sensor_col"} <= set(ds.coords)
    if kind == "scan":  # the cube flat-fielded as it is; positions per pixel
        want = ff
        assert "y" in ds["sensor_row"].dims and "x" in ds["sensor_col"].dims
        assert int(ds["sensor_col"].min()) == SCAN[0][1]
    elif demosaic is None:
        want = _tile_cube(ff, kind)
    else:  # every band at every pixel; at its own pixels, the value measured there
        sensor = Sensor.load(_sensor_path(kind))
        assert cube.shape[:2] == ff.shape
        got = np.asarray(cube.values, np.float64)
        for b, (r, c) in enumerate(np.asarray(sensor.band_offset)):
            np.testing.assert_allclose(got[r::4, c::4, b], ff[r::4, c::4], rtol=1e-5)
        want = None
    if want is not None:
        np.testing.assert_allclose(np.asarray(cube.values, np.float64), want, rtol=1e-5)
    np.testing.assert_array_equal(np.asarray(ds["raw"].values).reshape(-1)[:50],
                                  raw.reshape(-1)[:50]) if kind == "scan" else None
    assert not ds["mask"].values.any()


# -- snapcorr correct ------------------------------------------------------------------------

#: The cubes corrected: kind and how the flat field made them (None: the tile cube).
CORRECT_KINDS = [("whole", None), ("whole", "bilinear"), ("crop", None), ("crop", "bilinear"),
                 ("scan", None)]
VARIANTS = {"plain": [], "resample": ["--resample"], "none": ["--method", "none"],
            "virtual": ["--virtual-bands", "vendor"],
            "angle-aware": ["--virtual-bands", "angle-aware"],
            "uint16": ["--dtype", "uint16"], "store-derived": ["--store-derived"],
            "no-input": ["--no-input"]}
#: At most this far from the value computed, stored as uint16 (half a step of 6.1e-5).
PACKED_ERROR = 3.2e-5
CORRECT_ALL = [(k, dm, f, lay, out, v) for (k, dm), f, lay, out, v
               in itertools.product(CORRECT_KINDS, (".zarr", ".nc"), LAYOUTS, (".zarr", ".nc"),
                                    ("plain", "resample", "none"))] + [
    ("imec", "bilinear", f, lay, ".zarr", v) for f, lay, v
    in itertools.product((".zarr", ".nc"), LAYOUTS, ("virtual", "angle-aware"))] + [
    ("imec", None, ".zarr", "blocks", ".nc", "virtual")] + [
    (k, dm, f, lay, out, v) for (k, dm), f, lay, out, v
    in itertools.product([("whole", "bilinear"), ("scan", None)], (".zarr", ".nc"), LAYOUTS,
                         (".zarr", ".nc"), ("uint16", "store-derived", "no-input"))] + [
    (k, dm, f, "whole", out, "resample") for (k, dm), f, out
    in itertools.product(CORRECT_KINDS, (".hdr", ".tif", ".npy"), (".zarr", ".nc"))]
CORRECT_DEFAULT = [("whole", "bilinear", ".zarr", "native", ".zarr", "plain"),
                   ("crop", None, ".zarr", "blocks", ".zarr", "resample"),
                   ("scan", None, ".zarr", "blocks", ".zarr", "none"),
                   ("whole", None, ".nc", "whole", ".zarr", "resample"),
                   ("whole", "bilinear", ".zarr", "native", ".zarr", "uint16"),
                   ("crop", None, ".tif", "whole", ".nc", "resample")]
CORRECT_CASES = CORRECT_DEFAULT + [pytest.param(*c, marks=pytest.mark.slow)
                                   for c in CORRECT_ALL if c not in CORRECT_DEFAULT] + [
    pytest.param("bundled", "bilinear", ".zarr", "native", ".zarr", "resample",
                 marks=pytest.mark.slow)]

#: Flat-field results made once per module: (kind, demosaic, format) -> path.
_MADE = {}


def _flatfielded(work, kind, demosaic, fmt):
    """snapcorr's flat-field result of ``kind`` written as ``fmt``, and its reflectance."""
    key = (kind, demosaic, fmt)
    if key not in _MADE:
        d = work / f"ff-{kind}-{demosaic}-{fmt[1:]}"
        d.mkdir()
        paths, _ = _inputs(d, kind, ".npy" if kind != "scan" else ".hdr", None)
        out = d / f"ff{fmt}"
        _ok("flatfield", paths[0], "--dark", paths[1], "--white", paths[2], "--sensor",
            _sensor_arg(work, kind), *_origin_args(kind),
            *(["--demosaic", demosaic] if demosaic else []), "--out", out)
        _MADE[key] = out
    return _MADE[key]


def _reference(work, kind, demosaic, variant):
    """The same correction from the flat field as ``.nc`` in one block, in memory."""
    key = ("reference", kind, demosaic, variant)
    if key not in _MADE:
        src = _flatfielded(work, kind, demosaic, ".nc")
        out = src.parent / f"ref-{variant}.nc"
        _ok("correct", src, *_correct_args(work, kind, variant), "--out", out)
        _MADE[key] = read_dataset(out).load()
    return _MADE[key]


def _correct_args(work, kind, variant):
    return ["--lens", LENS, "--sensor", _sensor_arg(work, kind), "--f-number", "2.8",
            *VARIANTS[variant]]


@pytest.mark.parametrize("kind, demosaic, fmt, layout, out, variant", CORRECT_CASES)
def test_correct(work, tmp_path, kind, demosaic, fmt, layout, out, variant):
    first = _flatfielded(work, kind, demosaic, fmt if fmt in (".zarr", ".nc") else ".zarr")
    src = _relaid(first, tmp_path / f"in{fmt}", layout)
    result = tmp_path / f"corr{out}"
    _ok("correct", src, *_correct_args(work, kind, variant), "--out", result)
    ds = _read_back(result)
    ff = read_dataset(first).load()
    assert ds.attrs["cube_file"] == str(src)
    if variant == "no-input":
        assert "raw" not in ds
    elif fmt in (".zarr", ".nc"):  # the camera's numbers and the flat field's record kept
        np.testing.assert_array_equal(ds["raw"].values, ff["raw"].values)
        assert ds["raw"].dtype == ff["raw"].dtype
        assert ds.attrs["input_raw_file"] == ff.attrs["raw_file"]
    if variant == "no-input":  # no cube to correct again: said in one line
        assert "reflectance" not in ds and str(src) in ds.attrs["input_left_out"]
        code, _, err = run_cli("correct", result, *_correct_args(work, kind, "plain"), "--out",
                               tmp_path / f"again{out}", "--quiet")
        assert code == 1 and err.count("\n") == 1 and "holds no cube" in err, err
        ds = ds.assign(reflectance=ff["reflectance"])
    cube = ds["reflectance"]
    assert cube.dims == ("y", "x", "band")
    np.testing.assert_allclose(cube.values, ff["reflectance"].values, rtol=0,  # the input kept
                               atol=PACKED_ERROR if variant == "uint16" else 0)
    if variant == "store-derived":  # for readers without snapcorr
        assert "wavelength_corrected" in xr.open_dataset(result, engine=_engine(result))
    for name in ("sensor_row", "sensor_col", "wavelength"):
        np.testing.assert_array_equal(ds[name].values, ff[name].values, err_msg=name)
    wc = ds["wavelength_corrected"]
    assert wc.sizes == cube.sizes
    if variant == "none":
        np.testing.assert_allclose(wc.values, np.broadcast_to(ff["wavelength"].values,
                                                              wc.shape))
    else:  # within 2 % of the nominal; for filters of a nominal shape, a blue shift only
        nominal = ff["wavelength"].values
        assert np.all(np.abs(wc.values - nominal) < 0.02 * nominal)
        if kind != "imec":  # measured responses: the centroid, not the main peak, moves
            assert np.all(wc.values <= nominal + 1e-6)
    if variant == "resample":
        assert ds["resampled"].sizes == cube.sizes
    if variant in ("virtual", "angle-aware"):
        assert ds["virtual"].dims == ("y", "x", "virtual_band")
        assert np.isfinite(ds["virtual"].values).mean() > 0.9
    ref = _reference(work, kind, demosaic, variant)
    for name in set(ref.data_vars) & set(ds.data_vars):  # whatever the formats and blocks
        np.testing.assert_allclose(ds[name].values, ref[name].values, rtol=1e-6,
                                   equal_nan=True, err_msg=name)


# -- snapcorr stream -------------------------------------------------------------------------

STREAM_VARIANTS = {"plain": [], "lens": ["--lens", LENS, "--f-number", "2.8"],
                   "resample": ["--lens", LENS, "--f-number", "2.8", "--resample"],
                   "virtual": ["--lens", LENS, "--f-number", "2.8", "--virtual-bands",
                               "vendor"],
                   "uint16": ["--lens", LENS, "--f-number", "2.8", "--dtype", "uint16"],
                   "no-input": ["--no-input"]}
STREAM_INPUTS = [(".zarr", "blocks"), (".zarr", "whole"), (".nc", "blocks"), (".nc", "whole"),
                 (".npy", "whole")]
STREAM_ALL = [(k, f, lay, out, v) for k, (f, lay), out, v
              in itertools.product(("whole", "crop"), STREAM_INPUTS, (".zarr", ".nc"),
                                   ("plain", "lens", "resample"))] + [
    ("imec", f, lay, out, "virtual") for (f, lay), out
    in itertools.product(STREAM_INPUTS, (".zarr", ".nc"))] + [
    ("whole", f, lay, out, v) for (f, lay), out, v
    in itertools.product(STREAM_INPUTS, (".zarr", ".nc"), ("uint16", "no-input"))]
STREAM_DEFAULT = [("whole", ".zarr", "blocks", ".zarr", "lens"),
                  ("imec", ".zarr", "blocks", ".zarr", "virtual")]
STREAM_CASES = STREAM_DEFAULT + [pytest.param(*c, marks=pytest.mark.slow)
                                 for c in STREAM_ALL if c not in STREAM_DEFAULT]
N_FRAMES = 3


@pytest.mark.parametrize("kind, fmt, layout, out, variant", STREAM_CASES)
def test_stream(work, tmp_path, kind, fmt, layout, out, variant):
    blocks = {"frame": 2, "y": 8, "x": 24} if layout == "blocks" else None
    paths, (raw, dark, white) = _inputs(tmp_path, kind, fmt, blocks, n_frames=N_FRAMES)
    result = tmp_path / f"stream{out}"
    _ok("stream", paths[0], "--dark", paths[1], "--white", paths[2], "--sensor",
        _sensor_arg(work, kind), *_origin_args(kind), "--demosaic", "bilinear",
        *STREAM_VARIANTS[variant], "--out", result)
    ds = _read_back(result)
    cube = ds["reflectance"]
    assert cube.dims == ("frame", "y", "x", "band") and cube.sizes["frame"] == N_FRAMES
    if variant == "no-input":
        assert "raw" not in ds and str(paths[0]) in ds.attrs["input_left_out"]
    else:
        np.testing.assert_array_equal(ds["raw"].values, raw)  # the frames kept
    sensor = Sensor.load(_sensor_path(kind))
    tr, tc = sensor.mosaic_shape
    offsets = np.asarray(sensor.band_offset)
    if kind == "imec":  # the filter area starts at row 3: the tile grid with it
        offsets = offsets + np.array([3 - CROP_IMEC[0][0] % tr, 0])
    got = np.asarray(cube.values, np.float64)
    for i in range(N_FRAMES):  # at its own pixels, each band the value measured there
        ff = _pixel_flatfield(raw[i], dark, white)
        for b, (r, c) in enumerate(offsets % [tr, tc]):
            np.testing.assert_allclose(got[i, r::tr, c::tc, b], ff[r::tr, c::tc], rtol=1e-5,
                                       atol=PACKED_ERROR if variant == "uint16" else 0,
                                       err_msg=f"frame {i} band {b}")
    if "--lens" in STREAM_VARIANTS[variant]:
        assert ds["wavelength_corrected"].sizes["band"] == cube.sizes["band"]
    if variant == "resample":
        assert ds["resampled"].sizes == cube.sizes
    if variant == "virtual":
        assert ds["virtual"].dims == ("frame", "y", "x", "virtual_band")


# -- from Python: a selection in uneven blocks --------------------------------------------------


@pytest.mark.parametrize("out", [".zarr", ".nc"])
def test_a_crop_cut_from_blocks_of_rows_is_corrected_to_zarr_and_back(work, tmp_path, out):
    """``read_dataset(chunks=...)``, a crop cut across its blocks (uneven blocks, which zarr
    cannot store one for one), ``correct_cube``, ``write_dataset``: the result reads back as
    the same correction made in memory."""
    import snapcorr
    from snapcorr.correct import correct_cube

    src = _flatfielded(work, "crop", None, ".zarr")
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    lens = snapcorr.Lens.load(snapcorr.data.lens_path(LENS))
    ds = read_dataset(src, chunks={"y": 5}).isel(y=slice(3, None), x=slice(1, None))
    assert len(set(ds["reflectance"].chunks[0][:-1])) > 1  # uneven: 2, 5, 5, ...
    cube = ds["reflectance"]
    lazy = correct_cube(cube, sensor, 2.8, lens, resample=True)
    write_dataset(lazy, tmp_path / f"c{out}")
    back = read_dataset(tmp_path / f"c{out}").load()
    eager = correct_cube(cube.load(), sensor, 2.8, lens, resample=True)
    for name in ("reflectance", "wavelength_corrected", "resampled", "sensor_row"):
        np.testing.assert_allclose(back[name].values, eager[name].values, rtol=1e-6,
                                   err_msg=name)
