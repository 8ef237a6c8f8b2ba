"""Library messages the command line used to pass on in the library's words: a keyword that
carries a unit the option leaves out (``cra_deg`` for ``--cra``), a keyword followed by its
value, and a flat-field reference named by its place instead of its option and file."""

from __future__ import annotations

import numpy as np
import pytest
from hostile import assert_refused, save_cubes, write_envi

from snapcorr.cli import build_parser
from snapcorr.cli._errors import _message, command_parser, name_references, option_names


def _options(command):
    return option_names(command_parser(build_parser(), command))


@pytest.mark.parametrize("command, keyword, option", [
    ("shift", "cra_deg", "--cra"), ("budget", "cra_max_deg", "--cra-max"),
    ("shift", "n_eff", "--n-eff"), ("correct", "tolerance_nm", "--tolerance-nm"),
])
def test_a_keyword_with_the_unit_the_option_leaves_out_names_the_option(command, keyword,
                                                                        option):
    options = _options(command)
    assert options[keyword] == option
    message = _message(ValueError(f"{keyword} must lie in [0, 36.21) deg, got 95.0"), options)
    assert message == f"{option} must lie in [0, 36.21) deg, got 95.0"


def test_a_keyword_followed_by_its_value_names_the_option():
    """``target_fwhm_nm 0.5 nm is narrower ...`` reached the user as it was."""
    message = _message(ValueError("target_fwhm_nm 0.5 nm is narrower than the widest"),
                       _options("correct"))
    assert message == "--target-fwhm-nm 0.5 nm is narrower than the widest"
    # a message that only begins with a word of an option's name is left alone
    assert _message(ValueError("lens profile not found: x.toml"), _options("correct")) == \
        "lens profile not found: x.toml"


def test_shift_names_cra_for_a_nan_angle(cli, tmp_path):
    res = cli("shift", "--f-number", "2", "--cra", "nan", cwd=tmp_path)
    line = assert_refused(res.returncode, res.stderr, "--cra must be finite")
    assert "cra_deg" not in line


@pytest.mark.parametrize("message, expected", [
    ("white frame 2 of 2 and the cube have different wavelengths",
     "--white w2.hdr and the cube have different wavelengths"),
    ("dark has shape (12, 8, 4) but the cube (12, 10, 4)",
     "--dark d.npy has shape (12, 8, 4) but the cube (12, 10, 4)"),
    ("the white reference has 20 rows but the cube 12",
     "the --white reference has 20 rows but the cube 12"),
    ("dark frames differ in shape: (1, 2, 3) and (1, 2, 4)",
     "--dark frames (d.npy) differ in shape: (1, 2, 3) and (1, 2, 4)"),
    ("darkness is not a reference", "darkness is not a reference"),
])
def test_a_reference_is_named_by_its_option_and_file(message, expected):
    files = {"dark": ["d.npy"], "white": ["w1.hdr", "w2.hdr"]}
    assert name_references(message, files) == expected


def test_a_second_white_of_other_wavelengths_names_its_file(cli, tmp_path):
    """The library checks every frame (the command line's own copy of the check, which
    looked at shapes only, is gone); it said 'white frame 2 of 2', no option, no file."""
    save_cubes(tmp_path)
    white = np.full((12, 10, 4), 400.0, np.float32)
    write_envi(tmp_path / "w_same", white, wavelength=[500, 520, 540, 560])
    write_envi(tmp_path / "w_other", white, wavelength=[600, 620, 640, 660])
    res = cli("flatfield", "raw.npy", "--sensor", "sensor.toml", "--dark", "dark.npy",
              "--white", "w_same.hdr", "--white", "w_other.hdr", "--out", "o.nc", cwd=tmp_path)
    assert_refused(res.returncode, res.stderr, "--white w_other.hdr and the cube have "
                   "different wavelengths")
    np.save(tmp_path / "dark8.npy", np.full((12, 8, 4), 10.0, np.float32))
    res = cli("flatfield", "raw.npy", "--sensor", "sensor.toml", "--dark", "dark8.npy",
              "--white", "white.npy", "--out", "o.nc", cwd=tmp_path)
    assert_refused(res.returncode, res.stderr, "--dark dark8.npy has shape (12, 8, 4) but the "
                   "cube (12, 10, 4): x and band must match")
    assert not (tmp_path / "o.nc").exists()


