"""`snapcorr pupil`: target cubes to a lens profile with x (and n_eff); mistakes are one line,
and nothing is written when the target cannot tell x."""

from __future__ import annotations

import numpy as np
import pytest
import spectralsim as sim
from conftest import PAPER_TRUTH

from snapcorr import Lens
from snapcorr.cube import Sensor, make_cube, write_cube

PITCH_UM, SHAPE = 44.0, (96, 120)
CWL = np.arange(500.0, 849.0, 12.0)
TRUTH = PAPER_TRUTH
WHITE_SHAPE, WHITE_CWL = (64, 80), np.arange(500.0, 644.0, 12.0)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("pupil")
    sensor = Sensor("test", "snapscan", PITCH_UM, CWL, 12.0, 1.7, size_px=SHAPE)
    sensor.save(d / "sensor.toml")
    Lens(30.0, TRUTH.circles, TRUTH.magnification, TRUTH.pupil_magnification,
         name="circles known").save(d / "lens_ph.toml")
    rng = np.random.default_rng(7)
    for f in (2.0, 8.0):
        data = sim.target_cube(sim.rare_earth_glass, cwl_nm=CWL, fwhm_nm=12.0, n_eff=1.7,
                               f_number=f, lens=TRUTH, shape=SHAPE, pixel_pitch_um=PITCH_UM,
                               center_px=(61.0, 46.5))
        data = (data + rng.normal(0, 0.01, data.shape)).astype(np.float32)
        write_cube(make_cube(data, CWL), d / f"glass_f{f:g}.nc")
    # the white tile on a smaller sensor (its refusal refits the search twice)
    Sensor("test", "snapscan", PITCH_UM, WHITE_CWL, 12.0, 1.7, size_px=WHITE_SHAPE).save(
        d / "sensor_white.toml")
    for f in (2.0, 8.0):
        data = sim.target_cube(sim.white, cwl_nm=WHITE_CWL, fwhm_nm=12.0, n_eff=1.7,
                               f_number=f, lens=TRUTH, shape=WHITE_SHAPE,
                               pixel_pitch_um=PITCH_UM, center_px=(40.0, 31.5))
        data = (data + rng.normal(0, 0.01, data.shape)).astype(np.float32)
        write_cube(make_cube(data, WHITE_CWL), d / f"white_f{f:g}.nc")
    np.savetxt(d / "glass.csv", np.column_stack([np.arange(400.0, 950.0, 0.25),
                                                 sim.rare_earth_glass(np.arange(400.0, 950.0,
                                                                                0.25))]),
               delimiter=",", header="wavelength_nm,transmittance")
    return d


