"""Output options: ENVI results, --no-input, --store-derived, compression, units of raw data.

Every result is read back by another reader than snapcorr's (Spectral Python for ENVI,
plain xarray for netCDF and Zarr) and compared with what the library computes in memory.
"""

import h5py
import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_LENS
from spectral.io import envi

from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, make_cube, read_cube, read_dataset, write_cube, write_dataset

NB = 6


@pytest.fixture
def files(tmp_path):
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, NB), 10.0, 1.7)
    sensor.save(tmp_path / "sensor.toml")
    PAPER_LENS.save(tmp_path / "lens.toml")
    rng = np.random.default_rng(3)
    data = rng.random((24, 32, NB)).astype(np.float32)
    cube = make_cube(data, sensor.cwl_nm, name="reflectance", attrs={"units": "1"})
    write_cube(cube, tmp_path / "cube.nc")
    raw = make_cube(rng.integers(100, 4000, (24, 32, NB)).astype(np.uint16), sensor.cwl_nm)
    write_cube(raw, tmp_path / "raw.hdr")
    return tmp_path, cube, raw, sensor


def _correct(cli, d, out, *extra, cube="cube.nc"):
    res = cli("correct", cube, "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--out", out, *extra, cwd=d)
    assert res.returncode == 0, res.stderr
    return res


@pytest.mark.filterwarnings("ignore:Image data contains NaN")  # resampled: NaN, not made up
def test_envi_result_opens_in_spectral_python_with_wavelengths_only_where_one_per_band(
        files, cli):
    d, cube, _, sensor = files
    _correct(cli, d, "r.hdr", "--resample", "--harmonise")
    ref = correct_cube(cube, sensor, 1.4, PAPER_LENS, resample=True, harmonise=True)
    for name, file in (("reflectance", "r.hdr"),
                       ("wavelength_corrected", "r_wavelength_corrected.hdr"),
                       ("fwhm_corrected", "r_fwhm_corrected.hdr"),
                       ("resampled", "r_resampled.hdr"), ("harmonised", "r_harmonised.hdr")):
        img = envi.open(str(d / file))
        got = np.asarray(img.load())
        np.testing.assert_array_equal(got, ref[name].transpose("y", "x", "band").values,
                                      err_msg=name)
        meta = img.metadata
        if name in ("resampled", "harmonised"):  # one wavelength per band: in the header
            np.testing.assert_allclose([float(v) for v in meta["wavelength"]], sensor.cwl_nm)
        else:  # each pixel its own: none a reader would take for every pixel's
            assert "wavelength" not in meta, file
            assert "r_wavelength_corrected.hdr" in meta["description"]
    fw = [float(v) for v in envi.open(str(d / "r_harmonised.hdr")).metadata["fwhm"]]
    np.testing.assert_allclose(fw, ref["fwhm_harmonised"].values)
    cra = np.asarray(envi.open(str(d / "r_cra_deg.hdr")).load())
    np.testing.assert_allclose(cra[:, :, 0], ref["cra_deg"].values, rtol=1e-6)
    # snapcorr reads the resampled cube back as a cube at the nominal wavelengths
    back = read_cube(d / "r_resampled.hdr")
    np.testing.assert_array_equal(back.wavelength.values, sensor.cwl_nm)


def test_envi_result_writes_nothing_when_one_of_its_files_exists(files, cli):
    d, _, _, _ = files
    (d / "r_resampled.hdr").write_text("somebody's header\n")
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--out", "r.hdr", "--resample", cwd=d)
    assert res.returncode == 1 and "r_resampled.hdr exists" in res.stderr
    assert not (d / "r.hdr").exists() and not (d / "r_wavelength_corrected.hdr").exists()
    assert (d / "r_resampled.hdr").read_text() == "somebody's header\n"
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--out", "r.hdr", "--resample", "--overwrite", cwd=d)
    assert res.returncode == 1 and "snapcorr wrote" in res.stderr  # not ours: never replaced
    assert (d / "r_resampled.hdr").read_text() == "somebody's header\n"


