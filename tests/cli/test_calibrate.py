"""`snapcorr calibrate`: flats in any format to a lens profile; mistakes are one line."""

import numpy as np
import pytest
from conftest import PAPER_LENS

from snapcorr import Lens
from snapcorr.simulate import Detector, flat_frame

PAPER = PAPER_LENS
SHAPE, PITCH = (256, 256), 44.0  # the angles of a 2048 x 2048, 5.5 um sensor
CENTER = (140.2, 118.9)
OPTICS = ["--exit-pupil-mm", "21", "--pixel-pitch-um", str(PITCH), "--magnification", "0.06",
          "--pupil-magnification", "1.3"]


def _write_oiio(path, image):
    import OpenImageIO as oiio

    # (y, x, channel): OpenImageIO reads a 2-D array as transposed
    img = np.ascontiguousarray(image.reshape(image.shape[0], image.shape[1], -1))
    spec = oiio.ImageSpec(img.shape[1], img.shape[0], img.shape[2],
                          "uint16" if img.dtype == np.uint16 else "float")
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    assert out.write_image(img)
    out.close()


@pytest.fixture(scope="module")
def flats(tmp_path_factory):
    d = tmp_path_factory.mktemp("flats")
    rng = np.random.default_rng(0)
    dark = 100.0
    for f in (1.4, 2.0, 2.8, 4.0, 8.0):
        img = flat_frame(SHAPE, PITCH, f, PAPER, center_px=CENTER,
                         detector=Detector(dark_dn=dark, signal_electrons=2e4), rng=rng,
                         dtype=np.uint16)
        if f == 1.4:
            np.save(d / "f1.4.npy", img)
        elif f == 2.0:
            _write_oiio(d / "f2.tif", img)
        elif f == 2.8:
            _write_oiio(d / "f2.8.exr", img.astype(np.float32))
        elif f == 4.0:  # three bands in one ENVI file: averaged
            from spectral.io import envi

            cube = np.stack([img, img, img], axis=2)
            envi.save_image(str(d / "f4.hdr"), cube, dtype=np.uint16, ext=".raw")
        else:
            np.save(d / "f8.npy", img)
    np.save(d / "dark.npy", np.full(SHAPE, dark, np.uint16))
    return d


FLATS = ["--flat", "1.4=f1.4.npy", "--flat", "f/2=f2.tif", "--flat", "2.8=f2.8.exr",
         "--flat", "f4=f4.hdr", "--flat", "8=f8.npy"]


def test_calibrate_from_mixed_formats_writes_profile_and_plot(flats, cli):
    res = cli("calibrate", *FLATS, *OPTICS, "--dark", "dark.npy", "--out", "lens.toml", "--plot",
              "lens.png", cwd=flats)
    assert res.returncode == 0, res.stderr
    assert "mean of 3 bands" in res.stderr and "wrote lens.toml and lens.png" in res.stdout
    lens = Lens.load(flats / "lens.toml")
    assert abs(lens.vignetting[0][0] / 7.4236 - 1) < 0.01
    assert abs(lens.vignetting[0][1] / 16.991 - 1) < 0.01
    cal = lens.calibration
    assert cal["pixel_pitch_um"] == PITCH and cal["dark"] == "dark.npy"
    assert cal["bands"] == "mean of the bands in each file"
    assert abs(cal["center_px"][0] - CENTER[0]) < 1 and abs(cal["center_px"][1] - CENTER[1]) < 1
    assert cal["inputs"]["f/4"] == "f4.hdr" and cal["f_numbers"] == [1.4, 2.0, 2.8, 4.0, 8.0]
    assert (flats / "lens.png").read_bytes()[:4] == b"\x89PNG"
    # an existing output is kept unless --overwrite
    again = cli("calibrate", *FLATS, *OPTICS, "--out", "lens.toml", cwd=flats)
    assert again.returncode == 1 and "exists" in again.stderr
    assert Lens.load(flats / "lens.toml") == lens