def snapshot(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


def test_pupil_writes_the_lens_with_x_n_eff_and_provenance(files, cli):
    out, plot = files / "lens_x.toml", files / "lens_x.png"
    sensor_out = files / "sensor_fitted.toml"
    res = cli("pupil", "--cube", f"2={files / 'glass_f2.nc'}",
              "--cube", f"f/8={files / 'glass_f8.nc'}", "--sensor", files / "sensor.toml",
              "--lens", files / "lens_ph.toml", "--fit-n-eff", "--out", out,
              "--plot", plot, "--sensor-out", sensor_out)
    text = res.stdout
    assert res.returncode == 0, text
    lens = Lens.load(out)
    assert abs(lens.exit_pupil_mm - 21.0) < 0.25
    assert lens.vignetting == TRUTH.circles  # P and h copied from --lens
    cal = lens.calibration
    assert abs(cal["n_eff"] - 1.7) < 0.025
    for key in ("exit_pupil_stderr_mm", "n_eff_stderr", "reduced_chi2", "f_numbers", "inputs",
                "method", "center_px", "snapcorr_version", "target_spectrum"):
        assert key in cal
    assert cal["f_numbers"] == [2.0, 8.0]
    assert plot.stat().st_size > 10_000
    assert "exit pupil x =" in text and "n_eff =" in text
    # the precision the cubes can give, said before the fit, and recorded
    assert "predicted: this target can give x +-" in text
    assert text.index("predicted:") < text.index("exit pupil x =")
    assert cal["predicted_before_fit"]["tolerance_nm"] == 0.05
    # the circles of --lens belong to its pupil: kept, not chosen again
    assert lens.pupil_radiance == "paper" and "pupil_choice" not in cal
    # the sensor with the fitted index, for `snapcorr correct`, says where it came from
    fitted = Sensor.load(sensor_out)
    assert np.allclose(fitted.n_eff, cal["n_eff"]) and fitted.cwl_nm == tuple(CWL)
    assert fitted.calibration["n_eff_from"] == str(out)
    assert fitted.calibration["n_eff_design"] == [1.7] * CWL.size
    assert str(sensor_out) in text


def test_a_known_spectrum_from_a_file(files, cli):
    out = files / "lens_known.toml"
    res = cli("pupil", "--cube", f"2={files / 'glass_f2.nc'}", "--sensor",
              files / "sensor.toml", "--target-spectrum", files / "glass.csv",
              "--magnification", "0.06", "--pupil-magnification", "1.3",
              "--center", "46.5,61", "--out", out)
    assert res.returncode == 0, res
    lens = Lens.load(out)
    # --pupil auto (the default without circles): both pupils fitted, the paper's kept for
    # these cubes of the paper's pupil
    choice = lens.calibration["pupil_choice"]
    assert "pupil: paper" in res.stdout and choice["chosen"] == "paper" == lens.pupil_radiance
    assert res.stdout.count("predicted:") == 1  # the precision said once, not per pupil
    assert choice["chi2"]["lambertian"] > choice["chi2"]["paper"] + 10
    assert abs(lens.exit_pupil_mm - 21.0) < 0.21
    assert "given" in lens.calibration["target_spectrum"]
    assert lens.calibration["center_source"] == "given"


@pytest.mark.parametrize(("args", "message"), [
    (["--cube", "2={d}/white_f2.nc", "--cube", "8={d}/white_f8.nc", "--sensor",
      "{d}/sensor_white.toml"], "cannot pin x to the shift precision asked"),
    (["--cube", "2={d}/glass_f2.nc", "--cube", "2={d}/glass_f8.nc"], "given twice"),
    (["--cube", "2={d}/missing.nc"], "missing.nc"),
    ([], "give --cube"),
    (["--cube", "2={d}/glass_f2.nc", "--target-spectrum", "{d}/sensor.toml"],
     "not numbers"),
    (["--cube", "2={d}/glass_f2.nc", "--cube", "8={d}/glass_f8.nc", "--sensor-out",
      "{d}/sensor_never.toml"], "--sensor-out needs --fit-n-eff"),
    (["--cube", "2={d}/glass_f2.nc", "--fit-n-eff", "--sensor-out", "{d}/sensor_never.toml"],
     "two or more f-numbers"),
    (["--cube", "2={d}/glass_f2.nc", "--lens", "{d}/lens_ph.toml", "--pupil", "lambertian"],
     "belong to the paper pupil"),
    # a precision no target reaches: refused before the fit, saying what it would give
    (["--cube", "2={d}/glass_f2.nc", "--lens", "{d}/lens_ph.toml", "--tolerance-nm", "1e-6"],
     "above the tolerance of 1e-06 nm"),
    (["--cube", "2={d}/glass_f2.nc", "--tolerance-nm", "0"], "--tolerance-nm"),
    (["--cube", "2={d}/glass_f2.nc", "--tolerance-nm", "nan"], "--tolerance-nm"),
    # the planning options of --predict are not taken silently by a fit
    (["--cube", "2={d}/glass_f2.nc", "--cube", "8={d}/glass_f8.nc", "--f-number", "4"],
     "--f-number and --noise-pct describe a measurement to plan with --predict"),
    (["--cube", "2={d}/glass_f2.nc", "--noise-pct", "2"], "--predict"),
])
def test_mistakes_are_one_line_and_write_nothing(files, cli, args, message):
    before = snapshot(files)
    out = files / "never.toml"
    sensor = [] if "--sensor" in args else ["--sensor", files / "sensor.toml"]
    res = cli("pupil", *[a.format(d=files) for a in args], *sensor, "--out", out)
    err = res.stderr
    assert res.returncode != 0
    errors = [line for line in err.splitlines() if "error" in line]
    assert len(errors) == 1 and message in errors[0], err
    assert "Traceback" not in err and "warning" not in err
    assert not out.exists()
    assert snapshot(files) == before


def test_an_input_is_never_the_output(files, cli):
    before = snapshot(files)
    res = cli("pupil", "--cube", f"2={files / 'glass_f2.nc'}", "--sensor",
              files / "sensor.toml", "--out", files / "sensor.toml", "--overwrite")
    assert res.returncode == 1
    assert "also an input" in res.stderr
    assert snapshot(files) == before


def test_predict_ranks_the_targets(files, cli):
    res = cli("pupil", "--predict", "--sensor", files / "sensor.toml", "--f-number", "2",
              "--f-number", "8", "--noise-pct", "2", "--target-spectrum", files / "glass.csv")
    text = res.stdout
    assert res.returncode == 0
    rows = {line.split("  ")[0].strip(): line for line in text.splitlines()[2:]}
    assert "no information" in rows["white tile"]
    assert "mm (" in rows["rare-earth glass"]
    assert any("glass.csv" in k for k in rows)
    # bands to 878 nm: the chart's published spectra end at 780 nm, and it is not judged
    chart = rows["ColorChecker (24 patches)"]
    assert "not judged" in chart and "380-780 nm" in chart and "470-878 nm" in chart


@pytest.mark.parametrize("extra", [["--out", "{d}/never.toml"], ["--plot", "{d}/never.png"],
                                   ["--magnification", "0.06"], ["--center", "5,5"],
                                   ["--tolerance-nm", "0.1"], ["--overwrite"]])
def test_predict_refuses_the_options_of_a_fit(files, cli, extra):
    """--predict writes nothing and takes the lens from --lens: a fit's options are refused
    by name, not ignored."""
    before = snapshot(files)
    res = cli("pupil", "--predict", "--sensor", files / "sensor.toml", "--f-number", "2",
              *[a.format(d=files) for a in extra])
    assert res.returncode != 0
    assert extra[0] in res.stderr and "not --predict" in res.stderr
    assert "Traceback" not in res.stderr
    assert snapshot(files) == before


def test_predict_judges_a_colour_chart_on_a_visible_sensor(files, cli):
    """Bands within 380-780 nm: the chart's best patch gets its row (spectrum unknown and
    known), the next ones and the least informative said after it."""
    res = cli("pupil", "--predict", "--sensor", files / "sensor_white.toml", "--f-number",
              "2", "--f-number", "8", "--fit-n-eff")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.startswith("ColorChecker "))
    assert lines[i].count("mm (") == 2  # spectrum unknown, known
    assert "the best of the chart's 24 patches" in lines[i + 1]
    assert "the least, " in lines[i + 1]


