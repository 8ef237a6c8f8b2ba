"""`snapcorr pupil`: target cubes too small for any annulus are refused in one line."""

from __future__ import annotations

import numpy as np
import pytest


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


@pytest.mark.slow  # 10-60 s on two cores: kept out of the default run
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


def test_predict_checks_a_spectrum_as_the_fit_does_and_prints_no_part_of_a_failed_table(
        tmp_path, cli):
    """--target-spectrum of 500-600 nm was rated (held at its ends beyond, where the bands
    respond) and one in micrometres rated 'no information', where the fit refuses both; a
    sensor without n_eff printed the table's header, then the refusal."""
    lam = np.arange(500.0, 601.0)
    np.savetxt(tmp_path / "part.csv", np.column_stack([lam, 0.5 + 0.4 * np.sin(lam / 7)]),
               delimiter=",")
    np.savetxt(tmp_path / "um.csv", np.column_stack([lam / 1000, 0.5 + 0.4 * np.sin(lam / 7)]),
               delimiter=",")
    base = ("pupil", "--predict", "--sensor", "mosaic_4x4_vis", "--f-number", "2",
            "--f-number", "8")
    for name, said in (("part.csv", "covers 500-600 nm, but the bands need"),
                       ("um.csv", "look like micrometres")):
        res = cli(*base, "--target-spectrum", name, cwd=tmp_path)
        assert res.returncode == 1 and said in res.stderr and not res.stdout, res.stderr
    toml = (tmp_path / "s.toml")
    toml.write_text('[sensor]\nname = "no-index"\nlayout = "snapscan"\npixel_pitch_um = 5.5\n'
                    'size_px = [512, 512]\ncwl_nm = [500.0, 510.0, 520.0, 530.0]\n'
                    'fwhm_nm = [10.0, 10.0, 10.0, 10.0]\n')
    res = cli("pupil", "--predict", "--sensor", "s.toml", "--f-number", "2", cwd=tmp_path)
    assert res.returncode == 1 and "n_eff" in res.stderr and not res.stdout, (res.stdout,
                                                                              res.stderr)
