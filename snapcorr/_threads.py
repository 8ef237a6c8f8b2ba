"""Threads: BLAS on one where many small matrices are multiplied, a job on a thread of its own,
and an output's memory made ready by whichever thread is free.

Tables of small matrices (widths, virtual bands, harmonising matrices, the exit-pupil fit's
solves) gain nothing from BLAS threads, and on a loaded machine lose much to them: a virtual
bands' table of the 5x5 sensor took 4.4 s with the default threads and 1.4 s on one, with
the machine's two cores busy with other work (measured). Woken, the threads also keep spinning
after the work, which slowed a resampling pass that followed by half (measured).
"""

from __future__ import annotations

import threading
from concurrent import futures

__all__ = ["OutputPages", "dask_threads", "in_background", "one_blas_thread"]


def one_blas_thread():
    """A context in which BLAS runs on one thread (threadpoolctl). The limit is the
    process's: enter it on the calling thread only, not while another thread may be inside
    BLAS."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1, user_api="blas")


def dask_threads(*, import_dask=False):
    """A context in which dask computes on its threads, the scheduler given as the function.

    Named by a string, or not named, dask imports ``distributed`` at a process's first
    compute to look for a client: 0.2-0.3 s of each command. Where ``distributed`` is
    imported already (a client may be running) or a scheduler is set, dask's own choice
    stands. Without ``import_dask``, a process that has not imported dask computes nothing
    with it, and nothing is set.
    """
    import contextlib
    import sys

    if "distributed" in sys.modules or not (import_dask or "dask" in sys.modules):
        return contextlib.nullcontext()
    import dask
    import dask.threaded

    if dask.config.get("scheduler", None) is not None:
        return contextlib.nullcontext()
    return dask.config.set(scheduler=dask.threaded.get)


def in_background(fn, *args):
    """``fn(*args)`` on a thread of its own: a :class:`concurrent.futures.Future`."""
    pool = futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="snapcorr")
    try:
        return pool.submit(fn, *args)
    finally:
        pool.shutdown(wait=False)  # the thread ends with its one job


class OutputPages:
    """An array's memory made ready, every page of it touched once, by whichever threads
    call :meth:`touch`, a share at a time: the kernel maps and zeroes a cube's worth of fresh
    memory (about 0.6 of a copy's time), before the pass rather than in it, by the thread
    that is free (the width table's or the maps') rather than one chosen in advance."""

    SHARE_BYTES = 64 << 20

    def __init__(self, out):
        self._flat = out.reshape(-1)
        self._step = max(1, 4096 // out.itemsize)
        self._share = max(self._step, self.SHARE_BYTES // out.itemsize)
        self._next = 0
        self._lock = threading.Lock()

    def touch(self):
        """Touch shares until none is left (numpy lets go of the GIL while it writes)."""
        while (share := self._claim()) is not None:
            self._flat[share] = 0

    def _claim(self):
        """The next share not yet claimed (a slice: one element per page), or None."""
        with self._lock:
            start = self._next
            if start >= self._flat.size:
                return None
            self._next = start + self._share
        return slice(start, min(start + self._share, self._flat.size), self._step)

    def cancel(self):
        """Leave the shares not yet begun."""
        with self._lock:
            self._next = self._flat.size
