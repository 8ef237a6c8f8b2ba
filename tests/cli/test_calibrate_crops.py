"""`snapcorr calibrate` of flats that are a crop of the sensor: --center in sensor pixels as
every command takes it, flats and target cubes of the same pixels, the phase of raw vendor
flats, a centre the flats cannot show said to be assumed, a flat field's result refused."""

import argparse

import numpy as np
import pytest

from snapcorr import Lens

#: The sensor mosaic_4x4_vis: 1088 x 2048 px, its optical centre (the simulator's) at the
#: middle; crop A is rows 400:656, columns 800:1120.
TRUE_CENTER = (543.5, 1023.5)
ORIGIN = (400, 800)
CROP = (slice(400, 656), slice(800, 1120))
FLATS = ["--flat", "2=white_f2.npy", "--flat", "4=white_f4.npy", "--flat", "11=white_f11.npy",
         "--dark", "dark.npy", "--sensor", "mosaic_4x4_vis", "--magnification", "0.06",
         "--pupil-magnification", "1.3", "--max-circles", "1"]
TARGET = ["--pupil-radiance", "paper", "--target-tolerance-nm", "5"]


@pytest.fixture(scope="module")
def crops(tmp_path_factory):
    """Crop A of the bundled camera's whites at f/2, 4, 11 and its dark; target cubes
    flat-fielded (snapcorr flatfield) from crop A, from a 128 x 160 crop at the sensor's first
    pixel and from crop A less its first four rows."""
    from conftest import run_cli

    import snapcorr.data

    d = tmp_path_factory.mktemp("crops")
    frames = {f: snapcorr.data.mosaic_frames("mosaic_4x4_vis", f_number=f, seed=int(f))
              for f in (2, 4, 11)}
    for f, (_, dark, white) in frames.items():
        np.save(d / f"white_f{f}.npy", white[CROP])
        np.save(d / "dark.npy", dark[CROP])
    areas = {"a": CROP, "corner": (slice(0, 128), slice(0, 160)),
             "low": (slice(404, 656), slice(800, 1120))}
    for name, area in areas.items():
        for f in (2, 11):
            scene, dark, white = frames[f]
            for kind, img in (("scene", scene), ("dkc", dark), ("whc", white)):
                np.save(d / f"{kind}_{name}_f{f}.npy", img[area])
            res = run_cli("flatfield", f"scene_{name}_f{f}.npy", "--dark", f"dkc_{name}_f{f}.npy",
                      "--white", f"whc_{name}_f{f}.npy", "--sensor", "mosaic_4x4_vis",
                      "--sensor-origin-px", f"{area[0].start},{area[1].start}",
                      "--out", f"tgt_{name}_f{f}.nc", cwd=d)
            assert res.returncode == 0, res.stderr
    return d


def _cubes(name):
    return ["--target-cube", f"2=tgt_{name}_f2.nc", "--target-cube", f"11=tgt_{name}_f11.nc"]


def test_center_is_sensor_pixels_for_a_crop(crops, cli):
    """--center means sensor pixels, as pupil and correct take it: the profile holds it in
    the flats' pixels beside their origin, and correct carries it back to the same sensor
    pixels (it was taken as the crop's own pixels: 400 rows and 800 columns off)."""
    from snapcorr.correct.geometry import optical_center_rc
    from snapcorr.cube import Sensor
    from snapcorr.data import sensor_path

    res = cli("calibrate", *FLATS, "--sensor-origin-px", "400,800", "--exit-pupil-mm", "21",
              "--method", "joint", "--center", "543.5,1023.5", "--out", "given.toml", cwd=crops)
    assert res.returncode == 0, res.stderr
    assert "sensor row 543.5, col 1023.5" in res.stdout
    cal = Lens.load(crops / "given.toml").calibration
    assert cal["center_rc"] == [143.5, 223.5] and cal["center_source"] == "given"
    assert cal["sensor_origin_rc"] == [400, 800]
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    centre, _ = optical_center_rc(None, sensor, Lens.load(crops / "given.toml"))
    assert centre == pytest.approx(TRUE_CENTER)


