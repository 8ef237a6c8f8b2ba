"""`snapcorr correct`: a cube in, corrected wavelengths out; mistakes are one line."""

import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_LENS

from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, make_cube, read_dataset, write_cube

PAPER = PAPER_LENS


@pytest.fixture
def files(tmp_path):
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 5), 10.0, 1.7)
    sensor.save(tmp_path / "sensor.toml")
    PAPER.save(tmp_path / "lens.toml")
    data = np.random.default_rng(0).random((30, 40, 5)).astype(np.float32)
    cube = make_cube(data, sensor.cwl_nm, name="reflectance")
    write_cube(cube, tmp_path / "cube.nc")
    return tmp_path, cube, sensor


def test_correct_writes_what_the_library_computes(files, cli):
    d, cube, sensor = files
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--out", "out.nc", "--resample", cwd=d)
    assert res.returncode == 0, res.stderr
    assert "method vignetted" in res.stdout
    ds = read_dataset(d / "out.nc")
    ref = correct_cube(cube, sensor, 1.4, PAPER, resample=True)
    np.testing.assert_array_equal(ds["wavelength_corrected"].values,
                                  ref["wavelength_corrected"].values)
    np.testing.assert_array_equal(ds["reflectance"].values, cube.values)
    np.testing.assert_array_equal(ds["resampled"].values, ref["resampled"].values)
    assert ds.attrs["cube_file"] == "cube.nc" and ds.attrs["f_number"] == 1.4


def test_envi_without_the_input_says_what_it_wrote(files, cli):
    """--no-input with an ENVI --out: the cube's own pair is left out, and "wrote out.hdr"
    named a file that was never written."""
    d, _, _ = files
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--no-input", "--out", "out.hdr", cwd=d)
    assert res.returncode == 0, res.stderr
    assert not (d / "out.hdr").exists() and (d / "out_wavelength_corrected.hdr").exists()
    assert "wrote the corrected variables of out.hdr (not its input's copy" in res.stdout
    assert "wrote out.hdr" not in res.stdout


@pytest.mark.parametrize("extra", [[], ["--source", "solar"]], ids=["model", "budget"])
def test_a_cube_of_another_sensor_is_one_line(files, cli, extra):
    d, _, _ = files
    Sensor("four", "snapscan", 40.0, np.linspace(500, 900, 4), 10.0, 1.7).save(d / "four.toml")
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "four.toml",
              "--f-number", "2", "--out", "out.nc", *extra, cwd=d)
    assert res.returncode == 1 and "has 5 bands but the --sensor has 4" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and not (d / "out.nc").exists()


def test_method_harmonised_is_the_vignetted_shift_and_one_response_per_band(files, cli):
    d, cube, sensor = files
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--method", "harmonised", "--target-fwhm-nm", "30",
              "--out", "out.nc", cwd=d)
    assert res.returncode == 0, res.stderr
    ds = read_dataset(d / "out.nc")
    ref = correct_cube(cube, sensor, 1.4, PAPER, method="vignetted", harmonise=True,
                       target_fwhm_nm=30.0)
    assert ds.attrs["method"] == "harmonised" and ds.attrs["method_reason"] == "asked for"
    np.testing.assert_array_equal(ds["wavelength_corrected"].values,
                                  ref["wavelength_corrected"].values)
    np.testing.assert_array_equal(ds["harmonised"].values, ref["harmonised"].values)
    assert np.all(ds["fwhm_harmonised"].values == 30.0)


