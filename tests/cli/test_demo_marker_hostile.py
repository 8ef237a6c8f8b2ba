"""The demo's folder marker at the command line: a regular file, never followed, and alone no
proof that a file is the demo's; every target is checked before any work (what the marker
lists and how it is written: tests/test_demo.py)."""

from __future__ import annotations

import hashlib
import json
import os
import socket

import matplotlib

matplotlib.use("Agg")
import pytest
from conftest import deadline
from hostile import only_line, snapshot_bounded


def _users_png(path):
    from PIL import Image

    Image.new("RGB", (4, 4), (200, 10, 10)).save(path)


def _forbid_demo_work(monkeypatch):
    """The demo's computations fail the test if started: a refusal must come first."""
    import snapcorr.demo
    import snapcorr.paper_experiment

    def work(*args, **kwargs):
        raise AssertionError("the refusal must come before any work")

    monkeypatch.setattr(snapcorr.demo, "_mean_shift_over_the_field", work)
    monkeypatch.setattr(snapcorr.paper_experiment, "run", work)


def _hostile_marker(dm, tmp_path, kind):
    marker = dm / ".snapcorr-demo"
    if kind == "link-to-outside":
        (tmp_path / "p.txt").write_text("precious\n")
        marker.symlink_to("../p.txt")
    elif kind == "link-to-nothing":
        marker.symlink_to("../nowhere")
    elif kind == "fifo":
        os.mkfifo(marker)
    elif kind == "link-to-dev-zero":
        marker.symlink_to("/dev/zero")
    elif kind == "folder":
        marker.mkdir()
        (marker / "keep.txt").write_text("keep\n")
    elif kind == "socket":
        with socket.socket(socket.AF_UNIX) as s:
            s.bind(str(marker))
    else:
        raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["link-to-outside", "link-to-nothing", "fifo",
                                  "link-to-dev-zero", "folder", "socket"])
@pytest.mark.parametrize("overwrite", [False, True], ids=["plain", "overwrite"])
def test_demo_refuses_a_marker_that_is_not_a_regular_file_before_reading_it(
        tmp_path, monkeypatch, cli, kind, overwrite):
    monkeypatch.chdir(tmp_path)
    dm = tmp_path / "dm"
    dm.mkdir()
    _hostile_marker(dm, tmp_path, kind)
    before = snapshot_bounded(tmp_path)
    _forbid_demo_work(monkeypatch)
    with deadline():
        rc, _, err = cli("demo", "--out", "dm", *(["--overwrite"] if overwrite else []))
    assert rc == 1 and ".snapcorr-demo exists and is" in only_line(err), err
    assert "not the marker snapcorr demo writes" in err
    assert snapshot_bounded(tmp_path) == before


@pytest.mark.parametrize("marker", ["empty", "earlier-version", "lists-another-content",
                                    "not-json"])
def test_a_demo_marker_alone_does_not_make_a_users_file_replaceable(
        tmp_path, monkeypatch, cli, marker):
    monkeypatch.chdir(tmp_path)
    dm = tmp_path / "dm"
    dm.mkdir()
    (dm / "summary.txt").write_text("MINE\n")
    text = {"empty": "",
            "earlier-version": "written by snapcorr 0.0.9 demo\n",
            "lists-another-content": json.dumps({"files": {"summary.txt": {
                "size": 5, "sha256": hashlib.sha256(b"THEIRS").hexdigest()}}}),
            "not-json": "{files: summary.txt}"}[marker]
    (dm / ".snapcorr-demo").write_text(text)
    before = snapshot_bounded(tmp_path)
    _forbid_demo_work(monkeypatch)
    rc, _, err = cli("demo", "--out", "dm")
    line = only_line(err)
    assert rc == 1 and "summary.txt, which snapcorr demo did not write" in line, err
    assert "--overwrite" in line
    assert snapshot_bounded(tmp_path) == before


@pytest.mark.parametrize("case", ["users-png-and-summary", "users-toml", "users-csv",
                                  "link-at-an-output", "fifo-at-an-output",
                                  "folder-at-an-output"])
def test_demo_overwrite_checks_every_target_before_any_work(tmp_path, monkeypatch, cli,
                                                            case):
    monkeypatch.chdir(tmp_path)
    dm = tmp_path / "dm"
    dm.mkdir()
    (tmp_path / "p.txt").write_text("precious\n")
    if case == "users-png-and-summary":
        _users_png(dm / "maps.png")
        (dm / "summary.txt").write_text("MINE\n")
        words = ["maps.png exists and is a PNG that snapcorr did not write"]
    elif case == "users-toml":
        (dm / "lens.toml").write_text('# written by snapcorr 0.1.0\n[lens]\nname = "mine"\n')
        words = ["lens.toml exists and is a TOML file with snapcorr's mark of an earlier"]
    elif case == "users-csv":
        (dm / "mean_shift.csv").write_text("my,own,table\n1,2,3\n")
        words = ["mean_shift.csv exists and is a file snapcorr demo did not write"]
    elif case == "link-at-an-output":
        (dm / "summary.txt").symlink_to("../p.txt")
        words = ["summary.txt exists and is a symbolic link"]
    elif case == "fifo-at-an-output":
        os.mkfifo(dm / "summary.txt")
        words = ["summary.txt exists and is a FIFO"]
    else:
        (dm / "spectra.png").mkdir()
        words = ["spectra.png exists and is a folder"]
    before = snapshot_bounded(tmp_path)
    _forbid_demo_work(monkeypatch)
    with deadline():
        rc, _, err = cli("demo", "--out", "dm", "--overwrite")
    line = only_line(err)
    assert rc == 1, err
    for w in words:
        assert w in line, line
    assert snapshot_bounded(tmp_path) == before  # no marker planted, nothing written