@pytest.mark.parametrize("out", ["r.nc", "r.zarr", "r.hdr"])
def test_no_input_leaves_the_copy_out_and_says_where_the_input_is(files, cli, out):
    d, cube, _, sensor = files
    _correct(cli, d, out, "--resample", "--no-input")
    ref = correct_cube(cube, sensor, 1.4, PAPER_LENS, resample=True)
    if out.endswith(".hdr"):
        assert not (d / "r.hdr").exists()
        meta = envi.open(str(d / "r_resampled.hdr")).metadata
        assert "cube.nc" in meta["snapcorr attrs"] and "--no-input" in meta["snapcorr attrs"]
        return
    ds = read_dataset(d / out)
    assert "reflectance" not in ds.variables
    assert ds.attrs["input_left_out"] == "reflectance (--no-input); the input is cube.nc"
    np.testing.assert_array_equal(ds["resampled"].values, ref["resampled"].values)
    np.testing.assert_array_equal(ds["wavelength_corrected"].values,
                                  ref["wavelength_corrected"].values)


def test_flatfield_no_input_leaves_the_raw_copy_out(tmp_path, cli):
    rng = np.random.default_rng(1)
    wl = np.linspace(500, 900, NB)
    for name, level in (("raw", 2000), ("dark", 100), ("white", 3000)):
        data = (level + rng.integers(0, 50, (10, 12, NB))).astype(np.uint16)
        write_cube(make_cube(data, wl), tmp_path / f"{name}.hdr")
    for out, extra in (("a.nc", []), ("b.nc", ["--no-input"])):
        res = cli("flatfield", "raw.hdr", "--dark", "dark.hdr", "--white", "white.hdr",
                  "--out", out, *extra, cwd=tmp_path)
        assert res.returncode == 0, res.stderr
    a, b = read_dataset(tmp_path / "a.nc"), read_dataset(tmp_path / "b.nc")
    assert "raw" in a and "raw" not in b and "raw.hdr" in b.attrs["input_left_out"]
    xr.testing.assert_equal(a["reflectance"], b["reflectance"])


@pytest.mark.parametrize("out", ["r.nc", "r.zarr"])
def test_store_derived_gives_plain_readers_the_corrected_wavelengths(files, cli, out):
    d, cube, _, sensor = files
    _correct(cli, d, out, "--store-derived")
    ref = correct_cube(cube, sensor, 1.4, PAPER_LENS)
    plain = xr.open_dataset(d / out, engine="h5netcdf" if out.endswith(".nc") else "zarr")
    for name in ("wavelength_corrected", "fwhm_corrected"):
        np.testing.assert_array_equal(plain[name].values, ref[name].values, err_msg=name)
        assert plain[name].attrs["units"] == "nm" and "computed_from" in plain[name].attrs
    assert "derived_variables" not in plain.attrs
    ours = read_dataset(d / out)  # and snapcorr reads it as it was
    np.testing.assert_array_equal(ours["wavelength_corrected"].values,
                                  ref["wavelength_corrected"].values)
    # without the option a plain reader sees neither, only the compact form and the formula
    _correct(cli, d, "s" + out[1:])
    plain = xr.open_dataset(d / ("s" + out[1:]),
                            engine="h5netcdf" if out.endswith(".nc") else "zarr")
    assert "wavelength_corrected" not in plain.variables and "wavelength_scale" in plain


def _deflated(path):
    with h5py.File(path, "r") as f:
        return {k: f[k].compression for k in ("reflectance", "raw", "mask")}


def test_netcdf_compression_by_default(tmp_path):
    rng = np.random.default_rng(0)
    ds = xr.Dataset({"reflectance": (("y", "x", "band"), rng.random((20, 30, NB), np.float32)),
                     "raw": (("y", "x", "band"), rng.integers(0, 4000, (20, 30, NB), np.uint16)),
                     "mask": (("y", "x", "band"), rng.random((20, 30, NB)) > 0.99)})
    got = {}
    for comp in ("auto", "all", "none"):
        write_dataset(ds, tmp_path / f"{comp}.nc", compression=comp)
        got[comp] = _deflated(tmp_path / f"{comp}.nc")
        xr.testing.assert_equal(read_dataset(tmp_path / f"{comp}.nc")[list(ds)], ds)
    assert got["auto"] == {"reflectance": "gzip", "raw": "gzip", "mask": "gzip"}
    assert got["all"] == {"reflectance": "gzip", "raw": "gzip", "mask": "gzip"}
    assert got["none"] == {"reflectance": None, "raw": None, "mask": None}
    with pytest.raises(ValueError, match="compression must be one of"):
        write_dataset(ds, tmp_path / "x.nc", compression="zip")


