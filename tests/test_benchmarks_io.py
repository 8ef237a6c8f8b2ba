"""The file benchmark of ``flatfield`` and ``correct`` runs in CI in its quick mode, so it
cannot rot (no timing asserted), and its outputs are the flat field numpy computes.

About half a minute on 2 cores: five measuring processes (each imports snapcorr afresh and
runs under an address-space limit) and their numpy references.
"""

import math

import numpy as np
import pytest
import xarray as xr
from conftest import NO_X_FIRST_CENTER

from benchmarks import io_memory

pytestmark = [pytest.mark.examples,  # run by .ci/run: `python -m pytest -m examples`
              pytest.mark.filterwarnings(NO_X_FIRST_CENTER)]


def _finite_positive(*values):
    return all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0 for v in values)


def test_quick_io_benchmark_runs_and_its_outputs_are_the_flat_field(tmp_path):
    lines = []
    rows = io_memory.run(quick=True, echo=lines.append, write=False, workdir=tmp_path)
    assert [(r["command"], r["input"]) for r in rows] == list(io_memory.CASES)
    assert all(set(r) == set(io_memory.COLUMNS) for r in rows)
    for r in rows:
        assert r["status"] == "ok", r["status"]
        assert (r["ny"], r["nx"], r["bands"]) == (*io_memory.QUICK_LIMITED,
                                                  io_memory.QUICK_BANDS)
        assert _finite_positive(r["seconds"], r["numpy_io_s"], r["x_numpy_io"], r["peak_mib"],
                                r["base_mib"], r["peak_x_input"], r["input_bytes"],
                                r["output_bytes"], r["output_disk_bytes"], r["limit_mib"],
                                r["baseline_vm_mib"])
        # the peak includes the imports (the resident set before the run), and the run
        # stayed within the address-space limit it was given
        assert r["base_mib"] <= r["peak_mib"] < r["limit_mib"]
        assert r["output_bytes"] > r["input_bytes"]  # each output keeps its input
        assert r["target_met"] is True
    assert any("RLIMIT_AS" in line for line in lines)
    assert any("met in 5 of 5" in line for line in lines)

    # the flat fields written from ENVI BIL, ENVI BSQ and .npy are Eq. 29 of the inputs
    folder = tmp_path / "x".join(map(str, (*io_memory.QUICK_LIMITED, io_memory.QUICK_BANDS)))
    expected = io_memory.expected_flatfield(folder)
    assert expected.shape == (64, 64, 16) and np.all(np.isfinite(expected))
    dark = np.load(folder / "dark.npy")
    assert dark.shape == (1, 64, 16) and np.load(folder / "white.npy").shape == (1, 64, 16)
    for tag in ("envi_bil", "envi_bsq", "npy"):
        with xr.open_zarr(folder / f"flatfield_{tag}.zarr") as ds:
            got = ds["reflectance"].values
            assert got.dtype == np.float32
            np.testing.assert_allclose(got, expected, rtol=1e-6, atol=0)
            assert not ds["mask"].values.any()
            np.testing.assert_array_equal(ds["raw"].values, np.load(folder / "raw.npy"))

    # correct --resample from the flat field's .zarr and from the float32 .npy of the same
    # reflectance: the same resampled cube
    with xr.open_zarr(folder / "correct_zarr.zarr") as a, \
            xr.open_zarr(folder / "correct_npy.zarr") as b:
        ra, rb = a["resampled"].values, b["resampled"].values
    assert ra.shape == expected.shape and np.isfinite(ra).mean() > 0.5
    np.testing.assert_allclose(ra, rb, rtol=1e-5, atol=1e-6, equal_nan=True)

    io_memory.write_files(rows, tmp_path)  # the chart and the table, away from the repository's
    assert (tmp_path / "io_memory.png").stat().st_size > 0
    assert len((tmp_path / "io_memory.csv").read_text().splitlines()) == len(rows) + 1
