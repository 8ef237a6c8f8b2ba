"""Hostile inputs of a fourth round, each class refused where its mechanism lives: packing
ranges float32 cannot hold, a vendor file's tile, sensor size, grid, peaks and numbers that
would size an allocation or break later, and frame names whose numbers a float cannot tell
apart or whose reading is ambiguous."""

from __future__ import annotations

import dataclasses
import random

import numpy as np
import pytest
from vendorfiles import imec_4x4, write_newer, write_older

from snapcorr._validation import check_pack_range
from snapcorr.cube import Sensor
from snapcorr.cube.frames import natural_order

# --- packing ranges ------------------------------------------------------------------------


@pytest.mark.parametrize("lo, hi, words", [
    (0.0, 1e-40, "smallest normal"),          # the step rounds to a subnormal float32
    (-1e300, 1e300, "largest number"),        # add_offset and scale_factor overflow float32
    (-3.3e38, 3.3e38, "largest number"),      # each end fits, their difference does not
    (1e6, 1e6 + 1.0, "finer than float32"),   # neighbouring codes unpack to one float32
])
def test_a_pack_range_float32_cannot_hold_is_refused(lo, hi, words):
    with pytest.raises(ValueError, match=words) as info:
        check_pack_range("--pack-range", lo, hi)
    assert str(info.value).startswith("--pack-range ") and "\n" not in str(info.value)


def test_every_accepted_pack_range_unpacks_within_half_a_step():
    """Random ranges that pass: codes packed and unpacked in float32, as a CF reader does,
    land within half a step (plus float32 rounding at the range's size) of the value."""
    rng = np.random.default_rng(11)
    for _ in range(200):
        centre = 10.0 ** rng.uniform(-30, 30) * rng.choice([-1, 1])
        width = abs(centre) * 10.0 ** rng.uniform(-4, 2) + 1e-30
        lo, hi = centre - width, centre + width
        try:
            lo, hi = check_pack_range("r", lo, hi)
        except ValueError:
            continue
        scale, offset = np.float32((hi - lo) / 65534), np.float32(lo)
        values = rng.uniform(lo, hi, 50)
        codes = np.clip(np.rint((values - lo) / float(scale)), 0, 65534).astype(np.uint16)
        back = codes.astype(np.float32) * scale + offset
        bound = float(scale) / 2 + 4 * float(np.finfo(np.float32).eps) * max(abs(lo), abs(hi))
        assert np.all(np.isfinite(back)) and float(scale) > 0
        assert np.max(np.abs(back.astype(float) - values)) <= 2 * bound


def _tiny_mosaic(tmp_path):
    """An 8 x 8 crop of the 4 x 4 VIS mosaic: raw 1000, dark 64, white 2000 DN everywhere."""
    files = {}
    for name, value in (("raw", 1000), ("dark", 64), ("white", 2000)):
        files[name] = tmp_path / f"{name}.npy"
        np.save(files[name], np.full((8, 8), value, np.uint16))
    return files


@pytest.mark.parametrize("given", [["--pack-range", "-0.5,3.5"], ["--pack-range=-0.5,3.5"],
                                   ["--pack-range", "-1,2"]])
def test_a_pack_range_starting_with_a_minus_is_parsed(given, capsys):
    """The default range, -0.5,3.5, typed as the help shows it: argparse alone takes the
    value for an option and stops with 'expected one argument' before it reaches --help."""
    from snapcorr.cli import main

    assert main(["flatfield", "raw.npy", "--dark", "d.npy", "--white", "w.npy", "--out",
                 "x.nc", "--dtype", "uint16", *given, "--help"]) == 0
    assert "expected one argument" not in capsys.readouterr().err


@pytest.mark.slow
def test_a_pack_range_starting_with_a_minus_is_read_from_the_command_line(tmp_path):
    """The range reaches the file: its add_offset, and values within half a step."""
    import xarray as xr

    from snapcorr.cli import main

    f = _tiny_mosaic(tmp_path)
    out = tmp_path / "ff.nc"
    given = ["--pack-range", "-1,2"]
    rc = main(["flatfield", str(f["raw"]), "--dark", str(f["dark"]), "--white", str(f["white"]),
               "--sensor", "mosaic_4x4_vis", "--sensor-origin-px", "520,1000", "--dtype",
               "uint16", *given, "--out", str(out), "--quiet"])
    assert rc == 0
    lo = float(given[-1].split("=")[-1].split(",")[0])
    with xr.open_dataset(out, mask_and_scale=False) as ds:
        assert float(ds.reflectance.attrs["add_offset"]) == lo
    with xr.open_dataset(out) as ds:  # (1000 - 64) / (2000 - 64), within half a step
        step = (float(given[-1].split(",")[-1]) - lo) / 65534
        assert np.allclose(ds.reflectance.values, 936 / 1936, atol=step / 2 + 1e-7)


