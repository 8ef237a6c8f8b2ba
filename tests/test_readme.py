"""The README's examples run as written, and its command lines only use options that exist."""

import argparse
import fnmatch
import re
import shlex
from pathlib import Path

import matplotlib
import pytest
from conftest import NO_X_FIRST_CENTER

from snapcorr.cli import build_parser
from snapcorr.data import lens_path, sensor_path

matplotlib.use("Agg")

README = Path(__file__).resolve().parents[1] / "README.md"
FENCE = re.compile(r"^```(\w*)([^\n]*)\n(.*?)^```", re.M | re.S)
OPTION = re.compile(r"(?<![\w-])(?:--[a-z][a-z0-9-]*|-[a-zA-Z](?![\w-]))")
#: Options the parser still takes but the README must not show (deprecated forms).
DEPRECATED = {"--center-px", "--pupil"}  # earlier names, still taken


def blocks(language, walkthrough=None):
    """The README's blocks in ``language``; ``walkthrough`` True or False: only those marked
    (```` ```python walkthrough ````, run by ``tests/test_readme_walkthrough.py``) or only
    the others; None: all."""
    return [body for lang, info, body in FENCE.findall(README.read_text()) if lang == language
            and (walkthrough is None or ("walkthrough" in info.split()) == walkthrough)]


def command_lines(text):
    """Lines of a shell block with backslash continuations joined."""
    return re.sub(r"\\\n\s*", " ", text).splitlines()


def snapcorr_commands():
    """Every ``snapcorr ...`` command in the README's bash blocks (``&&`` chains split)."""
    found = []
    for block in blocks("bash"):
        for line in command_lines(block):
            for part in line.split("&&"):
                words = shlex.split(part, comments=True)
                if words[:1] == ["snapcorr"] and words[1:] != ["--help"]:
                    found.append(words[1:])
    return found


@pytest.mark.filterwarnings(NO_X_FIRST_CENTER)
def test_python_blocks_run_in_order_from_any_folder(tmp_path, monkeypatch):
    """Each block in turn, in one namespace, in an empty folder (not the repository)."""
    import matplotlib.pyplot as plt

    code = blocks("python", walkthrough=False)
    assert len(code) >= 4, "the README's python examples went missing"
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__readme__"}
    try:
        for i, block in enumerate(code, 1):
            exec(compile(block, f"README.md python block {i}", "exec"), namespace)
    finally:
        plt.close("all")
    patterns = [line.strip().rstrip("/") for line in
                (README.parent / ".gitignore").read_text().splitlines()]
    stray = [p.name for p in tmp_path.iterdir()
             if not any(fnmatch.fnmatch(p.name, pat) for pat in patterns if pat)]
    assert not stray, f"the README's examples write files .gitignore does not list: {stray}"


def test_readme_command_lines_parse():
    commands = snapcorr_commands()
    assert {c[0] for c in commands} >= {"demo", "budget", "calibrate"}
    parser = build_parser()
    for words in commands:
        try:
            parser.parse_args(words)
        except SystemExit:
            pytest.fail(f"the README shows a command the CLI refuses: snapcorr {shlex.join(words)}")


def subcommands():
    parser = build_parser()
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def synopsis_options():
    """``{subcommand: options shown}`` from the first block of the "Command line" section; a
    line starting ``snapcorr SUB`` opens SUB, the lines after it continue it."""
    section = README.read_text().split("\n## Command line\n", 1)[1]
    synopsis = FENCE.search(section).group(3)
    shown, command = {}, None
    for line in synopsis.splitlines():
        words = line.split()
        if words[:1] == ["snapcorr"] and len(words) > 1 and not words[1].startswith("-"):
            command = words[1]
        if command is not None:
            shown.setdefault(command, set()).update(OPTION.findall(line))
    return shown


def parser_options(subparser):
    """Every option string of a subcommand but help and the deprecated forms."""
    return {o for action in subparser._actions for o in action.option_strings
            if o not in ("-h", "--help") and o not in DEPRECATED}


def test_command_line_synopsis_names_real_options():
    """Every option in the "Command line" synopsis belongs to its subcommand, and none is a
    deprecated form."""
    choices = subcommands()
    shown = synopsis_options()
    assert set(shown) == set(choices), "the synopsis misses a subcommand or names one that is not"
    for command, options in shown.items():
        known = set(choices[command]._option_string_actions)
        for option in sorted(options):
            assert option in known, f"snapcorr {command} has no {option}"
            assert option not in DEPRECATED, f"the synopsis shows the deprecated {option}"


def test_command_line_synopsis_shows_every_option():
    """... and every option the parser takes is in it: the synopsis cannot drift."""
    shown = synopsis_options()
    missing = {command: sorted(parser_options(sub) - shown.get(command, set()))
               for command, sub in subcommands().items()}
    missing = {c: m for c, m in missing.items() if m}
    assert not missing, f"the README's synopsis lacks options `--help` shows: {missing}"


def test_readme_uses_no_deprecated_form():
    """Examples give the optical centre (row, col): --center ROW,COL, center_rc=."""
    for words in snapcorr_commands():
        assert not DEPRECATED & set(words), f"snapcorr {shlex.join(words)}"
    for block in blocks("python"):
        assert "center_px=" not in block


def test_envi_result_files_are_named():
    """Every image `correct --out STEM.hdr` writes is named in the README."""
    from snapcorr.files.envi_result import IMAGES

    text = README.read_text()
    missing = [name for name in IMAGES if f"STEM_{name}.hdr" not in text]
    assert not missing, f"the README does not name these ENVI images: {missing}"


@pytest.mark.parametrize("find, kind, name, bundled", [
    (lens_path, "lens", "no_such_lens", "['edmund_optics_16mm']"),
    (sensor_path, "sensor", "no_such_sensor", "'snapscan_vnir'"),
])
def test_unknown_bundled_name_lists_the_bundled_ones(find, kind, name, bundled):
    for given in (name, Path(f"somewhere/{name}.toml")):
        with pytest.raises(FileNotFoundError) as err:
            find(given)
        message = str(err.value)
        assert message.startswith(f"no bundled {kind} named '{name}'; bundled ")
        assert bundled in message and "Path(" not in message


def test_ci_runs_exactly_the_readme_test_command():
    """`.ci/run` is the README's test command, and that command runs the examples too."""
    ci = (README.parent / ".ci" / "run").read_text().splitlines()
    command = [ln for ln in ci if "pytest" in ln]
    assert len(command) == 1
    tests = [ln for b in blocks("bash") for ln in command_lines(b) if "pip install" in ln
             and "pytest" in ln]
    assert tests == command
    assert "-m examples" in command[0]
    from tomllib import loads

    addopts = loads((README.parent / "pyproject.toml").read_text())["tool"]["pytest"][
        "ini_options"]["addopts"]
    assert "not examples" in addopts and "not slow" in addopts