def test_zarr_compression_none_stores_plain_chunks(tmp_path):
    ds = xr.Dataset({"v": (("y", "x", "band"), np.zeros((8, 8, NB), np.float32))})
    write_dataset(ds, tmp_path / "a.zarr")
    write_dataset(ds, tmp_path / "b.zarr", compression="none")
    a = xr.open_zarr(tmp_path / "a.zarr")["v"].encoding.get("compressors")
    b = xr.open_zarr(tmp_path / "b.zarr")["v"].encoding.get("compressors")
    assert a and not b


def test_raw_counts_are_named_and_carry_units_through_the_correction(files, cli):
    d, _, raw, _ = files
    back = read_cube(d / "raw.hdr")
    assert back.name == "raw" and back.attrs["units"] == "count"
    np.testing.assert_array_equal(back.values, raw.values)
    _correct(cli, d, "r.nc", "--resample", cube="raw.hdr")
    ds = read_dataset(d / "r.nc")
    assert ds["raw"].attrs["units"] == "count"
    assert ds["resampled"].attrs["units"] == "count"
    # a float cube nobody gave units keeps none: "1" is only for ratios
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, NB), 10.0, 1.7)
    plain = make_cube(np.ones((4, 5, NB), np.float32), sensor.cwl_nm)
    out = correct_cube(plain, sensor, 1.4, PAPER_LENS, resample=True, harmonise=True)
    assert "units" not in out["resampled"].attrs and "units" not in out["harmonised"].attrs
    ratio = make_cube(np.ones((4, 5, NB), np.float32), sensor.cwl_nm, name="reflectance")
    assert correct_cube(ratio, sensor, 1.4, PAPER_LENS, resample=True)["resampled"].attrs[
        "units"] == "1"


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_compression_decides_for_variables_read_from_a_file(tmp_path, ext):
    """A variable read from a file carries that file's encoding: "all" and "none" override
    it, "auto" keeps a compression it already has."""
    rng = np.random.default_rng(2)
    ds = xr.Dataset({"v": (("y", "x", "band"), rng.random((12, 14, NB), np.float32)),
                     "n": (("y", "x", "band"), rng.integers(0, 9, (12, 14, NB), np.uint16))})
    write_dataset(ds, tmp_path / f"plain{ext}", compression="none")
    write_dataset(ds, tmp_path / f"packed{ext}", compression="all")
    engine = "h5netcdf" if ext == ".nc" else "zarr"

    def packed(path, name):
        e = xr.open_dataset(path, engine=engine)[name].encoding
        return bool(e.get("zlib")) if ext == ".nc" else bool(e.get("compressors"))

    for src, comp, want in (("plain", "all", True), ("packed", "none", False),
                            ("packed", "auto", True)):
        got = read_dataset(tmp_path / f"{src}{ext}", chunks={})
        out = tmp_path / f"{src}_{comp}{ext}"
        write_dataset(got, out, compression=comp)
        assert packed(out, "v") is want, (src, comp)
        xr.testing.assert_equal(read_dataset(out)[["v", "n"]], ds)


def test_envi_result_refuses_what_it_cannot_do_before_any_work(files, cli):
    d, _, _, sensor = files
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--out", "r.hdr", "--compression", "all", cwd=d)
    assert res.returncode == 1 and "go with .nc or .zarr" in res.stderr
    # an image of an earlier run this one would not rewrite: refused, nothing written
    _correct(cli, d, "r.hdr", "--harmonise")
    before = {p.name: p.stat().st_mtime_ns for p in d.iterdir()}
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--out", "r.hdr", "--overwrite", cwd=d)
    assert res.returncode == 1 and "r_harmonised.hdr exists" in res.stderr, res.stderr
    assert {p.name: p.stat().st_mtime_ns for p in d.iterdir()} == before
    # a cube read back from a result under a result's name is refused, not overwritten
    resampled = read_cube(d / "r_harmonised.hdr")
    assert resampled.name == "harmonised"
    with pytest.raises(ValueError, match="a result of a correction"):
        correct_cube(resampled, sensor, 1.4, PAPER_LENS, harmonise=True)


