"""The command line answers at once: ``--help``, each command's ``--help`` and a usage error
import none of the heavy libraries (the physics, the cube readers, the plotting), and the
package's public names still work, imported at their first use."""

import subprocess
import sys

import pytest

#: Libraries that take longer to import than numpy, or pull in those that do.
HEAVY = ("scipy", "dask", "numba", "xarray", "matplotlib", "pandas", "zarr", "h5netcdf", "h5py",
         "tqdm", "distributed")

COMMANDS = ("demo", "sensor", "flatfield", "stream", "calibrate", "pupil", "correct", "shift",
            "budget")


def _imported(stderr):
    """Top-level module names in ``python -X importtime``'s report."""
    names = set()
    for line in stderr.splitlines():
        if line.startswith("import time:") and line.count("|") == 2:
            names.add(line.rsplit("|", 1)[1].strip().split(".")[0])
    return names


def test_help_through_the_entry_point_imports_nothing_heavy():
    res = subprocess.run([sys.executable, "-X", "importtime", "-m", "snapcorr", "--help"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and "usage: snapcorr" in res.stdout
    names = _imported(res.stderr)
    assert "numpy" in names and "snapcorr" in names  # the report was read
    assert not names & set(HEAVY), sorted(names & set(HEAVY))


def test_every_commands_help_and_usage_errors_import_nothing_heavy():
    """In one process: every command's --help, a mistyped option, a missing argument, a bad
    choice and a bad value, each answered by argparse alone."""
    script = f"""
import sys
from snapcorr.cli import main
import contextlib, io
codes = []
for argv in ([[c, "--help"] for c in {COMMANDS!r}] + [["flatfield", "--bogus"],
             ["correct"], ["correct", "c.nc", "--method", "nope"], ["shift", "--f-number", "x"],
             ["--version"], []]):
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        codes.append(main(argv))
print(codes)
print(" ".join(sorted({{m.split(".")[0] for m in sys.modules}})))
"""
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    codes, modules = res.stdout.splitlines()
    assert codes == str([0] * len(COMMANDS) + [2, 2, 2, 2, 0, 0])
    heavy = set(modules.split()) & set(HEAVY)
    assert not heavy, sorted(heavy)


def test_public_names_are_imported_at_first_use():
    script = """
import sys
import snapcorr
assert "snapcorr.optics" not in sys.modules
from snapcorr import *
from snapcorr.optics import Lens, mean_shift
assert snapcorr.Lens is Lens and snapcorr.mean_shift is mean_shift
assert set(snapcorr.__all__) <= set(dir(snapcorr))
assert snapcorr.cube.read_dataset is __import__("snapcorr.cube").cube.read_dataset
print(snapcorr.__version__)
"""
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    import snapcorr

    assert res.stdout.strip() == snapcorr.__version__
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        snapcorr.nope  # noqa: B018


def test_the_command_lines_choices_are_the_librarys():
    from snapcorr import _names, calibrate, optics

    assert _names.SHIFT_METHODS == tuple(optics.METHODS)
    assert _names.CORRECTION_MODELS == optics.MODELS
    assert _names.CALIBRATION_METHODS == calibrate.METHODS
