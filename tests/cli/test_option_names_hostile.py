"""A message names only options its command has: ``correct --source`` with a sensor of
measured responses pointed to ``--profile``, an option of ``budget`` only."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import numpy as np
import pytest
from hostile import LENS, assert_refused

import snapcorr
from snapcorr.cli import COMMAND_MODULES, build_parser
from snapcorr.cli._errors import command_parser

PACKAGE = Path(snapcorr.__file__).parent

#: An option as a message names it (not a word with a hyphen, not ``---``).
OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")

#: A message naming another command's option says the command first: ``snapcorr pupil
#: --fit-n-eff``.
OTHER_COMMAND = re.compile(r"snapcorr (\w+)[^;.]*$")


def _options():
    parser = build_parser()
    return {c: {s for a in command_parser(parser, c)._actions for s in a.option_strings}
            for c in COMMAND_MODULES}


def _named(node):
    """``(option, other command or None, line)`` of every option the strings under ``node``
    name, docstrings and the names ``add_argument`` defines left out."""
    docs = {id(n.body[0].value) for n in ast.walk(node)
            if isinstance(n, ast.FunctionDef | ast.ClassDef | ast.Module) and n.body
            and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    docs |= {id(a) for n in ast.walk(node) if isinstance(n, ast.Call)
             and isinstance(n.func, ast.Attribute) and n.func.attr == "add_argument"
             for a in n.args}
    for n in ast.walk(node):
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs:
            for m in OPTION.finditer(n.value):
                other = OTHER_COMMAND.search(n.value[:m.start()])
                yield m.group(), other and other.group(1), n.lineno


def _cli_functions():
    """``{name: [(file, node)]}`` of the functions of the command line's modules."""
    found = {}
    for path in sorted((PACKAGE / "cli").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef):
                found.setdefault(node.name, []).append((path, node))
    return found


def _reached(command, functions):
    """The functions of the command line a command's ``run`` and ``add_parser`` reach (its
    own module's, and the shared modules', ``_options``, ``_frames``... by name)."""
    own = PACKAGE / "cli" / f"{command}.py"
    stack = [n for name in ("run", "add_parser") for f, n in functions[name] if f == own]
    seen = {}
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen[id(node)] = node
        names = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}
        names |= {n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)}
        for name in names - {"run", "add_parser"}:
            stack += [n for f, n in functions.get(name, [])
                      if f.stem not in COMMAND_MODULES or f == own]
    return seen.values()


@pytest.mark.parametrize("command", list(COMMAND_MODULES))
def test_a_command_line_message_names_only_the_commands_options(command):
    options = _options()[command]
    wrong = [f"{node.name}:{line} {option}" for node in _reached(command, _cli_functions())
             for option, other, line in _named(node)
             if option not in options and option != "--help" and other in (None, command)]
    assert not wrong, f"snapcorr {command} has no: {wrong}"


def test_every_option_a_message_names_is_one_a_command_has():
    options = set().union(*_options().values()) | {"--help", "--version"}
    wrong = [f"{path.relative_to(PACKAGE)}:{line} {option}"
             for path in sorted(PACKAGE.rglob("*.py"))
             for option, _, line in _named(ast.parse(path.read_text()))
             if option not in options]
    assert not wrong, wrong


def test_the_budget_names_no_option_of_a_command(tmp_path):
    """A library message says the keyword (``profile=``); the command line names the option
    where the command has one."""
    from snapcorr.budget.scene import profile_of
    from snapcorr.cube import Sensor

    with pytest.raises(ValueError) as err:
        profile_of(Sensor.load("imec_5x5_nir"))
    assert "profile=" in str(err.value) and "--" not in str(err.value)


def test_correct_source_with_measured_responses_names_its_own_options(tmp_path, cli):
    from snapcorr.cube import Sensor, make_cube, write_cube

    sensor = Sensor.load("imec_5x5_nir")
    write_cube(make_cube(np.ones((5, 5, len(sensor.cwl_nm)), np.float32), sensor.cwl_nm,
                         name="reflectance"), tmp_path / "m.nc")
    rc, _, err = cli("correct", tmp_path / "m.nc", "--lens", LENS, "--sensor", "imec_5x5_nir",
                     "--f-number", "2", "--source", "solar", "--sensor-origin-px", "0,0",
                     "--out", tmp_path / "o.nc")
    line = assert_refused(rc, err, "--source", "--method")
    named = {m.group() for m in OPTION.finditer(line.split("(snapcorr budget")[0])}
    assert named <= _options()["correct"], f"not options of correct: {named} in {line}"


def test_budget_with_measured_responses_names_profile(cli):
    rc, _, err = cli("budget", "--sensor", "imec_5x5_nir", "--lens", LENS, "--f-number", "2",
                     "--source", "solar")
    assert_refused(rc, err, "--profile")


def test_budget_places_a_cropped_cube_with_sensor_origin_px(tmp_path, cli):
    """The budget of a crop asked for --sensor-origin-px, which it did not have."""
    from snapcorr.cube import Sensor, make_cube, write_cube

    sensor = Sensor.load("snapscan_vnir")
    write_cube(make_cube(np.full((4, 5, len(sensor.cwl_nm)), 0.5, np.float32), sensor.cwl_nm,
                         name="reflectance"), tmp_path / "crop.nc")
    args = ("budget", "--cube", tmp_path / "crop.nc", "--sensor", "snapscan_vnir", "--lens",
            LENS, "--f-number", "2", "--source", "solar")
    rc, _, err = cli(*args)
    line = assert_refused(rc, err, "--sensor-origin-px")
    assert {m.group() for m in OPTION.finditer(line)} <= _options()["budget"], line
    rc, out, err = cli(*args, "--sensor-origin-px", "1000,1000")
    assert rc == 0, err
    assert "CRA up to 0.5" in out, out  # a crop near the sensor's centre


def test_correct_names_source_for_a_pixel_outside_the_cube(tmp_path, cli):
    from snapcorr.cube import Sensor, make_cube, write_cube

    sensor = Sensor.load("snapscan_vnir")
    write_cube(make_cube(np.full((4, 5, len(sensor.cwl_nm)), 0.5, np.float32), sensor.cwl_nm,
                         name="reflectance"), tmp_path / "crop.nc")
    rc, _, err = cli("correct", tmp_path / "crop.nc", "--lens", LENS, "--sensor",
                     "snapscan_vnir", "--f-number", "2", "--sensor-origin-px", "1000,1000",
                     "--source", "cube:99,99", "--out", tmp_path / "o.nc")
    assert_refused(rc, err, "--source cube:99,99", "outside")
