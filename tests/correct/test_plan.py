"""What a correction computes before its outputs (snapcorr.correct.plan): the width table
built on a second thread meanwhile, and the harmonised output's memory readied for it."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from snapcorr.correct import correct_cube
from snapcorr.correct.harmonise import harmonise_spectra
from snapcorr.cube import Sensor, make_cube

from .test_harmonise import CENTER, CWL, PAPER, PITCH, as_lens


def test_the_width_table_built_alongside_is_waited_for_and_its_errors_reach_the_caller():
    """The width table is built on a second thread while the scales are made: its result is
    the one used, its error is the caller's, and an error on this side waits for it (no work
    left running) and is the one raised."""
    import threading
    import time

    from snapcorr.correct import plan

    sensor = Sensor("t", "snapscan", PITCH, CWL, 12.0, 1.8)
    cube = make_cube(np.random.default_rng(4).random((4, 30, CWL.size)), CWL)
    lens = as_lens(PAPER)
    want = correct_cube(cube, sensor, 1.4, lens, harmonise=True, center_px=CENTER)
    built = plan._unlimited_width_table
    seen = []

    def slow_table(*args):
        time.sleep(0.3)
        table = built(*args)
        seen.append(threading.current_thread() is not threading.main_thread())
        return table

    def failing_table(*args):
        raise ValueError("no table here")

    def failing_scales(*args, **kwargs):
        raise RuntimeError("no scales here")

    limit = plan.one_blas_thread
    limited_on = []

    def spy_limit():  # the process-wide BLAS limit is set and reset on this thread only
        limited_on.append(threading.current_thread() is threading.main_thread())
        return limit()

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plan, "_unlimited_width_table", slow_table)
        mp.setattr(plan, "one_blas_thread", spy_limit)
        got = correct_cube(cube, sensor, 1.4, lens, harmonise=True, center_px=CENTER)
        assert seen == [True] and limited_on == [True]
        xr.testing.assert_identical(got, want)
        mp.setattr(plan, "_scales", failing_scales)
        with pytest.raises(RuntimeError, match="no scales here"):
            correct_cube(cube, sensor, 1.4, lens, harmonise=True, center_px=CENTER)
        assert seen == [True, True]  # finished before the error left
        mp.undo()
        mp.setattr(plan, "_unlimited_width_table", failing_table)
        with pytest.raises(ValueError, match="no table here"):
            correct_cube(cube, sensor, 1.4, lens, harmonise=True, center_px=CENTER)
        # both failing: this side's error is raised, and says the table's too
        mp.setattr(plan, "_scales", failing_scales)
        with pytest.raises(RuntimeError, match="no scales here") as both:
            correct_cube(cube, sensor, 1.4, lens, harmonise=True, center_px=CENTER)
        assert any("no table here" in note for note in both.value.__notes__)


def test_the_output_readied_in_advance_is_new_memory_and_the_input_is_untouched():
    sensor = Sensor("t", "snapscan", PITCH, CWL, 12.0, 1.8)
    data = np.random.default_rng(5).random((5, 20, CWL.size)).astype(np.float32)
    before = data.copy()
    cube = make_cube(data, CWL)
    ds = correct_cube(cube, sensor, 1.4, as_lens(PAPER), harmonise=True, center_px=CENTER)
    out = ds["harmonised"].values
    assert out.dtype == np.float32 and not np.shares_memory(out, data)
    np.testing.assert_array_equal(data, before)
    # the pass wrote into the array readied for it
    from snapcorr.correct import plan

    readied = []
    make = plan._output_buffer

    def spy(*args):
        readied.append(make(*args))
        return readied[-1]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plan, "_output_buffer", spy)
        again = correct_cube(cube, sensor, 1.4, as_lens(PAPER), harmonise=True,
                             center_px=CENTER)["harmonised"].values
    assert len(readied) == 1 and np.shares_memory(again, readied[0])
    np.testing.assert_array_equal(again, out)
    # a wrong array to write into is refused, not written past or over the data
    args = (data, np.full((5, 20, 1), 0.99), np.zeros(CWL.size, int), CWL, 0.5)
    for bad in (np.empty((5, 20, CWL.size - 1), np.float32), np.empty(data.shape),
                np.empty(data.shape[::-1], np.float32).T, data):
        with pytest.raises(ValueError, match="out must be"):
            harmonise_spectra(*args, out=bad)
    chunked = correct_cube(cube.chunk({"y": 2, "x": 7}), sensor, 1.4, as_lens(PAPER),
                           harmonise=True, center_px=CENTER)
    np.testing.assert_array_equal(chunked["harmonised"].values, out)
    # none readied where it would not be written into: a dask cube, bands listed otherwise
    assert plan._output_buffer(cube, CWL).shape == data.shape
    assert plan._output_buffer(cube.chunk({"y": 2}), CWL) is None
    assert plan._output_buffer(cube, CWL[::-1]) is None
