"""The library's messages name its keywords, never the command line's options: a Python caller
typed no ``--sensor-origin-px``. The command line says them as options (``cli/_errors.py`` maps
``keyword=`` and a check's leading keyword to the option its command has)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import snapcorr

PACKAGE = Path(snapcorr.__file__).resolve().parent

#: An option as a message would name it (``--sensor``, ``--{what}``).
OPTION = re.compile(r"(?<![\w-])--(?:[a-z][a-z0-9-]*|\{\})")

#: Messages that name an option and are meant to: each gives another command's whole command
#: line as the way to do what the library cannot from here, next to the library's own way.
#: ``(module, option): reason``.
JUSTIFIED = {
    ("files/datasets.py", "--lens"): "a stream is corrected by the stream command "
                                     "('snapcorr stream --lens LENS --f-number F'); in "
                                     "Python, read_dataset opens it, as the message says",
    ("files/datasets.py", "--f-number"): "the same command line",
    ("cube/sensor.py", "--fit-n-eff"): "a sensor without n_eff: the pupil command line that "
                                       "measures it and writes the sensor's TOML, beside "
                                       "locate_pupil(fit_n_eff=True)",
    ("cube/sensor.py", "--sensor-out"): "the same command line",
    ("calibrate/pupil/target.py", "--fit-n-eff"): "the pupil command fits n_eff to the cubes "
                                                  "directly ('snapcorr pupil --fit-n-eff'), "
                                                  "as locate_pupil(fit_n_eff=True) does",
    ("calibrate/pupil/locate.py", "--target-cube"): "the calibrate command line that fits flats "
                                                    "and target together, beside "
                                                    "calibrate_with_target",
    ("calibrate/pupil/locate.py", "--pupil-radiance"): "the same command line",
}


def _texts(node):
    """The strings of an expression, an f-string's values as ``{}``."""
    for n in ast.walk(node):
        if isinstance(n, ast.JoinedStr):
            yield "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in n.values)
        elif isinstance(n, ast.Constant) and isinstance(n.value, str):
            yield n.value


def _message_nodes(tree):
    """Each raised exception, warning and ``sensor.require`` reason, with the values of the
    names a raise uses that its function assigns (a message built first, raised after)."""
    for func in [tree, *(n for n in ast.walk(tree)
                         if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef))]:
        assigned = {}
        for n in ast.walk(func):
            if isinstance(n, ast.Assign):
                for t in n.targets:
                    if isinstance(t, ast.Name):
                        assigned.setdefault(t.id, []).append(n.value)
        for n in ast.walk(func):
            if isinstance(n, ast.Raise) and n.exc is not None:
                yield n.lineno, n.exc
                for name in {m.id for m in ast.walk(n.exc) if isinstance(m, ast.Name)}:
                    for value in assigned.get(name, []):
                        yield n.lineno, value
            elif isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute | ast.Name) and \
                    getattr(n.func, "attr", getattr(n.func, "id", "")) in ("warn", "require"):
                for arg in n.args:
                    yield n.lineno, arg


def _options_named():
    """``{(module, option): [line, ...]}`` over the library (snapcorr/ but cli/)."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel.startswith("cli/"):
            continue
        for line, node in _message_nodes(ast.parse(path.read_text())):
            for text in _texts(node):
                for option in OPTION.findall(text):
                    found.setdefault((rel, option), set()).add(line)
    return found


def test_the_library_names_keywords_not_options():
    """``check --sensor-origin-px (sensor_origin_px) and --sensor``, ``use --virtual-bands
    fitted``, ``choose another --out`` and the like were said to Python callers; each now
    names the keyword (``sensor_origin_px=``, ``virtual_bands='fitted'``, ``out_dir=``), which
    the command line says as its option."""
    wrong = {k: sorted(v) for k, v in _options_named().items() if k not in JUSTIFIED}
    assert not wrong, "library messages naming options:\n" + "\n".join(
        f"  snapcorr/{m}:{','.join(map(str, lines))}: {o}" for (m, o), lines in
        sorted(wrong.items()))


def test_every_justified_option_is_still_named():
    """An exception no message needs any longer is dropped from the list."""
    assert set(JUSTIFIED) <= set(_options_named())


def test_the_walk_finds_a_message_built_before_its_raise(tmp_path):
    tree = ast.parse("def f(what):\n    msg = f'give --{what}'\n    raise ValueError(msg)\n"
                     "def g():\n    raise ValueError('check --sensor and ' + 'n_eff=')\n")
    texts = [t for _, node in _message_nodes(tree) for t in _texts(node)]
    assert {o for t in texts for o in OPTION.findall(t)} == {"--{}", "--sensor"}


def test_the_command_line_says_the_keywords_as_its_options():
    """The forms the library now uses reach a command's user as that command's options."""
    from snapcorr.cli import build_parser
    from snapcorr.cli._errors import _message, command_parser, option_names

    parser = build_parser()
    correct = option_names(command_parser(parser, "correct"))
    for said, shown in [
        ("give sensor_origin_px= (row, col), the sensor row", "give --sensor-origin-px "
                                                              "row,col, the sensor row"),
        ("check sensor_origin_px= and sensor=", "check --sensor-origin-px and --sensor"),
        ("use virtual_bands='fitted'", "use --virtual-bands fitted"),
        ("virtual_bands='angle-aware' needs the lens", "--virtual-bands angle-aware needs the "
                                                       "lens"),
        ("give center_rc= (row, col) in this sensor's pixels", "give --center row,col in this "
                                                               "sensor's pixels"),
        ("sensor_origin_px (3, 4) disagrees", "--sensor-origin-px (3, 4) disagrees"),
        ("leave out resample=True (one band)", "leave out --resample (one band)"),
    ]:
        assert _message(ValueError(said), correct) == shown
    demo = option_names(command_parser(parser, "demo"))
    assert _message(ValueError("out_dir a/b: the folder a does not exist"), demo) == \
        "--out a/b: the folder a does not exist"
    assert _message(ValueError("choose another folder (out_dir=) or pass overwrite=True"),
                    demo) == "choose another folder (--out) or pass --overwrite"
