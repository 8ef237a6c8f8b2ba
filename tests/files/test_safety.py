"""Files a user can trust: inputs that are not regular files, bad ENVI headers, invalid cubes,
overwriting, and interruptions. Every refusal is one clear line, raised before anything is
written, with the inputs unchanged."""

import gc
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import deadline

from snapcorr.calibrate import read_flat
from snapcorr.cube import (
    check_cube,
    make_cube,
    read_cube,
    read_dataset,
    read_frame,
    write_cube,
    write_dataset,
)
from snapcorr.files import safety

WL = np.array([500.0, 550.0, 600.0, 650.0])
READERS = {"read_cube": lambda p: read_cube(p, wavelength_nm=WL), "read_flat": read_flat,
           "read_frame": read_frame, "read_dataset": read_dataset}


def _cube(dtype=np.uint16, shape=(5, 6, 4)):
    data = np.random.default_rng(1).integers(0, 1000, shape).astype(dtype)
    return make_cube(data, WL[:shape[2]], attrs={"f_number": 2.0})


def _snapshot(folder):
    """Every path under ``folder`` with its bytes (files) or None (folders, others)."""
    out = {}
    for p in sorted(Path(folder).rglob("*")):
        out[str(p.relative_to(folder))] = p.read_bytes() if p.is_file() and not \
            p.is_symlink() else None
    return out


def _one_line(err):
    text = str(err.value)
    assert "\n" not in text, text
    return text


# -- 1. inputs that are not regular files ----------------------------------------------------


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("ext", [".npy", ".hdr", ".tif", ".exr", ".nc"])
def test_a_fifo_is_refused_before_it_is_opened(tmp_path, reader, ext):
    if reader == "read_dataset" and ext != ".nc":
        pytest.skip("results are .nc or .zarr")
    os.mkfifo(tmp_path / f"pipe{ext}")
    with deadline(60), pytest.raises(ValueError, match=r"is a FIFO \(named pipe\), not a "
                                                       "regular file") as err:
        READERS[reader](tmp_path / f"pipe{ext}")
    _one_line(err)


@pytest.mark.parametrize("reader", ["read_cube", "read_flat", "read_frame", "read_dataset",
                                    "read_frames"])
def test_a_fifo_at_any_depth_of_a_zarr_store_is_refused_before_it_is_opened(tmp_path, reader):
    """Special files are refused wherever they sit in a store, before zarr opens it (a FIFO
    among the chunks hung flatfield, beyond the reach of SIGTERM)."""
    from snapcorr.cube import read_frames

    if reader == "read_dataset":
        write_dataset(xr.Dataset({"radiance": _cube()}), tmp_path / "s.zarr")
    else:
        write_cube(_cube(), tmp_path / "s.zarr")
    chunk = max((p for p in (tmp_path / "s.zarr").rglob("*") if p.is_file()),
                key=lambda p: len(p.parts))
    chunk.unlink()
    os.mkfifo(chunk)
    readers = {**READERS, "read_frames": read_frames}
    with deadline(60), pytest.raises(ValueError, match=r"inside the .* store .* is a FIFO "
                                                       r"\(named pipe\)") as err:
        readers[reader](tmp_path / "s.zarr")
    _one_line(err)


@pytest.mark.parametrize("reader", ["read_cube", "read_flat", "read_frame"])
def test_an_envi_data_file_that_is_a_fifo_is_refused(tmp_path, reader):
    write_cube(_cube(shape=(5, 6, 1)), tmp_path / "e.hdr")
    (tmp_path / "e.raw").unlink()
    os.mkfifo(tmp_path / "e.raw")
    with deadline(60), pytest.raises(ValueError, match=r"e\.raw is a FIFO") as err:
        READERS[reader](tmp_path / "e.hdr")
    _one_line(err)


