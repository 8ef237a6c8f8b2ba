"""Cube files as users write them: ENVI and netCDF wavelengths in micrometres, ENVI header fields
out of range, EXR with a repeated wavelength, multipage TIFFs, a pickled .npy.

Every input is built as a user would make it, with other libraries than snapcorr's
writers (Spectral Python, tifffile, OpenImageIO, numpy, xarray/h5netcdf, TOML written by
hand); each refusal is the exit status and one error line naming the problem in
command-line terms, with nothing written."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from hostile import (
    LENS,
    SENSOR4,
    WL4,
    assert_refused,
    correct_args,
    read_result,
    save_cubes,
    snapshot,
    write_envi,
)


def _envi_triplet(folder, wavelength, units):
    rng = np.random.default_rng(1)
    write_envi(folder / "scene", rng.uniform(100, 200, (6, 5, 4)).astype(np.float32),
               wavelength=wavelength, units=units)
    write_envi(folder / "dark", np.full((6, 5, 4), 10, np.float32), wavelength=wavelength,
               units=units)
    write_envi(folder / "white", np.full((6, 5, 4), 400, np.float32), wavelength=wavelength,
               units=units)
    return ("flatfield", "scene.hdr", "--dark", "dark.hdr", "--white", "white.hdr")


@pytest.mark.parametrize("units", [None, "Unknown", "Nanometers"],
                         ids=["no-units", "units-unknown", "labelled-nanometers"])
def test_envi_wavelengths_in_micrometres_without_units_are_refused(tmp_path, monkeypatch,
                                                                   units, cli):
    monkeypatch.chdir(tmp_path)
    args = _envi_triplet(tmp_path, [0.50, 0.52, 0.54, 0.56], units)
    before = snapshot(tmp_path)
    rc, _, err = cli(*args, "--out", "o.nc")
    assert_refused(rc, err, "wavelength")
    assert snapshot(tmp_path) == before


def test_envi_nm_values_labelled_micrometers_are_refused(tmp_path, monkeypatch, cli):
    """500 micrometres is not a filter of a VNIR camera: the header's units are wrong."""
    monkeypatch.chdir(tmp_path)
    args = _envi_triplet(tmp_path, WL4, "Micrometers")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args, "--out", "o.nc")
    assert_refused(rc, err, "wavelength")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("units", ["micrometers", "Micrometers"])
def test_envi_wavelength_units_micrometers_read_as_nm(tmp_path, monkeypatch, units, cli):
    monkeypatch.chdir(tmp_path)
    args = _envi_triplet(tmp_path, [0.50, 0.52, 0.54, 0.56], units)
    rc, _, err = cli(*args, "--out", "o.nc")
    assert rc == 0, err
    wl = read_result(tmp_path / "o.nc")["wavelength"].values
    np.testing.assert_allclose(wl, WL4, rtol=1e-9)


@pytest.mark.parametrize("units", ["um", "micrometre", "m"])
def test_netcdf_wavelength_in_um_reads_as_nm(tmp_path, monkeypatch, units, cli):
    monkeypatch.chdir(tmp_path)
    factor = 1e-9 if units == "m" else 1e-3
    rng = np.random.default_rng(2)
    for name, data in (("scene", rng.uniform(100, 200, (6, 5, 4))),
                       ("dark", np.full((6, 5, 4), 10.0)), ("white", np.full((6, 5, 4), 400.0))):
        xr.Dataset({"radiance": (("y", "x", "band"), data.astype(np.float32))},
                   coords={"wavelength": ("band", np.array(WL4) * factor,
                                          {"units": units})},
                   attrs={"instrument": "lab camera"}).to_netcdf(tmp_path / f"{name}.nc",
                                                                 engine="h5netcdf")
    rc, _, err = cli("flatfield", "scene.nc", "--dark", "dark.nc", "--white", "white.nc",
                     "--out", "o.nc")
    assert rc == 0, err
    wl = read_result(tmp_path / "o.nc")["wavelength"]
    np.testing.assert_allclose(wl.values, WL4, rtol=1e-9)
    assert wl.attrs.get("units") == "nm"


def test_netcdf_wavelength_in_um_without_units_is_refused(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    for name, value in (("scene", 150.0), ("dark", 10.0), ("white", 400.0)):
        xr.Dataset({"radiance": (("y", "x", "band"), np.full((6, 5, 4), value, np.float32))},
                   coords={"wavelength": ("band", [0.50, 0.52, 0.54, 0.56])}).to_netcdf(
                       tmp_path / f"{name}.nc", engine="h5netcdf")
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.nc", "--dark", "dark.nc", "--white", "white.nc",
                     "--out", "o.nc")
    assert_refused(rc, err, "wavelength")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("field, value, dtype", [
    ("byte order", "7", np.float32),
    ("data type", "99", np.float32),
    ("data type", "6", np.complex64),
    ("interleave", "xyz", np.float32),
    ("samples", "4.5", np.float32),
    ("header offset", "-8", np.float32),
], ids=["byte-order-7", "data-type-99", "data-type-6-complex", "interleave-xyz",
        "samples-4.5", "header-offset-negative"])
