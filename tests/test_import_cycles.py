"""Imports between snapcorr's modules go one way: the exit-pupil fit and its report do not
import each other, and no library module depends on the demo (``paper_experiment``).

The imports are read from the source with ``ast``, those inside functions included, so a lazy
import that closes a cycle is seen too.
"""

import ast
from pathlib import Path

import snapcorr

PACKAGE = Path(snapcorr.__file__).resolve().parent
FIT = "snapcorr.calibrate.pupil.locate"
REPORT = "snapcorr.calibrate.pupil.report"
SOLVER = "snapcorr.calibrate.pupil.solver"
DEMO = "snapcorr.paper_experiment"


def _module_name(path):
    parts = ["snapcorr", *path.relative_to(PACKAGE).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(source, name, is_package=False):
    """The snapcorr modules the module ``name`` imports anywhere in ``source``: ``from X
    import a`` counts as importing ``X.a`` when that is a module, else ``X``."""
    package = name.split(".") if is_package else name.split(".")[:-1]
    out = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
                origin = ".".join(base + ([node.module] if node.module else []))
            else:
                origin = node.module or ""
            for a in node.names:
                sub = f"{origin}.{a.name}"
                out.add(sub if sub in MODULES else origin)
    return {m for m in out if m in MODULES}


def _graph():
    return {m: _imports(p.read_text(), m, p.name == "__init__.py") for m, p in MODULES.items()}


def _reach(graph, start):
    """Every module ``start`` imports, directly or through others (packages' ``__init__``
    followed only where imported by name)."""
    seen, todo = set(), [start]
    while todo:
        for m in graph.get(todo.pop(), ()):
            if m not in seen:
                seen.add(m)
                todo.append(m)
    return seen


def test_the_checker_sees_a_lazy_import_that_closes_the_cycle():
    src = "import numpy\n\ndef plot(fit):\n    from .report import plot_pupil_fit\n"
    assert _imports(src, FIT) == {REPORT}
    assert _imports("from ... import paper_experiment\n", FIT) == {DEMO}
    assert _imports("from ...paper_experiment import colour_filter\n", FIT) == {DEMO}
    assert _imports("from .solver import _Problem\n", REPORT) == {SOLVER}
    assert _imports("from . import locate\n", "snapcorr.calibrate.pupil", True) == {FIT}


def test_the_fit_and_its_report_import_each_other_one_way_only():
    graph = _graph()
    # the fit reaches the report (PupilFit.plot); the report and the solver never the fit
    assert FIT not in _reach(graph, REPORT), graph[REPORT]
    assert not {FIT, REPORT} & _reach(graph, SOLVER), graph[SOLVER]


def test_no_module_of_calibrate_imports_itself_through_others():
    graph = _graph()
    inside = {m for m, p in MODULES.items()
              if m.startswith("snapcorr.calibrate.") and p.name != "__init__.py"}
    sub = {m: graph[m] & inside for m in inside}
    cycles = sorted(m for m in inside if m in _reach(sub, m))
    assert not cycles, cycles


def test_no_library_module_depends_on_the_demo():
    graph = _graph()
    assert DEMO not in _reach(graph, FIT), f"{FIT} imports {DEMO}"
    assert DEMO not in _reach(graph, "snapcorr.calibrate"), f"snapcorr.calibrate reaches {DEMO}"
    importers = sorted(m for m, deps in graph.items() if DEMO in deps)
    assert importers == ["snapcorr.demo"], importers