@pytest.mark.parametrize("reader", READERS)
def test_sockets_devices_loops_missing_files_and_folders(tmp_path, reader):
    read = READERS[reader]
    ext = ".nc"
    sock = socket.socket(socket.AF_UNIX)
    try:
        sock.bind(str(tmp_path / f"s{ext}"))
        with pytest.raises(ValueError, match="is a socket, not a regular file"):
            read(tmp_path / f"s{ext}")
    finally:
        sock.close()
    (tmp_path / f"null{ext}").symlink_to("/dev/null")
    with pytest.raises(ValueError, match="is a character device, not a regular file"):
        read(tmp_path / f"null{ext}")
    (tmp_path / f"a{ext}").symlink_to(tmp_path / f"b{ext}")
    (tmp_path / f"b{ext}").symlink_to(tmp_path / f"a{ext}")
    with pytest.raises(ValueError, match="a loop of symbolic links") as err:
        read(tmp_path / f"a{ext}")
    _one_line(err)
    with pytest.raises(FileNotFoundError, match="no such file"):
        read(tmp_path / f"missing{ext}")
    (tmp_path / f"dangling{ext}").symlink_to(tmp_path / "gone.nc")
    with pytest.raises(FileNotFoundError, match=r"a symbolic link to .*gone\.nc"):
        read(tmp_path / f"dangling{ext}")
    (tmp_path / f"folder{ext}").mkdir()
    with pytest.raises(ValueError, match=r"is a folder, but .* single file"):
        read(tmp_path / f"folder{ext}")
    (tmp_path / "file.zarr").write_text("not a store")
    with pytest.raises(ValueError, match=r"is a regular file, but a \.zarr store is a folder"):
        read(tmp_path / "file.zarr")


# -- 2. ENVI headers validated before use ----------------------------------------------------


def _envi(tmp_path, shape=(6, 5, 4)):
    hdr = tmp_path / "e.hdr"
    write_cube(make_cube(np.ones(shape, np.uint16), np.linspace(500, 800, shape[2])), hdr,
               overwrite=True)
    return hdr, tmp_path / "e.raw"


@pytest.mark.parametrize("old, new, message", [
    ("byte order = 0", "byte order = 7", r"'byte order = 7' must be 0 \(little-endian\) or 1"),
    ("byte order = 0", "byte order = big", r"'byte order = big' must be"),
    ("byte order = 0\n", "", "the header has no 'byte order'"),
    ("data type = 12", "data type = 99", r"'data type = 99' is not an ENVI data type snapcorr "
                                         r"can read \(1, 2, 3, 4, 5, 12, 13, 14, 15"),
    ("data type = 12", "data type = 6", r"'data type = 6' is complex64; a cube holds real"),
    ("data type = 12", "data type = 9", r"'data type = 9' is complex128"),
    ("data type = 12", "data type = 7", r"'data type = 7' is not an ENVI data type"),
    ("interleave = bsq", "interleave = xyz", "'interleave = xyz' must be bsq, bil or bip"),
    ("header offset = 0", "header offset = -5", "'header offset = -5' must be a whole number "
                                                ">= 0"),
    ("lines = 6", "lines = 0", "'lines = 0' must be a whole number > 0"),
    ("samples = 5", "samples = five", "'samples = five' must be a whole number > 0"),
    ("wavelength units = nm", "wavelength units = nm\nmajor frame offsets = {2, 0}",
     "'major frame offsets' are not supported"),
    ("file type = ENVI Standard", "file type = ENVI Spectral Library", "spectral library"),
])
@pytest.mark.parametrize("reader", ["read_cube", "read_flat", "read_frame"])
def test_bad_envi_headers_are_one_clear_line(tmp_path, capfd, old, new, message, reader):
    hdr, _ = _envi(tmp_path, shape=(6, 5, 1) if reader == "read_frame" else (6, 5, 4))
    text = hdr.read_text()
    assert old in text
    hdr.write_text(text.replace(old, new))
    with pytest.raises(ValueError, match=message) as err:
        READERS[reader](hdr)
    assert "KeyError" not in _one_line(err)
    assert capfd.readouterr().err == ""  # Spectral Python printed nothing of its own


def test_spectral_python_prints_nothing_for_odd_headers(tmp_path, capfd):
    hdr, _ = _envi(tmp_path)
    text = hdr.read_text()
    start, end = text.index("wavelength = {"), text.index("}", text.index("wavelength = {"))
    hdr.write_text(text[:start] + "Wavelength = {500, abc, 600, 700}" + text[end + 1:])
    with pytest.raises(ValueError, match="'wavelength' holds something that is not a number"):
        read_cube(hdr)
    assert capfd.readouterr().err == ""  # neither its log line nor its lower-case warning


