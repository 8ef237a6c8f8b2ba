"""The mosaic's phase read from a white reference (snapcorr.cube.phase).

The whites are simulated here, independently of snapcorr: the real imec 4x4 VIS responses
(``tests/vendorfiles.imec_4x4``) written to a vendor file of the newer variant, a camera whose
responses are off the file's (each band's gain by 5 %, its wavelength by up to 1 nm), every
pixel's filter scaled by its chief ray (``T(lambda / a)``, ``a = sqrt(1 - sin^2 phi /
n_eff^2)``, the band-pass fixed), cos^4 fall-off, a dark level and 1 % noise. The lamps: a
tungsten (Planck, 2856 K, computed here), daylight (CIE D65) and a phosphor white LED (CIE
LED-B3), from colour-science, never told to snapcorr.
"""

from __future__ import annotations

import numpy as np
import pytest
import vendorfiles
from conftest import run_cli

from snapcorr.cube import Sensor, mosaic_to_cube
from snapcorr.cube.phase import check_mosaic_phase, mosaic_phase

TILE = (4, 4)
X_MM, PITCH_MM, N_EFF = 20.0, 5.5e-3, 1.7


def planck(grid, kelvin):
    h, c, k = 6.62607015e-34, 2.99792458e8, 1.380649e-23
    lam = grid * 1e-9
    return 1.0 / lam**5 / np.expm1(h * c / (lam * k * kelvin))


def lamp(name, grid):
    if name == "tungsten":
        return planck(grid, 2856.0)
    import colour

    sd = colour.SDS_ILLUMINANTS[name].copy().align(
        colour.SpectralShape(grid[0], grid[-1], grid[1] - grid[0]),
        extrapolator_kwargs={"method": "constant", "left": 0.0, "right": 0.0})
    return np.asarray(sd.values, float)


def sodium(grid):
    """A lamp of narrow lines (high-pressure sodium-like): no smooth fingerprint."""
    lines = [(498.0, 0.2), (515.0, 0.15), (568.0, 0.6), (589.0, 1.0), (616.0, 0.5)]
    return sum(a * np.exp(-0.5 * ((grid - w) / 1.5) ** 2) for w, a in lines) + 1e-3


@pytest.fixture(scope="module")
def vendor(tmp_path_factory):
    fx = vendorfiles.imec_4x4()
    path = vendorfiles.write_newer(tmp_path_factory.mktemp("phase") / "imec4x4.xml", fx)
    return fx, Sensor.load(path), path


def band_at_position(fx):
    """Band ``i`` at tile row ``i // 4``, column ``i % 4`` (the vendor file's convention)."""
    return np.arange(len(fx.curves)).reshape(TILE)


def white_frame(fx, shape, origin, light, *, seed, noise=0.01, size=(1088, 2048)):
    """A raw white frame at sensor ``origin`` (row, col), as a camera would give it."""
    rng = np.random.default_rng(seed)
    grid = fx.grid
    bp = np.interp(grid, fx.components[0][1], fx.components[0][2])
    gain = 1 + 0.05 * rng.standard_normal(len(fx.curves))
    shift = rng.uniform(-1.0, 1.0, len(fx.curves))
    rows = origin[0] + np.arange(shape[0])[:, None]
    cols = origin[1] + np.arange(shape[1])[None, :]
    r_mm = np.hypot(rows - (size[0] - 1) / 2, cols - (size[1] - 1) / 2) * PITCH_MM
    phi = np.arctan(r_mm / X_MM)
    a = np.sqrt(1 - np.sin(phi) ** 2 / N_EFF**2)
    a_nodes = np.linspace(a.min() - 1e-6, 1.0, 48)
    band = band_at_position(fx)[(rows - fx.area[0]) % TILE[0], (cols - fx.area[1]) % TILE[1]]
    signal = np.empty(shape)
    for b, curve in enumerate(fx.curves):
        table = [gain[b] * np.sum(np.interp(grid / ak - shift[b], grid, curve, left=0, right=0)
                                  * bp * light) for ak in a_nodes]
        here = band == b
        signal[here] = np.interp(a[here], a_nodes, table)
    signal *= np.cos(phi) ** 4
    signal *= 500.0 / np.median(signal)  # the file's 10-bit codes: the brightest band ~850
    dark = 32.0
    frame = dark + signal * (1 + noise * rng.standard_normal(shape))
    return frame, np.full(shape, dark)