@pytest.mark.parametrize("args, message", [
    (["--f-number", "0"], "--f-number"),
    (["--f-number", "2", "--out", "cube.nc"], "also an input"),
    (["--f-number", "2", "--lens", "nolens.toml"], "nolens.toml"),
    (["--f-number", "2", "--lens", "badlens.toml"], "exit_pupil_mm"),
    (["--f-number", "2", "--sensor", "sensor6.toml"], "bands"),
    (["--f-number", "2", "--out", "out.txt"], ".nc or .zarr"),
    (["--f-number", "2", "--sensor", "badsensor.toml"], "cwl_nm"),
    (["--f-number", "2", "--center-px", "100000,0"], "cuts off the whole pupil"),
    (["--f-number", "2", "--target-fwhm-nm", "30"], "give --harmonise"),
    (["--f-number", "2", "--harmonise", "--target-fwhm-nm", "5"], "only widens"),
])
def test_mistakes_are_one_line_and_write_nothing(files, args, message, cli):
    d, cube, _ = files
    (d / "badlens.toml").write_text('[lens]\nname = "x"\n')
    (d / "badsensor.toml").write_text('[sensor]\nname = "x"\nlayout = "snapscan"\n'
                                      'pixel_pitch_um = 5.5\n')
    Sensor("s6", "snapscan", 40.0, np.linspace(500, 900, 6), 10.0, 1.7).save(d / "sensor6.toml")
    base = {"--lens": "lens.toml", "--sensor": "sensor.toml", "--out": "new.nc"}
    k = 0
    while k < len(args):  # flags with a value, and bare switches
        bare = k + 1 == len(args) or args[k + 1].startswith("--")
        base[args[k]] = None if bare else args[k + 1]
        k += 1 if bare else 2
    argv = ["cube.nc"] + [v for kv in base.items() for v in kv if v is not None]
    if "--f-number" not in base:
        argv += ["--f-number", "2"]
    res = cli("correct", *argv, cwd=d)
    assert res.returncode != 0 and message in res.stderr, res.stderr
    assert "Traceback" not in res.stderr
    assert not (d / "new.nc").exists() and not (d / "out.txt").exists()
    xr.testing.assert_identical(xr.open_dataset(d / "cube.nc")["reflectance"].load(),
                                cube)


@pytest.fixture(scope="module")
def cluster():
    from distributed import LocalCluster

    # every port the system's choice (another run of the tests may hold 8787, the default
    # of the scheduler's HTTP server, which it keeps even without a dashboard)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True,
                      dashboard_address=None,
                      scheduler_kwargs={"dashboard_address": "127.0.0.1:0"}) as c:
        yield c


def test_numpy_dask_and_distributed_give_identical_outputs(files, cluster, cli):
    from distributed import Client

    d, cube, sensor = files
    a = correct_cube(cube, sensor, 1.4, PAPER, resample=True, harmonise=True)
    b = correct_cube(cube.chunk({"y": 7, "x": 9}), sensor, 1.4, PAPER, resample=True,
                     harmonise=True)
    with Client(cluster):
        c = b.compute()
    xr.testing.assert_identical(a, b.compute())
    xr.testing.assert_identical(a, c)
    # and the command line on that cluster writes the same as in-process
    args = ["cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml", "--f-number", "1.4",
            "--resample", "--harmonise"]
    r1 = cli("correct", *args, "--out", "local.nc", cwd=d)
    r2 = cli("correct", *args, "--out", "cluster.zarr", "--scheduler",
             cluster.scheduler_address, cwd=d)
    assert r1.returncode == 0 and r2.returncode == 0, r1.stderr + r2.stderr
    one = read_dataset(d / "local.nc")
    two = read_dataset(d / "cluster.zarr")
    for name in ("reflectance", "wavelength_corrected", "resampled", "cra_deg", "harmonised",
                 "fwhm_corrected", "fwhm_harmonised"):
        np.testing.assert_array_equal(one[name].values, two[name].values)


def test_unreachable_scheduler_is_one_line(files, cli):
    d, _, _ = files
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "2", "--out", "x.nc", "--scheduler", "tcp://127.0.0.1:9", cwd=d)
    assert res.returncode == 1 and "scheduler" in res.stderr and "Traceback" not in res.stderr
    assert not (d / "x.nc").exists()


_PEAK = r"""
import resource, runpy, sys
from conftest import PAPER_LENS
sys.argv = ["snapcorr"] + sys.argv[1:]
try:
    runpy.run_module("snapcorr", run_name="__main__")
except SystemExit as e:
    assert not e.code, e.code
print("PEAK", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
"""


def _peak(args, cwd):
    res = subprocess.run([sys.executable, "-c", _PEAK, *args], capture_output=True, text=True,
                         timeout=600, cwd=cwd)
    assert res.returncode == 0, res.stderr
    return int(res.stdout.split("PEAK")[-1])


@pytest.mark.slow
@pytest.mark.parametrize("extra", [[], ["--harmonise", "--target-fwhm-nm", "30"]],
                         ids=["resample", "harmonise"])
