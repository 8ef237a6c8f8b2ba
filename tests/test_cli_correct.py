"""`snapcorr correct`: a cube in, corrected wavelengths out; mistakes are one line."""

import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

from snapcorr import Lens
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, make_cube, write_cube

PAPER = Lens("Edmund Optics 16 mm", 21.0, 7.4236, 16.991, 0.06, 1.3)


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "snapcorr", "correct", *args],
                          capture_output=True, text=True, timeout=300, cwd=cwd)


@pytest.fixture
def files(tmp_path):
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 5), 10.0, 1.7)
    sensor.save(tmp_path / "sensor.toml")
    PAPER.save(tmp_path / "lens.toml")
    data = np.random.default_rng(0).random((30, 40, 5)).astype(np.float32)
    cube = make_cube(data, sensor.cwl_nm, name="reflectance")
    write_cube(cube, tmp_path / "cube.nc")
    return tmp_path, cube, sensor


def test_correct_writes_what_the_library_computes(files):
    d, cube, sensor = files
    res = run("cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml", "--f-number", "1.4",
              "--out", "out.nc", "--resample", cwd=d)
    assert res.returncode == 0, res.stderr
    assert "method vignetted" in res.stdout
    ds = xr.open_dataset(d / "out.nc")
    ref = correct_cube(cube, PAPER, sensor, 1.4, resample=True)
    np.testing.assert_array_equal(ds["wavelength_corrected"].values,
                                  ref["wavelength_corrected"].values)
    np.testing.assert_array_equal(ds["reflectance"].values, cube.values)
    np.testing.assert_array_equal(ds["resampled"].values, ref["resampled"].values)
    assert ds.attrs["cube_file"] == "cube.nc" and ds.attrs["f_number"] == 1.4


@pytest.mark.parametrize("args, message", [
    (["--f-number", "0"], "f_number"),
    (["--f-number", "2", "--out", "cube.nc"], "also an input"),
    (["--f-number", "2", "--lens", "nolens.toml"], "nolens.toml"),
    (["--f-number", "2", "--lens", "badlens.toml"], "exit_pupil_mm"),
    (["--f-number", "2", "--sensor", "sensor6.toml"], "bands"),
    (["--f-number", "2", "--out", "out.txt"], ".nc or .zarr"),
])
def test_mistakes_are_one_line_and_write_nothing(files, args, message):
    d, cube, _ = files
    (d / "badlens.toml").write_text('[lens]\nname = "x"\n')
    Sensor("s6", "snapscan", 40.0, np.linspace(500, 900, 6), 10.0, 1.7).save(d / "sensor6.toml")
    base = {"--lens": "lens.toml", "--sensor": "sensor.toml", "--out": "new.nc"}
    for flag, value in zip(args[::2], args[1::2], strict=True):
        base[flag] = value
    argv = ["cube.nc"] + [v for kv in base.items() for v in kv]
    if "--f-number" not in base:
        argv += ["--f-number", "2"]
    res = run(*argv, cwd=d)
    assert res.returncode != 0 and message in res.stderr, res.stderr
    assert "Traceback" not in res.stderr
    assert not (d / "new.nc").exists() and not (d / "out.txt").exists()
    xr.testing.assert_identical(xr.open_dataset(d / "cube.nc")["reflectance"].load(),
                                cube)