@pytest.mark.parametrize("sub", ["calibrate", "pupil", "correct", "budget"])
def test_every_center_help_says_sensor_pixels(sub):
    from snapcorr.cli import build_parser

    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    (center,) = [a for a in subs.choices[sub]._actions if a.dest == "center"]
    assert "sensor pixels" in center.help, center.help


@pytest.mark.parametrize("cubes, origin, words", [
    ("corner", "0,0", ["256 x 320 px at sensor row 0, col 0",
                       "128 x 160 px at sensor row 0, col 0", "not of the same pixels"]),
    ("low", "404,800", ["256 x 320 px at sensor row 404, col 800",
                        "252 x 320 px at sensor row 404, col 800", "not of the same pixels"]),
    ("a", "0,0", ["256 x 320 px at sensor row 0, col 0",
                  "256 x 320 px at sensor row 400, col 800", "not of the same pixels"]),
    ("a", None, ["give --sensor-origin-px ROW,COL", "records row 400, col 800"]),
])
def test_flats_and_target_cubes_of_other_pixels_are_refused(crops, cli, cubes, origin, words):
    """Target cubes of another crop than the flats' were fitted (x = 8.4 mm from cubes of
    the sensor's corner against flats of the middle); without the origin the message asked
    for --sensor, which was given. One line naming both, nothing written."""
    extra = [] if origin is None else ["--sensor-origin-px", origin]
    out = f"bad_{cubes}_{origin}.toml"
    res = cli("calibrate", *FLATS, *TARGET, *_cubes(cubes), *extra, "--out", out, cwd=crops)
    assert res.returncode == 1, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if "error" in ln]
    assert len(lines) == 1 and lines[0] == res.stderr.strip().splitlines()[-1], res.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert "give its sensor" not in lines[0] and "leave it out" not in lines[0]
    assert not (crops / out).exists()


def test_flats_are_read_rows_first(crops, cli):
    res = cli("calibrate", *FLATS, "--sensor-origin-px", "0,0", *TARGET, *_cubes("a"),
              "--out", "rows_first.toml", cwd=crops)
    assert "read f/2: white_f2.npy (256 x 320 px)" in res.stderr, res.stderr


def test_flats_of_other_sizes_are_listed_rows_first():
    from snapcorr.calibrate import calibrate_lens

    flats = {2.0: np.ones((16, 24)), 4.0: np.ones((24, 16))}
    with pytest.raises(ValueError, match=r"f/2: 16 x 24, f/4: 24 x 16"):
        calibrate_lens(flats, exit_pupil_mm=21, pixel_pitch_um=5.5)


def test_a_flat_fields_result_is_no_calibration_flat(crops, cli):
    """A reflectance (by its name, or its long_name) given as a flat is a ratio to a white:
    its vignetting divided out, it calibrated a lens without any. Refused, naming it. Units
    of 1 alone are not refused here: a white another tool normalised keeps its fall-off."""
    import xarray as xr

    from snapcorr.cube.flatfield import ratio_kind

    for f in (2, 11):
        with xr.open_dataset(crops / f"tgt_a_f{f}.nc") as ds:
            signal = ds["reflectance"].mean("band").rename("signal").load()
        signal.attrs = {"units": "1", "long_name": "reflectance"}
        signal.to_dataset().to_netcdf(crops / f"ratio_f{f}.nc")
    assert ratio_kind(signal.assign_attrs(long_name="white"), by_units=False) is None
    assert ratio_kind(signal.assign_attrs(long_name="white")) == "a ratio (units '1')"
    for stem, kind in (("tgt_a", "a reflectance"), ("ratio", "a reflectance")):
        path = f"{stem}_f2.nc"
        res = cli("calibrate", "--flat", f"2={path}", "--flat", f"11={stem}_f11.nc",
                  "--exit-pupil-mm", "21", "--pixel-pitch-um", "5.5", "--out", "ratio.toml",
                  cwd=crops)
        assert res.returncode == 1, res.stderr
        line = res.stderr.strip().splitlines()[-1]
        assert f"the flat field {path} is {kind}" in line, line
        assert not (crops / "ratio.toml").exists()