def test_the_model_choice_options_reach_the_profile(flats, cli):
    res = cli("calibrate", *FLATS, *OPTICS, "--max-circles", "1", "--tolerance-nm", "0.01", "--out",
              "one.toml", cwd=flats)
    assert res.returncode == 0, res.stderr
    choice = Lens.load(flats / "one.toml").calibration["model_choice"]
    assert choice["models_tried"] == ["none", "one"] and choice["tolerance_nm"] == 0.01
    assert "joint fit, one circle" in res.stdout and "-> chosen" in res.stdout


@pytest.mark.parametrize("args, message", [
    (["--flat", "1.4=f1.4.npy", "--flat", "8=f8.npy", "--max-circles", "4"], "max-circles"),
    (["--flat", "1.4=f1.4.npy", "--flat", "8=f8.npy", "--tolerance-nm", "0"], "tolerance-nm"),
    (["--flat", "2=f1.4.npy", "--flat", "2.0=f8.npy"], "f/2 given twice"),
    (["--flat", "1.4=f1.4.npy"], "cannot tell"),
    (["--flat", "1.4=missing.npy", "--flat", "8=f8.npy"], "no such file"),
    (["--flat", "1.4=f1.4.npy", "--flat", "8=small.npy"], "differ in size"),
    (["--flat", "1.4", "--flat", "8=f8.npy"], "F_NUMBER=PATH"),
    (["--flat", "x=f1.4.npy", "--flat", "8=f8.npy"], "not an f-number"),
    (["--flat", "0=f1.4.npy", "--flat", "8=f8.npy"], "> 0"),
    (["--flat", "1.4=f1.4.npy", "--flat", "8=f8.npy", "--center-px", "3"], "CX,CY"),
    (["--flat", "1.4=f1.4.npy", "--flat", "8=notes.txt"], "unknown flat-field format"),
    (["--flat", "1.4=f1.4.npy", "--flat", "8=f8.npy", "--dark", "small.npy"], "dark frame"),
    (["--flat", "1.4=f1.4.npy", "--flat", "8=empty.npy"], "not a numpy array file"),
    (["--flat", "2=f8.npy", "--flat", "8=f8.npy"], "are they the same frames"),
])
def test_mistakes_are_one_line_and_write_nothing(flats, args, message, cli):
    np.save(flats / "small.npy", np.ones((10, 12)))
    (flats / "empty.npy").write_bytes(b"")
    (flats / "notes.txt").write_text("not an image")
    res = cli("calibrate", *args, *OPTICS, "--out", "bad.toml", "--plot", "bad.png", cwd=flats)
    assert res.returncode != 0
    assert message in res.stderr, res.stderr
    assert "Traceback" not in res.stderr
    assert not (flats / "bad.toml").exists() and not (flats / "bad.png").exists()


def test_output_may_not_be_an_input_or_not_toml(flats, cli):
    res = cli("calibrate", *FLATS, *OPTICS, "--out", "f8.npy", cwd=flats)
    assert res.returncode == 1 and "also an input" in res.stderr
    res = cli("calibrate", *FLATS, *OPTICS, "--out", "x.npy", cwd=flats)
    assert res.returncode == 1 and ".toml" in res.stderr
    res = cli("calibrate", *FLATS, *OPTICS, "--out", "x.toml", "--plot", "f8.npy", cwd=flats)
    assert res.returncode == 1 and "also an input" in res.stderr
    assert np.load(flats / "f8.npy").shape == SHAPE


def test_help_shows_the_command_shape(cli):
    res = cli("calibrate", "--help")
    assert res.returncode == 0
    for word in ("--flat F_NUMBER=PATH", "--exit-pupil-mm", "--pixel-pitch-um",
                 "--magnification", "--pupil-magnification", "--dark", "--center ROW,COL",
                 "--out", "--plot PNG", "examples:"):
        assert word in res.stdout, word