def test_the_simulator_places_bands_as_the_file_says(vendor):
    fx, sensor, _ = vendor
    assert sensor.mosaic_shape == TILE
    want = band_at_position(fx)
    for b, (r, c) in enumerate(sensor.band_offset):  # band b: the file's band vendor_band[b]
        assert want[r, c] == sensor.vendor_band[b]


@pytest.mark.parametrize("light", ["tungsten", "D65", "LED-B3"])
def test_every_phase_is_found_under_every_lamp(vendor, light):
    fx, sensor, _ = vendor
    spectrum = lamp(light, fx.grid)
    ratios = []
    for k, (pr, pc) in enumerate(np.ndindex(*TILE)):
        origin = (400 + pr, 700 + pc)  # the first pixel at tile position (pr, pc)
        white, dark = white_frame(fx, (64, 96), origin, spectrum, seed=k)
        found = mosaic_phase(white, sensor, dark=dark)
        assert found.phase_px == (pr, pc), (light, origin, found.describe())
        assert found.sensor_origin_px(near=(origin[0] + 1, origin[1] - 1)) == origin
        ratios.append(found.ratio)
        # stated right: agrees and passes; stated one row or column off: refused
        assert check_mosaic_phase(white, sensor, origin, dark=dark).agrees
        for wrong in ((origin[0] + 1, origin[1]), (origin[0], origin[1] + 2)):
            with pytest.raises(ValueError, match=rf"origin with the white's phase is "
                               rf"{origin[0]},{origin[1]} "):
                check_mosaic_phase(white, sensor, wrong, dark=dark)
    assert min(ratios) > 1.8  # 2.04 (LED-B3) to 2.87 (D65) when written


def test_a_lamp_of_lines_is_refused_never_guessed(vendor):
    fx, sensor, _ = vendor
    refused = 0
    for k, (pr, pc) in enumerate(np.ndindex(*TILE)):
        white, dark = white_frame(fx, (64, 64), (200 + pr, 300 + pc), sodium(fx.grid), seed=k)
        found = mosaic_phase(white, sensor, dark=dark)
        assert found.phase_px in (None, (pr, pc))
        refused += found.phase_px is None
        if found.phase_px is None:
            assert "cannot tell" in found.describe()
            # a stated origin is then taken as it is: the white cannot contradict it
            assert check_mosaic_phase(white, sensor, (201 + pr, 300 + pc), dark=dark) is not None
    assert refused > 0


def test_a_tile_cube_of_the_white_is_checked_too(vendor):
    fx, sensor, _ = vendor
    origin = (512, 1024)
    white, dark = white_frame(fx, (64, 64), origin, lamp("tungsten", fx.grid), seed=3)
    right = mosaic_to_cube(white - dark, sensor, sensor_origin_px=origin)
    assert check_mosaic_phase(right, sensor).agrees
    wrong = mosaic_to_cube(white - dark, sensor, sensor_origin_px=(origin[0] + 1, origin[1] + 1))
    with pytest.raises(ValueError, match="origin with the white's phase is 512,1024"):
        check_mosaic_phase(wrong, sensor, (origin[0] + 1, origin[1] + 1))


def test_a_whole_sensor_white_is_checked_against_the_file(vendor):
    fx, sensor, _ = vendor
    white, dark = white_frame(fx, (1088, 2048), (0, 0), lamp("D65", fx.grid), seed=5)
    found = check_mosaic_phase(white, sensor, dark=dark)
    assert found.agrees and found.phase_px == (0, 0)
    # the same sensor's frame read from its second row: taken as a whole frame, it is refused
    shifted = np.vstack([white[1:], white[-1:]])
    with pytest.raises(ValueError, match="whole-sensor frame's"):
        check_mosaic_phase(shifted, sensor, dark=dark)


