"""The FWHM table behind ``fwhm_corrected`` costs the same whatever the cube's size (most of a
small correction): ``correct_cube`` builds it when the widths are first read (their values, a
write, ``with_fwhm_table``), never when nothing reads them, and ``fwhm=False`` leaves them out;
everything else it gives is unchanged."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_TRUTH

from snapcorr import Lens
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, make_cube, read_dataset, write_dataset
from snapcorr.cube.derived import LazyTable, with_fwhm_table
from snapcorr.optics import FwhmTable

LENS = Lens(PAPER_TRUTH.exit_pupil_mm, PAPER_TRUTH.circles, PAPER_TRUTH.magnification,
            PAPER_TRUTH.pupil_magnification, name=PAPER_TRUTH.name)
SENSOR = Sensor("t", "snapscan", 44.0, np.linspace(480.0, 880.0, 9), 10.0, 1.75)
WIDTHS = ("fwhm_corrected", "fwhm_table", "fwhm_cra_deg")


def _cube():
    data = np.random.default_rng(4).random((40, 56, 9), dtype=np.float32)
    return make_cube(data, SENSOR.cwl_nm)


@pytest.fixture
def builds(monkeypatch):
    """Count the FWHM tables built."""
    calls = []
    original = FwhmTable.build.__func__

    def counted(cls, *args, **kwargs):
        calls.append(1)
        return original(cls, *args, **kwargs)

    monkeypatch.setattr(FwhmTable, "build", classmethod(counted))
    return calls


def _refuse(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the FWHM table was built")

    monkeypatch.setattr(FwhmTable, "build", refuse)


def test_without_fwhm_the_table_is_not_built_and_the_rest_is_the_same(monkeypatch, builds):
    cube = _cube()
    whole = with_fwhm_table(correct_cube(cube, SENSOR, 1.4, LENS, center_rc=(20.0, 28.0),
                                         resample=True))
    assert len(builds) == 1 and all(v in whole.variables for v in WIDTHS)
    _refuse(monkeypatch)
    lean = correct_cube(cube, SENSOR, 1.4, LENS, center_rc=(20.0, 28.0), resample=True,
                        fwhm=False)
    assert not any(v in lean.variables for v in WIDTHS)
    xr.testing.assert_identical(lean, whole.drop_vars(list(WIDTHS)))
    np.testing.assert_array_equal(lean["wavelength_corrected"].values,
                                  whole["wavelength_corrected"].values)


def test_the_table_waits_for_the_first_read_of_the_widths(monkeypatch, builds):
    """The default correction returns before any table is built; a correction whose widths
    nobody reads never builds one (resampled values read, written as a file without them)."""
    cube = _cube()
    ds = correct_cube(cube, SENSOR, 1.4, LENS, center_rc=(20.0, 28.0), resample=True)
    assert builds == [] and "fwhm_corrected" in ds.coords and "fwhm_table" not in ds
    ds["resampled"].values, ds["wavelength_corrected"].values
    ds.isel(y=slice(0, 5)).fwhm_corrected  # noqa: B018  (selecting reads nothing)
    assert builds == []
    first = ds["fwhm_corrected"].values
    assert len(builds) == 1
    np.testing.assert_array_equal(ds["fwhm_corrected"].values, first)  # kept, not rebuilt
    np.testing.assert_array_equal(ds.isel(band=[2, 5])["fwhm_corrected"].values,
                                  first[:, :, [2, 5]])
    assert len(builds) == 1


def test_the_default_builds_the_table_once_and_reads_the_same_widths(builds):
    """The widths (read lazily, block by block) are the table's, interpolated per pixel."""
    cube = _cube()
    ds = with_fwhm_table(correct_cube(cube, SENSOR, 1.4, LENS, center_rc=(20.0, 28.0)))
    assert len(builds) == 1
    table = FwhmTable.build(SENSOR.cwl_nm, SENSOR.fwhm_nm, SENSOR.n_eff, 1.4, LENS,
                            cra_max_deg=ds.attrs["cra_max_deg"], tolerance_nm=0.01)
    np.testing.assert_array_equal(ds["fwhm_table"].values, table.fwhm_nm)
    np.testing.assert_array_equal(ds["fwhm_cra_deg"].values, table.cra_deg)
    want = table(ds["cra_deg"].values).astype(np.float32)
    np.testing.assert_allclose(ds["fwhm_corrected"].values, want, rtol=0, atol=1e-4)
    # the lazy widths and the eager ones (a harmonising correction builds its table first)
    eager = correct_cube(cube, SENSOR, 1.4, LENS, center_rc=(20.0, 28.0), harmonise=True)
    np.testing.assert_array_equal(eager["fwhm_corrected"].values, ds["fwhm_corrected"].values)
    xr.testing.assert_identical(eager["fwhm_table"], ds["fwhm_table"])


