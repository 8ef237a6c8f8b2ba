"""Flat-fielding refusals: a white not above the dark anywhere, all-NaN inputs, a saturation
that masks everything, a reference larger than the cube; more than half masked is a loud
warning."""

from __future__ import annotations

import numpy as np
import pytest
from hostile import FF, assert_refused, read_result, save_cubes, snapshot


@pytest.mark.parametrize("white", [10.0, 5.0], ids=["white-equals-dark", "white-below-dark"])
def test_white_not_above_dark_anywhere_is_refused(tmp_path, monkeypatch, white, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, dark=10.0, white=white)
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert_refused(rc, err)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("which", ["raw", "dark", "white"])
def test_all_nan_input_is_refused(tmp_path, monkeypatch, which, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    np.save(tmp_path / f"{which}.npy", np.full((12, 10, 4), np.nan, np.float32))
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert_refused(rc, err)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("value", ["nan", "-1"])
def test_saturation_that_masks_everything_is_refused(tmp_path, monkeypatch, value, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc", f"--saturation={value}")
    assert_refused(rc, err, "saturation")
    assert snapshot(tmp_path) == before


def test_more_than_half_masked_is_a_loud_warning(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    white = np.full((12, 10, 4), 400.0, np.float32)
    white[:7] = 10.0  # 7 of 12 rows: white == dark
    np.save(tmp_path / "white.npy", white)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert rc == 0, err
    warned = [ln for ln in err.splitlines() if "warning" in ln.lower() and "mask" in ln.lower()]
    assert warned, f"no warning about the masked values:\n{err}"
    assert read_result(tmp_path / "o.nc")["mask"].values.mean() == pytest.approx(7 / 12)


@pytest.mark.parametrize("which, value", [("dark", 10.0), ("white", 400.0)])
def test_reference_with_more_rows_than_the_cube_is_refused(tmp_path, monkeypatch, which,
                                                          value, cli):
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    np.save(tmp_path / f"{which}.npy", np.full((20, 10, 4), value, np.float32))
    before = snapshot(tmp_path)
    rc, _, err = cli(*FF, "--out", "o.nc")
    assert_refused(rc, err, which)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("which", ["raw", "dark", "white"])
def test_a_flat_field_result_is_not_taken_as_counts(tmp_path, monkeypatch, which, cli):
    """A reflectance snapcorr wrote, given again as the raw (or a reference): every value came
    out wrong (-0.03 everywhere) with no pixel masked; now refused, naming what it is."""
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    rc, _, err = cli(*FF, "--out", "ff.nc")
    assert rc == 0, err
    args = list(FF)
    args[args.index(f"{which}.npy")] = "ff.nc"
    before = snapshot(tmp_path)
    rc, _, err = cli(*args, "--out", "again.nc")
    assert_refused(rc, err, "is a reflectance (a flat field's result", "not raw counts")
    assert snapshot(tmp_path) == before


def test_the_library_refuses_a_ratio_as_counts():
    from snapcorr.cube import flatfield, make_cube

    counts = make_cube(np.full((4, 5, 3), 100.0), [500.0, 510.0, 520.0])
    ratio = flatfield(counts, counts * 0.1, counts * 2)["reflectance"]
    with pytest.raises(ValueError, match="the raw input is a reflectance"):
        flatfield(ratio, counts * 0.1, counts * 2)
    with pytest.raises(ValueError, match="the white frame 2 of 2 is a reflectance"):
        flatfield(counts, counts * 0.1, [counts * 2, ratio])


def test_a_ratio_under_another_name_is_not_taken_as_counts(tmp_path, monkeypatch, cli):
    """A reflectance renamed (written as 'radiance') still says what it is, by its long_name
    and by its units of 1: refused as the raw input (before, flat-fielded again: every
    value -0.03, none masked), and of two whites the one that is a ratio is named."""
    from snapcorr.cube import flatfield, make_cube
    from snapcorr.files import write_cube

    counts = make_cube(np.full((4, 5, 3), 100.0), [500.0, 510.0, 520.0])
    ratio = flatfield(counts, counts * 0.1, counts * 2)["reflectance"]
    for v in (ratio.rename("radiance"),
              ratio.rename("radiance").assign_attrs(long_name="radiance")):
        with pytest.raises(ValueError, match="the raw input is a"):
            flatfield(v, counts * 0.1, counts * 2)
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    rc, _, err = cli(*FF, "--out", "ff.nc")
    assert rc == 0, err
    from snapcorr.files import read_cube

    write_cube(read_cube("ff.nc").rename("radiance"), tmp_path / "renamed.hdr")
    args = list(FF)
    args[args.index("raw.npy")] = "renamed.hdr"
    rc, _, err = cli(*args, "--out", "again.nc")
    assert_refused(rc, err, "raw input is a", "not raw counts")
    args = [*FF, "--white", "renamed.hdr"]
    rc, _, err = cli(*args, "--out", "again.nc")
    assert_refused(rc, err, "--white renamed.hdr is a", "not raw counts")


@pytest.mark.parametrize("white, top", [(60000, 65535), (4000, 4095)])
def test_the_types_largest_code_is_the_saturation_without_a_bit_depth_and_is_said(
        tmp_path, monkeypatch, cli, white, top):
    """A sensor that states no bit depth, whites stored as uint16: a pixel at 65535 was
    clipped by the file if not by the sensor, and is masked as calibrate masks it (it was
    taken as a white of 65535 and gave a reflectance too low by the clipping). The level is
    said even where no white reaches it: uint16 whites of a 12-bit camera peak at 4095, and
    65535 masks nothing that camera clipped (it was said only where a white reached 65535,
    and finding that out read every white once more)."""
    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path, dtype=np.uint16, white=white)
    frame = np.load("white.npy")
    frame[:3] = top
    np.save("white.npy", frame)
    rc, _, err = cli(*FF, "--out", "ff.nc")
    assert rc == 0, err
    assert "saturation: 65535 DN, the largest code of the whites' type, uint16" in err
    assert "bit_depth in a sensor TOML" in err
    mask = read_result(tmp_path / "ff.nc")["mask"].values
    assert mask[:3].all() == (top == 65535) and not mask[3:].any()


def test_whites_of_two_integer_types_get_no_saturation_of_one(tmp_path):
    """A uint8 and a uint16 white: no one code is the largest, and 255 would mask nearly every
    uint16 pixel; no level is taken."""
    from snapcorr.cube.mosaic import frame_saturation

    whites = [np.full((4, 4), 200, np.uint8), np.full((4, 4), 60000, np.uint16)]
    assert frame_saturation(None, whites) is None
    assert frame_saturation(None, whites[1:]) == 65535.0
    assert frame_saturation(None, [np.full((4, 4), 0.5)]) is None