def test_missing_output_folder_is_refused_before_any_work(flats, cli):
    res = cli("calibrate", *FLATS, *OPTICS, "--out", "nowhere/x.toml", "--plot", "o.png", cwd=flats)
    assert res.returncode == 1 and "--out nowhere/x.toml" in res.stderr
    assert "does not exist" in res.stderr and "read f/" not in res.stderr
    assert not (flats / "o.png").exists()


def test_multipage_tiff_pages_are_averaged(flats):
    import OpenImageIO as oiio

    from snapcorr.calibrate import read_flat

    path = flats / "pages.tif"
    a = np.full((20, 30, 1), 100, np.uint16)
    b = np.full((20, 30, 1), 300, np.uint16)
    out = oiio.ImageOutput.create(str(path))
    specs = [oiio.ImageSpec(30, 20, 1, "uint16")] * 2
    assert out.open(str(path), specs)
    assert out.write_image(a)
    assert out.open(str(path), specs[1], "AppendSubimage")
    assert out.write_image(b)
    out.close()
    image, info = read_flat(path)
    assert info["bands"] == 2 and np.all(image == 200.0)


def test_x_from_a_lens_profile_the_pupil_command_wrote(flats, cli):
    """Step 2 of the two-step workflow: x (and m, m_P) from the profile `snapcorr pupil`
    wrote, its provenance carried over; x given twice is refused."""
    found = flats / "x_found.toml"
    Lens(21.0, (), 0.06, 1.3, name="x from a target", calibration={
        "exit_pupil_stderr_mm": 0.04, "n_eff": 1.71, "n_eff_stderr": 0.01,
        "n_eff_fitted": "one"}).save(found)
    out = flats / "from_found.toml"
    args = ["calibrate", "--flat", f"1.4={flats / 'f1.4.npy'}", "--flat",
            f"8={flats / 'f8.npy'}", "--flat", f"2.8={flats / 'f2.8.exr'}",
            "--dark", str(flats / "dark.npy"), "--pixel-pitch-um", str(PITCH), "--out", str(out)]
    res = cli(*args, "--lens", found)
    assert res.returncode == 0, res.stderr
    lens = Lens.load(out)
    assert lens.exit_pupil_mm == 21.0
    assert (lens.magnification, lens.pupil_magnification) == (0.06, 1.3)
    assert abs(lens.vignetting[0][0] / 7.4236 - 1) < 0.01
    assert abs(lens.vignetting[0][1] / 16.991 - 1) < 0.01
    cal = lens.calibration
    assert cal["exit_pupil_from"] == str(found) and cal["exit_pupil_stderr_mm"] == 0.04
    assert cal["exit_pupil_n_eff"] == 1.71 and cal["exit_pupil_n_eff_fitted"] == "one"
    res = cli(*args[:-1], flats / "never.toml", "--lens", found, "--exit-pupil-mm", "21")
    assert res.returncode == 2 and "not allowed with" in res.stderr
    assert not (flats / "never.toml").exists()


def test_flats_without_a_dark_frame_are_said_to_be_taken_as_dark_subtracted(flats, cli):
    """These flats carry a 100 DN dark level. Without --dark it is read as light (here the
    selection even adds a second circle); the output says what was assumed, and the profile
    records it."""
    args = ["calibrate", "--flat", f"1.4={flats / 'f1.4.npy'}", "--flat",
            f"8={flats / 'f8.npy'}", "--flat", f"2.8={flats / 'f2.8.exr'}", *OPTICS]
    res = cli(*args, "--out", flats / "nodark.toml")
    assert res.returncode == 0, res.stderr
    assert "note: no --dark" in res.stdout
    assert Lens.load(flats / "nodark.toml").calibration["dark"].startswith("none given")
    res = cli(*args, "--dark", flats / "dark.npy", "--out", flats / "withdark.toml")
    assert res.returncode == 0, res.stderr
    assert "no --dark" not in res.stdout
    assert len(Lens.load(flats / "withdark.toml").vignetting) == 1


