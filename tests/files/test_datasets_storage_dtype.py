"""A result's values stored as float32, float16 or uint16 (``--dtype``), read back by readers
that are not snapcorr's: xarray directly, h5py (the netCDF file's own numbers, unpacked here by
the CF rule), Spectral Python for ENVI; packing refused where a format cannot say it and for a
camera's counts; values outside the packing range clipped and said."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
import xarray as xr

from snapcorr.cube import make_cube, read_dataset, write_cube, write_dataset
from snapcorr.files.datasets import PACKED_FILL, PACKED_TOP, RATIO_PACK_RANGE

NB = 6
WL = np.linspace(500.0, 600.0, NB)


def _result(rng, shape=(24, 20, NB)):
    """A flat-field result as snapcorr writes one: reflectance (noisy, NaN where masked, a
    few values outside the packing range), its mask and the raw counts."""
    refl = rng.normal(0.4, 0.05, shape).astype(np.float32)
    raw = rng.integers(60, 4000, shape).astype(np.uint16)
    mask = rng.random(shape) < 0.02
    refl[mask] = np.nan
    refl[0, 0, :3] = [-0.9, 3.7, 12.0]  # beyond the ratio range on both sides
    return xr.Dataset({"reflectance": (("y", "x", "band"), refl, {"units": "1"}),
                       "mask": (("y", "x", "band"), mask, {"units": "1"}),
                       "raw": (("y", "x", "band"), raw, {"units": "count"})},
                      coords={"wavelength": ("band", WL, {"units": "nm"})})


def _open(path):
    return xr.open_dataset(path, engine="zarr" if path.suffix == ".zarr" else "h5netcdf")


CASES = [(".nc", "float32"), (".nc", "uint16"), (".zarr", "float32"), (".zarr", "float16"),
         (".zarr", "uint16")]


@pytest.mark.parametrize(("ext", "dtype"), CASES)
def test_every_type_reads_back_with_xarray_as_the_values(tmp_path, ext, dtype):
    ds = _result(np.random.default_rng(1))
    path = tmp_path / f"r{ext}"
    write_dataset(ds, path, dtype=dtype)
    want = ds["reflectance"].values.astype(np.float64)
    with _open(path) as back:
        got = back["reflectance"]
        assert got.encoding["dtype"] == np.dtype(dtype)
        values = got.values.astype(np.float64)
        # NaN stays NaN, numbers stay numbers
        np.testing.assert_array_equal(np.isnan(values), np.isnan(want))
        # the raw counts and the mask as they were, the counts unpacked and of their type
        assert back["raw"].dtype == np.uint16 and "scale_factor" not in back["raw"].encoding
        np.testing.assert_array_equal(back["raw"].values, ds["raw"].values)
        np.testing.assert_array_equal(back["mask"].values, ds["mask"].values)
        inside = np.isfinite(want) & (want >= -0.5) & (want <= 3.5)
        err = np.abs(values - want)[inside]
        if dtype == "float32":
            assert err.max() == 0
        elif dtype == "float16":
            assert np.all(err <= 2.0**-11 * np.abs(want[inside]))  # the stated relative error
            assert got.attrs["packing_error"] == "relative 4.9e-4"
        else:
            stated = float(got.attrs["packing_error"])
            step = (RATIO_PACK_RANGE[1] - RATIO_PACK_RANGE[0]) / PACKED_TOP
            # within the error the file states, and that error not loose (noisy values fill
            # every part of a step)
            assert err.max() <= stated and err.max() > 0.45 * step
            assert stated < 0.55 * step
            assert "clipped" in got.attrs["storage"]
    if dtype != "float32":  # snapcorr's own reader agrees with xarray's
        back = read_dataset(path)
        np.testing.assert_allclose(back["reflectance"].values, values, rtol=0, atol=1e-6)


def test_uint16_netcdf_unpacked_by_the_cf_rule_from_the_stored_codes(tmp_path):
    """The file's own numbers, read with h5py (no xarray): codes, scale_factor, add_offset,
    _FillValue and valid_range as a netCDF tool sees them, unpacked here by CF's rule."""
    ds = _result(np.random.default_rng(2))
    write_dataset(ds, tmp_path / "r.nc", dtype="uint16")
    with h5py.File(tmp_path / "r.nc", "r") as f:
        v = f["reflectance"]
        codes = v[...]
        scale, offset = v.attrs["scale_factor"], v.attrs["add_offset"]
        fill, valid = v.attrs["_FillValue"], v.attrs["valid_range"]
        assert codes.dtype == np.uint16 and v.compression == "gzip"
        assert np.ravel(fill).tolist() == [PACKED_FILL] and list(valid) == [0, PACKED_TOP]
        assert f["raw"].dtype == np.uint16 and "scale_factor" not in f["raw"].attrs
    want = ds["reflectance"].values.astype(np.float64)
    scale, offset = np.ravel(scale)[0], np.ravel(offset)[0]
    values = np.where(codes == np.ravel(fill)[0], np.nan, codes * float(scale) + float(offset))
    np.testing.assert_array_equal(np.isnan(values), np.isnan(want))
    assert codes[np.isfinite(want)].max() <= PACKED_TOP
    # clipped to the range's ends, as the attributes say
    np.testing.assert_allclose(values[0, 0, :3], [-0.5, 3.5, 3.5], atol=1e-6)
    ok = np.isfinite(want) & (want >= -0.5) & (want <= 3.5)
    assert np.max(np.abs(values - want)[ok]) <= 0.5 * float(scale) * 1.01


