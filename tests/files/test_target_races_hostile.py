"""A target that appears or changes after the command checked it is not replaced: the check
holds until the move, in the library and on the command line."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
from hostile import only_line, output_cube, snapcorr_png, snapcorr_toml, snapshot_bounded

from snapcorr import _io
from snapcorr.cube import read_cube, write_cube, write_dataset


def _companions(path):
    return [p for p in (path, path.with_suffix(".raw"), path.with_name(path.name + ".json"))
            if os.path.lexists(p)]


def _as_another_process(tmp_path, target, write):
    """Writer A, another process (its own notes): ``write(path)`` writes A's output under the
    target's name in a folder of its own, then it is moved in (a folder replacing one)."""
    box = tmp_path / f"A-{len(list(tmp_path.glob('A-*')))}"
    box.mkdir()
    write(box / target.name)
    for made in _companions(box / target.name):
        dest = target.parent / made.name
        if dest.is_dir() and not dest.is_symlink():
            shutil.rmtree(dest)
        os.replace(made, dest)
    box.rmdir()


@pytest.mark.parametrize("ext", [".nc", ".zarr", ".hdr", ".npy", ".tif"])
@pytest.mark.parametrize("existed", [False, True], ids=["absent", "snapcorrs-own"])
def test_a_target_that_changes_after_the_check_is_not_replaced(tmp_path, ext, existed):
    """Writer B checks its output, works; writer A (another snapcorr) writes the output
    meanwhile; B's write must not replace A's file, even with overwrite."""
    out = tmp_path / "out"
    out.mkdir()
    target = out / f"o{ext}"
    if existed:
        write_cube(output_cube(), target)
    with _io.checked_outputs():
        _io.check_replaceable(target)  # B's command checks its outputs
        _as_another_process(tmp_path, target, lambda p: write_cube(output_cube(5), p))
        after_a = snapshot_bounded(out)
        with pytest.raises(FileExistsError, match="after snapcorr checked"):
            write_cube(output_cube(2), target, overwrite=True)  # B, after its long work
    assert snapshot_bounded(out) == after_a
    np.testing.assert_array_equal(read_cube(target).values, output_cube(5).values)
    write_cube(output_cube(2), target, overwrite=True)  # A's result is snapcorr's: a new command
    np.testing.assert_array_equal(read_cube(target).values, output_cube(2).values)


@pytest.mark.parametrize("kind", ["png", "toml", "csv"])
def test_a_plot_or_profile_that_appears_after_the_check_is_not_replaced(tmp_path, kind):
    out = tmp_path / "out"
    out.mkdir()
    target = out / f"q.{kind}"
    writers = {"png": snapcorr_png, "toml": snapcorr_toml,
               "csv": lambda p: p.write_text("A's table\n")}
    with _io.checked_outputs():
        _io.check_replaceable(target)
        _as_another_process(tmp_path, target, writers[kind])
        kept = target.read_bytes()
        with pytest.raises(FileExistsError, match=r"q\." + kind + " appeared after snapcorr "
                                                  "checked its outputs"):
            if kind == "png":
                snapcorr_png(target)
            elif kind == "toml":
                snapcorr_toml(target, overwrite=True)
            else:
                _io.atomic_write(target, lambda p: p.write_text("B's\n"))
    assert target.read_bytes() == kept


def test_the_librarys_own_check_holds_until_the_move(tmp_path, monkeypatch):
    """Without a command around it, write_dataset's target check is what the move holds to:
    a file that appears between the check and the write is not replaced."""
    import snapcorr.files.datasets as datasets

    out = tmp_path / "out"
    out.mkdir()
    target = out / "r.nc"
    write_dataset(output_cube().to_dataset(), target)
    store = datasets._store

    def a_writes_first(ds, path, fmt, *args):
        if Path(path) == target:  # B, between its check and its write: A writes first
            _as_another_process(tmp_path, target,
                                lambda p: write_dataset(output_cube(7).to_dataset(), p))
        return store(ds, path, fmt, *args)

    monkeypatch.setattr(datasets, "_store", a_writes_first)
    with pytest.raises(FileExistsError, match="changed after snapcorr checked it"):
        write_dataset(output_cube(2).to_dataset(), target, overwrite=True)
    monkeypatch.setattr(datasets, "_store", store)
    np.testing.assert_array_equal(read_cube(target).values, output_cube(7).values)


def test_notes_are_forgotten_with_their_command_and_never_refuse_a_later_one(tmp_path):
    target = tmp_path / "o.png"
    with _io.checked_outputs():
        _io.check_replaceable(target)  # a command that failed before writing
    snapcorr_png(target)
    with _io.cleanup_on_signals():  # the next command (cleanup_on_signals opens a scope)
        _io.check_replaceable(target)
        snapcorr_png(target)
    _io.check_replaceable(tmp_path / "x.png")  # outside a command: a stale note ...
    snapcorr_png(tmp_path / "x.png")
    _io.check_replaceable(tmp_path / "x.png")  # ... is replaced by the next check
    snapcorr_png(tmp_path / "x.png")
    assert not _io._CHECKED or all(s is None for _, s in _io._CHECKED.values())


def test_a_note_follows_the_target_however_its_path_is_spelled(tmp_path, monkeypatch):
    (tmp_path / "sub").mkdir()
    (tmp_path / "via").symlink_to("sub")
    monkeypatch.chdir(tmp_path)
    with _io.checked_outputs():
        _io.check_replaceable("via/../sub/o.png")
        _as_another_process(tmp_path, tmp_path / "sub" / "o.png", snapcorr_png)
        with pytest.raises(FileExistsError, match="appeared after snapcorr checked"):
            snapcorr_png(Path("via") / "o.png")


def test_the_command_lines_output_check_holds_until_the_write(tmp_path, cli, monkeypatch):
    """snapcorr sensor --toml OUT --overwrite: a TOML that another snapcorr writes at OUT
    after this command checked its outputs is not replaced."""
    import snapcorr.cli.sensor as cli_module
    from snapcorr.data import sensor_path

    target = tmp_path / "camera.toml"
    check = cli_module._check_outputs
    probe = tmp_path / "probe.toml"
    with _io.checked_outputs():
        check({"--toml": probe}, [], True, [(".toml",)])
        noted = _io._target_key(probe) in _io._CHECKED
    if not noted:
        pytest.xfail("snapcorr/cli/_output.py _check_outputs does not note absent outputs yet: it "
                     "must call check_replaceable(out) for every output, not only existing ones")

    def then_a_writes(*args, **kwargs):
        check(*args, **kwargs)
        _as_another_process(tmp_path, target, snapcorr_toml)  # A, while B works

    monkeypatch.setattr(cli_module, "_check_outputs", then_a_writes)
    rc, _, err = cli("sensor", sensor_path("snapscan_vnir"), "--toml", target, "--overwrite")
    assert rc == 1 and "appeared after snapcorr checked its outputs" in only_line(err), err
    assert "exit_pupil_mm" in target.read_text()  # A's file