@pytest.fixture(scope="module")
def mosaic_flats(tmp_path_factory):
    """Raw frames of a 4 x 4 mosaic (band gains 0.25-1.0) from the independent simulator, a
    dark frame, and the sensor (the whole 256 x 320 px sensor, 28.4 um pixels)."""
    from conftest import PAPER_TRUTH
    from flatsim import make_flats, shot_noise_frames, tile_gains

    from snapcorr.cube import Sensor

    d = tmp_path_factory.mktemp("mosaic_flats")
    shape, pitch, fs = (256, 320), 28.4, (2.0, 4.0, 11.0)
    _, light, _ = make_flats(PAPER_TRUTH, fs, shape=shape, pitch_um=pitch,
                             center_px=(174.75, 119.75), noise=0.0, seed=1, integer=False,
                             return_truth_maps=True)
    gains = np.random.default_rng(5).permutation(np.linspace(0.25, 1.0, 16)).reshape(4, 4)
    raw = shot_noise_frames({f: img * (30000 / 45000) for f, img in light.items()},
                            tile_gains(shape, gains))
    for f, img in raw.items():
        np.save(d / f"raw_f{f:g}.npy", (img + 100).astype(np.uint16))
    np.save(d / "dark.npy", np.full(shape, 100, np.uint16))
    Sensor("raw 4x4", "mosaic", pitch, tuple(500.0 + 10 * np.arange(16)), 10.0, 1.7,
           mosaic_shape=(4, 4), band_offset=tuple((b // 4, b % 4) for b in range(16)),
           size_px=shape).save(d / "raw4x4.toml")
    return d


MOSAIC = ["--flat", "2=raw_f2.npy", "--flat", "4=raw_f4.npy", "--flat", "11=raw_f11.npy",
          "--dark", "dark.npy", "--exit-pupil-mm", "21", "--pixel-pitch-um", "28.4",
          "--magnification", "0.06", "--pupil-magnification", "1.3", "--max-circles", "1",
          "--method", "joint"]


def test_raw_mosaic_flats_with_their_sensor(mosaic_flats, cli):
    """--sensor without --target-cube: the band gains are divided out of each raw flat and
    the profile says so (the library's figures: test_calibrate_mosaic_flats.py)."""
    res = cli("calibrate", *MOSAIC, "--sensor", "raw4x4.toml", "--out", "lens.toml",
              cwd=mosaic_flats)
    assert res.returncode == 0, res.stderr
    assert "divided out the band gains of raw 4x4" in res.stderr
    lens = Lens.load(mosaic_flats / "lens.toml")
    (P, h), = lens.vignetting
    assert abs(P / PAPER.vignetting[0][0] - 1) < 0.01 and abs(h / PAPER.vignetting[0][1] - 1) < 0.01
    gains = lens.calibration["band_gains"]
    assert gains["removed"] is True and gains["sensor_file"] == "raw4x4.toml"
    assert gains["sensor_origin_rc"] == "whole sensor" and len(gains["gains"]["f/2"]) == 16
    assert min(gains["gains"]["f/11"]) < 0.45 < 1.55 < max(gains["gains"]["f/11"])


@pytest.mark.parametrize("extra, words", [
    # flats of another pitch than snapscan_vnir's are not a crop of it: here they show a tile
    (["--sensor", "snapscan_vnir"], "raw frames of a snapshot mosaic; give its sensor"),
    (["--sensor-origin-px", "0,4"], "repeats a 4 x 4 pattern of pixel gains"),
    (["--sensor", "mosaic_4x4_vis"], "give the sensor row and column of its first pixel"),
    (["--sensor", "mosaic_4x4_vis", "--sensor-origin-px", "1000,0"], "reaches beyond the sensor"),
    (["--sensor", "raw4x4.toml", "--fit-n-eff"], "--fit-n-eff goes with --target-cube"),
    (["--sensor", "raw4x4.toml", "--target-tolerance-nm", "0.05"],
     "--target-tolerance-nm goes with --target-cube"),
])
def test_raw_mosaic_flat_mistakes_are_one_line(mosaic_flats, cli, extra, words):
    res = cli("calibrate", *MOSAIC, *extra, "--out", "bad.toml", cwd=mosaic_flats)
    assert res.returncode == 1 and words in res.stderr, res.stderr
    assert "Traceback" not in res.stderr and not (mosaic_flats / "bad.toml").exists()
    assert len([ln for ln in res.stderr.splitlines() if not ln.startswith("read ")]) == 1


def test_the_pixel_pitch_is_the_sensors_or_asked_for(flats, cli):
    """Without --pixel-pitch-um the flats' pitch is the --sensor's (said on stderr); with
    neither, one line asks for it and nothing is written."""
    res = cli("calibrate", "--flat", "1.4=f1.4.npy", "--flat", "8=f8.npy", "--exit-pupil-mm",
              "21", "--out", "nopitch.toml", cwd=flats)
    assert res.returncode == 1 and "--pixel-pitch-um" in res.stderr
    assert "Traceback" not in res.stderr and not (flats / "nopitch.toml").exists()
    import types

    import snapcorr.data
    from snapcorr.cli._flats import _pitch_option
    from snapcorr.cube import Sensor

    args = types.SimpleNamespace(pixel_pitch_um=None, sensor="imec_5x5_nir")
    _pitch_option(args, Sensor.load(snapcorr.data.sensor_path("imec_5x5_nir")))
    assert args.pixel_pitch_um == 5.5


@pytest.mark.parametrize("center, words", [
    ("5000,5000", ["86.", "row 5000, column 5000", "lies outside the 256 x 256 px flats",
                   "--center"]),
    ("140,119", ["row 140, column 119", "check the pixel pitch"]),
])
def test_flats_spanning_too_few_angles_say_about_which_centre(flats, cli, center, words):
    """A centre far off the flats (a typo) leaves them a sliver of chief-ray angles far out:
    the message gives the span, the centre and, when it lies outside the flats, names
    --center (it named only the pitch and x, and gave the span as its far end, 86 deg)."""
    optics = list(OPTICS)
    optics[optics.index("--pixel-pitch-um") + 1] = "0.2" if center == "140,119" else str(PITCH)
    res = cli("calibrate", *FLATS[:4], *optics, "--center", center, "--out", "never.toml",
              cwd=flats)
    assert res.returncode != 0
    line = res.stderr.strip().splitlines()[-1]
    assert "too few to see a fall-off" in line, line
    for w in words:
        assert w in line, (w, line)
    assert not (flats / "never.toml").exists()


def test_a_crop_of_flats_without_a_tile_pattern_records_where_it_sits(flats, cli):
    """Flats cut to rows 20-219 and columns 30-249 with --sensor-origin-px 20,30 (no mosaic:
    a Snapscan camera's region of interest): the profile records the origin and its centre
    in the crop's pixels (placed on the sensor by it: test_cleaning_band_gains.py)."""
    from snapcorr.calibrate import read_flat

    crop = []
    for arg in FLATS[1::2]:
        f, path = arg.split("=")
        np.save(flats / f"crop_{path}.npy", read_flat(flats / path)[0][20:220, 30:250])
        crop += ["--flat", f"{f}=crop_{path}.npy"]
    np.save(flats / "cropdark.npy", np.load(flats / "dark.npy")[20:220, 30:250])
    res = cli("calibrate", *crop, *OPTICS, "--dark", "cropdark.npy", "--sensor-origin-px",
              "20,30", "--out", "crop.toml", cwd=flats)
    assert res.returncode == 0, res.stderr
    cal = Lens.load(flats / "crop.toml").calibration
    assert cal["sensor_origin_rc"] == [20, 30]
    assert abs(cal["center_rc"][0] - (CENTER[1] - 20)) < 1, cal["center_rc"]
    assert abs(cal["center_rc"][1] - (CENTER[0] - 30)) < 1, cal["center_rc"]