@pytest.mark.parametrize("command", ["sensor", "stream"])
def test_a_cube_given_for_a_frame_is_told_in_command_line_terms(cli, tmp_path, command):
    """``read it with read_cube`` reached a command-line user, who has no read_cube."""
    np.save(tmp_path / "cube3.npy", np.ones((64, 64, 3), np.uint16))
    if command == "sensor":
        args = ("sensor", "imec_5x5_nir", "--phase-from", "cube3.npy")
    else:
        (tmp_path / "frames").mkdir()
        np.save(tmp_path / "frames" / "f1.npy", np.ones((64, 64, 3), np.uint16))
        np.save(tmp_path / "dark.npy", np.full((64, 64), 100, np.uint16))
        np.save(tmp_path / "white.npy", np.full((64, 64), 3500, np.uint16))
        args = ("stream", "frames", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
                "mosaic_4x4_vis", "--sensor-origin-px", "0,0", "--out", "s.zarr")
    rc, _, err = cli(*args, cwd=tmp_path)
    line = assert_refused(rc, err, "3 bands", "give the camera's raw 2-D frame")
    assert "read_cube" not in line


def test_a_message_of_megabytes_is_cut_before_it_is_rewritten():
    """A library message quoting ten megabytes of a file was rewritten whole (33 s for the
    correct command's 161 keywords, the line 10 MB long): it is cut first, the start said as
    it was, with how much was left out; the rewriting still applies to what is said."""
    from snapcorr.cli._errors import MESSAGE_MAX

    text = "n_eff must be finite, got '" + "1" * 10 * 2**20 + "'"
    message = _message(ValueError(text), _options("shift"))
    assert message.startswith("--n-eff must be finite, got '111")
    assert len(message) < MESSAGE_MAX + 100
    head, tail = MESSAGE_MAX * 3 // 4, MESSAGE_MAX // 4
    assert f"({len(text) - head - tail:,} characters left out) ..." in message
    # the end is kept: where a message quoting a long value says what is wrong with it
    cause = _message(ValueError("x" * 10_000 + ": this is the cause"), {})
    assert cause.endswith(": this is the cause") and len(cause) < MESSAGE_MAX + 100
    # a message of ordinary length is said whole
    assert _message(ValueError("x" * MESSAGE_MAX), {}) == "x" * MESSAGE_MAX


def test_a_vendor_file_with_megabytes_of_digits_is_one_short_line(tmp_path, cli):
    """<width> of ten megabytes of '1' took 33 s and printed a line of 10,485,844 bytes."""
    from conftest import VENDOR_XML

    text = VENDOR_XML.read_text(encoding="utf-8")
    assert "<width>2048</width>" in text
    (tmp_path / "x.xml").write_text(text.replace("<width>2048</width>",
                                                 "<width>" + "1" * 10 * 2**20 + "</width>", 1))
    rc, _, err = cli("sensor", "x.xml", cwd=tmp_path)
    line = assert_refused(rc, err, "x.xml", "<sensor_info/width>", "10,485,760 characters")
    assert len(err) < 300 and "1" * 30 in line, err[:400]


def test_a_damaged_zarr_chunk_is_said_in_a_users_words(tmp_path):
    """A shard whose index bytes were damaged (a truncated or corrupted copy): zarr's 'Stored
    and computed checksum do not match. Stored: b'...'' said neither what nor why."""
    import pathlib

    import zarr

    from snapcorr.cli._errors import _message

    root = zarr.open_group(tmp_path / "s.zarr", mode="w", zarr_format=3)
    a = root.create_array("raw", shape=(8, 16, 16), chunks=(1, 16, 16), shards=(4, 16, 16),
                          dtype="uint16")
    a[:] = np.arange(8 * 256, dtype="uint16").reshape(8, 16, 16)
    shard = sorted(p for p in pathlib.Path(tmp_path / "s.zarr" / "raw").rglob("*")
                   if p.is_file() and p.name != "zarr.json")[0]
    data = bytearray(shard.read_bytes())
    data[-10] ^= 0xFF  # inside the shard's index, which carries a checksum
    shard.write_bytes(bytes(data))
    try:
        zarr.open_group(tmp_path / "s.zarr", mode="r")["raw"][:]
    except ValueError as err:
        said = _message(err)
    else:
        raise AssertionError("the damaged shard was read")
    assert said.startswith("a chunk of an input Zarr store is damaged: its stored checksum")


