"""`snapcorr pupil`: target cubes too small for any annulus are refused in one line."""

from __future__ import annotations

import numpy as np


def test_target_cubes_too_small_for_any_annulus_are_refused_in_one_line(tmp_path, cli):
    """A 40 x 40 crop of a mosaic (10 x 10 tiles) leaves no annulus with a standard error:
    the pupil fit is refused saying why (the cube too small: fewer than 24 pixels a side),
    not by numpy's 'zero-size array' of an empty fit."""
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
    assert "10 x 10 pixels: too few" in res.stderr and "zero-size" not in res.stderr
    assert not (tmp_path / "x.toml").exists()


def test_a_crop_beside_the_axis_takes_the_true_centre_it_is_given(tmp_path, cli):
    """A crop of the sensor's corner (rows 0-127, columns 0-159; the axis at row 543.5, col
    1023.5): the cubes place the centre at the crop's edge (row 138, col 191, +- 22 and 30
    px), which says nothing of where the axis is. The true centre, given, was refused as 34
    standard errors from there; it is taken, and a centre far off is still refused where
    the cubes can place it (a crop about the axis)."""
    from snapcorr.data import mosaic_frames

    for f in (2, 11):
        frames = mosaic_frames(f_number=f, seed=f)
        for name, frame in zip(("raw", "dark", "white"), frames, strict=True):
            np.save(tmp_path / f"{name}{f}.npy", frame[:128, :160])
            np.save(tmp_path / f"a{name}{f}.npy", frame[400:656, 800:1120])
        for crop, origin in (("", "0,0"), ("a", "400,800")):
            res = cli("flatfield", f"{crop}raw{f}.npy", "--dark", f"{crop}dark{f}.npy",
                      "--white", f"{crop}white{f}.npy", "--sensor", "mosaic_4x4_vis",
                      "--sensor-origin-px", origin, "--out", f"{crop}t{f}.nc", "--quiet",
                      cwd=tmp_path)
            assert res.returncode == 0, res.stderr
    fit = ("pupil", "--sensor", "mosaic_4x4_vis", "--lens", "edmund_optics_16mm",
           "--tolerance-nm", "20")
    res = cli(*fit, "--cube", "2=t2.nc", "--cube", "11=t11.nc", "--center", "543.5,1023.5",
              "--out", "x.toml", cwd=tmp_path)
    assert "optical centre row 543.50, col 1023.50 (given)" in res.stdout, res.stderr
    res = cli(*fit, "--cube", "2=at2.nc", "--cube", "11=at11.nc", "--center", "5000,5000",
              "--out", "y.toml", cwd=tmp_path)
    assert res.returncode == 1 and "from where the f/2 cube places it" in res.stderr, \
        res.stderr
    assert not (tmp_path / "y.toml").exists()


def test_predict_refuses_an_impossible_f_number_before_printing_anything(cli):
    """``--f-number 0.3`` printed the table's two header lines, then the refusal."""
    res = cli("pupil", "--predict", "--sensor", "snapscan_vnir", "--lens", "edmund_optics_16mm",
              "--f-number", "2", "--f-number", "0.3")
    assert res.returncode == 1 and res.stdout == ""
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "f/0.3 is below the physical limit" in lines[0]
