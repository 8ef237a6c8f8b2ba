"""Packing ranges (``--pack-range``) that float32 cannot hold are refused, every accepted range
unpacks within half a step, and a range starting with a minus is read as a value."""

from __future__ import annotations

import numpy as np
import pytest

from snapcorr._validation import check_pack_range


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


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
@pytest.mark.parametrize("lazy", [False, True])
def test_values_beyond_the_packing_range_are_counted_and_said(tmp_path, suffix, lazy):
    """Values beyond the range are stored at its ends (as documented) and now said, with their
    count, once per variable, for numpy and dask cubes alike (the blocks' counts summed); a
    range that holds every value says nothing. Before, 4096 values of 4096 were clipped with
    the summary's '0 masked' and no word."""
    import warnings

    from snapcorr.cube import make_cube
    from snapcorr.files import PackingClipWarning, write_dataset

    values = np.linspace(-0.2, 1.0, 6 * 5 * 4).reshape(6, 5, 4)
    cube = make_cube(values, [500.0, 510.0, 520.0, 530.0]).rename("reflectance")
    cube.attrs["units"] = "1"
    if lazy:
        cube = cube.chunk({"y": 2})
    ds = cube.to_dataset()
    outside = int(np.sum((values < 0.0) | (values > 0.5)))
    with pytest.warns(PackingClipWarning) as record:
        write_dataset(ds, tmp_path / f"c{suffix}", dtype="uint16", pack_range=(0.0, 0.5))
    said = [str(w.message) for w in record if w.category is PackingClipWarning]
    assert len(said) == 1 and f"{outside} of {values.size} values of 'reflectance'" in said[0]
    assert {w.filename for w in record if w.category is PackingClipWarning} == {__file__}
    with warnings.catch_warnings():
        warnings.simplefilter("error", PackingClipWarning)
        write_dataset(ds, tmp_path / f"d{suffix}", dtype="uint16", pack_range=(-0.5, 1.5))


@pytest.mark.parametrize("lo, hi", [(-0.5, 3.5), (0.0, 0.1), (0.3, 1.7), (-1.0, 1.0)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_values_at_the_ends_of_the_range_are_not_counted_as_clipped(lo, hi, dtype):
    """float32's step puts the top end a hair beyond the last code: it is stored there, not
    clipped (it was counted, a warning for a cube that fits); beyond half a step it is."""
    from snapcorr.files._packing import pack_uint16

    scale, offset = np.float32((hi - lo) / 65534), np.float32(lo)
    counts = []
    pack_uint16(np.array([lo, hi], dtype), offset, scale, 65534, 65535, clipped=counts)
    pack_uint16(np.array([lo - 2 * float(scale), hi + 2 * float(scale)], dtype), offset, scale,
                65534, 65535, clipped=counts)
    assert counts == [(0, 2), (2, 2)]