def test_a_centre_the_flats_cannot_show_is_said_to_be_assumed(crops, cli):
    """Crop A shows no fall-off to find the centre from: the profile stored the crop's image
    centre (527.5, 959.5 on the sensor; the axis is at 543.5, 1023.5) without saying it was
    assumed, and correct used it as the lens's."""
    from snapcorr.correct.geometry import optical_center_rc
    from snapcorr.cube import Sensor
    from snapcorr.data import sensor_path

    res = cli("calibrate", *FLATS, "--sensor-origin-px", "400,800", "--exit-pupil-mm", "21",
              "--method", "joint", "--out", "assumed.toml", cwd=crops)
    assert res.returncode == 0, res.stderr
    assert "image centre, assumed" in res.stdout
    lens = Lens.load(crops / "assumed.toml")
    assert lens.calibration["center_source"].startswith("image centre (assumed")
    _, source = optical_center_rc(None, Sensor.load(sensor_path("mosaic_4x4_vis")), lens)
    assert "assumed" in source, source


@pytest.mark.slow
def test_the_target_finds_the_centre_the_flats_cannot(crops, cli):
    """With target cubes, the flats' assumed image centre was given to the target's fit as
    "given" (x fitted about it, the profile keeping it): the target's fit now finds its own,
    which the profile keeps, with where it came from."""
    res = cli("calibrate", *FLATS, *TARGET, *_cubes("a"), "--sensor-origin-px", "400,800",
              "--out", "target.toml", cwd=crops)
    assert res.returncode == 0, res.stderr
    assert "(given)" not in res.stdout
    cal = Lens.load(crops / "target.toml").calibration
    assert cal["center_source"].startswith("the target cubes: found from the f/2 cube")
    assert cal["exit_pupil_fit"]["center_source"].startswith("found from the f/2 cube")
    fitted = np.add(cal["exit_pupil_fit"]["center_rc"], 0)
    assert cal["center_rc"] == pytest.approx(fitted - ORIGIN)


def test_raw_vendor_flats_at_another_phase_are_refused(tmp_path, cli):
    """A crop of the vendor camera's raw whites at rows 300:550, columns 500:800, said to be
    at 301,500: calibrate took it (flatfield refuses such a white by its mosaic's phase)."""
    import snapcorr.data
    from snapcorr.cube import Sensor

    for f in (2, 4, 11):
        _, dark, white = snapcorr.data.mosaic_frames("imec_5x5_nir", f_number=f, seed=f)
        np.save(tmp_path / f"w{f}.npy", white[300:550, 500:800])
        np.save(tmp_path / "d.npy", dark[300:550, 500:800])
    res = cli("calibrate", "--flat", "2=w2.npy", "--flat", "4=w4.npy", "--flat", "11=w11.npy",
              "--dark", "d.npy", "--sensor", "imec_5x5_nir", "--sensor-origin-px", "301,500",
              "--exit-pupil-mm", "21", "--out", "wrong.toml", cwd=tmp_path)
    assert res.returncode == 1, res.stderr
    line = res.stderr.strip().splitlines()[-1]
    assert "--flat 2=w2.npy shows the mosaic at another phase" in line, line
    assert "300,500" in line and not (tmp_path / "wrong.toml").exists()
    # the right origin passes the same check
    from snapcorr.cli._flats import _check_flat_phase

    sensor = Sensor.load(snapcorr.data.sensor_path("imec_5x5_nir"))
    flats = {f: np.load(tmp_path / f"w{f:g}.npy").astype(float) for f in (2.0, 4.0, 11.0)}
    args = argparse.Namespace(flat=[(f, tmp_path / f"w{f:g}.npy") for f in flats])
    _check_flat_phase(args, sensor, flats, {f: 1023 for f in flats},
                      np.load(tmp_path / "d.npy").astype(float), (300, 500))


