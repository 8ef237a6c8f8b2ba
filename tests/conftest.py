import contextlib
import io
import os
import signal
import sys
import warnings
from pathlib import Path
from typing import NamedTuple


def _share_the_cores():
    """Under pytest-xdist, each worker's share of the cores for BLAS, OpenMP and numba's
    threads (set before numpy and numba load, and inherited by the command lines the tests
    start): ``-n auto`` already runs a worker per core, and threads beyond that only wait for
    one another. Idle threads also wait passively instead of spinning on the cores the other
    workers need. A variable already set is kept."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
    if not os.environ.get("PYTEST_XDIST_WORKER") or workers < 1:
        return
    share = str(max(1, (os.cpu_count() or 1) // workers))
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                "NUMBA_NUM_THREADS"):
        os.environ.setdefault(var, share)
    os.environ.setdefault("OMP_WAIT_POLICY", "passive")
    # a plugin may have loaded numpy already: its BLAS is limited in place
    from threadpoolctl import threadpool_limits

    threadpool_limits(int(os.environ["OPENBLAS_NUM_THREADS"]), user_api="blas")


_share_the_cores()


def _oracles_importable():
    """The independent simulators of ``tests/oracles/`` (they share no code with snapcorr)
    imported by their names, ``import flatsim``, from every test folder.

    The layout: ``tests/<package>/test_<module>.py`` (each folder a package, so that files of
    one name in two folders do not collide), the command line's tests by command in
    ``tests/cli/``, helpers shared by tests in ``tests/`` itself (importable as this folder is
    on the path), and ``tests/oracles/`` a plain folder on the path, so its modules have one
    name whether a test or the doctest collection imports them."""
    oracles = str(Path(__file__).resolve().parent / "oracles")
    if oracles not in sys.path:
        sys.path.insert(0, oracles)


_oracles_importable()

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from flatsim import LensTruth  # noqa: E402

from snapcorr import Lens  # noqa: E402

#: The paper's lens, the Edmund Optics 16 mm (Goossens 2019, Sec. 3.2, Eq. 31): exit pupil x,
#: vignetting circle (P, h), magnification m and pupil magnification m_P. Tests use these, the
#: ``edmund`` fixture, or the lens for the test suite's own simulators, never a new literal.
PAPER_X_MM, PAPER_CIRCLE, PAPER_M, PAPER_M_P = 21.0, (7.4236, 16.991), 0.06, 1.3
PAPER_LENS = Lens(PAPER_X_MM, [PAPER_CIRCLE], PAPER_M, PAPER_M_P,
                  name="Edmund Optics 16 mm C Series")
PAPER_TRUTH = LensTruth(PAPER_X_MM, (PAPER_CIRCLE,), PAPER_M, PAPER_M_P, name="paper lens")

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "reference"
#: Our own examples (the README's blocks, the notebooks, the benchmarks) give the optical centre
#: row first: the deprecated x-first form is an error there (tests written with it keep it:
#: pyproject.toml ignores its warning for the rest of the suite).
NO_X_FIRST_CENTER = "error:center_px is the old x-first form:FutureWarning"
DATA = Path(__file__).resolve().parent / "data"
REPO = Path(__file__).resolve().parents[1]
#: A real vendor calibration file (the older variant): imec 5x5 NIR mosaic on a CMV2000,
#: bundled with its licence (BSD-3-Clause).
VENDOR_XML = REPO / "calibration" / "sensors" / "CMV2K-SSM5x5-600_875-5.5.9.2.xml"
#: Real measured responses of imec 4x4 VIS and 5x5 NIR mosaic sensors (MIT): SpectralProfiles
#: (bands x 601, 400-1000 nm at 1 nm, no band-pass applied) and the central wavelengths.
RESPONSES_MAT = {4: DATA / "imec_responses_4x4.mat", 5: DATA / "imec_responses_5x5.mat"}


@pytest.fixture(autouse=True)
def _numpy_print_options():
    """numpy's print options as every test found them: libraries the tests import may change
    them for the whole process (colour-science sets ``legacy="1.13"`` on import), which would
    make later doctests print arrays differently."""
    saved = np.get_printoptions()
    yield
    np.set_printoptions(**saved)


@pytest.fixture(scope="session")
def edmund():
    """The paper's Edmund Optics 16 mm lens (Goossens 2019, Sec. 3.2, Eq. 31)."""
    return PAPER_LENS


def brute_force_mean(cwl, n_eff, x, R, d, P=None, dv=None, N=1500):
    """Average Eq. (3) over the pupil plane by brute force (no eta/nu/gamma, no kernel).

    Midpoint grid over the exit pupil's bounding square (mm); a point counts if it lies in the
    pupil and, if given, in the vignetting circle centred at ``dv`` on the same axis as the
    pixel's foot ``d``. Its ray to the pixel has ``tan(phi) = |p - F| / x``.
    """
    h = 2 * R / N
    c = (np.arange(N) + 0.5) * h - R
    X, Y = np.meshgrid(c, c, indexing="ij")
    inside = X**2 + Y**2 <= R * R
    if P is not None:
        inside &= (X - dv) ** 2 + Y**2 <= P * P
    r2 = (X[inside] - d) ** 2 + Y[inside] ** 2
    sin2 = r2 / (r2 + x * x)
    return float(np.mean(-cwl * (1 - np.sqrt(1 - sin2 / n_eff**2)))), int(inside.sum())


