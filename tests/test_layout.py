"""The code's own rules (CONTRIBUTING.md): imports go one way, functions stay short, and
public functions document their parameters."""

import ast
import importlib
import inspect
import pkgutil
from pathlib import Path

import pytest

import snapcorr

PACKAGE = Path(snapcorr.__file__).resolve().parent
SOURCES = sorted(PACKAGE.rglob("*.py"))


def _module_parts(path):
    return ["snapcorr", *path.relative_to(PACKAGE).with_suffix("").parts]


def _imports(source, here):
    """Every snapcorr module the module ``here`` (its dotted parts) imports in ``source``,
    anywhere in it, as dotted names (relative imports resolved)."""
    tree = ast.parse(source)
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("snapcorr")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[:len(here) - node.level]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ""
            if name.startswith("snapcorr"):
                out.add(name)
                out |= {f"{name}.{a.name}" for a in node.names}
    return out


# package -> packages it must never import (directly or lazily inside a function)
FORBIDDEN = {
    "optics": ("correct", "cube", "calibrate", "budget", "cli", "simulate", "spectra", "demo"),
    "correct": ("budget", "cli", "calibrate"),
    "cube": ("correct", "budget", "cli", "calibrate"),
}


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_imports_go_one_way(package):
    bad = []
    for path in sorted((PACKAGE / package).rglob("*.py")):
        for name in _imports(path.read_text(), _module_parts(path)):
            parts = name.split(".")
            if len(parts) > 1 and parts[1] in FORBIDDEN[package]:
                bad.append(f"{path.relative_to(PACKAGE)} imports {name}")
    assert not bad, bad


def test_no_function_is_over_100_lines():
    long = []
    for path in SOURCES:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > 100:
                    long.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name} ({n})")
    assert not long, long


