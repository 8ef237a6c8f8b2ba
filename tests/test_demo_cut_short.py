"""The demo cut short at any point leaves every file of its own listed in its marker, so a
rerun in the same folder replaces them without ``overwrite`` (and still never a user's)."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import pytest
from matplotlib.figure import Figure

_BLANK = Figure(figsize=(0.2, 0.2))


def snapcorr_png(path):
    """A small PNG written as snapcorr writes its figures (save_png, its mark)."""
    from snapcorr.files.png import save_png

    return save_png(_BLANK, path, dpi=10)


def _fake_experiment(out, *, echo=print, written=None, **kwargs):
    """The simulated experiment's files, written as it writes them (save_png, Lens.save)."""
    from snapcorr import Lens

    snapcorr_png(Path(out) / "calibration.png")
    Lens(21.0, [(7.4, 17.0)], 0.06, 1.3, name="demo").save(Path(out) / "lens.toml",
                                                            overwrite=True)
    written()
    for name in ("spectra.png", "maps.png"):
        snapcorr_png(Path(out) / name)
        written()
    return ["   (the experiment, faked for the test)"], {}


@pytest.fixture
def quick_demo(monkeypatch):
    """run_demo with the experiment replaced by writing its files, and part 1 computed once
    (its figure saved as a small one)."""
    import snapcorr.demo as demo
    import snapcorr.paper_experiment
    from snapcorr import Lens
    from snapcorr.data import lens_path

    part1 = demo._mean_shift_over_the_field(Lens.load(lens_path()))
    monkeypatch.setattr(demo, "_mean_shift_over_the_field", lambda lens: part1)
    monkeypatch.setattr(demo, "save_png", lambda fig, path, **kw: snapcorr_png(path))
    monkeypatch.setattr(snapcorr.paper_experiment, "run", _fake_experiment)
    return lambda out, **kw: demo.run_demo(out, echo=lambda *a: None, **kw)


def _killed_after_moving_in(monkeypatch, name):
    """Interrupt (as SIGTERM does) right after ``name`` is moved into place, before anything
    else runs."""
    import snapcorr.files.safety as safety

    original = safety._note_written

    def note_then_die(target):
        original(target)
        if Path(target).name == name:
            raise KeyboardInterrupt("SIGTERM received")

    monkeypatch.setattr(safety, "_note_written", note_then_die)
    return lambda: monkeypatch.setattr(safety, "_note_written", original)


def _listed(dm):
    from snapcorr.demo import MARKER

    if not (dm / MARKER).exists():
        return set()
    return set(json.loads((dm / MARKER).read_text())["files"])


def _new_process(monkeypatch):
    """Forget what this process moved in, as a run in a new process knows nothing of it."""
    import snapcorr.files.safety as safety

    monkeypatch.setattr(safety, "_WRITTEN", {})


@pytest.mark.parametrize("earlier_run", [False, True], ids=["new folder", "after a full run"])
def test_a_demo_killed_right_after_any_output_is_moved_in_lists_every_file_it_left(
        tmp_path, monkeypatch, quick_demo, earlier_run):
    """Killed between moving an output in and writing the marker, the demo left that file
    unlisted; and a rerun's marker listed only what the rerun had written, so the earlier
    run's files still there were refused by the next run as if they were the user's."""
    from snapcorr.demo import OUTPUTS, check_out_dir

    for name in OUTPUTS:
        dm = tmp_path / name
        if earlier_run:
            quick_demo(dm)
        _new_process(monkeypatch)
        restore = _killed_after_moving_in(monkeypatch, name)
        with pytest.raises(KeyboardInterrupt):
            quick_demo(dm)
        restore()
        on_disk = {p.name for p in dm.iterdir() if p.name in OUTPUTS}
        assert name in on_disk
        assert on_disk <= _listed(dm), name
        _new_process(monkeypatch)
        check_out_dir(dm)  # the rerun is not refused
        quick_demo(dm)
        assert _listed(dm) == set(OUTPUTS)


def test_a_demo_killed_before_an_output_is_moved_in_keeps_the_file_it_replaces_listed(
        tmp_path, monkeypatch, quick_demo):
    """The marker names the new file before it is moved in, and keeps the earlier run's file
    listed until it is replaced; a file a user put at a name is still refused after it."""
    import snapcorr.files.safety as safety
    from snapcorr.demo import MARKER, check_out_dir

    dm = tmp_path / "dm"
    quick_demo(dm)
    _new_process(monkeypatch)
    mkdir = safety.os.mkdir

    def die_before_lens(path, *args, **kwargs):  # the old file moved aside: not yet
        if Path(path).name.startswith(".lens.toml.old."):
            raise KeyboardInterrupt("SIGTERM received")
        return mkdir(path, *args, **kwargs)

    monkeypatch.setattr(safety.os, "mkdir", die_before_lens)
    with pytest.raises(KeyboardInterrupt):
        quick_demo(dm)
    monkeypatch.setattr(safety.os, "mkdir", mkdir)
    entries = json.loads((dm / MARKER).read_text())["files"]["lens.toml"]
    assert isinstance(entries, list) and len(entries) == 2  # the old file and the new one
    check_out_dir(dm)  # the earlier run's lens.toml, still there, is the demo's
    (dm / "lens.toml").write_text("# the user's own profile\n")
    with pytest.raises(FileExistsError, match=r"lens\.toml, which snapcorr demo did not"):
        check_out_dir(dm)


def test_before_moving_in_names_each_file_before_it_is_there(tmp_path):
    from snapcorr.files.safety import atomic_write, atomic_write_files, before_moving_in

    seen = []

    def hook(new, target):
        seen.append((Path(target).name, Path(new).read_text(), Path(target).exists()))

    with before_moving_in(hook):
        atomic_write(tmp_path / "a.txt", lambda p: p.write_text("A"))
        atomic_write_files([tmp_path / "b.hdr", tmp_path / "b.raw"],
                           lambda d: [(d / n).write_text(n) for n in ("b.hdr", "b.raw")])
    atomic_write(tmp_path / "c.txt", lambda p: p.write_text("C"))  # outside: not told
    assert seen == [("a.txt", "A", False), ("b.hdr", "b.hdr", False),
                    ("b.raw", "b.raw", False)]

    def refuse(new, target):
        raise OSError("cannot list it")

    with before_moving_in(refuse), pytest.raises(OSError, match="cannot list it"):
        atomic_write(tmp_path / "d.txt", lambda p: p.write_text("D"))
    assert not (tmp_path / "d.txt").exists()  # a hook that fails stops the move