def test_an_unreadable_or_missing_data_file_is_one_line(tmp_path, capfd, monkeypatch):
    import builtins

    hdr, raw = _envi(tmp_path)
    real_open = builtins.open

    def refusing_open(file, *args, **kwargs):  # as chmod 000 does for a user who is not root
        if Path(str(file)).name == "e.raw":
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", refusing_open)
    with pytest.raises(ValueError, match=r"cannot read its data file e\.raw: Permission "
                                         r"denied; check that it is readable") as err:
        read_cube(hdr)
    _one_line(err)
    monkeypatch.undo()
    raw.unlink()
    with pytest.raises(ValueError, match=r"no data file next to the header \(looked for e, "
                                         r"e\.img") as err:
        read_cube(hdr)
    _one_line(err)
    assert capfd.readouterr().err == ""


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_a_data_file_without_read_permission_is_one_line(tmp_path, capfd):
    hdr, raw = _envi(tmp_path)
    raw.chmod(0)
    try:
        with pytest.raises(ValueError, match="Permission denied") as err:
            read_cube(hdr)
        _one_line(err)
    finally:
        raw.chmod(0o644)
    assert capfd.readouterr().err == ""


# -- 4. and 10. cubes that cannot be held, on write and on read -----------------------------

BAD_DTYPES = [np.complex64, bool, object, "U3"]


@pytest.mark.parametrize("dtype", BAD_DTYPES, ids=str)
def test_make_and_check_cube_refuse_values_that_are_not_real_numbers(dtype):
    data = np.ones((2, 3, 4)).astype(dtype)
    with pytest.raises(TypeError, match=r"real numbers .* not .* values; .*astype"):
        make_cube(data, WL)
    with pytest.raises(TypeError, match="astype"):
        check_cube(xr.DataArray(data, dims=("y", "x", "band"), coords={"wavelength":
                                                                       ("band", WL)}))


@pytest.mark.parametrize("shape", [(0, 3, 4), (2, 0, 4), (2, 3, 0)])
def test_empty_cubes_are_refused(shape):
    with pytest.raises(ValueError, match="at least one value along every dim"):
        make_cube(np.ones(shape), WL[:shape[2]])


def test_repeated_wavelengths_are_refused():
    with pytest.raises(ValueError, match=r"repeats \[550.0\] nm"):
        make_cube(np.ones((2, 3, 4)), [500, 550, 550, 600])


def _raw_cube(data, wavelength):
    """A cube built without make_cube (as a user might with xarray alone)."""
    return xr.DataArray(data, dims=("y", "x", "band"), name="radiance",
                        coords={"wavelength": ("band", np.asarray(wavelength, float))})


@pytest.mark.parametrize("ext", [".hdr", ".tif", ".exr", ".nc", ".zarr", ".npy"])
@pytest.mark.parametrize("case, error, message", [
    ("repeats", ValueError, r"repeats \[550.0\] nm"),
    ("complex", TypeError, "not complex64 values"),
    ("bool", TypeError, "not bool values"),
    ("empty", ValueError, "no y"),
    ("micrometres", ValueError, "look like micrometres"),
])
def test_writers_refuse_invalid_cubes_before_writing_anything(tmp_path, ext, case, error,
                                                              message):
    data = np.ones((3, 4, 4), np.float32)
    wl = [500, 550, 600, 650]
    if case == "repeats":
        wl = [500, 550, 550, 650]
    elif case == "complex":
        data = data.astype(np.complex64)
    elif case == "bool":
        data = data.astype(bool)
    elif case == "empty":
        data = data[:0]
    elif case == "micrometres":
        wl = [0.5, 0.55, 0.6, 0.65]
    with pytest.raises(error, match=message) as err:
        write_cube(_raw_cube(data, wl), tmp_path / f"c{ext}")
    _one_line(err)
    assert not list(tmp_path.iterdir())


def _duplicate_exr(path):
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(4, 3, 2, "float")
    spec.channelnames = ("S0.500nm", "S0.500,0nm")
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    assert out.write_image(np.ones((3, 4, 2), np.float32))
    out.close()


