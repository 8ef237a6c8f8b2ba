"""An output path that is not a regular file: a FIFO, device or socket at an output (also through
a link) is refused before it is opened (``check_replaceable``, the library's writers, the
command line), and only a bounded part of a file is read for its mark."""

from __future__ import annotations

import os
import socket

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
import xarray as xr
from conftest import deadline
from hostile import only_line, output_cube, snapcorr_png, snapcorr_toml, snapshot_bounded

from snapcorr import _io
from snapcorr.cube import write_cube


def _special(path, kind):
    if kind == "fifo":
        os.mkfifo(path)
        return r"is a FIFO \(named pipe\)"
    if kind == "link-to-dev-zero":
        path.symlink_to("/dev/zero")
        return r"is a character device \(a symbolic link to /dev/zero\)"
    if kind == "link-to-fifo":
        os.mkfifo(path.with_name("pipe"))
        path.symlink_to("pipe")
        return r"is a FIFO \(named pipe\) \(a symbolic link to pipe\)"
    if kind == "socket":
        with socket.socket(socket.AF_UNIX) as s:
            s.bind(str(path))
        return "is a socket"
    if kind == "dangling-link":
        path.symlink_to("nowhere")
        return "is a symbolic link to nowhere, which does not exist"
    if kind == "link-loop":
        path.symlink_to(path.name)
        return "is a loop of symbolic links"
    raise AssertionError(kind)


SPECIALS = ["fifo", "link-to-dev-zero", "link-to-fifo", "socket", "dangling-link", "link-loop"]


@pytest.mark.parametrize("kind", SPECIALS)
@pytest.mark.parametrize("name", ["f.toml", "f.png", "f.csv", "f.nc"])
def test_check_replaceable_refuses_what_is_not_a_regular_file_before_opening_it(
        tmp_path, kind, name):
    target = tmp_path / name
    found = _special(target, kind)
    before = snapshot_bounded(tmp_path)
    with deadline(), pytest.raises(ValueError, match=f"{name} exists and {found}; "
                                                      "overwrite replaces only a file "
                                                      "snapcorr wrote") as err:
        _io.check_replaceable(target)
    only_line(err.value)
    assert snapshot_bounded(tmp_path) == before


@pytest.mark.parametrize("kind", ["fifo", "link-to-dev-zero"])
@pytest.mark.parametrize("writer", ["write_toml", "save_png", "atomic_write"])
def test_library_writers_refuse_a_special_file_at_the_target(tmp_path, kind, writer):
    target = tmp_path / ("t.toml" if writer == "write_toml" else "t.png")
    found = _special(target, kind)
    before = snapshot_bounded(tmp_path)
    with deadline(), pytest.raises(ValueError, match=found):
        if writer == "write_toml":
            snapcorr_toml(target, overwrite=True)
        elif writer == "save_png":
            snapcorr_png(target)
        else:
            _io.atomic_write(target, lambda p: p.write_bytes(b"new"))
    assert snapshot_bounded(tmp_path) == before


@pytest.mark.parametrize("kind", ["fifo", "link-to-dev-zero"])
@pytest.mark.parametrize("option", ["--toml", "--plot"])
def test_the_command_line_refuses_a_special_file_at_an_output(tmp_path, cli, kind, option):
    from snapcorr.data import sensor_path

    target = tmp_path / ("out.toml" if option == "--toml" else "out.png")
    found = _special(target, kind).replace("\\", "")
    before = snapshot_bounded(tmp_path)
    with deadline():
        rc, _, err = cli("sensor", sensor_path("snapscan_vnir"), option, target, "--overwrite")
    line = only_line(err)
    assert rc == 1 and "exists and " + found in line, err
    assert snapshot_bounded(tmp_path) == before


@pytest.mark.parametrize("name", ["big.toml", "big.png"])
def test_only_a_bounded_part_of_a_large_file_is_read_for_its_mark(tmp_path, name):
    target = tmp_path / name
    with open(target, "wb") as fh:  # sparse: 16 GiB that take no space
        fh.write(b"\x89PNG\r\n\x1a\n" if name.endswith(".png") else b"# written by snapcorr")
        fh.truncate(16 << 30)
    with deadline(30), pytest.raises(ValueError, match="snapcorr"):
        _io.check_replaceable(target)


def test_read_regular_refuses_special_files_links_and_large_files(tmp_path):
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "f").write_bytes(b"x" * 100)
    (tmp_path / "link").symlink_to("f")
    with deadline():
        with pytest.raises(_io.NotRegularFileError, match="FIFO"):
            _io.read_regular(tmp_path / "pipe", 10)
        with pytest.raises(_io.NotRegularFileError, match="character device"):
            _io.read_regular("/dev/zero", 10)
    with pytest.raises(_io.NotRegularFileError, match="symbolic link"):
        _io.read_regular(tmp_path / "link", 1000, follow_links=False)
    with pytest.raises(_io.NotRegularFileError, match="more than the 10"):
        _io.read_regular(tmp_path / "f", 10)
    assert _io.read_regular(tmp_path / "f", 10, whole=False) == b"x" * 10
    assert _io.read_regular(tmp_path / "link", 1000) == b"x" * 100


@pytest.mark.parametrize("case", ["huge-header", "huge-sidecar", "fifo-zarr-json",
                                  "dev-zero-zarr-json"])
def test_cube_targets_are_read_bounded_and_never_through_special_files(tmp_path, case):
    if case == "huge-header":
        target = tmp_path / "c.hdr"
        with open(target, "wb") as fh:
            fh.write(b"ENVI\nsnapcorr version = 0.1.0\n")
            fh.truncate(16 << 30)
        (tmp_path / "c.raw").write_bytes(b"\0" * 240)
    elif case == "huge-sidecar":
        target = tmp_path / "c.npy"
        np.save(target, np.ones((5, 6, 4), np.uint16))
        with open(tmp_path / "c.npy.json", "wb") as fh:
            fh.write(b'{"written_by": "snapcorr 0.1.0"')
            fh.truncate(16 << 30)
    else:
        target = tmp_path / "c.zarr"
        xr.Dataset({"t": ("n", np.arange(3.0))}).to_zarr(target, consolidated=False)
        os.unlink(target / "zarr.json")
        if case == "fifo-zarr-json":
            os.mkfifo(target / "zarr.json")
        else:
            (target / "zarr.json").symlink_to("/dev/zero")
    before = snapshot_bounded(tmp_path)
    with deadline(30), pytest.raises(ValueError, match="move it away or choose another name"):
        write_cube(output_cube(), target, overwrite=True)
    assert snapshot_bounded(tmp_path) == before
