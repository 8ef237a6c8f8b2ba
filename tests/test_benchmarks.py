"""The benchmarks run in CI in their quick mode, so they cannot rot."""

import numpy as np
import pytest
from conftest import NO_X_FIRST_CENTER

from benchmarks import mean_shift as bench

pytestmark = [pytest.mark.examples,  # run by .ci/run: `python -m pytest -m examples`
              pytest.mark.filterwarnings(NO_X_FIRST_CENTER)]


def test_quick_benchmark_runs_and_reports_sane_numbers():
    lines = []
    rows = bench.run(quick=True, echo=lines.append)
    assert rows and all(np.isfinite(r["rate"]) and r["rate"] > 0 for r in rows)
    exact = [r for r in rows if r["method"] in ("mean_shift('vignetted')", "ShiftTable",
                                                "ShiftGrid (built)")]
    assert all(r["error"] <= 1e-3 for r in exact)
    bench.targets(rows, echo=lines.append)
    assert any("target 1" in line for line in lines)


def test_quick_calibration_benchmark_runs():
    from benchmarks import calibration

    lines = []
    rows = calibration.noise_sweep(quick=True, echo=lines.append, write=False)
    assert {r["estimator"] for r in rows} == set(calibration.ESTIMATORS)
    joint = [r for r in rows if r["estimator"] == "joint"]
    assert all(abs(r["P_error_pct"]) < 1 and abs(r["h_error_pct"]) < 1 for r in joint)
    seconds, res = calibration.full_size_time(quick=True, echo=lines.append)
    assert seconds > 0 and res.lens.has_vignetting and "flats" in lines[-1]


def test_quick_circle_calibration_benchmark_runs():
    from benchmarks import calibration_circles

    lines = []
    rows = calibration_circles.noise_sweep(quick=True, echo=lines.append, write=False)
    assert rows and not any(r["spurious"] for r in rows)
    assert all(r["model"] == "one" for r in rows)


def test_quick_coverage_benchmark_runs_and_reports_z_scores():
    from benchmarks import calibration_circles

    lines = []
    rows = calibration_circles.coverage_sweep(quick=True, echo=lines.append, write=False,
                                              workers=1)
    assert len(rows) == 1 and all(np.isfinite(r["z"]) and r["z"] >= 0 for r in rows)
    assert all(r["reported_sd_nm"] > 0 for r in rows)
    assert "RMS z" in lines[1] and lines[-1].startswith("one_h_gt_x")


def test_quick_correction_benchmark_runs():
    from benchmarks import correct

    lines = []
    r = correct.run(quick=True, echo=lines.append)
    assert r["copy_s"] > 0 and r["resample_s"] > 0 and r["shift_map_s"] > 0
    assert np.isfinite(r["peak_ratio"]) and any("target 1.5 x" in line for line in lines)
    assert r["harmonise_s"] > 0 and np.isfinite(r["harmonise_peak_ratio"])
    assert any("harmonise=True" in line for line in lines)


def test_quick_speed_accuracy_chart_runs_and_the_default_meets_its_tolerance():
    from benchmarks import speed_accuracy

    rows = speed_accuracy.run(quick=True, echo=lambda *_: None, write=False)
    assert {r["method"] for r in rows} >= {"contour quadrature", "lookup (ShiftGrid)",
                                           "asymptotic (Eq. 6)", "Riemann sum (paper)",
                                           "Rienstra transform", "mean_shift auto"}
    for r in rows:
        if r["default"]:
            assert r["worst_error_nm"] <= 1e-3  # auto's stated tolerance, over the whole grid
    assert any(r["pareto"] for r in rows)


def test_auto_never_lands_where_a_method_fails():
    # the stability maps over (f-number, CRA) and over (h/x, P/R): auto's error stays within
    # its tolerance (0.001 nm) everywhere, while the cheap models fail over large regions
    from benchmarks import stability

    res = stability.maps(quick=True)
    assert res[("worst", "auto")] <= 1e-3
    assert res[("worst", "asymptotic")] > 1.0 and res[("worst", "ideal")] > 1.0
    fails = res[("fc", "asymptotic")]
    assert np.nansum(fails >= 3) > 0.2 * np.isfinite(fails).sum()  # > 1 nm over a fifth


def test_quick_fnumber_sweep_runs():
    from benchmarks import calibration

    rows = calibration.fnumber_sweep(quick=True, echo=lambda *_: None, write=False)
    joint = [r for r in rows if r["estimator"] == "joint"]
    assert joint and all(abs(r["P_error_pct"]) < 1 and abs(r["h_error_pct"]) < 1 for r in joint)