@pytest.mark.parametrize("ext", [".exr", ".hdr", ".nc", ".zarr", ".npy"])
def test_files_with_repeated_wavelengths_are_refused_on_read(tmp_path, ext):
    path = tmp_path / f"d{ext}"
    if ext == ".exr":
        _duplicate_exr(path)
    elif ext == ".hdr":
        from spectral.io import envi

        envi.save_image(str(path), np.ones((3, 4, 2), np.float32), ext=".raw",
                        metadata={"wavelength": [500, 500], "wavelength units": "nm"})
    elif ext == ".npy":
        write_cube(_cube(np.float32, (3, 4, 2)), path)
        side = tmp_path / "d.npy.json"
        side.write_text(side.read_text().replace("550.0", "500.0"))
    else:
        ds = xr.Dataset({"radiance": (("y", "x", "band"), np.ones((3, 4, 2)))},
                        coords={"wavelength": ("band", [500.0, 500.0], {"units": "nm"})})
        ds.to_netcdf(path) if ext == ".nc" else ds.to_zarr(path, consolidated=False)
    with pytest.raises(ValueError, match=r"repeats \[500.0\] nm") as err:
        read_cube(path)
    _one_line(err)


# -- 8. overwrite never loses data -----------------------------------------------------------


def test_overwrite_replaces_only_what_snapcorr_wrote(tmp_path):
    cube = _cube()
    for ext in (".hdr", ".tif", ".exr", ".nc", ".zarr", ".npy"):
        path = write_cube(cube, tmp_path / f"c{ext}")
        with pytest.raises(FileExistsError, match="exists; choose another name or pass "
                                                  "overwrite=True"):
            write_cube(cube, path)
        write_cube(cube * 2, path, overwrite=True)
        np.testing.assert_array_equal(read_cube(path).values, cube.values * 2)
    ds = _cube().to_dataset()
    write_dataset(ds, tmp_path / "r.nc")
    write_dataset(ds, tmp_path / "r.nc", overwrite=True)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def _foreign(tmp_path, kind):
    """Something at the target path that snapcorr did not write."""
    if kind == "text.nc":
        (tmp_path / "out.nc").write_text("lab notes\n")
        return tmp_path / "out.nc", r"is a file that is not netCDF 4"
    if kind == "users.nc":
        xr.Dataset({"t": ("n", np.arange(3.0))}).to_netcdf(tmp_path / "out.nc")
        return tmp_path / "out.nc", "is a netCDF file without snapcorr's 'written_by'"
    if kind == "folder.zarr":
        (tmp_path / "out.zarr" / "holiday").mkdir(parents=True)
        (tmp_path / "out.zarr" / "thesis.tex").write_text("two years of work\n")
        return tmp_path / "out.zarr", r"holding other things than a Zarr store \(holiday, " \
                                      r"thesis.tex\)"
    if kind == "users.zarr":
        xr.Dataset({"t": ("n", np.arange(3.0))}).to_zarr(tmp_path / "out.zarr",
                                                        consolidated=False)
        return tmp_path / "out.zarr", "a Zarr store without snapcorr's 'written_by'"
    if kind == "file.zarr":
        (tmp_path / "out.zarr").write_text("not a store\n")
        return tmp_path / "out.zarr", "is a regular file; overwrite replaces only a Zarr store"
    if kind == "fifo.nc":
        os.mkfifo(tmp_path / "out.nc")
        return tmp_path / "out.nc", r"is a FIFO \(named pipe\); overwrite replaces only a file"
    if kind == "folder.nc":
        (tmp_path / "out.nc").mkdir()
        (tmp_path / "out.nc" / "keep.txt").write_text("keep\n")
        return tmp_path / "out.nc", "is a folder; overwrite replaces only a file"
    if kind == "users.hdr":
        from spectral.io import envi

        envi.save_image(str(tmp_path / "out.hdr"), np.ones((5, 6, 4), np.uint16), ext=".raw")
        return tmp_path / "out.hdr", "an ENVI header without snapcorr's 'snapcorr version'"
    if kind == "lonely.raw":
        (tmp_path / "out.raw").write_bytes(b"\0" * 240)
        return tmp_path / "out.hdr", r"out\.raw exists and is a data file without its header"
    if kind == "users.tif":
        import OpenImageIO as oiio

        out = oiio.ImageOutput.create(str(tmp_path / "out.tif"))
        assert out.open(str(tmp_path / "out.tif"), oiio.ImageSpec(6, 5, 4, "uint16"))
        assert out.write_image(np.ones((5, 6, 4), np.uint16))
        out.close()
        return tmp_path / "out.tif", "a TIFF image snapcorr did not write"
    if kind == "bare.npy":
        np.save(tmp_path / "out.npy", np.ones((5, 6, 4), np.uint16))
        return tmp_path / "out.npy", r"a \.npy file without snapcorr's sidecar out\.npy\.json"
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["text.nc", "users.nc", "folder.zarr", "users.zarr",
                                  "file.zarr", "fifo.nc", "folder.nc", "users.hdr",
                                  "lonely.raw", "users.tif", "bare.npy"])
