"""The one-command workflow on a real vendor sensor: lens from raw flats, x and n_eff from a target.

The bundled imec 5 x 5 NIR sensor (its vendor file, 1088 x 2048 pixels of 5.5 um) behind the
paper lens. Everything the command reads is made here, not by snapcorr:

* the file is read element by element (``mosaicsim.read_older``): each band's curve, the
  band-pass, and the band at each pixel from the pattern positions and the filter area's
  offset;
* raw target frames: every band's response at a pixel is the sum over the vignetted pupil,
  sampled point by point (``spectralsim.pupil_samples``), of its whole curve scaled by each
  ray, ``T_b(lambda / a)``, times the band-pass, which does not move (``mosaicsim.responses``);
  a flat-fielded value is the rare-earth glass's reflectance averaged through it;
* raw flats: the relative illumination of ``flatsim.make_flats`` times each band's gain
  (its curve through the band-pass under a flat lamp), shot noise and a dark offset.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mosaicsim
import numpy as np
import pytest
import spectralsim as sim
from conftest import PAPER_TRUTH

from snapcorr import Lens, data
from snapcorr.cube import Sensor

X_MM = PAPER_TRUTH.exit_pupil_mm
N_EFF = 1.85  # the bundled file says 1.8 (a typical value): fitted from there
CENTER_RC = (547.4, 1015.8)
PITCH_UM = 5.5
SIZE = (1088, 2048)
TARGET_F = (1.4, 8.0)
FLAT_F = (2.0, 4.0, 11.0)


def vendor_file():
    return data.sensor_path("imec_5x5_nir").parent / "CMV2K-SSM5x5-600_875-5.5.9.2.xml"


def band_map(path, size=SIZE):
    """Each pixel's band (pattern position, reading order) from the file's own layout; -1
    outside the filter area."""
    fi = ET.parse(path).getroot().find("filter_info")
    area = fi.find("filter_area")
    oy, ox, h, w = (int(area.find(k).text) for k in ("offset_y", "offset_x", "height", "width"))
    ph, pw = int(fi.find("pattern_height").text), int(fi.find("pattern_width").text)
    rr, cc = np.mgrid[0:size[0], 0:size[1]]
    band = ((rr - oy) % ph) * pw + (cc - ox) % pw
    band[(rr < oy) | (rr >= oy + h) | (cc < ox) | (cc >= ox + w)] = -1
    return band


def _d2(size, center_rc, pitch_um):
    rr, cc = np.mgrid[0:size[0], 0:size[1]]
    return ((rr - center_rc[0]) ** 2 + (cc - center_rc[1]) ** 2) * (pitch_um * 1e-3) ** 2


def target_frames(f_numbers=TARGET_F, *, noise=0.005, seed=1, n_nodes=96, size=SIZE,
                  center_rc=CENTER_RC, n_eff=N_EFF, reflectance=sim.rare_earth_glass):
    """Flat-fielded raw frames of a uniform target at ``f_numbers``: each pixel its band's
    value at its distance from the axis (``n_nodes`` distances, linear in ``d^2``)."""
    path = vendor_file()
    mf = mosaicsim.read_older(path)
    band = band_map(path, size)
    d2 = _d2(size, center_rc, PITCH_UM)
    d2n = np.linspace(0.0, d2.max() * 1.001, n_nodes)
    rho = reflectance(mf.grid)[None]
    rng = np.random.default_rng(seed)
    out = {}
    for f in f_numbers:
        table = np.array([mosaicsim.band_values(mosaicsim.responses(
            mf, PAPER_TRUTH, f, np.rad2deg(np.arctan(np.sqrt(d) / X_MM)), n_eff,
            nodes=(16, 8)), rho)[0] for d in d2n]).T
        raw = np.full(size, float(np.mean(table)))  # outside the filter area: no band
        for b in range(table.shape[0]):
            m = band == b
            raw[m] = np.interp(d2[m], d2n, table[b])
        out[f] = raw + rng.normal(0.0, noise, size)
    return out


def raw_flats(f_numbers=FLAT_F, *, seed=2, pattern=True):
    """Raw flats (uint16, dark 100 DN) and the dark: the lens's relative illumination times
    each band's gain under an equal-energy lamp (``pattern=False``: every pixel at the bands'
    mean gain, the same light and electrons without the tile pattern)."""
    from flatsim import make_flats, shot_noise_frames

    path = vendor_file()
    mf = mosaicsim.read_older(path)
    signal = (mf.curves * mf.bandpass).sum(axis=1)
    band = band_map(path)
    gain = np.where(band >= 0, (signal / signal.max())[np.maximum(band, 0)], 1.0)
    if not pattern:
        gain = np.where(band >= 0, float(np.mean(signal / signal.max())), 1.0)
    _, light, _ = make_flats(PAPER_TRUTH, f_numbers, shape=SIZE, pitch_um=PITCH_UM,
                             center_px=(CENTER_RC[1], CENTER_RC[0]), noise=0.0, seed=seed,
                             integer=False, return_truth_maps=True)
    raw = shot_noise_frames({f: img * (700 / 45000) for f, img in light.items()}, gain)
    return ({f: np.clip(img + 100, 0, 1023).astype(np.uint16) for f, img in raw.items()},
            np.full(SIZE, 100, np.uint16))


def _lens_within_one_percent(path):
    """The profile the command wrote: x, P, h and n_eff each within 1 % of the truth."""
    lens = Lens.load(path)
    assert abs(lens.exit_pupil_mm / X_MM - 1) < 0.01
    (P, h), = lens.vignetting
    (P0, h0), = PAPER_TRUTH.circles
    assert abs(P / P0 - 1) < 0.01 and abs(h / h0 - 1) < 0.01
    assert abs(lens.calibration["n_eff"] / N_EFF - 1) < 0.01
    return lens


def test_the_file_layout_is_the_sensors():
    """The band map read from the file is the layout snapcorr reads (the frames above put
    each band where the sensor's cube will look for it)."""
    sensor = Sensor.load(data.sensor_path("imec_5x5_nir"))
    band = band_map(vendor_file())
    tr, tc = sensor.mosaic_shape
    r0, c0 = sensor.tile_origin_px
    for b, (r, c) in enumerate(sensor.in_file_order(sensor.band_offset)):
        assert band[r0 + r, c0 + c] == b
        assert band[r0 + r + tr, c0 + c + 2 * tc] == b


@pytest.mark.slow  # the whole sensor: three raw flats, two target frames (23 min, busy machine)
def test_calibrate_one_command_on_the_vendor_sensor(cli, tmp_path):
    flats, dark = raw_flats()
    args = []
    for f, img in flats.items():
        np.save(tmp_path / f"flat_f{f:g}.npy", img)
        args += ["--flat", f"{f:g}={tmp_path / f'flat_f{f:g}.npy'}"]
    np.save(tmp_path / "dark.npy", dark)
    for f, img in target_frames().items():
        np.save(tmp_path / f"glass_f{f:g}.npy", img.astype(np.float32))
        args += ["--target-cube", f"{f:g}={tmp_path / f'glass_f{f:g}.npy'}"]
    res = cli("calibrate", *args, "--dark", tmp_path / "dark.npy", "--sensor", "imec_5x5_nir",
              "--pixel-pitch-um", str(PITCH_UM), "--magnification", "0.06",
              "--pupil-magnification", "1.3", "--max-circles", "1", "--pupil", "paper",
              "--fit-n-eff", "--out", tmp_path / "lens.toml",
              "--sensor-out", tmp_path / "sensor.toml")
    assert res.returncode == 0, res.stdout + res.stderr
    _lens_within_one_percent(tmp_path / "lens.toml")
    sensor = Sensor.load(tmp_path / "sensor.toml")
    assert sensor.responses is not None  # the vendor file's curves, named by the TOML
    assert "CMV2K-SSM5x5-600_875-5.5.9.2.xml" in (tmp_path / "sensor.toml").read_text()
    assert abs(sensor.n_eff[0] / N_EFF - 1) < 0.01
    err = sensor.calibration["n_eff_stderr"]
    err = err[0] if isinstance(err, list) else err
    assert 0 < err < 0.01 * N_EFF
    assert abs(sensor.n_eff[0] - N_EFF) < 4 * err


def test_mosaic_frames_of_a_given_target():
    """``mosaic_frames(target=...)``: a grey target reads its reflectance through every band
    once flat-fielded, in every band alike (the default target's doctest in snapcorr.data)."""
    raw, dark, white = (f.astype(float) for f in data.mosaic_frames(
        "imec_5x5_nir", target=lambda wl: np.full(np.shape(wl), 0.4), seed=3))
    lit = white - dark > 200
    ratio = (raw - dark)[lit] / (white - dark)[lit]
    assert abs(np.median(ratio) - 0.4) < 0.01
    assert np.percentile(ratio, 99) - np.percentile(ratio, 1) < 0.25  # noise only


#: A crop off the tile grid (the 5 x 5 tile) that keeps the far corner, where the circle cuts:
#: rows 101-1087, columns 203-2047 of the sensor.
CROP = (slice(101, 1088), slice(203, 2048))


def _crop_command(folder, *, pattern=True):
    """``snapcorr calibrate`` on raw flats and target frames of the crop :data:`CROP`, placed
    by ``--sensor-origin-px``; returns the command's result and the profile's path."""
    from conftest import run_cli

    flats, dark = raw_flats(f_numbers=(2.0, 2.8, 11.0), pattern=pattern)
    origin = (CROP[0].start, CROP[1].start)
    args = []
    for f, img in flats.items():
        np.save(folder / f"flat_f{f:g}.npy", img[CROP])
        args += ["--flat", f"{f:g}={folder / f'flat_f{f:g}.npy'}"]
    np.save(folder / "dark.npy", dark[CROP])
    for f, img in target_frames().items():
        np.save(folder / f"glass_f{f:g}.npy", img[CROP].astype(np.float32))
        args += ["--target-cube", f"{f:g}={folder / f'glass_f{f:g}.npy'}"]
    res = run_cli("calibrate", *args, "--dark", folder / "dark.npy", "--sensor", "imec_5x5_nir",
                  "--sensor-origin-px", f"{origin[0]},{origin[1]}",
                  "--pixel-pitch-um", str(PITCH_UM), "--magnification", "0.06",
                  "--pupil-magnification", "1.3", "--max-circles", "1", "--pupil", "paper",
                  "--fit-n-eff", "--target-tolerance-nm", "0.1",  # a crop pins less
                  "--out", folder / "lens.toml")
    return res, folder / "lens.toml"


@pytest.fixture(scope="module")
def crop_run(tmp_path_factory):
    return _crop_command(tmp_path_factory.mktemp("crop"))


@pytest.mark.slow  # four fifths of the sensor: three raw flats, two target frames
def test_calibrate_one_command_on_a_crop_of_the_vendor_sensor(crop_run):
    """Raw flats and target frames of the same crop, placed by ``--sensor-origin-px``: the
    band gains are divided out by the layout the origin gives (before, the flats were taken
    as a pattern-free image and refused for their tile), and the profile's centre, measured
    on the crop, is placed on the sensor by the origin it records. Its field reaches 15.8 deg
    (the sensor's 17.0): the circle's onset at f/4 lies beyond it, so the flats are taken at
    f/2, 2.8 and 11 (at f/2, 4 and 11 one onset is left, too few to tell P from h)."""
    from snapcorr.correct.geometry import optical_center_rc
    from snapcorr.cube import mosaic_to_cube

    res, path = crop_run
    origin = (CROP[0].start, CROP[1].start)
    assert res.returncode == 0, res.stdout + res.stderr
    lens = _lens_within_one_percent(path)
    assert lens.calibration["sensor_origin_rc"] == list(origin)
    sensor = Sensor.load(data.sensor_path("imec_5x5_nir"))
    cube = mosaic_to_cube(np.load(path.parent / "glass_f8.npy"), sensor, sensor_origin_px=origin)
    center, source = optical_center_rc(cube, sensor, lens)
    assert np.hypot(center[0] - CENTER_RC[0], center[1] - CENTER_RC[1]) < 1.0, (center, source)


@pytest.mark.slow  # the same crop twice more: with and without the tile pattern
def test_the_crops_reported_error_is_the_flats_noise_not_the_tile_pattern(crop_run, tmp_path):
    """The mean shift's reported error, of the flats alone and with x's part, within 1.5 times
    what the same light gives without the tile pattern (every pixel at the bands' mean gain:
    the same electrons, spread evenly). Before the layout was used, the pattern was taken as
    noise: 7 times. (Against flats with every pixel at the brightest band's gain, 1.3 times
    the electrons, the flats' part was 1.51 times.)"""
    res, path = crop_run
    assert res.returncode == 0, res.stdout + res.stderr
    plain, plain_path = _crop_command(tmp_path, pattern=False)
    assert plain.returncode == 0, plain.stdout + plain.stderr

    def errors(p):
        table = Lens.load(p).calibration
        total = np.array(table["shift_stderr_nm"])
        x_part = np.array(table["shift_stderr_exit_pupil_nm"])
        return total, np.sqrt(np.clip(total ** 2 - x_part ** 2, 0, None))

    (total, own), (total0, own0) = errors(path), errors(plain_path)
    print("reported shift error (nm), pattern:", total, own, "pattern-free:", total0, own0)
    assert np.all(total <= 1.5 * total0), (total, total0)
    # where the circle moves the shift (f/11's onset lies outside the field: its flats' part
    # is 0 with and without the pattern)
    cut = own0 > 0.1 * total0
    assert cut.sum() >= 2, own0
    assert np.all(own[cut] <= 1.5 * own0[cut]), (own, own0)
    assert np.all(own[~cut] <= 0.1 * total0[~cut] + 1.5 * own0[~cut]), (own, own0)
