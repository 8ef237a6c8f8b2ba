"""`snapcorr demo`'s output folder: a folder the demo did not make, or a file in its place, is
refused before any work; a new folder is made and filled."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import pytest
from hostile import assert_refused, snapshot


def _forbid_demo_work(monkeypatch):
    """The demo's computations fail the test if started: a refusal must come before them."""
    import snapcorr.demo
    import snapcorr.paper_experiment

    def work(*args, **kwargs):
        raise AssertionError("the refusal must come before any work")

    monkeypatch.setattr(snapcorr.demo, "mean_shift", work)
    monkeypatch.setattr(snapcorr.paper_experiment, "run", work)


@pytest.mark.parametrize("files", [("lens.toml", "summary.txt"), ("notes.txt",)],
                         ids=["demo-like-names", "other-file"])
def test_demo_refuses_a_folder_it_did_not_make(tmp_path, monkeypatch, files, cli):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "results"
    out.mkdir()
    for i, name in enumerate(files):
        (out / name).write_text(f"the user's own {name}, {i}\n")
    before = snapshot(tmp_path)
    _forbid_demo_work(monkeypatch)
    rc, _, err = cli("demo", "--out", "results")
    assert_refused(rc, err, "--overwrite")
    assert snapshot(tmp_path) == before


def test_demo_refuses_a_file_as_its_folder(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").write_text("not a folder\n")
    before = snapshot(tmp_path)
    _forbid_demo_work(monkeypatch)
    rc, _, err = cli("demo", "--out", "results")
    assert_refused(rc, err, "results")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("given", ["missing/demo", "missing/deeper/demo"])
def test_demo_refuses_a_folder_whose_parent_does_not_exist(tmp_path, monkeypatch, cli, given):
    """As every command refuses an output whose folder does not exist: the demo made every
    missing folder above its own (a typo in a parent's name went unnoticed)."""
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    _forbid_demo_work(monkeypatch)
    rc, out, err = cli("demo", "--out", given)
    line = assert_refused(rc, err, "--out", given, "does not exist")
    assert "\n" not in line and not out.strip()
    assert snapshot(tmp_path) == before


@pytest.mark.slow
def test_demo_runs_in_a_new_folder(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    rc, _, err = cli("demo", "--out", "fresh")
    assert rc == 0, err
    names = {p.name for p in (tmp_path / "fresh").iterdir()}
    assert {"summary.txt", "lens.toml", "spectra.png"} <= names
    # no temporary left; a marker saying the folder is the demo's own is fine
    assert not [n for n in names if n.startswith(".") and not n.startswith(".snapcorr")]