@pytest.mark.parametrize("writer", ["write_cube", "write_dataset"])
def test_overwrite_never_replaces_what_snapcorr_did_not_write(tmp_path, kind, writer):
    target, message = _foreign(tmp_path, kind)
    if writer == "write_dataset" and target.suffix not in (".nc", ".zarr"):
        pytest.skip("write_dataset writes .nc and .zarr")
    before = _snapshot(tmp_path)
    with deadline(60), pytest.raises(ValueError, match=message) as err:
        if writer == "write_cube":
            write_cube(_cube(), target, overwrite=True)
        else:
            write_dataset(_cube().to_dataset(), target, overwrite=True)
    assert "move it away or choose another name" in _one_line(err)
    assert _snapshot(tmp_path) == before


def test_outputs_never_touch_inputs_or_their_companions(tmp_path):
    cube = _cube()
    write_cube(cube, tmp_path / "scene.hdr")
    write_cube(cube, tmp_path / "c.npy")
    store = write_cube(cube, tmp_path / "in.zarr")
    box = tmp_path / "box.zarr"
    box.mkdir()
    np.save(box / "raw.npy", cube.values)
    (tmp_path / "link.nc").symlink_to(tmp_path / "scene.raw")
    (tmp_path / "other.raw").symlink_to(tmp_path / "scene.raw")  # a data file shared by link
    os.link(tmp_path / "c.npy", tmp_path / "hard.npy")
    before = _snapshot(tmp_path)
    cases = [
        (lambda: write_cube(cube, tmp_path / "scene.hdr", overwrite=True,
                            inputs=[tmp_path / "scene.raw"]), r"scene\.hdr is also an input"),
        (lambda: write_cube(cube, tmp_path / "other.hdr", overwrite=True,
                            inputs=[tmp_path / "scene.hdr"]), r"other\.raw is also an input"),
        (lambda: write_cube(cube, tmp_path / "c.npy", overwrite=True,
                            inputs=[tmp_path / "c.npy"]), r"c\.npy is also an input"),
        (lambda: write_dataset(cube.to_dataset(), box, overwrite=True,
                               inputs=[box / "raw.npy"]), r"box\.zarr contains the input"),
        (lambda: write_dataset(cube.to_dataset(), store / "inside.nc",
                               inputs=[store]), r"inside\.nc lies inside the input"),
        (lambda: write_cube(cube, tmp_path / "link.nc", overwrite=True,
                            inputs=[tmp_path / "scene.hdr"]), r"link\.nc is also an input"),
        (lambda: write_cube(cube, tmp_path / "hard.npy", overwrite=True,
                            inputs=[tmp_path / "c.npy"]), r"hard\.npy is also an input"),
    ]
    for write, message in cases:
        with pytest.raises(ValueError, match=message) as err:
            write()
        _one_line(err)
        assert _snapshot(tmp_path) == before


def test_an_envi_header_is_not_written_beside_another_data_file(tmp_path):
    with pytest.raises(ValueError, match=r"written by its header's name: .*s\.hdr"):
        write_cube(_cube(), tmp_path / "s.raw")
    (tmp_path / "s.img").write_bytes(b"\0" * 240)
    before = _snapshot(tmp_path)
    with pytest.raises(ValueError, match=r"s\.img exists next to s\.hdr, and ENVI readers "
                                         r"would take it"):
        write_cube(_cube(), tmp_path / "s.hdr")
    assert _snapshot(tmp_path) == before


