"""`snapcorr budget` and `snapcorr correct --source`: the model a scene needs."""

import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_LENS

from snapcorr import budget, spectra
from snapcorr.cube import Sensor, make_cube, read_dataset, write_cube

PAPER = PAPER_LENS


@pytest.fixture
def files(tmp_path):
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 5), 10.0, 1.7)
    sensor.save(tmp_path / "sensor.toml")
    Sensor("sized", "snapscan", 5.5, np.linspace(500, 900, 5), 10.0, 1.7,
           size_px=(1024, 1024)).save(tmp_path / "sized.toml")
    PAPER.save(tmp_path / "lens.toml")
    lam = np.arange(300.0, 1100.0, 0.5)
    np.savetxt(tmp_path / "flat.csv", np.c_[lam, np.ones_like(lam)], delimiter=",",
               header="wavelength_nm,value")
    data = np.random.default_rng(0).random((30, 40, 5)).astype(np.float32) + 0.5
    write_cube(make_cube(data, sensor.cwl_nm, name="reflectance"), tmp_path / "cube.nc")
    return tmp_path


def test_budget_prints_the_table_and_the_library_recommendation(files, cli):
    res = cli("budget", "--sensor", "sized.toml", "--lens", "lens.toml", "--f-number", "4",
              "--source", "solar", "--tolerance-pct", "1", "--plot", "b.png", cwd=files)
    assert res.returncode == 0, res.stderr
    sensor = Sensor.load(files / "sized.toml")
    cra_max = np.degrees(np.arctan(sensor.field_radius_mm / PAPER.exit_pupil_mm))
    b = budget.scene_budget(spectra.solar(), sensor, 4.0, PAPER, cra_max_deg=cra_max,
                            tolerance_pct=1.0)
    model, reason = b.recommend()
    assert f"recommended: {model}: {reason}" in res.stdout
    assert "1024 x 1024 px field" in res.stdout
    (row,) = [line for line in res.stdout.splitlines() if line.lstrip().startswith("all")]
    for m in budget.MODELS:
        assert f"{b.worst_pct(m):.3g}%" in row
    assert (files / "b.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_budget_table_says_na_where_the_source_ends_near_a_band(files, cli):
    lam = np.arange(400.0, 910.6, 0.5)  # reaches the 900 nm band, not its 5 nm shifts
    np.savetxt(files / "short.csv", np.c_[lam, 1 + 0.001 * lam], delimiter=",")
    res = cli("budget", "--sensor", "sensor.toml", "--lens", "lens.toml", "--f-number", "4",
              "--source", "short.csv", "--cra-max", "10", "--profile", "multi_lorentzian",
              cwd=files)
    assert res.returncode == 0, res.stderr
    (row,) = [line for line in res.stdout.splitlines() if line.startswith("   4 ")]
    assert "n/a" in row


def test_budget_of_a_flat_source_recommends_no_correction(files, cli):
    res = cli("budget", "--sensor", "sensor.toml", "--lens", "lens.toml", "--f-number", "1.4",
              "--source", "flat.csv", "--cra-max", "15", cwd=files)
    assert res.returncode == 0, res.stderr
    assert "recommended: none" in res.stdout and "over the whole field" in res.stdout


@pytest.mark.parametrize("args, message", [
    (["--source", "sun"], "unknown source"),
    (["--source", "tungsten:warm"], "temperature"),
    (["--source", "cube"], "give --cube"),
    (["--sensor", "sensor.toml"], "size_px"),
    (["--cra-max", "80"], "cut-off"),
    (["--tolerance-pct", "0"], "--tolerance-pct"),
    (["--plot", "b.jpg"], ".png"),
    (["--plot", "lens.toml"], "also an input"),
    (["--plot", "old.png"], "exists"),
    (["--cube", "cube.nc"], "bands"),
    (["--source", "missing.csv"], "no spectrum file"),
    (["--lens", "nolens.toml"], "nolens.toml"),
    (["--f-number", "-1"], "--f-number"),
])
def test_budget_mistakes_are_one_line(files, args, message, cli):
    (files / "old.png").write_bytes(b"keep")
    Sensor("s7", "snapscan", 40.0, np.linspace(500, 900, 7), 10.0, 1.7,
           size_px=(100, 100)).save(files / "s7.toml")
    base = {"--sensor": "sized.toml", "--lens": "lens.toml", "--f-number": "2",
            "--source": "tungsten:2856"}
    if "--cube" in args:
        base["--sensor"] = "s7.toml"  # 7 bands against the cube's 5
    for flag, value in zip(args[::2], args[1::2], strict=True):
        base[flag] = value
    res = cli("budget", *[v for kv in base.items() for v in kv], cwd=files)
    assert res.returncode in (1, 2)  # 2: usage
    err = res.stderr
    assert message in err and len(err.strip().splitlines()) == 1, err
    assert not (files / "b.jpg").exists() and (files / "old.png").read_bytes() == b"keep"


def test_correct_with_a_source_uses_the_budget(files, cli):
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "4", "--source", "flat.csv", "--out", "flat.nc", cwd=files)
    assert res.returncode == 0, res.stderr
    ds = read_dataset(files / "flat.nc")
    # a flat scene: no shift changes its signal, so no correction is needed
    assert ds.attrs["method"] == "none" and ds.attrs["budget_source"] == "flat.csv"
    assert ds.attrs["tolerance_pct"] == 0.5
    np.testing.assert_array_equal(ds["wavelength_corrected"].values[..., 2],
                                  np.float32(700.0))
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "1.4", "--source", "solar", "--tolerance-pct", "0.2",
              "--out", "sun.nc", cwd=files)
    assert res.returncode == 0, res.stderr
    ds = xr.open_dataset(files / "sun.nc")
    # the sun's lines within a band: the budget asks for one response per band too
    assert ds.attrs["method"] == "harmonised" and "sun" in ds.attrs["method_reason"]
    assert "harmonised" in ds and ds.attrs["method_requested"] == "auto"
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "4", "--source", "solar", "--method", "ideal", "--out", "x.nc",
              cwd=files)
    assert res.returncode != 0 and "--method auto" in res.stderr
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "4", "--tolerance-pct", "1", "--out", "x.nc", cwd=files)
    assert res.returncode != 0 and "give --source" in res.stderr
    assert not (files / "x.nc").exists()


