"""The tests mirror the package: a module's tests are found from its name alone.

``snapcorr/<package>/<module>.py`` is tested in ``tests/<package>/test_<module>.py``, or in
files named ``test_<module>_<aspect>.py`` beside it (``test_vendor_xml_bounds.py``); a module
of the top level in ``tests/test_<module>.py``. A private module's name is read without its
leading underscore (``snapcorr/_coords.py``: ``tests/test_coords.py``). Compatibility
re-exports left at an old path need no tests of their own.

Every test folder is a package (files of one name in two folders do not collide), except
``tests/oracles/``: the independent simulators, imported by their names, which share no code
with snapcorr.
"""

import ast
import re
from pathlib import Path

import snapcorr

PACKAGE = Path(snapcorr.__file__).resolve().parent
TESTS = Path(__file__).resolve().parent
ORACLES = TESTS / "oracles"
#: Folders of tests/ that are no packages: the simulators, imported by name, and data.
NOT_PACKAGES = {"oracles", "data"}

#: Modules without a test file of their name: none. A new module comes with its tests.
UNTESTED = set()


def _modules():
    """Every module of snapcorr but ``__init__``, ``__main__`` and compatibility re-exports:
    dotted name -> path."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name in ("__init__.py", "__main__.py"):
            continue
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        if doc.startswith("Compatibility re-exports"):
            continue
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        found[".".join(rel.parts)] = path
    return found


def _has_tests(module):
    *packages, name = module.split(".")[1:]
    folder = TESTS.joinpath(*packages)
    stem = "test_" + name.lstrip("_")
    return (folder / f"{stem}.py").is_file() or any(folder.glob(f"{stem}_*.py"))


def test_every_module_has_tests_of_its_name_or_is_listed():
    missing = {m for m in _modules() if not _has_tests(m)}
    listing = "".join(f'    "{m}",\n' for m in sorted(missing))
    assert missing == UNTESTED, (
        f"now tested, leave the list: {sorted(UNTESTED - missing)}; "
        f"new and untested, write tests/<package>/test_<module>.py: "
        f"{sorted(missing - UNTESTED)}\nthe list as it is now:\n{listing}")


def test_every_test_folder_is_a_package():
    for folder in sorted(p for p in TESTS.rglob("*") if p.is_dir()):
        rel = folder.relative_to(TESTS)
        if rel.parts[0] in NOT_PACKAGES or folder.name == "__pycache__":
            continue
        assert (folder / "__init__.py").is_file(), \
            f"tests/{rel.as_posix()} is no package: its files' names would collide"


def test_the_oracles_import_no_snapcorr():
    """The simulators are evidence only while they share no code with what they check."""
    for path in sorted(ORACLES.glob("*.py")):
        if path.name.startswith("test_"):
            continue
        names = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                names.add((node.module or "").split(".")[0])
        assert "snapcorr" not in names, f"tests/oracles/{path.name} imports snapcorr"


#: Where the docs and the code name a test file or a simulator by its path.
NAMING = ["README.md", "CONTRIBUTING.md", "benchmarks/README.md", "pyproject.toml",
          "benchmarks/*.py", "notebooks/*.py", "snapcorr/**/*.py", "tests/**/*.py"]


def test_every_test_file_the_docs_name_exists():
    root = TESTS.parent
    named = {}
    for pattern in NAMING:
        for path in sorted(root.glob(pattern)):
            for found in re.findall(r"\btests/[\w/]+\.py\b", path.read_text()):
                named.setdefault(found, path.relative_to(root).as_posix())
    missing = {f: where for f, where in named.items() if not (root / f).is_file()}
    assert len(named) > 20 and not missing, missing
