"""Cubes the data model refuses: empty along any axis, zero rows, complex or boolean values;
nothing is written."""

from __future__ import annotations

import numpy as np
import pytest
from hostile import (
    FF,
    assert_refused,
    correct_args,
    save_cubes,
    snapshot,
)


@pytest.mark.parametrize("shape", [(0, 10, 4), (12, 0, 4), (12, 10, 0)],
                         ids=["no-rows", "no-columns", "no-bands"])
def test_empty_cube_is_refused_and_nothing_written(tmp_path, monkeypatch, shape, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=shape)
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert_refused(rc, err)
    assert snapshot(tmp_path) == before


def test_correct_refuses_a_zero_row_cube(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, shape=(0, 10, 4))
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("raw.npy", "o.nc"))
    assert_refused(rc, err)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("dtype", [np.complex64, np.bool_], ids=["complex", "bool"])
@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_complex_or_bool_cube_is_refused(tmp_path, monkeypatch, command, dtype, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    np.save(tmp_path / "raw.npy", np.ones((12, 10, 4), dtype))
    args = (*FF, "--out", "o.nc") if command == "flatfield" else correct_args("raw.npy", "o.nc")
    before = snapshot(tmp_path)
    rc, _, err = cli(*args)
    assert_refused(rc, err, "complex" if dtype is np.complex64 else "bool")
    assert snapshot(tmp_path) == before