def test_zarr_cube_larger_than_the_memory_limit_streams(tmp_path, extra):
    # A 1 GiB cube; the limit set here: beyond what a run on a small cube of the same kind
    # uses (imports, compiled code, buffers), the run may hold at most a third of the cube.
    # Measured: about 0.36 of it (chunks in flight), and not growing with the cube.
    sensor = Sensor("s", "snapscan", 2.0, np.linspace(500, 900, 128), 10.0, 1.7)
    sensor.save(tmp_path / "sensor.toml")
    PAPER.save(tmp_path / "lens.toml")
    import dask.array as da

    rng = da.random.default_rng(0)
    for name, rows in (("small", 64), ("big", 8192)):
        data = rng.random((rows, 256, 128), chunks=(128, 256, 128), dtype=np.float32)
        write_cube(make_cube(data, sensor.cwl_nm, name="reflectance"), tmp_path / f"{name}.zarr")
    nbytes = 8192 * 256 * 128 * 4
    args = ["--lens", "lens.toml", "--sensor", "sensor.toml", "--f-number", "1.4", "--resample",
            *extra]
    # the least of two runs each: how many chunks the scheduler keeps in flight varies from
    # run to run (+-40 MB here, measured), what a run needs does not
    baseline = min(_peak(["correct", "small.zarr", *args, "--out", f"small_out{k}.zarr"],
                         tmp_path) for k in range(2))
    peak = min(_peak(["correct", "big.zarr", *args, "--out", f"out{k}.zarr"], tmp_path)
               for k in range(2))
    assert peak - baseline < nbytes / 2.5, (peak - baseline) / nbytes
    out = xr.open_zarr(tmp_path / "out0.zarr", consolidated=False)
    assert out["resampled"].shape == (8192, 256, 128)
    big = xr.open_zarr(tmp_path / "big.zarr", consolidated=False)["reflectance"]
    ref = correct_cube(big[:64].load(), sensor, 1.4, PAPER, resample=True,
                       center_px=(127.5, 4095.5))  # the full cube's centre
    np.testing.assert_array_equal(out["resampled"][:64].values, ref["resampled"].values)
    if extra:  # one common response (asked for), so the crop's and the cube's agree
        ref = correct_cube(big[:64].load(), sensor, 1.4, PAPER, harmonise=True,
                           target_fwhm_nm=30.0, center_px=(127.5, 4095.5))
        np.testing.assert_allclose(out["harmonised"][:64].values, ref["harmonised"].values,
                                   atol=2e-5, equal_nan=True)


@pytest.mark.parametrize("no_input", [False, True], ids=["kept", "no-input"])
def test_an_envi_correction_of_a_flat_field_keeps_its_raw_counts(tmp_path, cli, no_input):
    """The camera's numbers sit beside what was computed from them in ENVI output too, as in
    .nc and .zarr: ``STEM_raw.hdr`` holds the flat-field result's raw counts, read back with
    Spectral Python (not snapcorr's reader); ``--no-input`` leaves them out with the input."""
    from spectral.io import envi

    from snapcorr.cube import flatfield, write_dataset

    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 5), 10.0, 1.7)
    sensor.save(tmp_path / "sensor.toml")
    PAPER.save(tmp_path / "lens.toml")
    rng = np.random.default_rng(1)
    counts = rng.integers(100, 900, (12, 16, 5)).astype(np.uint16)
    raw = make_cube(counts, sensor.cwl_nm, name="raw")
    dark = make_cube(np.full((12, 16, 5), 50, np.uint16), sensor.cwl_nm, name="dark")
    white = make_cube(np.full((12, 16, 5), 1000, np.uint16), sensor.cwl_nm, name="white")
    write_dataset(flatfield(raw, dark, white), tmp_path / "ff.nc")
    res = cli("correct", "ff.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "2", "--out", "out.hdr", *(["--no-input"] if no_input else []),
              cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "out_wavelength_corrected.hdr").exists()
    if no_input:
        assert not (tmp_path / "out_raw.hdr").exists() and not (tmp_path / "out.hdr").exists()
        return
    img = envi.open(str(tmp_path / "out_raw.hdr"), str(tmp_path / "out_raw.raw"))
    np.testing.assert_array_equal(np.asarray(img.load()), counts)
    refl = np.asarray(envi.open(str(tmp_path / "out.hdr"), str(tmp_path / "out.raw")).load())
    np.testing.assert_allclose(refl, (counts - 50.0) / 950.0, rtol=1e-6)
