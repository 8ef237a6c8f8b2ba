"""An output that cannot be written (its folder read-only, missing, or a file) is refused by
every command before any work and before any output is written, naming the option and the
path; never found at the write, by a hidden temporary's name."""

from __future__ import annotations

import pytest
from hostile import FF, LENS, assert_refused, correct_args, read_only, save_cubes


def _flatfield(folder):
    save_cubes(folder, shape=(4, 5, 4))
    return FF, {"--out": "o.nc", "--plot": "o.png"}


def _correct(folder):
    save_cubes(folder, shape=(4, 5, 4))
    return correct_args("raw.npy", "o.nc")[:-2], {"--out": "o.nc", "--plot": "o.png"}


def _sensor(folder):
    return ("sensor", "snapscan_vnir"), {"--toml": "s.toml", "--plot": "s.png"}


def _budget(folder):
    return (("budget", "--sensor", "snapscan_vnir", "--lens", LENS, "--f-number", "2",
             "--source", "solar", "--cra-max", "5"), {"--plot": "b.png"})


#: Each command: its inputs made in a folder, its arguments but the outputs, {option: name}.
COMMANDS = {"flatfield": _flatfield, "correct": _correct, "sensor": _sensor, "budget": _budget}


def _args(outputs, where):
    """The output options, the one named ``where`` in the folder ``ro``."""
    out = []
    for option, name in outputs.items():
        out += [option, f"ro/{name}" if option == where else name]
    return out


CASES = [("flatfield", "--out"), ("flatfield", "--plot"), ("correct", "--out"),
         ("correct", "--plot"), ("sensor", "--toml"), ("sensor", "--plot"),
         ("budget", "--plot")]


@pytest.mark.parametrize(("command", "option"), CASES)
def test_a_read_only_output_folder_is_refused_before_any_write(tmp_path, monkeypatch, cli,
                                                              command, option):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ro").mkdir()
    before, outputs = COMMANDS[command](tmp_path)
    read_only(monkeypatch, tmp_path / "ro")
    rc, out, err = cli(*before, *_args(outputs, option))
    line = assert_refused(rc, err, option, f"ro/{outputs[option]}", "write")
    assert "/." not in line, f"a hidden temporary is named: {line}"
    written = [n for o, n in outputs.items() if o != option and (tmp_path / n).exists()]
    assert not written, f"written before the refusal: {written}"
    assert not out.strip() or "wrote" not in out, out


@pytest.mark.parametrize("kind", ["missing", "file"])
@pytest.mark.parametrize(("command", "option"), [("correct", "--plot"), ("sensor", "--toml"),
                                                 ("budget", "--plot")])
def test_an_output_folder_that_is_missing_or_a_file_names_the_option(tmp_path, monkeypatch, cli,
                                                                     command, option, kind):
    monkeypatch.chdir(tmp_path)
    if kind == "file":
        (tmp_path / "ro").write_text("not a folder")
    before, outputs = COMMANDS[command](tmp_path)
    rc, _, err = cli(*before, *_args(outputs, option))
    assert_refused(rc, err, option, f"ro/{outputs[option]}",
                   "does not exist" if kind == "missing" else "not a folder")
    assert not any((tmp_path / n).exists() for n in outputs.values())


def test_demo_refuses_a_read_only_folder_before_any_work(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ro").mkdir()
    read_only(monkeypatch, tmp_path / "ro")
    rc, out, err = cli("demo", "--out", "ro/demo")
    assert_refused(rc, err, "--out", "ro/demo", "write")
    assert not out.strip(), f"work was done first: {out}"


def test_stream_refuses_a_read_only_folder_before_reading(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ro").mkdir()
    read_only(monkeypatch, tmp_path / "ro")
    rc, _, err = cli("stream", "missing_frames", "--dark", "d.npy", "--white", "w.npy",
                     "--sensor", "mosaic_4x4_vis", "--out", "ro/s.zarr")
    assert_refused(rc, err, "--out", "ro/s.zarr", "write")


LONG = "n" * 300  # past any file system's 255 bytes a name


@pytest.mark.parametrize("bad", ["suffix", "long", "proc"])
@pytest.mark.parametrize(("command", "option"), CASES)
def test_every_refused_output_names_its_option(tmp_path, monkeypatch, cli, command, option,
                                               bad):
    """A wrong suffix and a name too long were said without the option (or as a bare
    ``[Errno 36]``), and a folder that exists but cannot hold files (/proc) was said not to
    exist."""
    monkeypatch.chdir(tmp_path)
    before, outputs = COMMANDS[command](tmp_path)
    name = outputs[option]
    given = {"suffix": name + ".txt", "long": LONG + name, "proc": f"/proc/{name}"}[bad]
    args = []
    for o, n in outputs.items():
        args += [o, given if o == option else n]
    rc, _, err = cli(*before, *args)
    line = assert_refused(rc, err, option)
    assert {"suffix": "must end in", "long": "too long", "proc": "cannot write"}[bad] in line
    assert "Errno" not in line and "does not exist" not in line, line
    assert not any((tmp_path / n).exists() for n in outputs.values())


def test_demo_names_its_option_for_a_name_too_long(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    rc, _, err = cli("demo", "--out", LONG)
    line = assert_refused(rc, err, "--out", "too long")
    assert "Errno" not in line
