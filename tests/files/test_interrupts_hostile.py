"""Interrupted writes: SIGINT or SIGTERM during a write (Ctrl-C twice too) leaves no temporary
and no partial result behind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from hostile import LENS, hidden, read_result


@pytest.fixture(scope="module")
def big_inputs(tmp_path_factory):
    """A 160 MB float32 cube (and one-row dark and white strips): its result takes a moment
    to write."""
    d = tmp_path_factory.mktemp("big")
    ny, nx, nb = 1000, 1250, 32
    raw = np.lib.format.open_memmap(d / "raw.npy", mode="w+", dtype=np.float32,
                                    shape=(ny, nx, nb))
    raw[:] = np.linspace(100, 300, nx, dtype=np.float32)[None, :, None]
    raw.flush()
    del raw
    np.save(d / "dark.npy", np.full((1, nx, nb), 10.0, np.float32))
    np.save(d / "white.npy", np.full((1, nx, nb), 900.0, np.float32))
    cwl = ", ".join(f"{500.0 + 10 * i:.1f}" for i in range(nb))
    (d / "sensor.toml").write_text(
        f'[sensor]\nname = "big"\nlayout = "snapscan"\npixel_pitch_um = 5.5\n'
        f"cwl_nm = [{cwl}]\nfwhm_nm = 10.0\nn_eff = 1.7\n")
    return d


def _sigint_default():
    """In the child: Ctrl-C as a terminal sends it. A shell starts background jobs with
    SIGINT ignored, and Python then installs no KeyboardInterrupt handler."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupt(args, folder, out, signals, *, after=0.0, attempts=3):
    """Run ``snapcorr ARGS`` in ``folder``; once a hidden temporary appears (the write has
    begun), wait ``after`` s and send ``signals`` (10 ms apart). Returns (status, stderr).

    An attempt where the result was written before the first signal arrived proves nothing
    and is repeated; one whose result was still being written after it (its newest content
    is later than the signal) shows the interrupt was lost, and fails."""
    for _ in range(attempts):
        proc = subprocess.Popen([sys.executable, "-m", "snapcorr", *map(str, args)], cwd=folder,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=_sigint_default)
        try:
            deadline = time.monotonic() + 90
            while not hidden(folder):
                if proc.poll() is not None:
                    pytest.fail(f"finished (status {proc.returncode}) before a temporary "
                                f"appeared: {proc.stderr.read()}")
                if time.monotonic() > deadline:
                    pytest.fail("no temporary appeared within 90 s")
                time.sleep(0.01)
            time.sleep(after)
            sent_ns = time.time_ns()
            for i, sig in enumerate(signals):
                if proc.poll() is None:
                    proc.send_signal(sig)
                if i + 1 < len(signals):
                    time.sleep(0.01)
            stdout, stderr = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        if "wrote" not in stdout:
            return proc.returncode, stderr
        if _last_written_ns(out) > sent_ns:
            pytest.fail(f"the command went on writing after {signals[0].name} and finished "
                        f"(status {proc.returncode}): the interrupt was lost\n{stderr}")
        # the write won the race: start again
        if out.is_dir():
            import shutil

            shutil.rmtree(out)
        elif out.exists():
            out.unlink()
    pytest.fail(f"the write finished before the signal in {attempts} attempts")


def _last_written_ns(out):
    """When the content of the file or folder ``out`` was last written (the file system's
    clock, which never runs ahead of ``time.time_ns``), ns."""
    if not out.is_dir():
        return out.stat().st_mtime_ns
    return max(os.stat(os.path.join(root, f)).st_mtime_ns
               for root, _, files in os.walk(out) for f in files)


def _assert_interrupted_cleanly(status, err, folder, out):
    assert status != 0
    assert "Traceback" not in err, err
    assert not hidden(folder), f"left behind: {hidden(folder)}"
    if out.exists():  # renamed just before the signal: it must then be whole
        read_result(out).load()


def _flatfield_big(d, out):
    return ("flatfield", d / "raw.npy", "--dark", d / "dark.npy", "--white", d / "white.npy",
            "--sensor", d / "sensor.toml", "--out", out)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_signal_during_write_leaves_no_temporary(tmp_path, big_inputs, sig, ext):
    out = tmp_path / f"result{ext}"
    status, err = _interrupt(_flatfield_big(big_inputs, out), tmp_path, out, [sig], after=0.1)
    _assert_interrupted_cleanly(status, err, tmp_path, out)


@pytest.mark.slow
@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_sigterm_during_correct_leaves_no_temporary(tmp_path, big_inputs, ext):
    d = big_inputs
    out = tmp_path / f"corrected{ext}"
    args = ("correct", d / "raw.npy", "--lens", LENS, "--sensor", d / "sensor.toml",
            "--f-number", "1.4", "--resample", "--out", out)
    status, err = _interrupt(args, tmp_path, out, [signal.SIGTERM])
    _assert_interrupted_cleanly(status, err, tmp_path, out)


@pytest.mark.slow
@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_ctrl_c_twice_during_write_leaves_no_temporary(tmp_path, big_inputs, ext):
    """An impatient user presses Ctrl-C again while snapcorr cleans up."""
    out = tmp_path / f"result{ext}"
    status, err = _interrupt(_flatfield_big(big_inputs, out), tmp_path, out,
                             [signal.SIGINT] * 6, after=0.1)
    _assert_interrupted_cleanly(status, err, tmp_path, out)
