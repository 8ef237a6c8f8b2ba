"""Variables rebuilt from their compact stored form, against the same numbers worked out
pixel by pixel with numpy: the corrected wavelength ``cwl_b * s(y, x, k_b)`` rounded once to
float32, the widths interpolated in the chief-ray angle as ``np.interp`` does, whatever the
blocks; a lazy table built once; a file's list of derived variables restored or refused."""

import copy
import pickle
import threading

import numpy as np
import pytest
import xarray as xr
from numpy.testing import assert_array_equal

from snapcorr.cube.derived import (
    LazyTable,
    corrected_fwhm,
    corrected_wavelength,
    rebuildable,
    restore,
)


def _scaled(ny=9, nx=7, nb=5, columns=2, seed=1):
    rng = np.random.default_rng(seed)
    return xr.Dataset({"wavelength_scale": (("y", "x", "scale"),
                                            1 - 0.03 * rng.random((ny, nx, columns))),
                       "scale_index": ("band", rng.integers(0, columns, nb))},
                      coords={"wavelength": ("band", np.linspace(450.0, 900.0, nb))})


@pytest.mark.parametrize("columns", [1, 3])
@pytest.mark.parametrize("chunks", [None, ((4, 5), (3, 4), (2, 3))])
def test_the_corrected_wavelength_is_cwl_times_its_scale_rounded_once(columns, chunks):
    ds = _scaled(columns=columns)
    got = corrected_wavelength(ds, chunks=chunks)
    cwl, scale = ds["wavelength"].values, ds["wavelength_scale"].values
    index = ds["scale_index"].values
    want = np.empty(got.shape, np.float32)
    for y, x, b in np.ndindex(*got.shape):
        want[y, x, b] = np.float32(cwl[b] * scale[y, x, index[b]])
    assert got.dtype == np.float32 and got.dims == ("y", "x", "band")
    assert_array_equal(got.values, want)


@pytest.mark.parametrize("per_band", [False, True])
def test_the_corrected_width_is_the_table_interpolated_at_the_angle(per_band):
    rng = np.random.default_rng(2)
    nodes = np.array([0.0, 4.0, 9.0, 15.0, 22.0])
    table = 10 + rng.random((4, nodes.size))
    cra = rng.uniform(0.0, 22.0, (6, 5, 4) if per_band else (6, 5))
    ds = xr.Dataset({"cra_deg": (("y", "x", "band")[:cra.ndim], cra),
                     "fwhm_table": (("band", "fwhm_cra"), table)},
                    coords={"fwhm_cra_deg": ("fwhm_cra", nodes)})
    got = corrected_fwhm(ds, chunks=((2, 4), (5,), (1, 3))).values
    for y, x, b in np.ndindex(*got.shape):
        c = cra[y, x, b] if per_band else cra[y, x]
        assert got[y, x, b] == pytest.approx(np.interp(c, nodes, table[b]), rel=1e-6)


def test_a_lazy_table_is_built_once_and_copies_are_itself():
    calls = []
    table = LazyTable(lambda: calls.append(1) or {"built": True})
    assert not table.built
    threads = [threading.Thread(target=table) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert calls == [1] and table.built and table() == {"built": True}
    assert copy.copy(table) is table and copy.deepcopy(table) is table
    again = pickle.loads(pickle.dumps(LazyTable(dict)))
    assert not again.built and again() == {}


def test_a_files_derived_variables_are_restored_or_refused():
    ds = _scaled()
    assert rebuildable(ds, "wavelength_corrected") and not rebuildable(ds, "fwhm_corrected")
    back = restore(ds.assign_attrs(derived_variables="wavelength_corrected"))
    assert_array_equal(back["wavelength_corrected"].values, corrected_wavelength(ds).values)
    assert "wavelength_corrected" in back.coords
    with pytest.raises(ValueError, match="cannot rebuild"):
        restore(ds.assign_attrs(derived_variables=["wavelength_corrected", "mystery"]))