@pytest.mark.filterwarnings("ignore:Image data contains NaN")
def test_every_image_of_an_envi_result_reads_back_as_the_result_holds_it(files, cli):
    """Its images at each pixel's own wavelengths were refused by read_cube ('carries no
    wavelengths; pass wavelength_nm'), though their headers name the bands' nominal ones."""
    d, cube, _, sensor = files
    _correct(cli, d, "r.hdr", "--resample", "--harmonise")
    _correct(cli, d, "r.nc", "--resample", "--harmonise")
    with read_dataset(d / "r.nc") as ref:
        for name, file in (("reflectance", "r.hdr"),
                           ("wavelength_corrected", "r_wavelength_corrected.hdr"),
                           ("fwhm_corrected", "r_fwhm_corrected.hdr"),
                           ("resampled", "r_resampled.hdr"), ("harmonised", "r_harmonised.hdr")):
            got = read_cube(d / file)
            assert got.name == name
            np.testing.assert_array_equal(got.wavelength.values, sensor.cwl_nm, err_msg=file)
            np.testing.assert_array_equal(
                got.values, ref[name].transpose("y", "x", "band").values.astype(got.dtype),
                err_msg=file)
    # the input's values are the input, back at its nominal wavelengths
    again = read_cube(d / "r.hdr")
    np.testing.assert_array_equal(again.values, cube.values)
    np.testing.assert_array_equal(again.wavelength.values, cube.wavelength.values)


@pytest.mark.filterwarnings("ignore:Image data contains NaN")
@pytest.mark.parametrize("image", ["resampled", "harmonised", "wavelength_corrected",
                                   "virtual"])
def test_correct_refuses_an_image_of_its_own_result_naming_the_file(files, cli, image):
    """The refusal said 'the cube is named ...' with no file, and 'in Python, rename it' to a
    command line; a result's virtual bands (other bands than the sensor's) were said to be of
    another sensor."""
    d, *_ = files
    _correct(cli, d, "r.hdr", "--resample", "--harmonise")
    if image == "virtual":  # three virtual bands, as a result records them
        write_cube(make_cube(np.ones((24, 32, 3), np.float32), [550.0, 650.0, 750.0],
                             name="virtual", attrs={"cube_file": "cube.nc"}),
                   d / "r_virtual.hdr")
    res = cli("correct", f"r_{image}.hdr", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--out", "again.nc", cwd=d)
    assert res.returncode == 1
    line = res.stderr.strip()
    assert "\n" not in line, line
    assert f"r_{image}.hdr holds '{image}'" in line and "correct the cube it was made from " \
        "(cube.nc" in line, line
    assert "Python" not in line and not (d / "again.nc").exists()


def test_envi_float32_result_clips_values_beyond_float32_and_says_so(files, cli):
    """--dtype float32 of float64 values cast those beyond 3.4e38 to infinity without a word
    in ENVI (the .nc and .zarr writers clip and warn): now clipped to float32's largest of
    their sign and counted, as theirs are."""
    d, cube, _, _ = files
    values = cube.values.astype(np.float64)
    values[0, 0, :2] = [1e39, -1e300]
    make_cube(values, cube.wavelength.values, name="reflectance",
              attrs={"units": "1"}).pipe(write_cube, d / "big.nc")
    res = _correct(cli, d, "r.hdr", "--dtype", "float32", cube="big.nc")
    assert "2 of 4608 values of 'reflectance'" in res.stderr, res.stderr
    got = np.asarray(envi.open(str(d / "r.hdr")).load())
    assert got.dtype == np.float32 and np.all(np.isfinite(got))
    top = np.finfo(np.float32).max
    np.testing.assert_array_equal(got[0, 0, :2], [top, -top])
    np.testing.assert_array_equal(got[1:], values[1:].astype(np.float32))