@pytest.mark.parametrize("center_px, refused", [([100.0, 900.0], True), ([900.0, 100.0], False)])
def test_a_profile_with_two_centres_that_disagree_is_refused(tmp_path, center_px, refused):
    """center_rc is row first, center_px x first: the two disagreeing were read silently."""
    path = tmp_path / "lens.toml"
    path.write_text("[lens]\nname = \"t\"\nexit_pupil_mm = 21.0\n\n[calibration]\n"
                    f"center_rc = [100.0, 900.0]\ncenter_px = {center_px}\n"
                    "pixel_pitch_um = 5.5\n")
    if refused:
        with pytest.raises(ValueError, match=r"center_rc \[100.0, 900.0\] .* disagree"):
            Lens.load(path)
    else:
        assert Lens.load(path).calibration["center_rc"] == [100.0, 900.0]


def test_calibrate_with_target_refuses_cubes_of_other_pixels(crops):
    """The library as the command: cubes recording another sensor area than the flats' are
    refused before any fit (the corner's cubes against flats at the same origin were fitted;
    cubes elsewhere were refused after the flats' fit, asking to leave the origin out)."""
    from snapcorr.calibrate import calibrate_with_target
    from snapcorr.cube import Sensor
    from snapcorr.data import sensor_path
    from snapcorr.pipeline import read_cube_or_frame

    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    flats = {f: np.load(crops / f"white_f{f}.npy") for f in (2, 11)}
    for name, origin, words in (("corner", (0, 0), "128 x 160 px at sensor row 0, col 0"),
                                ("a", (0, 0), "256 x 320 px at sensor row 400, col 800")):
        cubes = {f: read_cube_or_frame(crops / f"tgt_{name}_f{f}.nc", sensor) for f in (2, 11)}
        with pytest.raises(ValueError, match="not of the same pixels") as err:
            calibrate_with_target(flats, cubes, sensor, pixel_pitch_um=5.5, magnification=0.06,
                                  pupil_magnification=1.3, max_circles=1,
                                  sensor_origin_px=origin, pupil_radiance="paper")
        assert words in str(err.value)


