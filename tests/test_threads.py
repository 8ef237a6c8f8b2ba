"""Threads (snapcorr._threads): an output's memory made ready by whichever threads are
free, a job on a thread of its own, BLAS on one thread."""

import numpy as np
import pytest

from snapcorr._threads import in_background, one_blas_thread


def test_a_job_in_the_background_gives_its_result_and_its_error():
    import threading

    def where():
        return threading.current_thread() is threading.main_thread()

    assert in_background(where).result() is False
    with pytest.raises(ZeroDivisionError):
        in_background(lambda: 1 / 0).result()


def test_blas_runs_on_one_thread_inside_the_context():
    from threadpoolctl import threadpool_info

    with one_blas_thread():
        assert all(p["num_threads"] == 1 for p in threadpool_info()
                   if p["user_api"] == "blas")


def test_the_output_pages_are_shared_out_between_the_threads_once_each():
    """Threads claiming shares of the output's memory at once get each element once, every
    page is touched, and nothing is after a cancel."""
    import threading

    from snapcorr import _threads

    out = np.full(3_000_001, np.nan, np.float32)  # 12 MB: 46 shares of 256 kB, one short
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(_threads.OutputPages, "SHARE_BYTES", 256 << 10)
        pages = _threads.OutputPages(out)
        claimed = {0: [], 1: [], 2: []}

        def claim(j):
            while (share := pages._claim()) is not None:
                claimed[j].append(share)

        threads = [threading.Thread(target=claim, args=(j,)) for j in claimed]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        shares = sorted((s for got in claimed.values() for s in got), key=lambda s: s.start)
        assert [s.start for s in shares] == list(range(0, out.size, 65536))
        assert [s.stop for s in shares] == [*range(65536, out.size, 65536), out.size]
        assert all(s.step == 1024 for s in shares)
        _threads.OutputPages(out).touch()
        assert np.all(out[::1024] == 0) and np.all(np.isnan(out[1::1024]))
        out[:] = np.nan
        pages = _threads.OutputPages(out)
        pages.cancel()
        pages.touch()
        assert np.all(np.isnan(out))


def test_dask_threads_names_the_threaded_scheduler_and_keeps_a_choice_made():
    import sys

    import dask
    import dask.threaded

    from snapcorr._threads import dask_threads

    with dask.config.set(scheduler="synchronous"), dask_threads(import_dask=True):
        assert dask.config.get("scheduler") == "synchronous"  # the caller's choice stands
    before = dask.config.get("scheduler", None)
    with dask_threads(import_dask=True):
        if "distributed" in sys.modules or before is not None:
            # a client may be running, or a choice was made: dask's own choice stands
            assert dask.config.get("scheduler", None) is before
        else:
            assert dask.config.get("scheduler") is dask.threaded.get
    assert dask.config.get("scheduler", None) is before  # and put back
