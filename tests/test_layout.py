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
