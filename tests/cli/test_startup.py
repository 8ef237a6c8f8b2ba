"""The command line answers at once: ``--help``, each command's ``--help`` and a usage error
import none of the heavy libraries (the physics, the cube readers, the plotting), and the
package's public names still work, imported at their first use."""

import subprocess
import sys

import numpy as np
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


def test_the_physics_and_the_pipeline_import_no_fitting_library():
    """``scipy.optimize`` (0.2-0.6 s of a command's start) is imported where a fit runs, not by
    importing the physics or the pipeline that every ``flatfield --demosaic`` and ``stream``
    loads; the fits that need it still run."""
    script = """
import sys
import numpy as np
import snapcorr.cli, snapcorr.optics, snapcorr.pipeline
from snapcorr.cli import flatfield, stream
print("scipy.optimize" in sys.modules)
from snapcorr.optics import fit_n_eff
from snapcorr.optics.profiles import _multi_lorentzian_unit, fwhm_of, _multi_lorentzian_shape
aoi = np.array([0.0, 8.0, 16.0, 24.0])
fit = fit_n_eff(aoi, 600.0 * np.sqrt(1 - np.sin(np.deg2rad(aoi)) ** 2 / 1.9 ** 2))
k, _ = _multi_lorentzian_unit()
lam = np.linspace(-40 * k, 40 * k, 16001)
print(fit.n_eff, fwhm_of(lam, _multi_lorentzian_shape(lam, k)))
"""
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    before, after = res.stdout.splitlines()
    assert before == "False"
    n_eff, fwhm = map(float, after.split())
    assert abs(n_eff - 1.9) < 1e-9 and abs(fwhm - 1.0) < 1e-9


def _modules_imported(stderr):
    """Every module name in ``python -X importtime``'s report."""
    return {line.rsplit("|", 1)[1].strip() for line in stderr.splitlines()
            if line.startswith("import time:") and line.count("|") == 2}


def test_commands_that_fit_nothing_import_no_fitting_library(tmp_path):
    """``flatfield`` (with ``--demosaic`` too) runs no fit: it never imports ``scipy.optimize``
    (the command line's own start, through ``python -m snapcorr``, and its work)."""
    rng = np.random.default_rng(0)
    np.save(tmp_path / "raw.npy", rng.integers(100, 3000, (32, 32)).astype(np.uint16))
    np.save(tmp_path / "dark.npy", np.full((32, 32), 64, np.uint16))
    np.save(tmp_path / "white.npy", np.full((32, 32), 3500, np.uint16))
    frames = ["raw.npy", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
              "mosaic_4x4_vis", "--sensor-origin-px", "400,800", "--quiet"]
    for extra in (["--demosaic", "ri", "--out", "ff.zarr"], ["--out", "ff.nc"]):
        res = subprocess.run([sys.executable, "-X", "importtime", "-m", "snapcorr",
                              "flatfield", *frames, *extra], cwd=tmp_path,
                             capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stderr[-2000:]
        assert (tmp_path / extra[-1]).exists()
        names = _modules_imported(res.stderr)
        assert {"numpy", "dask.array", "xarray"} <= names  # the report was read
        assert "scipy.optimize" not in names, extra