def test_envi_header_field_out_of_range_is_refused(tmp_path, monkeypatch, field, value, dtype, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=(6, 5, 4))
    data = np.ones((6, 5, 4), dtype)
    stem = tmp_path / "scene"
    write_envi(stem, data, data_type=4 if field != "data type" else value,
               fields={field: value})
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.hdr", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "sensor.toml", "--out", "o.nc")
    assert_refused(rc, err, field)
    assert snapshot(tmp_path) == before


def test_envi_header_with_fewer_wavelengths_than_bands_is_refused(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=(6, 5, 4))
    write_envi(tmp_path / "scene", np.ones((6, 5, 4), np.float32), wavelength=WL4[:3])
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.hdr", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "sensor.toml", "--out", "o.nc")
    assert_refused(rc, err, "wavelength")
    assert snapshot(tmp_path) == before


def test_exr_with_a_repeated_wavelength_is_refused_on_read(tmp_path, monkeypatch, cli):
    import OpenImageIO as oiio

    monkeypatch.chdir(tmp_path)
    for name, value in (("scene", 0.5), ("dark", 0.0), ("white", 1.0)):
        spec = oiio.ImageSpec(5, 6, 4, "float")
        spec.channelnames = ("T.500nm", "T.500,0nm", "T.520nm", "T.540nm")
        spec.attribute("spectralLayoutVersion", "1.0")
        out = oiio.ImageOutput.create(str(tmp_path / f"{name}.exr"))
        assert out.open(str(tmp_path / f"{name}.exr"), spec)
        out.write_image(np.full((6, 5, 4), value, np.float32))
        out.close()
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.exr", "--dark", "dark.exr", "--white", "white.exr",
                     "--out", "o.nc")
    assert_refused(rc, err, "500")
    assert snapshot(tmp_path) == before


def test_exr_with_a_repeated_wavelength_is_refused_on_write(tmp_path):
    from snapcorr.cube import write_cube

    cube = xr.DataArray(np.ones((6, 5, 3), np.float32), dims=("y", "x", "band"),
                        coords={"wavelength": ("band", [500.0, 500.0, 520.0], {"units": "nm"})},
                        name="reflectance")
    with pytest.raises(ValueError, match="500"):
        write_cube(cube, tmp_path / "twice.exr")
    assert list(tmp_path.iterdir()) == []


def _multipage(path, cube):
    import tifffile

    with tifffile.TiffWriter(path) as tw:
        for b in range(cube.shape[2]):
            tw.write(np.ascontiguousarray(cube[:, :, b]), photometric="minisblack")