def _failing(ds):
    """``ds`` with a lazy variable whose second block fails when written."""
    import dask.array as da

    def block(x, block_info=None):
        if block_info[0]["chunk-location"][0] == 1:
            raise OSError("disk full")
        return x

    bad = da.ones((4, 3), chunks=(2, 3)).map_blocks(block, dtype=float)
    return ds.assign(late=(("a", "b"), bad))


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_a_failed_overwrite_leaves_the_old_result_in_place(tmp_path, ext):
    path = tmp_path / f"r{ext}"
    old = _cube().to_dataset()
    write_dataset(old, path)
    before = _snapshot(tmp_path)
    registered = set(safety.temporary_paths())
    with pytest.raises(OSError, match="disk full"):
        write_dataset(_failing(_cube(np.float32).to_dataset()), path, overwrite=True)
    assert _snapshot(tmp_path) == before
    assert set(safety.temporary_paths()) == registered
    name = next(iter(old.data_vars))  # an integer cube: "raw"
    xr.testing.assert_equal(read_dataset(path)[name], old[name])


def test_replacing_a_group_moves_old_files_back_on_failure(tmp_path, monkeypatch):
    cube = _cube()
    write_cube(cube, tmp_path / "e.hdr")
    before = _snapshot(tmp_path)
    real = os.rename
    calls = []

    def rename(src, dst):  # fail when the second new file would move in
        calls.append((src, dst))
        if len(calls) == 4:
            raise OSError("device went away")
        return real(src, dst)

    monkeypatch.setattr(os, "rename", rename)
    with pytest.raises(OSError, match="device went away"):
        write_cube(cube * 3, tmp_path / "e.hdr", overwrite=True)
    monkeypatch.undo()
    assert _snapshot(tmp_path) == before


def test_atomic_writes_never_replace_a_folder_by_a_file_or_a_file_by_a_folder(tmp_path):
    (tmp_path / "plot.png").mkdir()
    (tmp_path / "plot.png" / "keep.txt").write_text("keep")
    (tmp_path / "store.zarr").write_text("a file")
    before = _snapshot(tmp_path)
    with pytest.raises(ValueError, match=r"plot\.png exists and is a folder; it is not "
                                         r"replaced by a file"):
        safety.atomic_write(tmp_path / "plot.png", lambda tmp: tmp.write_text("png"))
    with pytest.raises(ValueError, match=r"store\.zarr exists and is a regular file"):
        safety.atomic_write_dir(tmp_path / "store.zarr", lambda tmp: None)
    assert _snapshot(tmp_path) == before


def test_what_appears_at_the_output_during_the_write_is_never_replaced(tmp_path):
    """The final move replaces only what was there when the write began: a file, a folder or
    a group member that appears meanwhile (another program, a second writer) is kept, the new
    output is discarded, and no temporary is left."""
    def appears(target, make):
        def write(tmp):
            make(target)
            if tmp.is_dir():
                (tmp / "zarr.json").write_text("{}")
            else:
                tmp.write_text("new")
        return write

    def folder(t):
        t.mkdir()
        (t / "thesis.tex").write_text("years of work")

    def file(t):
        t.write_text("someone else's")

    write, write_dir = safety.atomic_write, safety.atomic_write_dir
    cases = [(write, "out.png", file), (write, "out.png", folder),
             (write_dir, "out.zarr", folder), (write_dir, "out.zarr", file)]
    for i, (writer, name, make) in enumerate(cases):
        target = tmp_path / str(i) / name
        target.parent.mkdir()
        with pytest.raises((FileExistsError, ValueError), match="out"):
            writer(target, appears(target, make))
        kept = (target / "thesis.tex").read_text() if target.is_dir() else target.read_text()
        assert kept in ("years of work", "someone else's")
        assert sorted(p.name for p in target.parent.iterdir()) == [name]  # no temporary
    # a header and its data: the data file appears during the write
    hdr, raw = tmp_path / "g.hdr", tmp_path / "g.raw"

    def write_group(folder):
        raw.write_text("someone else's data")
        (folder / "g.hdr").write_text("ENVI")
        (folder / "g.raw").write_text("ours")

    with pytest.raises(FileExistsError, match="appeared while the output was written"):
        safety.atomic_write_files([raw, hdr], write_group)
    assert raw.read_text() == "someone else's data" and not hdr.exists()


