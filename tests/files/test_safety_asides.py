"""Replacing an output moves the old one into a folder of its own first (put back on any
failure, deleted once the new one is in): an interruption at any step leaves neither that
folder nor a half-deleted old output behind. A SIGTERM right after the folder was made left
an empty ``..snapcorr-demo.old.XXXXXXXX`` in the demo's output that no later run removed."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from snapcorr.cube import make_cube, read_cube, write_cube
from snapcorr.files import safety


def _cube(k=1):
    data = np.random.default_rng(1).integers(0, 1000, (5, 6, 4)).astype(np.uint16) * k
    return make_cube(data, np.array([500.0, 550.0, 600.0, 650.0]))


def _asides(folder):
    return [p.name for p in Path(folder).iterdir() if ".old." in p.name]


def test_an_interrupt_as_the_old_ones_folder_is_made_leaves_nothing(tmp_path, monkeypatch):
    write_cube(_cube(), tmp_path / "e.hdr")
    real = os.mkdir

    def made_then_interrupted(path, *args, **kwargs):
        real(path, *args, **kwargs)
        if ".old." in os.path.basename(os.fspath(path)):
            monkeypatch.setattr(os, "mkdir", real)
            raise KeyboardInterrupt("SIGTERM received")

    monkeypatch.setattr(os, "mkdir", made_then_interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_cube(_cube(3), tmp_path / "e.hdr", overwrite=True)
    monkeypatch.undo()
    assert not _asides(tmp_path)
    np.testing.assert_array_equal(read_cube(tmp_path / "e.hdr").values, _cube().values)


def test_an_interrupt_while_the_old_ones_are_deleted_leaves_nothing(tmp_path, monkeypatch):
    write_cube(_cube(), tmp_path / "e.hdr")
    real = shutil.rmtree

    def interrupted(path, *args, **kwargs):
        if ".old." in os.path.basename(os.fspath(path)):
            monkeypatch.setattr(shutil, "rmtree", real)
            raise KeyboardInterrupt("SIGTERM received")
        return real(path, *args, **kwargs)

    monkeypatch.setattr(shutil, "rmtree", interrupted)
    with pytest.raises(KeyboardInterrupt), safety.cleanup_on_signals():
        write_cube(_cube(3), tmp_path / "e.hdr", overwrite=True)
    monkeypatch.undo()
    assert not _asides(tmp_path)
    np.testing.assert_array_equal(read_cube(tmp_path / "e.hdr").values, _cube(3).values)