def test_packing_what_has_no_known_range_or_holds_counts_is_refused(tmp_path):
    rng = np.random.default_rng(3)
    radiance = xr.Dataset({"radiance": (("y", "x", "band"), rng.random((5, 4, NB)) * 80,
                                        {"units": "W m-2 sr-1 um-1"})},
                          coords={"wavelength": ("band", WL)})
    with pytest.raises(ValueError, match=r"give the range \(pack_range=\)"):
        write_dataset(radiance, tmp_path / "r.zarr", dtype="uint16")
    assert not (tmp_path / "r.zarr").exists()
    write_dataset(radiance, tmp_path / "r.zarr", dtype="uint16", pack_range=(0, 100))
    with _open(tmp_path / "r.zarr") as back:
        np.testing.assert_allclose(back["radiance"].values, radiance["radiance"].values,
                                   atol=float(back["radiance"].attrs["packing_error"]))
    counts = radiance.assign(radiance=radiance["radiance"].assign_attrs(units="count"))
    for dtype in ("uint16", "float16"):
        with pytest.raises(ValueError, match="camera's numbers"):
            write_dataset(counts, tmp_path / f"c_{dtype}.zarr", dtype=dtype, pack_range=None
                          if dtype == "float16" else (0, 100))
    with pytest.raises(ValueError, match="no 16-bit float"):
        write_dataset(_result(rng), tmp_path / "h.nc", dtype="float16")
    with pytest.raises(ValueError, match="LO < HI"):
        write_dataset(_result(rng), tmp_path / "h.zarr", dtype="uint16", pack_range=(2, 1))


def test_float16_clips_what_it_cannot_hold(tmp_path):
    from snapcorr.files import PackingClipWarning

    ds = xr.Dataset({"radiance": (("y", "x", "band"), np.full((2, 3, NB), 1e6, np.float32),
                                  {"units": "W m-2"})})
    with pytest.warns(PackingClipWarning, match=f"{2 * 3 * NB} of {2 * 3 * NB} values"):
        write_dataset(ds, tmp_path / "h.zarr", dtype="float16")
    with _open(tmp_path / "h.zarr") as back:
        assert np.all(back["radiance"].values == 65504)
        assert "clipped" in back["radiance"].attrs["storage"]


def _ratios(values, lazy=False):
    values = np.asarray(values, np.float32)[None, None, :]
    cube = make_cube(values, np.linspace(500.0, 500.0 + 10 * (values.shape[2] - 1),
                                         values.shape[2]), name="reflectance",
                     attrs={"units": "1"})
    return xr.Dataset({"reflectance": cube.chunk({"band": 2}) if lazy else cube})


def test_float16_keeps_infinities_as_they_are(tmp_path):
    import warnings

    from snapcorr.files import PackingClipWarning

    with warnings.catch_warnings():
        warnings.simplefilter("error", PackingClipWarning)  # infinities are not clipped
        write_dataset(_ratios([np.inf, np.nan, -np.inf]), tmp_path / "x.zarr", dtype="float16")
    with _open(tmp_path / "x.zarr") as back:  # xarray's own reader
        assert back["reflectance"].encoding["dtype"] == np.float16
        values = back["reflectance"].values[0, 0]
    assert values[0] == np.inf and np.isnan(values[1]) and values[2] == -np.inf