def test_quick_virtual_bands_benchmark_runs_and_angle_aware_stays_right_off_axis():
    from benchmarks import virtual_bands

    lines = []
    rows, timing = virtual_bands.run(quick=True, echo=lines.append, write=False)
    by = {(r["method"], r["cra_deg"]): r["rmse"] for r in rows}
    assert by[("angle-aware", 15.0)] <= 0.85 * by[("vendor", 0.0)]
    # in absolute terms too: bands fed in another order than the sensor's give errors of
    # 0.17-0.21 for every method, and the ratio above still held
    assert by[("angle-aware", 0.0)] < 0.01 and by[("angle-aware", 15.0)] < 0.01
    assert by[("none", 0.0)] < 0.15
    assert all(0.5 <= r["z_rms"] <= 2 for r in rows if r["method"] != "none")
    assert timing["angle_aware_s"] > 0 and timing["build25_s"] > 0
    assert any("np.einsum" in line for line in lines)


def test_quick_demosaic_benchmark_runs_and_ranks_the_methods():
    from benchmarks import demosaic

    lines = []
    rows = demosaic.run(quick=True, echo=lines.append, write=False)
    for tile in ("4x4", "5x5"):
        psnr = {r["method"]: r["psnr_db"] for r in rows if r["tile"] == tile}
        assert psnr["nearest"] < psnr["bilinear"] < psnr["ppid"] < psnr["ri"]
    for r in rows:
        for key in ("x_copy", "rss_growth_x", "tracemalloc_x", "peak_x"):
            assert np.isfinite(r[key]) and r[key] > 0
    assert any("target <= 5 x" in line for line in lines)


def test_quick_stream_benchmark_runs_zarr_to_zarr():
    from benchmarks import stream

    lines = []
    rows = stream.run(quick=True, echo=lines.append, write=False)
    assert [r["frames"] for r in rows] == [3, 6] and {r["less_frames"] for r in rows} == {2}
    for r in rows:
        assert r["rc"] == 0, r["error"]
        assert np.isfinite(r["x_copy"]) and r["peak_mib"] > 0
    assert any("peak memory" in line for line in lines)


def test_quick_startup_benchmark_runs_and_reports_every_ratio():
    from benchmarks import startup

    lines = []
    rows = startup.run(quick=True, echo=lines.append, write=False)
    assert {r["figure"] for r in rows} == {"numpy", "help", "command_help", "usage_error",
                                           "first_flatfield", "second_flatfield", "work"}
    for r in rows:
        assert np.isfinite(r["seconds"]) and r["seconds"] > 0 and r["ratio"] > 0
    assert sum("target <= 3 x" in line for line in lines) == 2


@pytest.mark.slow
def test_quick_output_size_benchmark_runs_every_type_and_codec():
    from benchmarks import output_size

    lines = []
    rows, codecs = output_size.run(quick=True, echo=lines.append, write=False)
    assert [(r["format"], r["dtype"], r["compression"]) for r in rows] == output_size.RUNS
    for r in rows:
        assert 0 < r["x_float32_plain"] <= 1.0 and np.isfinite(r["x_time"])
        if r["dtype"] == "uint16":  # within the error the file states
            assert float(r["max_error"]) <= float(r["stated_error"])
    assert {c["data"] for c in codecs} == {"float32", "uint16"}


def test_quick_unknown_lens_benchmark_runs_and_reports_every_parameter():
    from benchmarks import unknown_lens

    lines = []
    rows = unknown_lens.coverage(quick=True, echo=lines.append, write=False, workers=1)
    assert len(rows) == 1 and abs(rows[0]["exit_pupil_mm_rel_error"]) < 0.005
    assert all(np.isfinite(rows[0][f"{p}_z"]) for p in ("exit_pupil_mm", "n_eff", "P_mm",
                                                         "h_mm", "center_row_px",
                                                         "center_col_px"))
    assert lines[-1].startswith("paper lens")


def test_quick_pupil_model_benchmark_runs():
    from benchmarks import pupil_model

    lines = []
    rows = pupil_model.run(quick=True, echo=lines.append, write=False, workers=1)
    assert len(rows) == 1 and np.isfinite(rows[0]["x_rel_error"])
    assert lines[-1].startswith("sine")
    # the sine-condition lens: pupil_radiance="auto" takes the Lambertian pupil, and x comes right
    assert rows[0]["chosen"] == "lambertian" and abs(rows[0]["x_rel_error"]) < 0.005


def test_quick_virtual_coverage_benchmark_runs_and_its_error_bars_cover():
    from benchmarks import virtual_coverage

    lines = []
    rows = virtual_coverage.run(quick=True, echo=lines.append, write=False)
    assert {r["case"] for r in rows} == {"two", "off_centre"}
    assert all(0.5 <= r["z_rms"] <= 2 for r in rows)
    assert all(r["rmse"] < 0.1 for r in rows)  # the bands in the sensor's order
    assert max(r["cra_deg"] for r in rows if r["case"] == "off_centre") > 25
    assert len(lines) == 4 and all("outside [0.5, 2]: 0" in line for line in lines)
