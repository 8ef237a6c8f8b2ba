"""BLAS threads where many small matrices are multiplied.

Tables of small matrices (widths, virtual bands, harmonising matrices, the exit-pupil fit's
solves) gain nothing from BLAS threads, and on a loaded machine lose much to them: a virtual
bands' table of the 5x5 sensor took 4.4 s with the default threads and 1.4 s on one, with
the machine's two cores busy with other work (measured). Woken, the threads also keep spinning
after the work, which slowed a resampling pass that followed by half (measured).
"""

from __future__ import annotations

__all__ = ["one_blas_thread"]


def one_blas_thread():
    """A context in which BLAS runs on one thread (threadpoolctl). The limit is the
    process's: enter it on the calling thread only, not while another thread may be inside
    BLAS."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1, user_api="blas")
