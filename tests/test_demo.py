"""The demo's folder marker: it lists the files the demo wrote, vouches for nothing else, and
is written last and atomically."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import stat
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import pytest
from hostile import snapcorr_png, snapshot_bounded


def _fake_experiment(out, *, echo=print, **kwargs):
    """The simulated experiment's files, written as it writes them (save_png, Lens.save)."""
    from snapcorr import Lens

    for name in ("calibration.png", "spectra.png", "maps.png"):
        snapcorr_png(Path(out) / name)
    Lens(21.0, [(7.4, 17.0)], 0.06, 1.3, name="demo").save(Path(out) / "lens.toml",
                                                            overwrite=True)
    return ["   (the experiment, faked for the test)"], {}


@pytest.fixture
def quick_demo(monkeypatch):
    """run_demo with the experiment's heavy work replaced by writing its files."""
    import snapcorr.paper_experiment

    monkeypatch.setattr(snapcorr.paper_experiment, "run", _fake_experiment)
    from snapcorr.demo import run_demo

    return lambda out, **kw: run_demo(out, echo=lambda *a: None, **kw)


def test_the_demo_marker_lists_what_the_demo_wrote_and_vouches_for_nothing_else(
        tmp_path, quick_demo):
    from snapcorr.demo import MARKER, OUTPUTS, check_out_dir

    dm = tmp_path / "dm"
    quick_demo(dm)
    doc = json.loads((dm / MARKER).read_text())
    assert set(doc["files"]) == set(OUTPUTS)
    for name, entry in doc["files"].items():
        data = (dm / name).read_bytes()
        assert entry == {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    quick_demo(dm)  # its own files: replaced without --overwrite
    (dm / "summary.txt").write_text("MINE: edited since\n")
    before = snapshot_bounded(tmp_path)
    with pytest.raises(FileExistsError, match=r"summary\.txt, which snapcorr demo did not"):
        quick_demo(dm)
    with pytest.raises(ValueError, match=r"summary\.txt exists and is a file snapcorr demo did"):
        quick_demo(dm, overwrite=True)
    assert snapshot_bounded(tmp_path) == before
    (dm / "summary.txt").unlink()
    check_out_dir(dm)  # a missing output is fine


def test_the_demo_marker_never_vouches_for_a_file_put_there_during_the_run(tmp_path,
                                                                          monkeypatch,
                                                                          quick_demo):
    """A file the demo did not move in (it appeared while the demo ran, at a name the demo
    then failed to write) is not listed: a later run does not take it for the demo's."""
    import snapcorr.demo as demo

    dm = tmp_path / "dm"
    original = demo.atomic_write

    def users_csv_first(path, write, **kw):
        if Path(path).name == "mean_shift.csv":
            Path(path).write_text("the user's own table\n")
        return original(path, write, **kw)

    monkeypatch.setattr(demo, "atomic_write", users_csv_first)
    with pytest.raises(FileExistsError, match=r"mean_shift\.csv appeared after snapcorr checked"):
        quick_demo(dm)
    assert (dm / "mean_shift.csv").read_text() == "the user's own table\n"
    # a failed run's marker vouches for what it moved in, never for the user's table
    assert json.loads((dm / demo.MARKER).read_text())["files"].keys() == {"mean_shift.png"}
    # and the marker lists only files the demo moved in itself
    monkeypatch.setattr(demo, "atomic_write", original)
    (dm / "mean_shift.csv").unlink()
    quick_demo(dm, overwrite=True)
    os.replace(dm / "summary.txt", dm / "kept.txt")
    shutil.copy(dm / "kept.txt", dm / "summary.txt")  # same bytes, not the file written
    demo._write_marker(dm)
    assert "summary.txt" not in json.loads((dm / demo.MARKER).read_text())["files"]


def test_the_demo_writes_its_marker_atomically_never_through_what_was_there(tmp_path,
                                                                           quick_demo):
    from snapcorr.demo import MARKER

    dm = tmp_path / "dm"
    quick_demo(dm)
    os.link(dm / MARKER, tmp_path / "hard-link-to-marker")
    kept = (tmp_path / "hard-link-to-marker").read_bytes()
    quick_demo(dm)
    assert (tmp_path / "hard-link-to-marker").read_bytes() == kept  # replaced, not rewritten
    assert not stat.S_ISLNK(os.lstat(dm / MARKER).st_mode)


def test_a_demo_cut_short_can_be_run_again_in_its_folder(tmp_path, monkeypatch):
    """Interrupted in the experiment (Ctrl-C), the demo left its first outputs and no marker,
    and a second run in the same folder was refused as holding files the demo did not make."""
    import snapcorr.paper_experiment
    from snapcorr.demo import MARKER, check_out_dir, run_demo

    def cut_short(out, *, echo=print, written=None, **kwargs):
        from snapcorr import Lens

        snapcorr_png(Path(out) / "calibration.png")
        Lens(21.0, [(7.4, 17.0)], 0.06, 1.3, name="demo").save(Path(out) / "lens.toml")
        written()
        raise KeyboardInterrupt("SIGINT received")

    monkeypatch.setattr(snapcorr.paper_experiment, "run", cut_short)
    dm = tmp_path / "dm"
    with pytest.raises(KeyboardInterrupt):
        run_demo(dm, echo=lambda *a: None)
    listed = set(json.loads((dm / MARKER).read_text())["files"])
    assert listed == {"mean_shift.png", "mean_shift.csv", "calibration.png", "lens.toml"}
    check_out_dir(dm)  # a second run is not refused
    monkeypatch.setattr(snapcorr.paper_experiment, "run", _fake_experiment)
    run_demo(dm, echo=lambda *a: None)


@pytest.mark.parametrize("name, edit", [
    ("summary.txt", lambda text: text + "my own notes about this run\n"),
    ("mean_shift.csv", lambda text: text.splitlines()[0] + "\n1.0,2.0,3.0\n"),
])
def test_overwrite_keeps_a_table_or_summary_edited_since_the_demo_wrote_it(
        tmp_path, quick_demo, name, edit):
    """The table's and the summary's mark is their first line, which an edit keeps: the
    user's appended notes, or rows of their own under the header, were replaced with
    overwrite=True. The marker lists the file the demo wrote there; another one is kept."""
    dm = tmp_path / "dm"
    quick_demo(dm)
    path = dm / name
    path.write_text(edit(path.read_text()))
    before = snapshot_bounded(tmp_path)
    with pytest.raises(ValueError, match=rf"{name.replace('.', '[.]')} exists and is not the "
                                         r"file snapcorr demo wrote there"):
        quick_demo(dm, overwrite=True)
    assert snapshot_bounded(tmp_path) == before
