"""``correct_cube(..., fwhm=False)``: the FWHM table behind ``fwhm_corrected`` costs the same
whatever the cube's size (most of a small correction), so a correction that does not read the
widths can skip it; everything else it gives is unchanged."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_TRUTH

from snapcorr import Lens
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, make_cube, read_dataset, write_dataset
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
    whole = correct_cube(cube, SENSOR, 1.4, LENS, center_px=(28.0, 20.0), resample=True)
    assert len(builds) == 1 and all(v in whole.variables for v in WIDTHS)
    _refuse(monkeypatch)
    lean = correct_cube(cube, SENSOR, 1.4, LENS, center_px=(28.0, 20.0), resample=True,
                        fwhm=False)
    assert not any(v in lean.variables for v in WIDTHS)
    xr.testing.assert_identical(lean, whole.drop_vars(list(WIDTHS)))
    np.testing.assert_array_equal(lean["wavelength_corrected"].values,
                                  whole["wavelength_corrected"].values)


def test_the_default_builds_the_table_once_and_reads_the_same_widths(builds):
    """The widths (read lazily, block by block) are the table's, interpolated per pixel."""
    cube = _cube()
    ds = correct_cube(cube, SENSOR, 1.4, LENS, center_px=(28.0, 20.0))
    assert len(builds) == 1
    table = FwhmTable.build(SENSOR.cwl_nm, SENSOR.fwhm_nm, SENSOR.n_eff, 1.4, LENS,
                            cra_max_deg=ds.attrs["cra_max_deg"], tolerance_nm=0.01)
    np.testing.assert_array_equal(ds["fwhm_table"].values, table.fwhm_nm)
    np.testing.assert_array_equal(ds["fwhm_cra_deg"].values, table.cra_deg)
    want = table(ds["cra_deg"].values).astype(np.float32)
    np.testing.assert_allclose(ds["fwhm_corrected"].values, want, rtol=0, atol=1e-4)


def test_harmonising_builds_the_table_once_and_gives_the_same_values_either_way(builds):
    cube = _cube()
    whole = correct_cube(cube, SENSOR, 1.4, LENS, center_px=(28.0, 20.0), harmonise=True)
    lean = correct_cube(cube, SENSOR, 1.4, LENS, center_px=(28.0, 20.0), harmonise=True,
                        fwhm=False)
    assert len(builds) == 2  # one a correction: the harmonising needs it
    assert not any(v in lean.variables for v in WIDTHS)
    xr.testing.assert_identical(lean, whole.drop_vars(list(WIDTHS)))


def test_a_correction_without_widths_round_trips_through_a_file(tmp_path, monkeypatch):
    _refuse(monkeypatch)
    ds = correct_cube(_cube(), SENSOR, 1.4, LENS, center_px=(28.0, 20.0), fwhm=False)
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
    cube = mosaic_to_cube(frame, sensor, origin_px=(40, 60))
    whole = correct_cube(cube, sensor, 2.0, PAPER_LENS, method=method)
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
