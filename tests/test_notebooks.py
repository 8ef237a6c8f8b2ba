"""The notebooks: every source is paired with its .ipynb, and every notebook runs top to bottom.

The plain-text sources ``notebooks/*.py`` (jupytext percent format) are what is edited; the
``.ipynb`` next to each is generated from it and kept without outputs. Each notebook is
executed in a fresh ``python3`` kernel with nbclient, from ``notebooks/`` as the working
directory, with RuntimeWarning an error as in the rest of the suite.
"""

import difflib
from pathlib import Path

import jupytext
import pytest
from conftest import NO_X_FIRST_CENTER
from nbclient import NotebookClient

NOTEBOOK_DIR = Path(__file__).resolve().parents[1] / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.py"))
RESYNC = ("re-sync with `jupytext --sync notebooks/*.py` (the newer file of each pair updates "
          "the other; a missing .ipynb is made from the source) and keep both files")
CELL_TIMEOUT_S = 120


def _cells(nb):
    return [(cell.cell_type, cell.source) for cell in nb.cells]


def _first_difference(a, b):
    for i, (x, y) in enumerate(zip(a, b, strict=False)):
        if x != y:
            diff = difflib.unified_diff(x[1].splitlines(), y[1].splitlines(), ".py", ".ipynb",
                                        lineterm="", n=1)
            kinds = f" ({x[0]} / {y[0]})" if x[0] != y[0] else ""
            return f"cell {i}{kinds}:\n" + "\n".join(list(diff)[:20])
    return f"the .py has {len(a)} cells, the .ipynb {len(b)}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_paired_and_in_sync(path):
    source = jupytext.read(path)
    formats = source.metadata.get("jupytext", {}).get("formats", "")
    assert set(formats.split(",")) >= {"ipynb", "py:percent"}, (
        f"{path.name}: its jupytext header must declare `formats: ipynb,py:percent`; "
        f"add it with `jupytext --set-formats ipynb,py:percent notebooks/{path.name}`")
    paired = path.with_suffix(".ipynb")
    assert paired.exists(), f"{paired.name} is missing; {RESYNC}"
    notebook = jupytext.read(paired)
    a, b = _cells(source), _cells(notebook)
    assert a == b, (f"{paired.name} is out of sync with {path.name}; {RESYNC}.\n"
                    f"First difference, {_first_difference(a, b)}")
    stale = [i for i, cell in enumerate(notebook.cells) if cell.cell_type == "code"
             and (cell.get("outputs") or cell.get("execution_count") is not None)]
    assert not stale, (f"{paired.name} holds outputs (cells {stale}); regenerate it without "
                       f"them: `jupytext --sync notebooks/{path.name}` (carries edits made in "
                       f"the .ipynb back to the source), then `jupytext --to ipynb "
                       f"notebooks/{path.name}`")


@pytest.mark.examples
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs(path, monkeypatch):
    # inherited by the kernel; our examples give the centre row first
    monkeypatch.setenv("PYTHONWARNINGS", f"error::RuntimeWarning,{NO_X_FIRST_CENTER}")
    before = sorted(p.name for p in NOTEBOOK_DIR.iterdir())
    client = NotebookClient(jupytext.read(path), kernel_name="python3",
                            timeout=CELL_TIMEOUT_S,
                            resources={"metadata": {"path": str(NOTEBOOK_DIR)}})
    client.execute()  # raises CellExecutionError, with the cell and traceback, on any error
    after = sorted(p.name for p in NOTEBOOK_DIR.iterdir())
    assert after == before, (f"{path.name} wrote {sorted(set(after) - set(before))} into "
                             "notebooks/; write into a temporary directory instead")