def test_a_pack_range_float32_cannot_hold_is_a_usage_error(tmp_path, capsys):
    from snapcorr.cli import main

    f = _tiny_mosaic(tmp_path)
    rc = main(["flatfield", str(f["raw"]), "--dark", str(f["dark"]), "--white", str(f["white"]),
               "--sensor", "mosaic_4x4_vis", "--dtype", "uint16", "--pack-range=0,1e-40",
               "--out", str(tmp_path / "ff.nc")])
    err = capsys.readouterr().err
    assert rc == 2 and "--pack-range" in err and "Traceback" not in err
    assert not (tmp_path / "ff.nc").exists()


@pytest.mark.parametrize("dtype", [[], ["--dtype", "float32"], ["--dtype", "float16"]])
def test_a_pack_range_without_uint16_names_the_option(tmp_path, capsys, dtype):
    from snapcorr.cli import main

    f = _tiny_mosaic(tmp_path)
    rc = main(["flatfield", str(f["raw"]), "--dark", str(f["dark"]), "--white", str(f["white"]),
               "--sensor", "mosaic_4x4_vis", *dtype, "--pack-range", "0,1", "--out",
               str(tmp_path / "ff.zarr")])
    err = capsys.readouterr().err
    assert rc == 1 and "--pack-range goes with --dtype uint16" in err, err


# --- vendor files --------------------------------------------------------------------------


def _refused(path, words):
    with pytest.raises(ValueError, match=words) as info:
        Sensor.load(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path.name}: "), message


def test_a_tile_of_1e18_bands_is_refused_by_counting_the_bands_first(tmp_path):
    """A tile of 1e5 x 1e5 on a sensor as large: comparing the band indices with
    ``range(tile bands)`` built a list of 1e10 numbers (a MemoryError) before any count; a
    tile of 1e9 x 1e9 on a sensor of 1e12 px is refused by the sensor's size first."""
    fx = dataclasses.replace(imec_4x4(), tile=(10**5, 10**5), size=(10**5, 10**5),
                             area=(0, 0, 10**5, 10**5))
    _refused(write_newer(tmp_path / "tile.xml", fx), r"lists bands \[0, 1, 2, 3, 4, 5\]\.\.\. "
                                                     r"\(16\), but a 10000000000-band tile")
    fx = dataclasses.replace(imec_4x4(), tile=(10**9, 10**9), size=(10**12, 10**12),
                             area=(0, 0, 10**12, 10**12))
    _refused(write_newer(tmp_path / "tile2.xml", fx), "is 1000000000000 px; no sensor")


@pytest.mark.parametrize("writer", [write_newer, write_older])
def test_a_sensor_larger_than_any_is_refused(tmp_path, writer):
    fx = dataclasses.replace(imec_4x4(), size=(10**8, 10**8), area=(0, 0, 1088, 2048))
    _refused(writer(tmp_path / "big.xml", fx), r"sensor_info/(height_px|height)> is 100000000 px")
    with pytest.raises(ValueError, match="size_px"):
        Sensor(name="big", layout="snapscan", cwl_nm=[500.0, 600.0], fwhm_nm=[10.0, 10.0],
               pixel_pitch_um=5.5, n_eff=1.7, size_px=(10**8, 2048))


def test_one_tiny_grid_step_at_a_peak_does_not_license_a_tiny_width(tmp_path):
    """A grid with one step of 1e-9 nm where a peak of 2e-9 nm FWHM sits: the local step
    allowed it, and the centres' fine grid then asked for 26 TiB."""
    fx = imec_4x4()
    at = fx.peaks[0][0][0]
    grid = np.unique(np.r_[fx.grid, at - 1e-9, at])
    curves = np.array([np.interp(grid, fx.grid, c) for c in fx.curves])
    peaks = [list(p) for p in fx.peaks]
    peaks[0] = [(at, 2e-9, 0.5)]
    fx = dataclasses.replace(fx, grid=grid, curves=curves, peaks=peaks)
    _refused(write_newer(tmp_path / "step.xml", fx), r"fwhm_nm> is 2e-09 nm, narrower than the "
                                                     r"response grid's 1 nm step")


@pytest.mark.parametrize("writer", [write_newer, write_older])
def test_a_band_whose_peaks_lie_outside_the_grid_is_refused(tmp_path, writer):
    fx = imec_4x4()
    peaks = [list(p) for p in fx.peaks]
    peaks[2] = [(5000.0, 8.0, 0.5)]
    path = writer(tmp_path / "out.xml", dataclasses.replace(fx, peaks=peaks))
    _refused(path, r"band 2: its peaks \(5000 nm\) all lie outside the response grid "
                   r"\(400-1000 nm\)")


@pytest.mark.parametrize("writer", [write_newer, write_older])
def test_a_virtual_band_outside_the_grid_is_refused(tmp_path, writer):
    fx = imec_4x4()
    name, kind, wl, fw, coeffs = fx.matrices[-1]
    wl = wl.copy()
    wl[5] = 5000.0
    fx = dataclasses.replace(fx, matrices=[*fx.matrices[:-1], (name, kind, wl, fw, coeffs)])
    _refused(writer(tmp_path / "vb.xml", fx), "has a virtual band at 5000 nm, outside the "
                                              "responses' 400-1000 nm")