def load_reference_csv():
    path = SHARED / "mean_shift_edmund16mm.csv"
    if not path.exists():
        path = DATA / "mean_shift_edmund16mm.csv"
    rows = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    assert rows[0].startswith("f_number")
    return np.array([[float(v) for v in ln.split(",")] for ln in rows[1:]])


# -- the command line, run in-process ----------------------------------------------------------


class CliResult(NamedTuple):
    """What ``snapcorr ARGS`` did, as ``subprocess.run(..., capture_output=True, text=True)``
    reports it; also unpacks as ``(returncode, stdout, stderr)``."""

    returncode: int
    stdout: str
    stderr: str


_SIGNALS = [getattr(signal, s) for s in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, s)]


def _global_state():
    """What a run of ``main(argv)`` must leave as it found it (a Python caller's process)."""
    from snapcorr import _io

    state = {
        "signal handlers": {s: signal.getsignal(s) for s in _SIGNALS},
        "warnings.filters": list(warnings.filters),
        "warnings.showwarning": warnings.showwarning,
        "sys.unraisablehook": sys.unraisablehook,
        "sys.excepthook": sys.excepthook,
        "sys.stdout, sys.stderr": (sys.stdout, sys.stderr),
        "working folder": os.getcwd(),
        "numpy error handling": np.geterr(),
        "registered temporaries": sorted(map(str, _io.temporary_paths())),
    }
    # modules a run may import for the first time: their state as if not imported
    state["dask scheduler"] = None
    if "dask" in sys.modules:
        state["dask scheduler"] = sys.modules["dask"].config.get("scheduler", None)
    state["distributed default client"] = None
    if "distributed.client" in sys.modules:
        state["distributed default client"] = sys.modules["distributed.client"] \
            ._get_global_client()
    state["open pyplot figures"] = []
    if "matplotlib.pyplot" in sys.modules:
        state["open pyplot figures"] = sys.modules["matplotlib.pyplot"].get_fignums()
    return state


def _exit_status(code, stderr):
    """The exit status of ``sys.exit(code)``: None 0, an int itself, anything else printed on
    stderr and 1."""
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    print(code, file=stderr)
    return 1


@contextlib.contextmanager
def _environ(**values):
    """Environment variables set for a block, then as they were (only these)."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def run_cli(*args, cwd=None):
    """Run ``snapcorr ARGS`` in this process, as ``python -m snapcorr ARGS`` would: the exit
    status (``sys.exit(main(argv))``, argparse's ``SystemExit`` included), stdout and stderr
    (warnings and progress bars too), in ``cwd`` if given. stdout and stderr are no terminal,
    as with a pipe: no progress bar, help text 80 columns wide.

    An exception escaping ``main`` (a traceback the user would see) is not caught: it fails
    the test. A run must leave no signal handler, warning filter or other global state behind
    (a Python caller of ``main(argv)`` keeps its process); that is checked after each run.
    """
    from snapcorr.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.ExitStack() as stack:
        if cwd is not None:
            stack.enter_context(contextlib.chdir(cwd))
        stack.enter_context(_environ(COLUMNS="80"))
        before = _global_state()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main([os.fspath(a) if isinstance(a, os.PathLike) else str(a)
                             for a in args])
            except SystemExit as exit_:  # argparse, or a sys.exit() within a command
                code = exit_.code
            except BaseException as exc:  # a traceback for the user: fails the test, as is
                exc.add_note(f"stderr of snapcorr {' '.join(map(str, args))}:\n"
                             f"{err.getvalue()}")
                raise
            code = _exit_status(code, err)
        after = _global_state()
    changed = {k: (before[k], after[k]) for k in before if after[k] != before[k]}
    assert not changed, f"snapcorr {' '.join(map(str, args))} left global state behind: " \
        f"{changed}\nstderr:\n{err.getvalue()}"
    return CliResult(code, out.getvalue(), err.getvalue())


@pytest.fixture(scope="session")
def cli():
    """``cli(*args, cwd=None)``: run ``snapcorr ARGS`` in-process (:func:`run_cli`)."""
    return run_cli


@contextlib.contextmanager
def deadline(seconds=60):
    """Fail instead of hanging: an alarm interrupts a blocked open of a FIFO or a read of
    /dev/zero. Only a guard (generous: a first call may import readers on a busy machine), no
    duration asserted."""
    def fire(signum, frame):
        raise TimeoutError(f"still blocked after {seconds} s")

    old = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