def test_a_checked_output_swapped_during_the_write_is_put_back(tmp_path):
    """An output that existed (and was checked) is replaced only if it is still the same file:
    swapped for another one meanwhile, the other one is put back untouched."""
    target = tmp_path / "table.csv"
    target.write_text("old table")

    def write(tmp):
        target.unlink()
        target.write_text("a new file the user put there")
        tmp.write_text("new table")

    with pytest.raises(FileExistsError, match="changed while the output was written"):
        safety.atomic_write(target, write)
    assert target.read_text() == "a new file the user put there"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]
    # unchanged, it is replaced as before
    safety.atomic_write(target, lambda tmp: tmp.write_text("new table"))
    assert target.read_text() == "new table"


def test_an_interrupted_final_move_leaves_neither_reservation_nor_temporary(tmp_path,
                                                                          monkeypatch):
    """Interrupted between reserving a store's name and moving the store in: the empty
    reservation is removed with the temporary, and nothing is left."""
    real = os.rename

    def rename(src, dst):
        if Path(dst).name == "out.zarr":
            raise KeyboardInterrupt
        return real(src, dst)

    monkeypatch.setattr(os, "rename", rename)
    with pytest.raises(KeyboardInterrupt):
        safety.atomic_write_dir(tmp_path / "out.zarr", lambda tmp: (tmp / "zarr.json").write_text(
            "{}"))
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []


def test_two_writers_of_one_output_never_both_succeed(tmp_path):
    """The second writer to finish finds the first one's output and fails; the first stays."""
    cube = _cube()
    out = tmp_path / "c.nc"

    def slow_second(tmp):  # the first writer finishes while the second is still writing
        write_cube(cube, out)
        tmp.write_text("second")

    with pytest.raises(FileExistsError, match="second snapcorr writing the same output"):
        safety.atomic_write(out, slow_second)
    assert np.array_equal(read_cube(out).values, cube.values)


# -- 9. temporary files on signals -----------------------------------------------------------


def test_atomic_write_removes_its_temporary_on_keyboard_interrupt(tmp_path):
    def write(tmp):
        tmp.write_bytes(b"half")
        raise KeyboardInterrupt

    registered = set(safety.temporary_paths())
    with pytest.raises(KeyboardInterrupt):
        safety.atomic_write(tmp_path / "x.nc", write)
    assert not list(tmp_path.iterdir()) and set(safety.temporary_paths()) == registered


def test_the_registry_holds_only_temporaries_that_exist(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # relative paths, as the command line gives them
    registered = set(safety.temporary_paths())
    cube = _cube()
    for name in ("c.nc", "c.zarr", "c.hdr", "c.npy", "c.tif"):
        write_cube(cube, name)
        write_cube(cube, name, overwrite=True)
    assert set(safety.temporary_paths()) == registered
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_cleanup_on_signals_turns_sigterm_into_an_interrupt_and_cleans_up(tmp_path):
    before = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)}
    left = tmp_path / ".left.x"
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"), safety.cleanup_on_signals():
        left.write_text("partial")
        safety._register(left)
        assert signal.getsignal(signal.SIGTERM) is not before[signal.SIGTERM]
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # interrupted long before
    assert not left.exists() and safety._key(left) not in map(str, safety.temporary_paths())
    assert {s: signal.getsignal(s) for s in before} == before
    folder = tmp_path / ".left.zarr"
    with safety.cleanup_on_signals():  # leaving normally cleans up too
        (folder / "c").mkdir(parents=True)
        safety._register(folder)
    assert not folder.exists()


@pytest.mark.parametrize("kind", ["file", "folder"])
def test_a_signal_as_the_temporary_is_created_leaves_nothing(tmp_path, monkeypatch, kind):
    """A handler runs between any two steps: here just after the temporary is created,
    before the function creating it has returned."""
    create = "open" if kind == "file" else "mkdir"
    real = getattr(os, create)

    def created_then_interrupted(path, *args, **kwargs):
        result = real(path, *args, **kwargs)
        if os.path.basename(os.fspath(path)).startswith(".x."):
            monkeypatch.setattr(os, create, real)
            raise KeyboardInterrupt("SIGTERM received")
        return result

    monkeypatch.setattr(os, create, created_then_interrupted)
    registered = set(safety.temporary_paths())
    write = safety.atomic_write if kind == "file" else safety.atomic_write_dir
    with pytest.raises(KeyboardInterrupt):
        write(tmp_path / ("x.nc" if kind == "file" else "x.zarr"), lambda tmp: None)
    assert not list(tmp_path.iterdir()) and set(safety.temporary_paths()) == registered