@pytest.mark.parametrize("lazy", [False, True])
def test_float16_says_the_finite_values_it_clips(tmp_path, lazy):
    """Finite values float16 cannot hold (its cast would make them infinite) are stored at
    its ends, counted and said as uint16's packing says them; 65519 rounds to 65504 (not
    clipped), 65520 would be infinite (clipped)."""
    from snapcorr.files import PackingClipWarning

    given = [119800.0, -1e5, 65519.0, 65520.0, 0.5, np.inf, np.nan]
    with pytest.warns(PackingClipWarning) as record:
        write_dataset(_ratios(given, lazy), tmp_path / "x.zarr", dtype="float16")
    said = [w for w in record if w.category is PackingClipWarning]
    assert len(said) == 1 and said[0].filename == __file__
    assert "3 of 7 values of 'reflectance'" in str(said[0].message)
    assert "float16's range -65504 to 65504" in str(said[0].message)
    with _open(tmp_path / "x.zarr") as back:
        values = back["reflectance"].values[0, 0].astype(np.float64)
        storage = back["reflectance"].attrs["storage"]
    np.testing.assert_array_equal(values[:6], [65504, -65504, 65504, 65504, 0.5, np.inf])
    assert np.isnan(values[6])
    assert "+-65504 (clipped)" in storage and "infinities and NaN as they are" in storage


def test_float16_kept_from_a_store_clips_and_says_it(tmp_path):
    """A variable read from a float16 store keeps float16 as its encoding: new values written
    with it are clipped and said as ``dtype="float16"`` does, not cast to infinities."""
    from snapcorr.files import PackingClipWarning

    write_dataset(_ratios([0.5, 0.25]), tmp_path / "a.zarr", dtype="float16")
    ds = read_dataset(tmp_path / "a.zarr")
    ds["reflectance"] = ds["reflectance"].copy(data=np.full((1, 1, 2), 7e4, np.float32))
    assert ds["reflectance"].encoding["dtype"] == np.float16
    with pytest.warns(PackingClipWarning, match="2 of 2 values"):
        write_dataset(ds, tmp_path / "b.zarr")
    with _open(tmp_path / "b.zarr") as back:
        np.testing.assert_array_equal(back["reflectance"].values, 65504)


def test_the_command_line_says_float16_clipped_values(tmp_path, capsys):
    from snapcorr.cli import main

    raw = np.full((4, 4, 3), 1000, np.uint16)
    raw[0, 0, 0] = 60000
    white = np.full((4, 4, 3), 3000.0, np.float32)
    white[0, 0, 0] = 100.5  # (60000 - 100) / 0.5 = 119800
    wl = [500.0, 550.0, 600.0]
    write_cube(make_cube(raw, wl), tmp_path / "raw.hdr")
    write_cube(make_cube(np.full((4, 4, 3), 100.0, np.float32), wl, attrs={"units": "count"}),
               tmp_path / "dark.hdr")
    write_cube(make_cube(white, wl, attrs={"units": "count"}), tmp_path / "white.hdr")
    assert main(["flatfield", str(tmp_path / "raw.hdr"), "--dark", str(tmp_path / "dark.hdr"),
                 "--white", str(tmp_path / "white.hdr"), "--dtype", "float16", "--out",
                 str(tmp_path / "x.zarr")]) == 0
    err = capsys.readouterr().err
    assert "snapcorr: warning:" in err
    assert "1 of 48 values of 'reflectance'" in err and "float16's range" in err
    with _open(tmp_path / "x.zarr") as back:
        assert back["reflectance"].values[0, 0, 0] == 65504