def test_saturated_and_dead_pixels_are_left_out(vendor):
    fx, sensor, _ = vendor
    white, dark = white_frame(fx, (64, 64), (8, 8), lamp("tungsten", fx.grid), seed=9)
    white[::7, ::5] = 1023.0
    white[3::11, ::3] = 0.0
    assert mosaic_phase(white, sensor, dark=dark, saturation=1023).phase_px == (0, 0)


def test_the_sensors_largest_code_is_saturated_by_default(vendor):
    """The sensor's bit depth sets the saturation where none is given, as in flatfield: a
    white clipped at its largest code everywhere is said to hold nothing usable (it was
    said to fit no phase within 10 %), and a few clipped pixels are left out."""
    fx, sensor, _ = vendor
    assert sensor.full_scale_dn == 1023
    white, dark = white_frame(fx, (64, 64), (8, 8), lamp("tungsten", fx.grid), seed=9)
    with pytest.raises(ValueError, match="no whole tile of usable values"):
        mosaic_phase(np.full_like(white, 1023.0), sensor, dark=dark)
    white[::7, ::5] = 1023.0
    assert mosaic_phase(white, sensor, dark=dark).phase_px == (0, 0)


def test_a_sensor_without_measured_responses_is_not_checked():
    import snapcorr.data

    gaussian = Sensor.load(snapcorr.data.sensor_path("mosaic_4x4_vis"))
    frame = np.ones((1088, 2048))
    assert check_mosaic_phase(frame, gaussian) is None
    with pytest.raises(ValueError, match="measured responses"):
        mosaic_phase(frame, gaussian)


def test_sensor_phase_from_prints_the_phase(vendor, tmp_path):
    fx, _, path = vendor
    white, dark = white_frame(fx, (64, 64), (101, 202), lamp("LED-B3", fx.grid), seed=1)
    np.save(tmp_path / "white.npy", white.astype(np.uint16))
    np.save(tmp_path / "dark.npy", dark.astype(np.uint16))
    code, out, err = run_cli("sensor", str(path), "--phase-from", str(tmp_path / "white.npy"),
                             "--dark", str(tmp_path / "dark.npy"))
    assert code == 0, err
    assert "first pixel sits at row 1, col 2 of the 4 x 4 tile" in out


def test_sensor_phase_from_fails_where_the_stated_origin_disagrees(vendor, tmp_path):
    """A script checking a crop's origin learns of a disagreement by the exit status, not
    only by reading the word (before: DISAGREES, exit status 0)."""
    fx, _, path = vendor
    white, dark = white_frame(fx, (64, 64), (101, 202), lamp("LED-B3", fx.grid), seed=1)
    np.save(tmp_path / "white.npy", white.astype(np.uint16))
    np.save(tmp_path / "dark.npy", dark.astype(np.uint16))
    for origin, status, word in (("101,202", 0, "agrees"), ("102,202", 1, "DISAGREES")):
        code, out, err = run_cli("sensor", str(path), "--phase-from", str(tmp_path / "white.npy"),
                                 "--dark", str(tmp_path / "dark.npy"), "--sensor-origin-px",
                                 origin)
        assert code == status and f"--sensor-origin-px {origin}: {word}" in out, (out, err)


@pytest.fixture(scope="module")
def crop_files(vendor, tmp_path_factory):
    """A 64 x 64 crop at sensor row 101, column 202: raw (a grey target), dark and white, and
    a stream of two raw frames."""
    fx, _, _ = vendor
    folder = tmp_path_factory.mktemp("crop")
    white, dark = white_frame(fx, (64, 64), (101, 202), lamp("tungsten", fx.grid), seed=2)
    raw = dark + 0.4 * (white - dark)
    for name, frame in (("raw", raw), ("dark", dark), ("white", white)):
        np.save(folder / f"{name}.npy", np.clip(np.rint(frame), 0, 1023).astype(np.uint16))
    np.save(folder / "frames.npy", np.clip(np.rint(np.stack([raw, raw])), 0, 1023).astype(
        np.uint16))
    return folder


