"""The README's walk-through of a vendor mosaic sensor runs start to finish (its blocks marked
``walkthrough``, in order, in an empty folder): the mosaic phase, the lens from raw mosaic
flats, x and n_eff from a rare-earth glass, the lens again at that x, a scene flat-fielded,
demosaicked, corrected and given virtual bands. The frames are ``snapcorr.data.mosaic_frames``
(the bundled lens, x = 21 mm, m = 0.06, m_P = 1.3; the sensor's n_eff = 1.8), so the
measured values are checked against those."""

import os
import shlex
import subprocess
import sys
import tomllib

import pytest
from test_readme import blocks, command_lines

import snapcorr.data
from snapcorr import Lens
from snapcorr.cube import Sensor, read_dataset

pytestmark = pytest.mark.slow  # (about 5 minutes on 2 cores: whole-sensor frames)


def test_the_vendor_mosaic_walkthrough_runs_and_measures_the_camera(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for block in blocks("python", walkthrough=True):
        exec(compile(block, "README.md walkthrough", "exec"), {"__name__": "__readme__"})
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [os.path.dirname(os.path.dirname(snapcorr.__file__)), os.environ.get("PYTHONPATH", "")])}
    lines = [ln for b in blocks("bash", walkthrough=True) for ln in command_lines(b)
             if ln.strip() and not ln.lstrip().startswith("#")]
    assert len(lines) == 8, lines
    for line in lines:
        words = shlex.split(line)
        assert words[0] == "snapcorr"
        quiet = [] if words[1] == "sensor" else ["--quiet"]  # (no progress bars to a log)
        res = subprocess.run([sys.executable, "-m", "snapcorr", *words[1:], *quiet],
                             capture_output=True, text=True, env=env)
        assert res.returncode == 0, f"{line}\n{res.stderr}"
        assert "Traceback" not in res.stderr
    truth = Lens.load(snapcorr.data.lens_path())
    lens = Lens.load("my_lens.toml")
    sx = float(Lens.load("lens_x.toml").calibration["exit_pupil_stderr_mm"])
    assert abs(lens.exit_pupil_mm - truth.exit_pupil_mm) < 0.01 * truth.exit_pupil_mm
    assert abs(lens.exit_pupil_mm - truth.exit_pupil_mm) < 4 * sx, (lens.exit_pupil_mm, sx)
    (P, h), = lens.vignetting
    (P0, h0), = truth.vignetting
    assert abs(P - P0) < 0.01 * P0 and abs(h - h0) < 0.01 * h0, (P, h)
    sensor = Sensor.load("my_nir.toml")
    n_eff = float(sensor.n_eff[0])
    assert abs(n_eff - 1.8) < 0.01 * 1.8, n_eff
    s_n = _found(tomllib.loads((tmp_path / "my_nir.toml").read_text()), "n_eff_stderr")
    assert abs(n_eff - 1.8) < 4 * s_n, (n_eff, s_n)  # (one draw: within 4 of its errors)
    out = read_dataset("corrected.zarr")
    assert {"reflectance", "raw", "wavelength_corrected", "virtual"} <= set(out.variables)
    assert out.attrs["input_demosaic_method"] == "ri"


def _found(doc, key):
    """The value of ``key`` wherever it sits in a TOML's tables."""
    for k, v in doc.items():
        if k == key:
            return float(v[0] if isinstance(v, list) else v)
        if isinstance(v, dict):
            try:
                return _found(v, key)
            except KeyError:
                pass
    raise KeyError(key)