def test_correct_with_the_cubes_own_spectrum_on_the_command_line(files, tmp_path, cli):
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 21), 10.0, 1.7)
    sensor.save(tmp_path / "s21.toml")
    step = np.where(np.asarray(sensor.cwl_nm) < 700, 1.0, 0.05).astype(np.float32)
    write_cube(make_cube(np.broadcast_to(step, (20, 30, 21)).copy(), sensor.cwl_nm),
               tmp_path / "edge.nc")  # tmp_path is the folder of `files` (lens.toml)
    res = cli("correct", "edge.nc", "--lens", "lens.toml", "--sensor", "s21.toml",
              "--f-number", "1.4", "--source", "cube", "--tolerance-pct", "0.01", "--out",
              "out.zarr", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    ds = xr.open_zarr(tmp_path / "out.zarr", consolidated=False)
    assert ds.attrs["budget_source"] == "cube mean" and ds.attrs["method"] != "none"
    assert "no model is within" in ds.attrs["method_reason"]
    assert "harmonised" in ds and "harmonised:" in res.stdout  # what the budget chose


def test_budget_refusals_name_their_cause(tmp_path, cli):
    """A source in micrometres said 'the spectrum does not cover the band and its shifts'
    (no file, no ranges), as did one too short, without its range; a --center far off the
    cube was refused as '--cra-max must lie in [0, 36.21)', an option not given."""
    import numpy as np

    lam = np.arange(400.0, 701.0, 5.0)
    np.savetxt(tmp_path / "um.csv", np.column_stack([lam / 1000, np.ones_like(lam)]))
    np.savetxt(tmp_path / "short.csv", np.array([[500.0, 1.0], [560.0, 1.2]]))
    base = ("budget", "--sensor", "mosaic_4x4_vis", "--lens", "edmund_optics_16mm",
            "--f-number", "2")
    res = cli(*base, "--source", "um.csv", cwd=tmp_path)
    assert res.returncode == 1 and "--source um.csv: its wavelengths must be in nanometres" \
        in res.stderr and "look like micrometres" in res.stderr, res.stderr
    res = cli(*base, "--source", "short.csv", cwd=tmp_path)
    assert res.returncode == 1 and "the spectrum (500-560 nm) does not cover the band at" \
        in res.stderr and "nm and its shifts (" in res.stderr, res.stderr
    cube = np.full((8, 10, 16), 0.5, np.float32)
    np.save(tmp_path / "c.npy", cube)
    res = cli(*base, "--source", "cube:2,2", "--cube", "c.npy", "--sensor-origin-px", "400,800",
              "--center", "99999,99999", cwd=tmp_path)
    assert res.returncode == 1 and "beyond the lens's full cut-off at f/2" in res.stderr \
        and "check --center" in res.stderr and "--cra-max must" not in res.stderr, res.stderr