def test_a_lazy_table_is_written_with_the_file(tmp_path, builds):
    """The file holds the table (built for the write), so readers rebuild the same widths;
    a selection of bands writes their rows of it."""
    ds = correct_cube(_cube(), SENSOR, 1.4, LENS, center_rc=(20.0, 28.0))
    write_dataset(ds, tmp_path / "c.nc")
    assert len(builds) == 1
    back = read_dataset(tmp_path / "c.nc")
    assert "fwhm_table" in back and "fwhm_corrected" in back.coords
    np.testing.assert_array_equal(back["fwhm_corrected"].values, ds["fwhm_corrected"].values)
    some = ds.isel(band=[6, 1, 3], x=slice(10, 30))
    write_dataset(some, tmp_path / "some.zarr")
    back = read_dataset(tmp_path / "some.zarr")
    np.testing.assert_array_equal(back["fwhm_corrected"].values,
                                  some["fwhm_corrected"].values)
    np.testing.assert_array_equal(back["fwhm_table"].values,
                                  with_fwhm_table(ds)["fwhm_table"].values[[6, 1, 3]])
    assert len(builds) == 1


def test_what_a_file_could_not_rebuild_is_stored_whole(tmp_path):
    """A derived variable whose compact form a selection dropped (or whose lazy table was
    lost) is written as a plain variable, not listed for a rebuild the reader cannot do."""
    ds = correct_cube(_cube(), SENSOR, 1.4, LENS, center_rc=(20.0, 28.0))
    cut = ds.drop_vars("wavelength_scale")
    cut["fwhm_corrected"].encoding.clear()
    write_dataset(cut, tmp_path / "cut.nc")
    raw = xr.open_dataset(tmp_path / "cut.nc")
    assert {"wavelength_corrected", "fwhm_corrected"} <= set(raw.data_vars)
    assert "derived_variables" not in raw.attrs
    back = read_dataset(tmp_path / "cut.nc")
    for name in ("wavelength_corrected", "fwhm_corrected"):
        np.testing.assert_array_equal(back[name].values, ds[name].values)
    raw.close()


def test_the_lazy_table_travels_and_is_built_once(builds):
    """Copies share it (xarray copies encodings); pickled, it carries what was built."""
    import copy
    import pickle
    import threading

    ds = correct_cube(_cube(), SENSOR, 1.4, LENS, center_rc=(20.0, 28.0))
    table = ds["fwhm_corrected"].encoding["snapcorr_fwhm_table"]
    assert isinstance(table, LazyTable) and not table.built
    assert copy.deepcopy(ds)["fwhm_corrected"].encoding["snapcorr_fwhm_table"] is table
    fresh = pickle.loads(pickle.dumps(table))
    assert not fresh.built
    threads = [threading.Thread(target=table) for _ in range(4)]  # at once: built once
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(builds) == 1 and table.built
    again = pickle.loads(pickle.dumps(table))
    assert again.built
    xr.testing.assert_identical(again(), table())
    assert len(builds) == 1