def test_help_shows_the_two_step_workflow(cli):
    res = cli("pupil", "--help")
    assert res.returncode == 0
    text = res.stdout
    assert "--predict" in text and "snapcorr calibrate" in text
    assert "circles are scaled to the x found" in text
    assert "--sensor-out" in text


@pytest.mark.parametrize("given", [["--center", "37.25,81.5"], ["--center-px", "81.5,37.25"]],
                         ids=["center", "center-px"])
def test_the_centre_reaches_the_fit_row_first(files, cli, monkeypatch, tmp_path, given):
    """--center ROW,COL reaches the fit as center_rc=(row, col); --center-px CX,CY, its
    deprecated x-first form, as the same row-first pair, said on stderr."""
    import snapcorr.calibrate

    seen = {}

    def capture(*args, **kwargs):
        seen.update(kwargs)
        raise ValueError("stopped here")

    monkeypatch.setattr(snapcorr.calibrate, "locate_pupil", capture)
    res = cli("pupil", "--cube", f"2={files / 'glass_f2.nc'}", "--sensor",
              files / "sensor.toml", *given, "--out", tmp_path / "l.toml")
    assert res.returncode == 1 and "stopped here" in res.stderr, res.stderr
    assert seen["center_rc"] == (37.25, 81.5) and "center_px" not in seen
    assert ("--center-px CX,CY is deprecated" in res.stderr) == (given[0] == "--center-px")


@pytest.mark.parametrize("command", ["pupil", "calibrate"])
def test_the_pupil_radiance_option_and_its_earlier_name_are_one(command):
    """--pupil-radiance names what it chooses (Lens.pupil_radiance: how light fills the exit
    pupil); --pupil, its earlier name, gives the same value."""
    from snapcorr.cli import build_parser

    base = (["pupil", "--sensor", "s.toml"] if command == "pupil"
            else ["calibrate", "--flat", "2=f.npy", "--out", "l.toml"])
    parser = build_parser()
    new = parser.parse_args([*base, "--pupil-radiance", "lambertian"])
    old = parser.parse_args([*base, "--pupil", "lambertian"])
    assert new.pupil == old.pupil == "lambertian"
    assert "--pupil-radiance" in parser._subparsers._group_actions[0].choices[command] \
        .format_help()