class _SignalledWhenCollected:
    """An object in a reference cycle whose finalizer a signal interrupts: the garbage
    collector runs it in the middle of any work (a progress bar left from an earlier step,
    collected while a module is imported during a write)."""

    def __init__(self, signum):
        self.signum, self.cycle = signum, self

    def __del__(self):
        signal.raise_signal(self.signum)  # its handler runs here, inside the finalizer


def _collect_during_a_signal(signum):
    _SignalledWhenCollected(signum)
    gc.collect()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupt_that_comes_while_a_finalizer_runs_is_not_lost(signum):
    """Python drops an exception raised in a finalizer: the interrupt must come again."""
    with pytest.raises(KeyboardInterrupt, match=signal.Signals(signum).name), \
            safety.cleanup_on_signals():
        _collect_during_a_signal(signum)
        for _ in range(500):  # 5 s
            time.sleep(0.01)


def test_no_output_is_moved_in_after_a_signal_whose_interrupt_was_lost(tmp_path, monkeypatch):
    """Whatever swallowed the interrupt, a write that ends after the signal is discarded."""
    monkeypatch.setattr(safety, "_deliver_again", lambda signum: None, raising=False)
    out = tmp_path / "x.txt"
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"), safety.cleanup_on_signals():
        _collect_during_a_signal(signal.SIGTERM)
        safety.atomic_write(out, lambda tmp: tmp.write_text("written after the signal"))
    assert not list(tmp_path.iterdir())
    safety.atomic_write(out, lambda tmp: tmp.write_text("a later command"))  # not held
    assert out.read_text() == "a later command"


def _sigint_default():
    """In the child: Ctrl-C as a terminal sends it. A shell starts background jobs with
    SIGINT ignored, and Python then installs no KeyboardInterrupt handler."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


SCRIPT = textwrap.dedent("""
    import faulthandler
    import signal
    import sys
    import time

    import dask.array as da
    import xarray as xr

    from snapcorr.files.safety import cleanup_on_signals
    from snapcorr.cube import write_dataset


    def stalled(block, block_info=None):
        # from the fifth block on, the write waits: the signal always comes in the middle of
        # it, however busy the machine is (96 blocks of 3 s each); a block already started
        # when the signal comes delays the exit by its 3 s at most
        if block_info[0]["chunk-location"][0] >= 4:
            time.sleep(3)
        return block


    faulthandler.register(signal.SIGUSR1, all_threads=True)  # where a stalled exit waits


    data = da.random.random((5000, 1000, 20), chunks=(50, 1000, 20)).astype("float32")
    data = data.map_blocks(stalled, dtype="float32")
    ds = xr.Dataset({"radiance": (("y", "x", "band"), data)})
    with cleanup_on_signals():
        write_dataset(ds, sys.argv[1])
""")


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_write_leaves_no_temporary(tmp_path, ext, signum):
    script = tmp_path / "write.py"
    script.write_text(SCRIPT)
    out = tmp_path / "work"
    out.mkdir()
    proc = subprocess.Popen([sys.executable, str(script), str(out / f"big{ext}")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=_sigint_default)
    try:
        deadline = time.monotonic() + 120  # a guard only: the machine may be busy
        while not any(p.name.startswith(".") for p in out.iterdir()):
            assert proc.poll() is None, proc.communicate()[1].decode()[-2000:]
            assert time.monotonic() < deadline, "no temporary appeared"
            time.sleep(0.01)
        proc.send_signal(signum)
        try:
            _, err = proc.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGUSR1)
            time.sleep(2)
            proc.kill()
            pytest.fail("the interrupted write did not end; its threads were at:\n"
                        + proc.communicate()[1].decode()[-6000:])
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode != 0
    assert "KeyboardInterrupt" in err.decode()
    assert not list(out.iterdir()), [p.name for p in out.iterdir()]