def test_an_older_grid_of_a_picometre_span_is_refused(tmp_path):
    """601 samples 1e-12 nm apart: the whole grid at 400 nm, every band's peak outside."""
    path = write_older(tmp_path / "pico.xml", imec_4x4(), replace={
        "<measurement_resolution_nm>1.0</measurement_resolution_nm>":
        "<measurement_resolution_nm>1e-12</measurement_resolution_nm>"})
    _refused(path, "outside the response grid")


def test_a_negative_quantum_efficiency_is_refused(tmp_path):
    fx = imec_4x4()
    peaks = [list(p) for p in fx.peaks]
    peaks[1] = [(peaks[1][0][0], 8.0, -0.3)]
    _refused(write_newer(tmp_path / "qe.xml", dataclasses.replace(fx, peaks=peaks)),
             "QE -0.3: a quantum efficiency is not negative")


def test_numbers_with_underscores_are_not_numbers(tmp_path):
    """Python's float() reads '1_0' as 10; a calibration file never writes it so."""
    fx = imec_4x4()
    first = repr(float(fx.curves[0][0]))
    path = write_newer(tmp_path / "us.xml", fx, replace={
        f'<response values="{first} ': '<response values="1_0 '})
    _refused(path, "holds '1_0', not a number")
    path = write_newer(tmp_path / "us2.xml", fx, replace={"<pixel_pitch_um>5.5<":
                                                          "<pixel_pitch_um>5_5<"})
    _refused(path, "pixel_pitch_um> must be a number, got '5_5'")


def test_a_response_of_subnormal_numbers_is_nowhere_positive(tmp_path):
    fx = imec_4x4()
    curves = fx.curves.copy()
    curves[4] = 1e-320
    _refused(write_newer(tmp_path / "sub.xml", dataclasses.replace(fx, curves=curves)),
             "band\\[4\\]/response> is nowhere positive")


# --- frame names ---------------------------------------------------------------------------


@pytest.mark.parametrize("ordered", [
    ["f_1733112345123456789", "f_1733112345123456790", "f_1733112345123456791"],
    ["a" + "1" * 400, "a" + "1" * 399 + "2"],
    ["exp_1e-3", "exp_2.5e-3", "exp_1e-2", "exp_1E-1", "exp_1"],
    ["t0,25", "t0,50", "t0,75", "t1,00"],  # a decimal comma of one length: either reading
    ["t0,5", "t1", "t1,5", "t2"],
])
def test_numbers_in_names_are_compared_exactly(ordered):
    rng = random.Random(3)
    for _ in range(5):
        names = list(ordered)
        rng.shuffle(names)
        assert natural_order(names) == ordered


def test_a_comma_read_two_ways_is_refused():
    """t0,5 t0,25 t1: as a decimal comma 0.25 < 0.5, as a separator 5 < 25."""
    with pytest.raises(ValueError, match="decimal comma or a separator"):
        natural_order(["t0,5", "t0,25", "t1"])


def test_the_same_number_written_twice_is_still_refused():
    for names in (["f1", "f1.0"], ["f1e3", "f1000"], ["t0,5", "t0.5"]):
        with pytest.raises(ValueError, match="same number"):
            natural_order(names)


def test_a_stream_that_is_not_there_is_said_to_be_missing(tmp_path):
    from snapcorr.cube import read_frames

    with pytest.raises(FileNotFoundError, match="no such file or folder of frames"):
        read_frames(tmp_path / "frames")


def test_a_pickled_npy_is_refused_without_numpys_advice(tmp_path):
    """A .npy of Python objects (or an AppleDouble ``._`` file beside the frames) is refused
    in one line that gives no Python argument and no unsafe advice (``allow_pickle=``)."""
    from snapcorr.cube import read_cube

    path = tmp_path / "objects.npy"
    np.save(path, np.array([{"a": 1}, None], dtype=object), allow_pickle=True)
    with pytest.raises(ValueError, match="pickled Python objects") as info:
        read_cube(path)
    assert "allow_pickle" not in str(info.value) and "\n" not in str(info.value)


def test_target_cubes_too_small_for_any_annulus_are_refused_in_one_line(tmp_path, cli):
    """A 40 x 40 crop of a mosaic (10 x 10 tiles) leaves no annulus with a standard error:
    the pupil fit is refused saying why, not by numpy's 'zero-size array' of an empty fit."""
    from snapcorr.data import mosaic_frames

    r0, c0 = 520, 1000
    for name, frame in zip(("raw", "dark", "white"), mosaic_frames(), strict=True):
        np.save(tmp_path / f"{name}.npy", frame[r0:r0 + 40, c0:c0 + 40])
    res = cli("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy", "--sensor",
              "mosaic_4x4_vis", "--sensor-origin-px", f"{r0},{c0}", "--out", "t.nc", "--quiet",
              cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    res = cli("pupil", "--cube", "2=t.nc", "--cube", "8=t.nc", "--sensor", "mosaic_4x4_vis",
              "--out", "x.toml", "--quiet", cwd=tmp_path)
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert "no annulus" in res.stderr and "zero-size" not in res.stderr
    assert not (tmp_path / "x.toml").exists()
