"""The scaling benchmark runs in CI in its quick mode, so it cannot rot (no timing asserted).

About 30 s on 2 cores: four measuring processes (each imports snapcorr afresh) and two
LocalClusters of worker processes, as in the full run.
"""

import math

import pytest
from conftest import NO_X_FIRST_CENTER

from benchmarks import scaling

pytestmark = [pytest.mark.examples,  # run by .ci/run: `python -m pytest -m examples`
              pytest.mark.filterwarnings(NO_X_FIRST_CENTER)]


def _finite_positive(*values):
    return all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0 for v in values)


def test_quick_scaling_benchmark_runs_and_reports_sane_figures(tmp_path):
    lines = []
    rows = scaling.run(quick=True, echo=lines.append, write=False)
    parts = {r["part"] for r in rows}
    assert parts == {"numpy copy", "Numba pass alone", "in memory", "dask, in memory",
                     "dask, zarr to zarr", "threads, no cluster", "cluster"}
    assert all(set(r) == set(scaling.COLUMNS) for r in rows)

    memory = [r for r in rows if r["part"] == "in memory"]
    assert [r["n"] for r in memory] == list(scaling.QUICK_SIZES)
    for r in memory:
        assert _finite_positive(r["seconds"], r["copy_s"], r["x_copy"], r["s_per_gib"],
                                r["gib_per_s"])
        assert math.isfinite(r["slope"])  # its sign is noise at these sizes on a busy machine
        # the input and the resampled result are both resident (2 cubes, less what the
        # allocator already held: more than 1.5); at the quick sizes (a few MB) imports and
        # allocator pools weigh as much, so no upper bound here (the full run measures 2.0 x)
        assert math.isfinite(r["peak_x_cube"]) and r["peak_x_cube"] > 1.5
    for part in ("numpy copy", "Numba pass alone"):
        assert all(_finite_positive(r["seconds"]) and math.isfinite(r["slope"])
                   for r in rows if r["part"] == part)

    for r in (r for r in rows if r["part"].startswith("dask")):
        assert r["n"] in scaling.QUICK_SIZES
        assert _finite_positive(r["seconds"], r["x_in_memory"], r["x_copy"], r["s_per_gib"])
        assert math.isfinite(r["peak_x_cube"]) and r["peak_x_cube"] >= 0

    batch = {r["workers"]: r for r in rows if r["workers"] is not None}
    assert set(batch) == {0, 1, 2}  # threads without a cluster, then 1 and 2 workers
    for r in batch.values():
        assert r["cubes"] == scaling.QUICK_BATCH[0]
        assert _finite_positive(r["seconds"], r["cubes_per_s"], r["gib_per_s"], r["speedup"])
    assert any("LocalCluster, 2 workers" in line for line in lines)
    assert any("log-log slope" in line for line in lines)

    scaling.write_files(rows, tmp_path)  # the chart and the table, away from the repository's
    assert (tmp_path / "scaling.png").stat().st_size > 0
    assert len((tmp_path / "scaling.csv").read_text().splitlines()) == len(rows) + 1