def test_a_name_too_long_for_the_file_system_is_said_so(tmp_path):
    """A 300-character file name gave Python's bare '[Errno 36] File name too long: ...'."""
    from conftest import run_cli

    np.save(tmp_path / "w.npy", np.ones((8, 8), np.uint16))
    code, _, err = run_cli("flatfield", "w.npy", "--dark", "d" * 300 + ".npy", "--white",
                           "w.npy", "--out", "o.nc", cwd=tmp_path)
    assert code == 1 and len(err.strip().splitlines()) == 1, err
    assert "a name in this path is too long for the file system (at most 255 bytes a name, " \
           "304 here)" in err and "Errno" not in err, err


def test_a_path_too_long_with_short_names_is_said_so_not_its_names(tmp_path):
    """A path of 5 000 bytes whose every name is 200 bytes long was said to have "a name too
    long (at most 255 bytes a name, 200 here)"; as an output, the cause was cut off the line."""
    from conftest import run_cli

    np.save(tmp_path / "w.npy", np.ones((8, 8), np.uint16))
    deep = str(tmp_path / "/".join(["a" * 200] * 25))
    for args in (("flatfield", deep + "/w.npy", "--dark", "w.npy", "--white", "w.npy",
                  "--out", "o.nc"),
                 ("flatfield", "w.npy", "--dark", "w.npy", "--white", "w.npy", "--out",
                  deep + "/o.nc")):
        code, _, err = run_cli(*args, cwd=tmp_path)
        assert code == 1 and len(err.strip().splitlines()) == 1, err
        assert "this path is too long for the file system (at most" in err, err
        assert "every name in it short enough" in err and len(err) < 600, err


def test_a_truncated_chunk_of_a_raw_store_is_one_line_in_a_real_process(tmp_path):
    """Blosc's RuntimeError ("error during blosc decompression: -1") escaped the command line
    as a 118-line traceback when flatfield met a truncated chunk of its raw store; with zarr's
    pending reads said at exit too."""
    import subprocess
    import sys

    from snapcorr.cube import Sensor, make_cube, write_cube

    rng = np.random.default_rng(0)
    for name, level in (("raw", 1500), ("dark", 100), ("white", 3000)):
        counts = (level + rng.random((24, 32, 6)) * 10).astype("uint16")
        write_cube(make_cube(counts, np.linspace(500, 900, 6), name="counts").chunk({"y": 8}),
                   tmp_path / f"{name}.zarr")
    Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 6), 10.0, 1.7).save(tmp_path / "s.toml")
    chunk = tmp_path / "raw.zarr" / "counts" / "c" / "2" / "0" / "0"
    chunk.write_bytes(chunk.read_bytes()[:100])
    res = subprocess.run([sys.executable, "-m", "snapcorr", "flatfield", "raw.zarr", "--dark",
                          "dark.zarr", "--white", "white.zarr", "--sensor", "s.toml", "--out",
                          "ff.nc"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert res.returncode == 1
    assert res.stderr.startswith("snapcorr flatfield: error: a chunk of an input cannot be "
                                 "decoded"), res.stderr[-2000:]
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr[-2000:]
    assert not (tmp_path / "ff.nc").exists()


def test_a_chunk_that_does_not_fit_its_array_is_said_of_the_store():
    """A chunk copied in from another array, not the first (which is checked on opening):
    numpy's "cannot reshape array of size 768 into shape (8,32,6)" named neither cause nor
    store."""
    said = _message(ValueError("cannot reshape array of size 768 into shape (8,32,6)"), {})
    assert said.startswith("a chunk of an input Zarr store does not hold what its metadata "
                           "says (cannot reshape array of size 768")