def test_harmonising_builds_the_table_once_and_gives_the_same_values_either_way(builds):
    cube = _cube()
    whole = correct_cube(cube, SENSOR, 1.4, LENS, center_rc=(20.0, 28.0), harmonise=True)
    lean = correct_cube(cube, SENSOR, 1.4, LENS, center_rc=(20.0, 28.0), harmonise=True,
                        fwhm=False)
    assert len(builds) == 2  # one a correction: the harmonising needs it
    assert not any(v in lean.variables for v in WIDTHS)
    xr.testing.assert_identical(lean, whole.drop_vars(list(WIDTHS)))


def test_a_correction_without_widths_round_trips_through_a_file(tmp_path, monkeypatch):
    _refuse(monkeypatch)
    ds = correct_cube(_cube(), SENSOR, 1.4, LENS, center_rc=(20.0, 28.0), fwhm=False)
    write_dataset(ds, tmp_path / "c.nc")
    back = read_dataset(tmp_path / "c.nc")
    assert not any(v in back.variables for v in WIDTHS)
    np.testing.assert_array_equal(back["wavelength_corrected"].values,
                                  ds["wavelength_corrected"].values)


@pytest.mark.parametrize("method", ["vignetted", "ideal"])
def test_measured_responses_build_only_the_table_their_centres_need(monkeypatch, method):
    """A measured sensor's centres come from the table of its responses through the lens
    (the vignetted one, which also holds the widths); the ideal model takes a table of the
    lens without vignetting instead, so without the widths the vignetted one is not built."""
    import dataclasses

    from conftest import PAPER_LENS, VENDOR_XML

    from snapcorr.cube import mosaic_to_cube
    from snapcorr.optics.measured import MeasuredTable

    vendor = Sensor.load(VENDOR_XML)
    sensor = dataclasses.replace(vendor, n_eff=(1.8,) * 25, pixel_pitch_um=5.5)
    frame = np.random.default_rng(0).uniform(0.2, 0.8, (20, 20)).astype(np.float32)
    cube = mosaic_to_cube(frame, sensor, sensor_origin_px=(40, 60))
    whole = with_fwhm_table(correct_cube(cube, sensor, 2.0, PAPER_LENS, method=method))
    calls = []
    original = MeasuredTable.build.__func__

    def counted(cls, *args, **kwargs):
        calls.append(1)
        return original(cls, *args, **kwargs)

    monkeypatch.setattr(MeasuredTable, "build", classmethod(counted))
    lean = correct_cube(cube, sensor, 2.0, PAPER_LENS, method=method, fwhm=False)
    assert len(calls) == 1
    assert not any(v in lean.variables for v in WIDTHS)
    xr.testing.assert_identical(lean, whole.drop_vars(list(WIDTHS)))


def test_the_lazy_coordinates_copy_nothing_until_read():
    """``wavelength_corrected`` and ``fwhm_corrected`` read the per-pixel scale and chief-ray
    angle block by block: making them copies neither (``dask.array.from_array`` copies any
    array with a ``copy`` method and hashes it, copying a transposed view once more); the
    values are the same."""
    import tracemalloc

    from snapcorr.cube.derived import corrected_wavelength, lazy_fwhm

    ds = correct_cube(make_cube(np.random.default_rng(4).random((400, 500, 9), np.float32),
                                SENSOR.cwl_nm), SENSOR, 2.0, LENS)
    scale = ds["wavelength_scale"]
    cra = xr.DataArray(np.random.default_rng(1).random((500, 400, 1)) * 10,
                       dims=("x", "y", "c")).transpose("y", "x", "c")  # not contiguous
    tracemalloc.start()
    try:
        wl = corrected_wavelength(ds)
        fw = lazy_fwhm(cra.isel(c=0), lambda: None, 9)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.1 * min(scale.nbytes, cra.nbytes), peak
    assert fw.shape == (400, 500, 9)
    want = ds["wavelength"].values * scale.values[..., 0:1]
    np.testing.assert_allclose(wl.values, want.astype(np.float32), rtol=1e-7)