def _public_callables():
    for info in pkgutil.walk_packages(snapcorr.__path__, "snapcorr."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if inspect.isfunction(obj):
                yield f"{obj.__module__}.{obj.__qualname__}", obj
            elif inspect.isclass(obj):
                for attr, value in vars(obj).items():
                    func = getattr(value, "__func__", value)
                    if not attr.startswith("_") and inspect.isfunction(func):
                        yield f"{obj.__module__}.{obj.__qualname__}.{attr}", func


def test_public_functions_of_three_or_more_arguments_document_them():
    missing = set()
    for qualname, func in _public_callables():
        params = [p for p in inspect.signature(func).parameters if p not in ("self", "cls")]
        if len(params) >= 3 and "Parameters\n----------" not in (inspect.getdoc(func) or ""):
            missing.add(qualname)
    assert not missing, sorted(missing)


def test_a_forbidden_import_is_seen():
    """The check reads relative imports, also those inside a function."""
    here = ["snapcorr", "optics", "probe"]
    found = _imports("import numpy\n\ndef f():\n    from ..budget import scene_budget\n", here)
    assert "snapcorr.budget" in found
    assert _imports("from . import goossens2019\n", here) >= {"snapcorr.optics",
                                                              "snapcorr.optics.goossens2019"}


# Each room's floor. A module imports only from its own room and from rooms on lower floors
# (never from another room on its own floor)
# (lazy imports inside functions, and modules named in strings for a lazy ``__getattr__``,
# included), so the house reads from the ground up. A dotted key is a room of its own: the
# data model (cube.model, cube.derived) sits below the files that store it.
FLOORS = {
    "_validation": 0,
    "_coords": 1, "_names": 1, "_threads": 1, "_bundled": 1, "_lazy": 1,
    "cube.model": 2, "cube.derived": 2,
    "files": 3, "_io": 3,
    "optics": 4, "spectra": 4,
    "cube": 5,
    "correct": 6, "simulate": 6,
    "calibrate": 7, "budget": 7, "pipeline": 7, "stream": 7,
    "data": 8, "quicklook": 8,
    "paper_experiment": 9,
    "demo": 10,
    "cli": 11,
    "_entry": 12, "__main__": 13, "__init__": 13,
}


def _room(dotted):
    """The key of :data:`FLOORS` a dotted module name belongs to (the longest that fits)."""
    parts = dotted.split(".")[1:]
    for n in (2, 1):
        if len(parts) >= n and ".".join(parts[:n]) in FLOORS:
            return ".".join(parts[:n])
    return parts[0] if parts else "__init__"


def _is_shim(source):
    return "\n_MOVED_TO = " in source


def _named_modules(source):
    """The snapcorr modules ``source`` names as the values of a dict (a lazy ``__getattr__``'s
    table of homes)."""
    return {v.value for node in ast.walk(ast.parse(source)) if isinstance(node, ast.Dict)
            for v in node.values
            if isinstance(v, ast.Constant) and isinstance(v.value, str)
            and v.value.startswith("snapcorr.") and " " not in v.value
            and (PACKAGE.parent / v.value.replace(".", "/")).with_suffix(".py").exists()}


def _all_imports(path):
    """:func:`_imports`, and the modules a lazy ``__getattr__`` names in strings."""
    source = path.read_text()
    return _imports(source, _module_parts(path)) | _named_modules(source)


def test_every_room_has_a_floor():
    rooms = {_room(".".join(_module_parts(p))) for p in SOURCES}
    assert rooms <= set(FLOORS), sorted(rooms - set(FLOORS))


def test_imports_go_down_the_floors():
    up = []
    for path in SOURCES:
        if _is_shim(path.read_text()):
            continue  # a compatibility module re-exports from where its names now live
        room = _room(".".join(_module_parts(path)))
        for name in _all_imports(path) - {"snapcorr"}:  # the package itself: its version
            other = _room(name)
            if other != room and FLOORS.get(other, -1) >= FLOORS[room]:
                up.append(f"{path.relative_to(PACKAGE)} imports {name}")
    assert not up, sorted(up)


def _private_imports(source, here):
    """``module.name`` for every private name the module ``here`` (its dotted parts) imports
    in ``source`` from another top-level room of the package."""
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            origin = here[:len(here) - node.level] + ([node.module] if node.module else [])
        else:
            origin = (node.module or "").split(".")
        if origin[:1] != ["snapcorr"] or origin[1:2] == here[1:2]:
            continue
        for a in node.names:
            if a.name.startswith("_") and not a.name.startswith("__"):
                yield f"{'.'.join(origin)}.{a.name}"


def test_no_private_name_is_imported_from_another_room():
    found = sorted(f"{p.relative_to(PACKAGE)}: {n}" for p in SOURCES
                   if not _is_shim(p.read_text())
                   for n in _private_imports(p.read_text(), _module_parts(p)))
    assert not found, found


def test_a_private_import_from_another_room_is_seen():
    here = ["snapcorr", "optics", "probe"]
    source = "def f():\n    from ..cube.io import _read_file, read_cube\n"
    assert list(_private_imports(source, here)) == ["snapcorr.cube.io._read_file"]
    assert not list(_private_imports("from .chief_ray import _cra_deg_rc\n", here))


def test_a_lazy_import_named_in_a_string_is_seen():
    assert _named_modules('_HOMES = {"read_cube": "snapcorr.files.api"}\n') == {
        "snapcorr.files.api"}
    assert not _named_modules('x = "snapcorr.no_such_module"\n')


MAX_MODULE_LINES = 800
MAX_COMMAND_LINES = 300


def test_no_module_is_over_800_lines():
    long = [f"{p.relative_to(PACKAGE)} ({n})" for p in SOURCES
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES]
    assert not long, long


def test_no_command_module_is_over_300_lines():
    """The command line is a thin shell: each command's module parses and calls the library."""
    commands = sorted((PACKAGE / "cli").glob("*.py"))
    assert len(commands) > 5, "snapcorr/cli/ holds one module per command"
    long = [f"{p.relative_to(PACKAGE)} ({n})" for p in commands
            if (n := len(p.read_text().splitlines())) > MAX_COMMAND_LINES]
    assert not long, long


def _shims():
    return {".".join(_module_parts(p)) for p in SOURCES if _is_shim(p.read_text())}


def test_the_package_imports_no_compatibility_module():
    """Compatibility modules are for users' code: the package imports each name from its home
    (but ``calibrate/__init__``, which loads the old ``pupil_precision`` module first so that
    the function of that name stays the package's attribute)."""
    shims = _shims()
    assert {"snapcorr._io", "snapcorr.cube.io", "snapcorr.stream"} <= shims
    found = sorted(f"{p.relative_to(PACKAGE)} imports {n}" for p in SOURCES
                   if not _is_shim(p.read_text()) and p != PACKAGE / "calibrate" / "__init__.py"
                   for n in _imports(p.read_text(), _module_parts(p)) & shims
                   if not n.endswith(".pupil_precision"))
    assert not found, found
