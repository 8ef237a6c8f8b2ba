"""What `snapcorr flatfield` and `snapcorr correct` write: every attribute of the result, CF
units and long names, values that read back as computed, the mask carried into correct, zarr
with consolidated metadata."""

from __future__ import annotations

import warnings

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
import xarray as xr
from hostile import FF, LENS, correct_args, cra_of, read_result, save_cubes


@pytest.fixture(scope="module")
def pipeline(tmp_path_factory, cli):
    """raw -> flatfield (.nc, .zarr) -> correct --resample (.nc, .zarr), one masked pixel."""
    d = tmp_path_factory.mktemp("pipeline")
    save_cubes(d)
    white = np.full((12, 10, 4), 400.0, np.float32)
    white[3, 4, :] = 10.0  # white == dark here: masked
    np.save(d / "white.npy", white)
    runs = {}
    for ext in (".nc", ".zarr"):
        runs[f"ff{ext}"] = cli(*FF, "--out", f"ff{ext}", cwd=d)
        runs[f"c{ext}"] = cli(*correct_args(f"ff{ext}", f"c{ext}", "--resample",
                                            "--source", "tungsten:3000"), cwd=d)
    return d, runs


def _ok(pipeline, name):
    d, runs = pipeline
    rc, _, err = runs[name]
    assert rc == 0, err
    return d / name


def _correct_as_the_cli_does(cube, sensor):
    """``correct --resample --source tungsten:3000`` at f/1.4, in memory."""
    from snapcorr import Lens
    from snapcorr.budget import recommend_model
    from snapcorr.correct import correct_cube

    lens = Lens.load(LENS)
    model, _, attrs = recommend_model(cube, sensor, 1.4, lens, "tungsten:3000")
    ds = correct_cube(cube, sensor, 1.4, lens, method=model, resample=True)
    ds.attrs.update(attrs)
    return ds


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_every_attribute_of_correct_is_written(pipeline, ext):
    from snapcorr.cube import Sensor, read_cube

    path = _ok(pipeline, f"c{ext}")
    d = pipeline[0]
    sensor = Sensor.load(d / "sensor.toml")
    cube = read_cube(d / f"ff{ext}", wavelength_nm=sensor.cwl_nm)
    mem = _correct_as_the_cli_does(cube, sensor).attrs
    written = read_result(path).attrs
    assert "optical_center_px" in mem
    _compare_attrs(mem, written)


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_every_attribute_of_flatfield_is_written(pipeline, ext):
    from snapcorr.cube import Sensor, flatfield, read_cube

    path = _ok(pipeline, f"ff{ext}")
    d = pipeline[0]
    wl = Sensor.load(d / "sensor.toml").cwl_nm
    mem = flatfield(*(read_cube(d / f"{n}.npy", wavelength_nm=wl)
                      for n in ("raw", "dark", "white"))).attrs
    written = read_result(path).attrs
    _compare_attrs(mem, written, skip_values=("created", "source"))


def _compare_attrs(mem, written, skip_values=()):
    missing = sorted(set(mem) - set(written))
    assert not missing, f"not in the file: {missing}"
    for k, v in mem.items():
        if k in skip_values:
            continue
        w = written[k]
        if isinstance(v, str):
            assert w == v, (k, v, w)
        elif isinstance(v, (list, tuple, np.ndarray)):
            assert isinstance(w, (list, tuple, np.ndarray)), (k, v, w)
            assert np.shape(w) == np.shape(v), (k, v, w)
            if len(v) and isinstance(np.asarray(v).flat[0], str):
                assert list(w) == list(v), (k, v, w)
            else:
                np.testing.assert_allclose(np.asarray(w, float), np.asarray(v, float),
                                           rtol=1e-12, err_msg=k)
        elif isinstance(v, (bool, np.bool_)):
            assert bool(w) == bool(v), (k, v, w)
        else:
            assert float(w) == pytest.approx(float(v), rel=1e-12), (k, v, w)


@pytest.mark.parametrize("name, var", [
    ("ff.nc", "reflectance"), ("ff.nc", "mask"), ("c.nc", "cra"),
    ("c.nc", "wavelength_corrected"), ("c.nc", "resampled"), ("c.nc", "reflectance"),
])
def test_cf_units_and_long_name(pipeline, name, var):
    ds = read_result(_ok(pipeline, name))
    if var == "cra":
        var = cra_of(ds).name
    assert var in ds.variables, f"{var} not in {name}"
    attrs = ds[var].attrs
    assert str(attrs.get("units", "")).strip(), f"{var} has no units: {attrs}"
    assert str(attrs.get("long_name", "")).strip(), f"{var} has no long_name: {attrs}"


def test_cf_units_and_long_name_in_zarr(pipeline):
    ds = read_result(_ok(pipeline, "c.zarr"))
    for var in ("reflectance", "mask", cra_of(ds).name, "wavelength_corrected", "resampled"):
        assert var in ds.variables, var
        assert str(ds[var].attrs.get("units", "")).strip(), var
        assert str(ds[var].attrs.get("long_name", "")).strip(), var


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_written_result_reads_back_as_computed(pipeline, ext):
    from snapcorr.cube import Sensor, read_cube

    path = _ok(pipeline, f"c{ext}")
    d = pipeline[0]
    sensor = Sensor.load(d / "sensor.toml")
    cube = read_cube(d / f"ff{ext}", wavelength_nm=sensor.cwl_nm)
    mem = _correct_as_the_cli_does(cube, sensor)
    got = read_result(path)
    for var in ("wavelength_corrected", "resampled", "reflectance"):
        np.testing.assert_allclose(np.asarray(got[var].values, float),
                                   np.asarray(mem[var].values, float), rtol=1e-6,
                                   equal_nan=True, err_msg=var)
    np.testing.assert_allclose(cra_of(got).values, cra_of(mem).values, rtol=1e-12)


def test_wavelength_corrected_is_a_coordinate_to_plot_against(pipeline):
    import matplotlib.pyplot as plt

    ds = read_result(_ok(pipeline, "c.nc"))
    assert "wavelength_corrected" in ds.coords
    fig = plt.figure()
    try:
        ds["reflectance"].isel(y=0, x=0).plot(x="wavelength_corrected")
    finally:
        plt.close(fig)


def test_flatfield_mask_is_carried_into_correct(pipeline):
    ff = read_result(_ok(pipeline, "ff.nc"))
    res = read_result(_ok(pipeline, "c.nc"))
    assert "mask" in res.variables
    np.testing.assert_array_equal(res["mask"].values, ff["mask"].values)
    assert bool(res["mask"].values[3, 4].all()) and int(res["mask"].values.sum()) == 4


@pytest.mark.parametrize("name", ["ff.zarr", "c.zarr"])
def test_zarr_result_opens_with_consolidated_metadata_without_warnings(pipeline, name):
    path = _ok(pipeline, name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds = xr.open_zarr(path)
        assert "reflectance" in ds
    assert not caught, [str(w.message) for w in caught]
