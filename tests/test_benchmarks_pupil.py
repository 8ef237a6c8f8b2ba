"""The exit-pupil benchmark runs in CI in its quick mode, so it cannot rot (no timing asserted).

About 30 s on 2 cores: a timing process and two worker processes (each imports snapcorr
afresh) fit 64 x 80 x 16-band cubes, as the full run fits 256 x 320 x 100.
"""

import math

import pytest
from conftest import NO_X_FIRST_CENTER

from benchmarks import pupil

pytestmark = [pytest.mark.examples,  # run by .ci/run: `python -m pytest -m examples`
              pytest.mark.filterwarnings(NO_X_FIRST_CENTER)]


def _finite(*values):
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def test_quick_pupil_benchmark_runs_and_reports_sane_figures(tmp_path):
    lines = []
    rows = pupil.run(quick=True, echo=lines.append, write=False)
    assert all(set(r) == set(pupil.COLUMNS) for r in rows)
    assert {r["part"] for r in rows} == {"speed", "bound", "bound (check)", "fit"}

    speed = [r for r in rows if r["part"] == "speed"]
    assert [r["n_eff_mode"] for r in speed] == ["known", "fitted"]
    for r in speed:
        assert _finite(r["seconds"], r["x_copy"], r["x_design"], r["z_x"], r["chi2_red"])
        assert r["seconds"] > 0 and r["x_copy"] > 0 and r["x_design"] > 0
        # the fit finds the simulator's lens (coarse cubes: loose), and its error is honest
        assert abs(r["x_mm"] - pupil.TRUTH.exit_pupil_mm) < 0.02 * pupil.TRUTH.exit_pupil_mm
        assert abs(r["z_x"]) < 5
    assert speed[0]["z_n"] is None and _finite(speed[1]["z_n"]) and abs(speed[1]["z_n"]) < 5
    assert any(line.startswith("requirement:") for line in lines)

    bounds = {(r["target"], r["spectrum"], r["n_eff_mode"]): r for r in rows
              if r["part"] == "bound"}
    assert len(bounds) == 2 * 4  # the quick targets, spectrum and n_eff known or not
    for (target, _, mode), r in bounds.items():
        assert r["bound_x_stderr_mm"] > 0
        assert (r["bound_n_eff_stderr"] is None) == (mode == "known")
        # a white tile pins nothing; the glass pins x to a few per mille here
        assert (r["note"] == "not informative") == (target == "white tile")
    glass = bounds[("rare-earth glass", "unknown", "known")]["bound_x_stderr_mm"]
    assert glass < 0.01 * pupil.TRUTH.exit_pupil_mm
    # knowing the spectrum or the index can only help
    assert bounds[("rare-earth glass", "known", "known")]["bound_x_stderr_mm"] <= glass
    assert bounds[("rare-earth glass", "unknown", "fitted")]["bound_x_stderr_mm"] >= glass

    fits = [r for r in rows if r["part"] == "fit"]
    assert len(fits) == 2
    for r in fits:
        assert _finite(r["x_mm"], r["x_stderr_mm"], r["z_x"], r["bound_x_stderr_mm"])
        # the reported error is the bound's, within what two seeds of a coarse cube allow
        assert 0.5 < r["x_stderr_mm"] / r["bound_x_stderr_mm"] < 2
    assert any("the bound against fits" in line for line in lines)

    pupil.write_files(rows, tmp_path)  # the chart and the table, away from the repository's
    assert (tmp_path / "pupil.png").stat().st_size > 0
    assert len((tmp_path / "pupil.csv").read_text().splitlines()) == len(rows) + 1