def test_multipage_tiff_is_a_cube_in_flatfield(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sensor.toml").write_text(SENSOR4)
    raw = np.random.default_rng(5).uniform(100, 200, (12, 10, 4)).astype(np.float32)
    raw[:, :, 2] += 1000  # bands differ, so a page mix-up shows
    _multipage(tmp_path / "raw.tif", raw)
    _multipage(tmp_path / "dark.tif", np.full((12, 10, 4), 10.0, np.float32))
    _multipage(tmp_path / "white.tif", np.full((12, 10, 4), 2000.0, np.float32))
    rc, _, err = cli("flatfield", "raw.tif", "--dark", "dark.tif", "--white", "white.tif",
                     "--sensor", "sensor.toml", "--out", "ff.nc")
    assert rc == 0, err
    got = read_result(tmp_path / "ff.nc")["reflectance"]
    assert got.shape == (12, 10, 4)
    np.testing.assert_allclose(got.values, (raw - 10.0) / 1990.0, rtol=1e-5)


def test_multipage_tiff_with_pages_of_different_sizes_is_refused(tmp_path, monkeypatch, cli):
    import tifffile

    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    with tifffile.TiffWriter(tmp_path / "scene.tif") as tw:
        for b in range(4):
            tw.write(np.ones((12, 10) if b != 2 else (12, 9), np.float32),
                     photometric="minisblack")
    before = snapshot(tmp_path)
    rc, _, err = cli("flatfield", "scene.tif", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "sensor.toml", "--out", "o.nc")
    assert_refused(rc, err, "scene.tif")
    assert snapshot(tmp_path) == before


def test_multipage_tiff_flat_with_pages_of_different_sizes_is_refused(tmp_path, monkeypatch, cli):
    import tifffile

    monkeypatch.chdir(tmp_path)
    with tifffile.TiffWriter(tmp_path / "f14.tif") as tw:
        for shape in ((64, 64), (64, 64), (32, 64)):
            tw.write(np.full(shape, 1000.0, np.float32), photometric="minisblack")
    np.save(tmp_path / "f2.npy", np.full((64, 64), 1000.0))
    before = snapshot(tmp_path)
    rc, _, err = cli("calibrate", "--flat", "1.4=f14.tif", "--flat", "2=f2.npy",
                     "--exit-pupil-mm", "21", "--pixel-pitch-um", "5.5", "--out", "lens.toml")
    assert_refused(rc, err, "f14.tif")
    assert snapshot(tmp_path) == before


def test_multipage_tiff_is_a_cube_in_correct(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sensor.toml").write_text(SENSOR4)
    _multipage(tmp_path / "scene.tif", np.ones((12, 10, 4), np.float32))
    rc, _, err = cli(*correct_args("scene.tif", "c.nc"))
    assert rc == 0, err
    assert read_result(tmp_path / "c.nc")["wavelength_corrected"].shape == (12, 10, 4)


def test_multipage_tiff_flats_are_averaged_in_calibrate(tmp_path, monkeypatch, cli):
    from snapcorr import Lens
    from snapcorr.simulate import flat_frame

    monkeypatch.chdir(tmp_path)
    lens = Lens.load(LENS)
    rng = np.random.default_rng(0)
    args = []
    for f in (1.4, 2, 2.8, 4, 8):
        flat = flat_frame((256, 256), 44.0, f, lens, center_px=(130, 120), rng=rng)
        _multipage(tmp_path / f"f{f}.tif", np.stack([flat] * 3, axis=-1))
        args += ["--flat", f"{f}=f{f}.tif"]
    rc, _, err = cli("calibrate", *args, "--exit-pupil-mm", "21", "--pixel-pitch-um", "44",
                     "--magnification", "0.06", "--pupil-magnification", "1.3",
                     "--out", "lens.toml")
    assert rc == 0, err
    assert err.count("mean of 3 bands") == 5, err
    got = Lens.load(tmp_path / "lens.toml")
    assert got.vignetting[0][0] == pytest.approx(7.4236, rel=0.02)
    assert got.vignetting[0][1] == pytest.approx(16.991, rel=0.03)


def test_a_pickled_npy_is_refused_without_numpys_advice(tmp_path):
    """A .npy of Python objects (or an AppleDouble ``._`` file beside the frames) is refused
    in one line that gives no Python argument and no unsafe advice (``allow_pickle=``)."""
    from snapcorr.cube import read_cube

    path = tmp_path / "objects.npy"
    np.save(path, np.array([{"a": 1}, None], dtype=object), allow_pickle=True)
    with pytest.raises(ValueError, match="pickled Python objects") as info:
        read_cube(path)
    assert "allow_pickle" not in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("stored", ["[1,2]", "5", '"text"', "null"])
def test_envi_snapcorr_attrs_that_are_no_json_object_are_refused(tmp_path, monkeypatch, cli,
                                                                 stored):
    """'snapcorr attrs = json:[1,2]' was refused as 'cannot convert dictionary update sequence
    element #0 to a sequence', naming neither the file nor the key."""
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=(6, 5, 4))
    write_envi(tmp_path / "scene", np.ones((6, 5, 4), np.float32),
               fields={"snapcorr attrs": f"json:{stored}"})
    rc, _, err = cli("flatfield", "scene.hdr", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "sensor.toml", "--out", "o.nc")
    line = assert_refused(rc, err, "scene.hdr", "snapcorr attrs", "JSON object")
    assert "dictionary update" not in line


@pytest.mark.parametrize("field, value", [
    ("byte order", "1" * 100_000),
    ("interleave", "x" * 100_000),
    ("data ignore value", "y" * 100_000),
    ("samples", "9" * 100_000),
], ids=["byte-order", "interleave", "data-ignore-value", "samples"])
def test_an_envi_header_value_of_100_kb_is_quoted_as_an_excerpt(tmp_path, monkeypatch, cli,
                                                                field, value):
    """A header line of 100 000 characters was quoted whole in the error."""
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=(6, 5, 4))
    write_envi(tmp_path / "scene", np.ones((6, 5, 4), np.float32), fields={field: value})
    rc, _, err = cli("flatfield", "scene.hdr", "--dark", "dark.npy", "--white", "white.npy",
                     "--sensor", "sensor.toml", "--out", "o.nc")
    line = assert_refused(rc, err, "scene.hdr", field)
    assert len(line) < 300 and value[:20] in line, line[:400]
