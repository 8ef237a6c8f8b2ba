"""An unknown lens in one run: flats and a spectral target give x, n_eff, P, h and the centre.

The flats come from ``tests/oracles/flatsim.py`` and the target cubes from
``tests/oracles/spectralsim.py``, two simulators that share no code with snapcorr. The flats alone
fit equally well at any x
(they fix P / x and h / x^2); the target alone needs the circles. Neither the API nor the
command is given x.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import spectralsim as sim
from flatsim import LensTruth, make_flats, mean_shift_nm

from calibrate.pupil.test_locate import CENTER, N_EFF, PAPER, PITCH_UM, SHAPE, cubes, sensor
from snapcorr import Lens
from snapcorr.calibrate import calibrate_with_target
from snapcorr.cube import Sensor, make_cube, write_cube

FLAT_F_NUMBERS = (1.4, 2.0, 2.8, 4.0, 8.0)
TRUTH = {"exit_pupil_mm": PAPER.exit_pupil_mm, "n_eff": N_EFF, "P_mm": PAPER.circles[0][0],
         "h_mm": PAPER.circles[0][1], "center_row_px": CENTER[1], "center_col_px": CENTER[0]}


def one_run(seed, fit_n_eff=True, noise=0.002, magnifications=True):
    flats = make_flats(PAPER, FLAT_F_NUMBERS, shape=SHAPE, pitch_um=PITCH_UM,
                       center_px=CENTER, noise=0.005, seed=seed)
    given = (dict(magnification=PAPER.magnification,
                  pupil_magnification=PAPER.pupil_magnification) if magnifications else {})
    return calibrate_with_target(
        flats, cubes("colour_filter", "paper", (2.0, 8.0), noise=noise, seed=100 + seed),
        sensor(), pixel_pitch_um=PITCH_UM, fit_n_eff=fit_n_eff, **given, max_circles=1)


def z_scores(got):
    return {n: (v - TRUTH[n]) / e for n, v, e in zip(got.names, got.values, got.stderr,
                                                      strict=True)}


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_one_run_recovers_x_n_eff_p_h_and_the_centre_without_x():
    """x within 0.5 %, P, h and n_eff within 1 %, each within 3 of its standard error; the
    profile holds the joint covariance and the circles at the x found."""
    got = one_run(1)
    assert got.names == ("exit_pupil_mm", "n_eff", "P_mm", "h_mm", "center_row_px",
                         "center_col_px")
    rel = {n: v / TRUTH[n] - 1 for n, v in zip(got.names, got.values, strict=True)}
    assert abs(rel["exit_pupil_mm"]) < 0.005, got.summary()
    for n in ("n_eff", "P_mm", "h_mm"):
        assert abs(rel[n]) < 0.01, (n, got.summary())
    z = z_scores(got)
    assert all(abs(v) < 3 for v in z.values()), z
    # the covariance: symmetric, positive definite, and P's error carries x's (dP/dx = P/x)
    cov = got.covariance
    assert np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)
    i, p = got.names.index("exit_pupil_mm"), got.names.index("P_mm")
    P, x = got.values[p], got.values[i]
    assert cov[p, i] == pytest.approx(P / x * cov[i, i], rel=1e-9)
    assert got.stderr[p] > P / x * got.stderr[i]
    # the profile: the circles at the x found, and everything to rebuild the covariance
    lens = got.lens
    assert lens.exit_pupil_mm == pytest.approx(x)
    assert lens.vignetting[0] == pytest.approx((P, got.values[got.names.index("h_mm")]),
                                               rel=1e-6)
    joint = lens.calibration["joint"]
    assert joint["names"] == list(got.names)
    assert np.allclose(joint["covariance"], cov, rtol=1e-5, atol=0)
    assert lens.calibration["exit_pupil_scaling"]["exit_pupil_stderr_mm"] == pytest.approx(
        got.stderr[i])
    # x's error moves every pixel's angle and the scaled circles: its part of the shift's
    # error, against the independent simulator's pupil quadrature at x -+ its error
    sx = got.stderr[i]
    d = np.linspace(0.0, x * np.tan(np.radians(got.calibration.max_cra_deg)), 25)
    for f, part in zip(FLAT_F_NUMBERS, got.shift_stderr_exit_pupil_nm, strict=True):
        shifts = []
        for xi in (x - sx, x + sx):
            k = xi / x
            truth = LensTruth(xi, [(P * k, got.values[got.names.index("h_mm")] * k * k)],
                              PAPER.magnification, PAPER.pupil_magnification)
            shifts.append(mean_shift_nm(truth, 1000.0, 1.5, f, np.degrees(np.arctan(d / xi))))
        want = np.nanmax(np.abs(shifts[1] - shifts[0])) / 2
        assert part == pytest.approx(want, rel=0.05, abs=2e-5), (f, part, want)
    assert not got.notes, got.notes  # both calibrations agree on P / x and h / x^2


@pytest.mark.slow
@pytest.mark.parametrize("fit_n_eff", [True, False])
def test_the_joint_errors_cover_over_seeds(fit_n_eff):
    """Over 8 seeds of independent flats and target cubes: every error within 0.5 % (x) or
    1 % (the rest), every |z| < 3.5, and the RMS z of each parameter in [0.5, 2]."""
    zs = []
    for seed in range(8):
        got = one_run(10 + seed, fit_n_eff)
        rel = {n: v / TRUTH[n] - 1 for n, v in zip(got.names, got.values, strict=True)}
        assert abs(rel["exit_pupil_mm"]) < 0.005 and all(
            abs(rel[n]) < 0.01 for n in rel), got.summary()
        zs.append(list(z_scores(got).values()))
    zs = np.asarray(zs)
    assert np.all(np.abs(zs) < 3.5), zs
    rms = np.sqrt(np.mean(zs**2, axis=0))
    assert np.all((rms > 0.5) & (rms < 2.0)), (got.names, rms)


# -- the command -------------------------------------------------------------------------------
CLI_SHAPE = (96, 120)
CLI_CENTER = (61.0, 46.5)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("unknown_lens")
    cwl = np.arange(500.0, 849.0, 12.0)
    Sensor("test", "snapscan", PITCH_UM, cwl, 12.0, 1.7, size_px=CLI_SHAPE).save(
        d / "sensor.toml")
    flats = make_flats(PAPER, FLAT_F_NUMBERS, shape=CLI_SHAPE, pitch_um=PITCH_UM,
                       center_px=CLI_CENTER, noise=0.005, seed=3)
    for f, img in flats.items():
        np.save(d / f"flat_f{f:g}.npy", img.astype(np.float32))
    rng = np.random.default_rng(8)
    for f in (2.0, 8.0):
        data = sim.target_cube(sim.colour_filter, cwl_nm=cwl, fwhm_nm=12.0, n_eff=1.7,
                               f_number=f, lens=PAPER, shape=CLI_SHAPE,
                               pixel_pitch_um=PITCH_UM, center_px=CLI_CENTER)
        data = (data + rng.normal(0, 0.003, data.shape)).astype(np.float32)
        write_cube(make_cube(data, cwl), d / f"target_f{f:g}.nc")
    return d


def _args(d):
    flats = [a for f in FLAT_F_NUMBERS for a in ("--flat", f"{f:g}={d / f'flat_f{f:g}.npy'}")]
    return [*flats, "--target-cube", f"2={d / 'target_f2.nc'}", "--target-cube",
            f"8={d / 'target_f8.nc'}", "--sensor", d / "sensor.toml",
            "--pixel-pitch-um", str(PITCH_UM), "--magnification", "0.06",
            "--pupil-magnification", "1.3", "--max-circles", "1", "--pupil", "paper"]


def test_calibrate_with_target_cubes_writes_one_consistent_profile(files, cli):
    out, sensor_out = files / "lens.toml", files / "sensor_fitted.toml"
    res = cli("calibrate", *_args(files), "--fit-n-eff", "--out", out,
              "--sensor-out", sensor_out)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "jointly (flats + target" in res.stdout
    lens = Lens.load(out)
    assert abs(lens.exit_pupil_mm / 21.0 - 1) < 0.005
    (P, h), = lens.vignetting
    assert abs(P / PAPER.circles[0][0] - 1) < 0.01 and abs(h / PAPER.circles[0][1] - 1) < 0.01
    cal = lens.calibration
    assert abs(cal["n_eff"] / 1.7 - 1) < 0.01
    assert cal["joint"]["names"][:2] == ["exit_pupil_mm", "n_eff"]
    assert "shift_stderr_exit_pupil_nm" in cal and "exit_pupil_fit" in cal
    assert cal["dark"].startswith("none given")
    assert Sensor.load(sensor_out).n_eff[0] == pytest.approx(cal["n_eff"], rel=1e-5)


@pytest.mark.parametrize("extra, words", [
    (["--exit-pupil-mm", "21"], "leave out --exit-pupil-mm"),
    (["--sensor-out", "s.toml"], "--sensor-out needs --fit-n-eff"),
])
def test_calibrate_with_target_cubes_refuses_contradictions(files, cli, extra, words, tmp_path):
    res = cli("calibrate", *_args(files), *extra, "--out", tmp_path / "l.toml")
    assert res.returncode == 1 and words in res.stderr, res.stderr
    assert "Traceback" not in res.stderr and not (tmp_path / "l.toml").exists()


def test_calibrate_without_x_says_the_three_ways(files, cli, tmp_path):
    res = cli("calibrate", "--flat", f"2={files / 'flat_f2.npy'}", "--flat",
              f"8={files / 'flat_f8.npy'}", "--pixel-pitch-um", "44", "--out",
              tmp_path / "l.toml")
    assert res.returncode == 1 and "--target-cube" in res.stderr, res.stderr
    res = cli("calibrate", "--flat", f"2={files / 'flat_f2.npy'}", "--flat",
              f"8={files / 'flat_f8.npy'}", "--pixel-pitch-um", "44", "--exit-pupil-mm", "21",
              "--fit-n-eff", "--out", tmp_path / "l.toml")
    assert res.returncode == 1 and "goes with --target-cube" in res.stderr, res.stderr


def test_pupil_is_the_earlier_name_of_pupil_radiance():
    """The old keyword warns and reaches the calibration as the new one does (a model that is
    none is refused by both, naming it, before any fit)."""
    flats = make_flats(PAPER, (2.0, 8.0), shape=SHAPE, pitch_um=PITCH_UM, center_px=CENTER,
                       noise=0.005, seed=1)
    data = cubes("colour_filter", "paper", (2.0, 8.0), noise=0.002, seed=101)
    said = {}
    for key in ("pupil", "pupil_radiance"):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            with pytest.raises(ValueError, match=r"pupil_radiance must be one of .*'uniform'"):
                calibrate_with_target(flats, data, sensor(), pixel_pitch_um=PITCH_UM,
                                      **{key: "uniform"})
        said[key] = [str(w.message) for w in seen if w.category is FutureWarning]
    assert len(said["pupil"]) == 1 and said["pupil"][0].startswith(
        "pupil is the earlier name of pupil_radiance and will be removed in snapcorr 0.3")
    assert said["pupil_radiance"] == []
    with pytest.raises(TypeError, match="give pupil_radiance once"):
        calibrate_with_target(flats, data, sensor(), pixel_pitch_um=PITCH_UM, pupil="paper",
                              pupil_radiance="paper")


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_the_centre_is_taken_row_first_and_its_x_first_form_warns():
    """center_rc=(row, col), off both middles of the frame, is the flats' centre, held, and
    the target's, carried to the cubes by the flats' lens; center_px=(cx, cy), the x-first
    form of 0.1, gives the same calibration and warns."""
    row, col = 37.25, 81.5
    flats = make_flats(PAPER, FLAT_F_NUMBERS, shape=SHAPE, pitch_um=PITCH_UM,
                       center_px=(col, row), noise=0.005, seed=4)
    data = cubes("colour_filter", "paper", (2.0, 8.0), noise=0.002, seed=104,
                 center=(col, row))
    kw = dict(pixel_pitch_um=PITCH_UM, magnification=PAPER.magnification,
              pupil_magnification=PAPER.pupil_magnification, max_circles=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)
        new = calibrate_with_target(flats, data, sensor(), center_rc=(row, col), **kw)
        assert new.calibration.center_rc == (row, col)
        assert new.calibration.center_source == "given"
        assert new.pupil.center_rc == (row, col)
    assert abs(new.pupil.exit_pupil_mm / PAPER.exit_pupil_mm - 1) < 0.01, new.summary()
    assert abs(new.lens.vignetting[0][0] / PAPER.circles[0][0] - 1) < 0.01, new.summary()
    cal = new.lens.calibration
    assert cal["center_rc"] == [row, col] and cal["exit_pupil_fit"]["center_rc"] == [row, col]
    with pytest.warns(FutureWarning, match=r"center_px is the old x-first form .* "
                                           r"center_rc=\(37\.25, 81\.5\)"):
        old = calibrate_with_target(flats, data, sensor(), center_px=(col, row), **kw)
    assert old.names == new.names
    np.testing.assert_array_equal(old.values, new.values)
    np.testing.assert_array_equal(old.covariance, new.covariance)
    assert {k: v for k, v in old.lens.calibration.items() if k != "date"} == \
        {k: v for k, v in cal.items() if k != "date"}
    with pytest.raises(TypeError, match="give the optical centre once"):
        calibrate_with_target(flats, data, sensor(), center_rc=(row, col),
                              center_px=(col, row), **kw)


@pytest.mark.parametrize("given", [["--center", "37.25,81.5"], ["--center-px", "81.5,37.25"]],
                         ids=["center", "center-px"])
def test_the_command_gives_the_centre_row_first(files, cli, monkeypatch, tmp_path, given):
    """calibrate --target-cube: --center ROW,COL reaches the calibration as center_rc=(row,
    col); --center-px CX,CY, its deprecated x-first form, as the same row-first pair."""
    import snapcorr.calibrate

    seen = {}

    def capture(*args, **kwargs):
        seen.update(kwargs)
        raise ValueError("stopped here")

    monkeypatch.setattr(snapcorr.calibrate, "calibrate_with_target", capture)
    res = cli("calibrate", *_args(files), *given, "--out", tmp_path / "l.toml")
    assert res.returncode == 1 and "stopped here" in res.stderr, res.stderr
    assert seen["center_rc"] == (37.25, 81.5) and "center_px" not in seen
    assert ("--center-px CX,CY is deprecated" in res.stderr) == (given[0] == "--center-px")


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
def test_flats_and_cubes_of_a_crop_keep_their_origin_in_the_profile():
    """Flats and target cubes of a crop at sensor row 16, col 20 (``sensor_origin_px``): the
    profile held the centre in the crop's pixels and not the crop's origin, so a reader took
    it as sensor pixels, 16 rows and 20 columns off. The origin is recorded, and the centre
    carried through it lands on the simulators' axis."""
    from snapcorr.correct.geometry import optical_center_rc

    r0, c0 = 16, 20
    flats = {f: v[r0:, c0:] for f, v in make_flats(
        PAPER, FLAT_F_NUMBERS, shape=SHAPE, pitch_um=PITCH_UM, center_px=CENTER, noise=0.005,
        seed=3).items()}
    data = {f: c.isel(y=slice(r0, None), x=slice(c0, None)) for f, c in cubes(
        "colour_filter", "paper", (2.0, 8.0), noise=0.002, seed=103).items()}
    got = calibrate_with_target(flats, data, sensor(), pixel_pitch_um=PITCH_UM,
                                magnification=PAPER.magnification,
                                pupil_magnification=PAPER.pupil_magnification, max_circles=1,
                                sensor_origin_px=(r0, c0))
    assert got.lens.calibration["sensor_origin_rc"] == [r0, c0]
    assert not any("could not be carried" in n for n in got.notes), got.notes
    assert abs(got.pupil.center_rc[0] - CENTER[1]) < 0.5, got.pupil.center_rc  # the flats'
    whole = make_cube(np.zeros((*SHAPE, sensor().n_bands)), sensor().cwl_nm)
    (row, col), _ = optical_center_rc(whole, sensor(), got.lens)
    assert abs(row - CENTER[1]) < 0.5 and abs(col - CENTER[0]) < 0.5, (row, col)


def test_the_two_calibrations_are_compared_circle_for_circle_in_either_order():
    """Two right circles that the fits at the provisional x and at the final x listed in the
    other order were said to differ by 110 %; a real change of scale is still said."""
    from types import SimpleNamespace

    from snapcorr.calibrate.unknown_lens import _consistency

    def cal(circles):
        return SimpleNamespace(model="two", lens=SimpleNamespace(vignetting=circles))

    x0, x = 15.0, 21.0
    k = x / x0
    first = cal([(7.42 / k, 17.0 / k**2), (10.5 / k, 35.0 / k**2)])
    assert _consistency(first, cal([(10.5, 35.0), (7.42, 17.0)]), x0, x) == []
    assert _consistency(first, cal([(7.42, 17.0), (10.5, 35.0)]), x0, x) == []
    said = _consistency(first, cal([(7.42, 17.0), (10.5, 40.0)]), x0, x)
    assert len(said) == 1 and "differ by 14 %" in said[0], said