def test_a_tile_cube_of_the_flats_pixels_is_taken_whatever_their_size(tmp_path, cli):
    """A crop of 250 x 318 px is 62 x 79 whole tiles: its tile cube records 248 x 316 px, and
    was refused as 'not of the same pixels' as the flats it was cut with; so was every cube
    of a sensor whose filter area is smaller than its frame. A raw frame given as the target
    is read at the flats' origin (it was read without one and refused), and a sensor without
    a size is not said to be cropped."""
    import dataclasses

    import snapcorr.data
    from snapcorr.calibrate.unknown_lens import flats_areas
    from snapcorr.cli._targets import _target_cubes
    from snapcorr.cube import Sensor

    sensor = Sensor.load("mosaic_4x4_vis")
    scene, dark, white = snapcorr.data.mosaic_frames("mosaic_4x4_vis", f_number=2, seed=2)
    area = (slice(400, 650), slice(800, 1118))
    for kind, img in (("scene", scene), ("dark", dark), ("white", white)):
        np.save(tmp_path / f"{kind}.npy", img[area])
    res = cli("flatfield", "scene.npy", "--dark", "dark.npy", "--white", "white.npy",
              "--sensor", "mosaic_4x4_vis", "--sensor-origin-px", "400,800", "--out", "t.nc",
              "--quiet", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert flats_areas((250, 318), sensor, (400, 800)) == {(400, 800, 250, 318),
                                                          (400, 800, 248, 316)}
    args = argparse.Namespace(target_cube=[(2.0, tmp_path / "t.nc"),
                                           (11.0, tmp_path / "scene.npy")],
                              sensor_origin_px=(400, 800))
    cubes, origin = _target_cubes(args, sensor, (250, 318))
    assert origin == (400, 800) and cubes[2.0].attrs["mosaic_area_px"] == [400, 800, 248, 316]
    assert cubes[11.0].attrs["mosaic_area_px"] == [400, 800, 248, 316]
    sizeless = dataclasses.replace(sensor, size_px=None)
    args = argparse.Namespace(target_cube=[(2.0, tmp_path / "t.nc")], sensor_origin_px=None)
    cubes, origin = _target_cubes(args, sizeless, (250, 318))
    assert origin == (400, 800)


@pytest.mark.parametrize(("flat_shape", "words"), [
    ((120, 100), ["a crop of the sensor 'scan' (300 x 300 px)", "give --sensor-origin-px ROW,COL"]),
    ((310, 300), ["310 x 300 px, larger than the sensor 'scan' (300 x 300 px)", "--sensor"]),
])
def test_snapscan_flats_of_a_crop_without_their_place_are_refused_before_any_work(
        tmp_path, cli, flat_shape, words):
    """Flats and target cubes of a snapscan-like sensor, smaller than it, no origin: the
    flats were calibrated first (about a centre found beside them) and refused for "too few
    f-numbers"; now one line asks for --sensor-origin-px before anything is fitted."""
    from snapcorr.cube import Sensor, make_cube, write_cube

    cwl = np.arange(500.0, 800.0, 20.0)
    Sensor("scan", "snapscan", 44.0, cwl, 12.0, 1.7, size_px=(300, 300)).save(
        tmp_path / "sensor.toml")
    rng = np.random.default_rng(0)
    args = []
    for f in (2, 4, 8):
        np.save(tmp_path / f"flat_f{f}.npy", 3000.0 + rng.normal(0, 3, flat_shape))
        args += ["--flat", f"{f}=flat_f{f}.npy"]
    for f in (2, 8):
        write_cube(make_cube(0.5 + rng.normal(0, 0.01, (*flat_shape, cwl.size)), cwl),
                   tmp_path / f"cube_f{f}.nc")
        args += ["--target-cube", f"{f}=cube_f{f}.nc"]
    res = cli("calibrate", *args, "--sensor", "sensor.toml", "--out", "lens.toml",
              "--magnification", "0", "--pupil-magnification", "1", cwd=tmp_path)
    assert res.returncode == 1, res.stderr
    last = res.stderr.strip().splitlines()[-1]
    for w in words:
        assert w in last, (w, last)
    assert "calibrating" not in res.stderr  # refused before the flats were fitted
    assert not (tmp_path / "lens.toml").exists()


def test_snapscan_flats_and_cubes_of_other_sizes_are_refused_before_any_work(tmp_path, cli):
    """Whole-sensor flats and 60 x 80 target cubes were fitted (the precision predicted, x
    scanned) and refused only for the target's lack of features."""
    from snapcorr.cube import Sensor, make_cube, write_cube

    cwl = np.arange(500.0, 800.0, 20.0)
    Sensor("scan", "snapscan", 44.0, cwl, 12.0, 1.7, size_px=(120, 100)).save(
        tmp_path / "sensor.toml")
    rng = np.random.default_rng(0)
    args = []
    for f in (2, 8):
        np.save(tmp_path / f"flat_f{f}.npy", 3000.0 + rng.normal(0, 3, (120, 100)))
        write_cube(make_cube(0.5 + rng.normal(0, 0.01, (60, 80, cwl.size)), cwl),
                   tmp_path / f"cube_f{f}.nc")
        args += ["--flat", f"{f}=flat_f{f}.npy", "--target-cube", f"{f}=cube_f{f}.nc"]
    res = cli("calibrate", *args, "--sensor", "sensor.toml", "--out", "lens.toml",
              "--magnification", "0", "--pupil-magnification", "1", cwd=tmp_path)
    assert res.returncode == 1, res.stderr
    last = res.stderr.strip().splitlines()[-1]
    assert "(120 x 100 px) and the target cube f/2 cube_f2.nc (60 x 80 px) are not of the " \
           "same pixels" in last
    assert "predicted" not in res.stderr and not (tmp_path / "lens.toml").exists()