def test_the_command_line_stores_as_asked_and_refuses_envi_packing(tmp_path, cli):
    rng = np.random.default_rng(4)
    write_cube(make_cube(rng.integers(1000, 3000, (8, 6, NB)).astype(np.uint16), WL),
               tmp_path / "raw.hdr")
    write_cube(make_cube(np.full((8, 6, NB), 50, np.uint16), WL), tmp_path / "dark.hdr")
    write_cube(make_cube(np.full((8, 6, NB), 3500, np.uint16), WL), tmp_path / "white.hdr")
    args = ["flatfield", "raw.hdr", "--dark", "dark.hdr", "--white", "white.hdr"]
    res = cli(*args, "--dtype", "uint16", "--out", "r.nc", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "stored as uint16, CF-packed, computed in float32" in res.stdout  # the summary
    with _open(tmp_path / "r.nc") as back:
        assert back["reflectance"].encoding["dtype"] == np.uint16
        assert back["raw"].dtype == np.uint16
    res = cli(*args, "--dtype", "float16", "--out", "h.nc", cwd=tmp_path)
    assert res.returncode == 1 and "no 16-bit float" in res.stderr
    assert "Traceback" not in res.stderr and not (tmp_path / "h.nc").exists()
    res = cli(*args, "--dtype", "float32", "--pack-range", "0,2", "--out", "p.zarr",
              cwd=tmp_path)
    assert res.returncode == 1 and "goes with --dtype uint16" in res.stderr
    from snapcorr.files.datasets import check_storage

    for dtype in ("uint16", "float16"):
        with pytest.raises(ValueError, match="ENVI has no packing"):
            check_storage(dtype, None, "envi", what="--dtype")


def test_an_envi_result_is_float32_as_spectral_python_reads_it_and_never_packed(tmp_path, cli):
    """ENVI has no packing a reader applies: ``--dtype float32`` writes float32 pairs that
    Spectral Python (not snapcorr's reader) reads as the values; uint16 and float16 are
    refused before any work, in one line."""
    spectral = pytest.importorskip("spectral")
    from snapcorr import data
    from snapcorr.cube import Sensor

    sensor = Sensor.load(data.sensor_path("snapscan_vnir"))
    rng = np.random.default_rng(5)
    values = rng.uniform(0.05, 0.9, (6, 5, sensor.n_bands))  # float64
    write_cube(make_cube(values, sensor.cwl_nm, name="reflectance",
                         attrs={"units": "1"}), tmp_path / "cube.nc")
    args = ["correct", "cube.nc", "--lens", "edmund_optics_16mm", "--sensor", "snapscan_vnir",
            "--f-number", "2", "--sensor-origin-px", "1000,1000"]
    for dtype in ("uint16", "float16"):
        res = cli(*args, "--dtype", dtype, "--out", f"{dtype}.hdr", cwd=tmp_path)
        assert res.returncode == 1 and "ENVI has no packing" in res.stderr, res.stderr
        assert res.stderr.count("\n") == 1 and not list(tmp_path.glob(f"{dtype}*"))
    res = cli(*args, "--dtype", "float32", "--out", "r.hdr", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    img = spectral.open_image(str(tmp_path / "r.hdr"))
    got = np.asarray(img.load())
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, values.astype(np.float32))
    # the nominal wavelengths (each pixel has its own, in r_wavelength_corrected.hdr)
    assert np.all(np.diff(np.asarray(img.metadata["snapcorr nominal wavelength"], float)) > 0)


@pytest.mark.parametrize("chunks", [None, {"y": 2}])
def test_a_packed_cube_reads_back_as_float32_from_zarr_as_from_netcdf(tmp_path, chunks):
    """uint16-packed values unpack to float32, their scale_factor's type, from either store
    (from Zarr they came back float64: twice the memory, and another type than the same cube
    read from netCDF), with the same values, lazily (unpacked as a block is read)."""
    from snapcorr.cube import make_cube
    from snapcorr.files import read_cube, read_dataset, write_dataset

    cube = make_cube(np.linspace(0, 1, 6 * 5 * 3).reshape(6, 5, 3), [500.0, 510.0, 520.0])
    ds = cube.rename("reflectance").assign_attrs(units="1").to_dataset()
    got = {}
    for suffix in (".nc", ".zarr"):
        path = write_dataset(ds, tmp_path / f"c{suffix}", dtype="uint16")
        back = read_cube(path) if chunks is None else read_cube(path, chunks=chunks)
        assert back.dtype == np.float32, suffix
        whole = read_dataset(path)["reflectance"]
        assert whole.dtype == np.float32, suffix
        assert not isinstance(whole.variable._data, np.ndarray), suffix  # not read yet
        got[suffix] = np.asarray(back.values)
    np.testing.assert_array_equal(got[".nc"], got[".zarr"])
    np.testing.assert_allclose(got[".nc"], cube.values, atol=1e-4)


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_float32_from_float64_says_the_finite_values_it_clips(tmp_path, ext):
    """float64 values beyond float32's range were cast to infinities, unsaid; they are now
    stored at float32's ends and said, as float16 and uint16 say theirs."""
    from snapcorr.files import PackingClipWarning

    values = np.array([[[1e39, -1e40, np.inf, 0.5]]])
    ds = make_cube(values, WL[:4], name="radiance", attrs={"units": "W m-2"}).to_dataset()
    with pytest.warns(PackingClipWarning, match=r"2 of 4 values of 'radiance' .* float32's "
                                                r"range") as record:
        write_dataset(ds, tmp_path / f"r{ext}", dtype="float32")
    assert {w.filename for w in record if w.category is PackingClipWarning} == {__file__}
    with _open(tmp_path / f"r{ext}") as back:
        assert back["radiance"].encoding["dtype"] == np.float32
        got = back["radiance"].values[0, 0]
    top = np.finfo(np.float32).max
    np.testing.assert_array_equal(got, np.array([top, -top, np.inf, 0.5], np.float32))


@pytest.mark.parametrize(("wide", "narrow"), [(np.float32, np.float16), (np.float64, np.float16),
                                              (np.float64, np.float32)])
def test_the_narrower_float_clip_counts_what_the_cast_makes_infinite(wide, narrow):
    """The values counted and clipped are exactly those numpy's cast rounds to infinity."""
    from snapcorr.files.datasets import _narrowed

    info = np.finfo(narrow)
    edge = wide(float(info.max) + 2.0 ** (info.maxexp - 2 - info.nmant))
    one = np.array([info.max, np.nextafter(edge, wide(0)), edge,
                    np.nextafter(edge, wide(np.inf)), np.inf, np.nan, 1.0], wide)
    values = np.concatenate([one, -one])
    with np.errstate(over="ignore"):
        made_infinite = np.isfinite(values) & np.isinf(values.astype(narrow))
    counts = []
    out = _narrowed(values, np.dtype(narrow), counts)
    assert counts == [(int(made_infinite.sum()), values.size)] and made_infinite.sum() == 4
    stored = out.astype(narrow)
    np.testing.assert_array_equal(np.isinf(stored), np.isinf(values))
    np.testing.assert_array_equal(np.isnan(stored), np.isnan(values))


@pytest.mark.parametrize("lazy", [False, True])
def test_float16_values_go_to_netcdf_as_float32_every_value_exact(tmp_path, lazy):
    """A float16 cube (from a float16 Zarr store) and a float16 raw copy (frames of a float16
    camera file) were written into netCDF-4 as HDF5 half floats, which netCDF tools cannot read
    (netCDF4-python crashed opening them). They are stored as float32, each value exactly, and
    say so; asking for float16 storage in .nc is still refused before any work."""
    rng = np.random.default_rng(8)
    refl = rng.normal(0.4, 0.05, (6, 5, NB)).astype(np.float16)
    raw = (rng.random((6, 5, NB)) * 1000).astype(np.float16)
    ds = xr.Dataset({"reflectance": (("y", "x", "band"), refl, {"units": "1"}),
                     "raw": (("y", "x", "band"), raw, {"units": "count"})},
                    coords={"wavelength": ("band", WL)})
    if lazy:
        ds = ds.chunk({"y": 3})
    write_dataset(ds, tmp_path / "h.nc")
    with h5py.File(tmp_path / "h.nc") as f:
        assert f["reflectance"].dtype == np.float32 and f["raw"].dtype == np.float32
        assert np.array_equal(f["raw"][...], raw.astype(np.float32))
        assert "every float16 value exactly" in str(f["raw"].attrs["stored_as"])
    back = read_dataset(tmp_path / "h.nc")
    assert np.array_equal(back["reflectance"].values, refl.astype(np.float32))
    with pytest.raises(ValueError, match="netCDF has no 16-bit float"):
        write_dataset(ds, tmp_path / "h2.nc", dtype="float16")
