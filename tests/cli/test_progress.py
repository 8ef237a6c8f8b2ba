"""Progress on long jobs: a stream says frames done, frames per second and the time left; bars
show on a terminal (after a second of work), never with ``--quiet``, and off a terminal only
when asked (``--progress``)."""

import contextlib
import io
import re

import numpy as np
import pytest

from snapcorr import cli as cli_module
from snapcorr.cli import _progress

#: tqdm's bar of a stream at its end: frames done of all, elapsed<left, and the rate.
FRAMES_DONE = re.compile(r"(\d+)/(\d+) \[[\d:]+<[\d:?]+, +[\d.?]+ ?(frame/s|s/frame)\]")
ANY_BAR = re.compile(r"\d+/\d+ \[|\d+ (block|step|frame)s? \[")


class _Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """Four raw 64 x 96 frames of the 4x4 mosaic (a crop at sensor row 400, col 800)."""
    import zarr

    d = tmp_path_factory.mktemp("frames")
    rng = np.random.default_rng(3)
    dark = rng.normal(64, 2, (64, 96)).astype(np.float32)
    white = rng.normal(3000, 40, (64, 96)).astype(np.float32)
    raw = np.round(dark + rng.uniform(0.1, 0.9, (4, 64, 96)) * (white - dark)).astype(np.uint16)
    np.save(d / "dark.npy", dark)
    np.save(d / "white.npy", white)
    np.save(d / "raw.npy", raw[0])
    zarr.save_array(str(d / "frames.zarr"), raw)
    return d


STREAM = ("stream", "frames.zarr", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
          "mosaic_4x4_vis", "--sensor-origin-px", "400,800", "--demosaic", "bilinear",
          "--overwrite")


def _on_a_terminal(monkeypatch, d, *args):
    """``snapcorr ARGS`` in-process with stderr a terminal, bars shown at once."""
    monkeypatch.setattr(_progress._StageBar, "DELAY_S", 0.0)
    err = _Terminal()
    with contextlib.chdir(d), contextlib.redirect_stdout(io.StringIO()), \
            contextlib.redirect_stderr(err):
        code = cli_module.main(list(args))
    assert code == 0, err.getvalue()
    return err.getvalue()


def test_a_stream_reports_frames_done_the_rate_and_the_time_left(frames, cli):
    res = cli(*STREAM, "--out", "s.zarr", "--progress", cwd=frames)
    assert res.returncode == 0, res.stderr
    done = [m.groups() for m in FRAMES_DONE.finditer(res.stderr)]
    assert done and all(total == "4" for _, total, _ in done), res.stderr
    assert ("4", "4") in {(n, total) for n, total, _ in done}  # every frame, at the end
    assert "flat-fielding, demosaicking (bilinear), writing s.zarr" in res.stderr
    # off a terminal, not asked: no bar (a log or a pipe gets the result's lines only)
    res = cli(*STREAM, "--out", "s.zarr", cwd=frames)
    assert res.returncode == 0 and not ANY_BAR.search(res.stderr), res.stderr


def test_quiet_silences_the_bars_a_terminal_shows(frames, monkeypatch):
    shown = _on_a_terminal(monkeypatch, frames, *STREAM, "--out", "t.zarr")
    assert FRAMES_DONE.search(shown), shown
    quiet = _on_a_terminal(monkeypatch, frames, *STREAM, "--out", "t.zarr", "--quiet")
    assert not ANY_BAR.search(quiet), quiet
    ff = ("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
          "mosaic_4x4_vis", "--sensor-origin-px", "400,800", "--demosaic", "bilinear", "--out",
          "f.zarr", "--overwrite")
    assert re.search(r"\d+/\d+ \[", _on_a_terminal(monkeypatch, frames, *ff))
    assert not ANY_BAR.search(_on_a_terminal(monkeypatch, frames, *ff, "--quiet"))
    assert _progress._SHOW_PROGRESS is None  # the run's choice does not outlive it


def test_quiet_and_progress_together_are_a_usage_error(cli):
    res = cli("stream", "f.zarr", "--dark", "d.npy", "--white", "w.npy", "--sensor",
              "mosaic_4x4_vis", "--out", "o.zarr", "--quiet", "--progress")
    assert res.returncode == 2 and "not allowed with argument" in res.stderr


@pytest.mark.parametrize("skipped", [0, 2])
def test_a_bar_of_steps_ends_at_its_total(monkeypatch, skipped):
    """A bar counts a step when the next begins, so the last was never counted: pupil
    --predict's bar ended at 32/33. It ends at its total, with steps found not to apply taken
    off it (skip), and where the work fails it stays where it stopped."""
    monkeypatch.setattr(_progress, "_SHOW_PROGRESS", True)
    for fails in (False, True):
        err = _Terminal()
        with contextlib.redirect_stderr(err), contextlib.suppress(RuntimeError):
            with _progress._StepBar("steps", total=5) as bar:
                for k in range(5 - skipped):
                    bar.step(f"step {k}")
                if skipped:
                    bar.skip(skipped)
                if fails:
                    raise RuntimeError("stopped")
        done = FINAL.findall(err.getvalue())[-1]
        want = 5 - skipped
        assert done == (str(want - 1 if fails else want), str(want)), err.getvalue()


FINAL = re.compile(r"(\d+)/(\d+) \[")