@pytest.mark.parametrize("command", ["flatfield", "flatfield --demosaic", "stream"])
def test_a_stated_origin_the_white_contradicts_is_refused_in_one_line(vendor, crop_files,
                                                                      command, tmp_path):
    _, _, xml = vendor
    f = crop_files
    first = ["stream", str(f / "frames.npy")] if command == "stream" else \
        ["flatfield", str(f / "raw.npy")] + (["--demosaic", "bilinear"] if "demosaic" in command
                                             else [])
    common = [*first, "--dark", str(f / "dark.npy"), "--white", str(f / "white.npy"),
              "--sensor", str(xml)]
    code, _, err = run_cli(*common, "--sensor-origin-px", "102,202",
                             "--out", str(tmp_path / "wrong.zarr"))
    assert code != 0 and err.count("\n") == 1, err
    assert "shows the mosaic at another phase than the stated origin 102,202" in err
    assert "an origin with the white's phase is 101,202" in err
    assert not (tmp_path / "wrong.zarr").exists()
    code, _, err = run_cli(*common, "--sensor-origin-px", "101,202",
                             "--out", str(tmp_path / "right.zarr"))
    assert code == 0, err


def test_a_crop_without_its_origin_is_refused_with_the_phase_its_white_shows(vendor, crop_files,
                                                                             tmp_path):
    _, _, xml = vendor
    f = crop_files
    code, _, err = run_cli("flatfield", str(f / "raw.npy"), "--dark", str(f / "dark.npy"),
                             "--white", str(f / "white.npy"), "--sensor", str(xml),
                             "--out", str(tmp_path / "ff.nc"))
    assert code != 0 and err.count("\n") == 1, err
    assert "64 x 64 px crop of the 1088 x 2048 px sensor" in err
    assert "first pixel sits at row 1, col 2 of the 4 x 4 tile" in err


def test_a_tile_of_too_few_bands_cannot_tell(vendor):
    _, sensor, _ = vendor
    import dataclasses

    from snapcorr.cube.responses import FilterResponses

    r = sensor.responses
    few = FilterResponses(r.wavelength_nm, r.curves[:4], r.system, r.peaks[:4], r.system_name)
    tiny = dataclasses.replace(sensor, cwl_nm=sensor.cwl_nm[:4], fwhm_nm=sensor.fwhm_nm[:4],
                               mosaic_shape=(2, 2), band_offset=((0, 0), (0, 1), (1, 0), (1, 1)),
                               responses=few, matrices=(), vendor_band=None)
    white = np.random.default_rng(0).uniform(100, 200, (32, 32))
    found = mosaic_phase(white, tiny)
    assert found.phase_px is None and "too few to tell" in found.describe()
    assert check_mosaic_phase(white, tiny, (0, 0)).agrees is None  # passes, unchecked


def test_a_white_with_nothing_usable_is_refused_naming_it(vendor, crop_files, tmp_path):
    _, _, xml = vendor
    f = crop_files
    np.save(tmp_path / "white.npy", np.zeros((64, 64), np.uint16))  # at or below the dark
    code, _, err = run_cli("flatfield", str(f / "raw.npy"), "--dark", str(f / "dark.npy"),
                           "--white", str(tmp_path / "white.npy"), "--sensor", str(xml),
                           "--sensor-origin-px", "101,202", "--out", str(tmp_path / "ff.nc"))
    assert code != 0 and err.count("\n") == 1, err
    assert f"--white {tmp_path / 'white.npy'}: the white holds no whole tile" in err


def test_origin_px_is_the_earlier_name_of_sensor_origin_px(vendor):
    fx, sensor, _ = vendor
    origin = (401, 702)
    white, dark = white_frame(fx, (64, 96), origin, lamp("D65", fx.grid), seed=3)
    found = mosaic_phase(white, sensor, dark=dark, sensor_origin_px=origin)
    with pytest.warns(FutureWarning, match="origin_px is the earlier name of sensor_origin_px"):
        assert mosaic_phase(white, sensor, dark=dark, origin_px=origin).stated_px == \
            found.stated_px
    with pytest.warns(FutureWarning, match="MosaicPhase.origin_px is the earlier name of "
                                           "MosaicPhase.sensor_origin_px"):
        assert found.origin_px(origin) == found.sensor_origin_px(origin) == origin
    with pytest.warns(FutureWarning, match="origin_px is the earlier name"):
        assert check_mosaic_phase(white, sensor, dark=dark, origin_px=origin).agrees
