"""Lens files and a lens calibration's placement keys with values of the wrong type or too large
for a float, and a calibrated lens centre on a binned sensor or one of another size. Each
refusal is one line naming what is wrong."""

from __future__ import annotations

import numpy as np
import pytest
from hostile import (
    HUGE,
    LENS,
    assert_refused,
    correct_args,
    cra_of,
    read_result,
    refused_in_one_line,
    snapshot,
)

from snapcorr import Lens


def lens_text(**override):
    lines = {
        "name": '"user lens"',
        "exit_pupil_mm": "21.0",
        "vignetting_radius_mm": "7.4236",
        "vignetting_distance_mm": "16.991",
        "magnification": "0.06",
        "pupil_magnification": "1.3",
    }
    lines.update(override)
    return "[lens]\n" + "".join(f"{k} = {v}\n" for k, v in lines.items())


@pytest.mark.parametrize("key, value", [
    ("exit_pupil_mm", "true"), ("exit_pupil_mm", '"twenty"'), ("vignetting_radius_mm", "true"),
    ("magnification", "true"), ("pupil_magnification", "false"),
])
def test_lens_value_of_the_wrong_type_is_refused(tmp_path, monkeypatch, key, value, cli):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "lens.toml").write_text(lens_text(**{key: value}))
    rc, out, err = cli("shift", "--lens", "lens.toml", "--f-number", "2", "--cra", "5")
    assert_refused(rc, err, key)
    assert out == ""


def _calibrated_lens(folder):
    text = LENS.read_text().split("[calibration]")[0]
    text += ("[calibration]\ncenter_px = [1100.0, 950.0]\npixel_pitch_um = 5.5\n"
             "image_size_px = [2048, 2048]\n")
    (folder / "lens.toml").write_text(text)


def _sensor(pitch, size):
    return (f'[sensor]\nname = "binned"\nlayout = "snapscan"\npixel_pitch_um = {pitch}\n'
            f"size_px = [{size}, {size}]\ncwl_nm = [550.0, 650.0]\nfwhm_nm = 10.0\n"
            "n_eff = 1.7\n")


def test_lens_center_follows_binning(tmp_path, monkeypatch, cli):
    monkeypatch.chdir(tmp_path)
    _calibrated_lens(tmp_path)
    (tmp_path / "binned.toml").write_text(_sensor(11.0, 1024))
    np.save(tmp_path / "binned.npy", np.ones((1024, 1024, 2), np.float32))
    rc, _, err = cli(*correct_args("binned.npy", "c.nc", "--method", "none",
                                   sensor="binned.toml", lens="lens.toml"))
    assert rc == 0, err
    res = read_result(tmp_path / "c.nc")
    cx, cy = ((1100 + 0.5) * 5.5 / 11 - 0.5, (950 + 0.5) * 5.5 / 11 - 0.5)
    np.testing.assert_allclose(res.attrs["optical_center_px"], [cx, cy], rtol=0, atol=1e-9)
    y, x = np.mgrid[0:1024, 0:1024]
    expected = np.degrees(np.arctan(np.hypot(x - cx, y - cy) * 0.011 / 21.0))
    np.testing.assert_allclose(cra_of(res).values, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize("pitch, size", [(11.0, 512), (5.5, 1024)],
                         ids=["binned-half-size", "same-pitch-smaller-sensor"])
def test_lens_center_on_a_sensor_of_another_size_is_refused(tmp_path, monkeypatch, pitch, size,
                                                            cli):
    monkeypatch.chdir(tmp_path)
    _calibrated_lens(tmp_path)
    (tmp_path / "other.toml").write_text(_sensor(pitch, size))
    np.save(tmp_path / "cube.npy", np.ones((size, size, 2), np.float32))
    before = snapshot(tmp_path)
    rc, _, err = cli(*correct_args("cube.npy", "c.nc", "--method", "none",
                                   sensor="other.toml", lens="lens.toml"))
    assert_refused(rc, err, "--center ROW,COL")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("body", [
    f"[lens]\nexit_pupil_mm = {HUGE}\n",
    f"[lens]\nexit_pupil_mm = 21.0\nmagnification = {HUGE}\n",
    f"[lens]\nexit_pupil_mm = 21.0\n[[lens.vignetting]]\nradius_mm = {HUGE}\n"
    "distance_mm = 17.0\n",
])
def test_a_huge_integer_in_a_lens_file_is_one_line(tmp_path, cli, body):
    (tmp_path / "l.toml").write_text(body)
    err = refused_in_one_line(cli("shift", "--lens", "l.toml", "--f-number", "2.8", "--cra", "5",
                        cwd=tmp_path))
    assert "finite number" in err and len(err) < 300


@pytest.mark.parametrize(("calibration", "match"), [
    ({"pixel_pitch_um": "100"}, "pixel_pitch_um must be a number, got text"),
    ({"pixel_pitch_um": True}, "pixel_pitch_um must be a number, got a boolean"),
    ({"pixel_pitch_um": 10**400}, "pixel_pitch_um must be a finite number"),
    ({"image_size_px": 5}, "image_size_px must be a list of two numbers"),
    ({"image_size_px": [1, 2, 3]}, "image_size_px must be two whole numbers"),
    ({"image_size_px": [640.5, 512]}, "image_size_px must be whole numbers"),
    # beyond int64: refused before the cast, which made garbage and a numpy warning
    ({"image_size_px": [10**20, 512]}, "image_size_px must be whole numbers of at most "
                                        "1,000,000"),
    # the flats' shape, written beside image_size_px: never read, so never checked
    ({"image_shape_px": [512, 0]}, r"image_shape_px must be two whole numbers > 0"),
    ({"image_shape_px": "512x640"}, "image_shape_px must be a list of two numbers"),
    ({"image_shape_px": [512, 640], "image_size_px": [512, 640]},
     r"image_shape_px \[512, 640\] \(rows, columns\) and image_size_px \[512, 640\] "
     r"\(width, height\) disagree"),
    ({"center_rc": [1.0, "a"]}, "center_rc must be a number, got text"),
    ({"center_px": 3}, "center_px must be a list of two numbers"),
    # the bounds --center and --sensor-origin-px have on the command line
    ({"center_rc": [1e7, 1e7]}, "no sensor is wider than 1,000,000 pixels"),
    ({"center_px": [-2e6, 5.0]}, "no sensor is wider"),
    ({"sensor_origin_rc": [-100000, -100000]}, "whole pixels from 0"),
    ({"sensor_origin_rc": [0.5, 3.7]}, "whole pixels from 0"),
    ({"sensor_origin_rc": [1e30, 0]}, "whole pixels from 0"),
    ({"sensor_origin_rc": [True, 0]}, "sensor_origin_rc must be a number, got a boolean"),
    ({"sensor_origin_rc": [1, 2, 3]}, "sensor_origin_rc"),
])
def test_the_placement_keys_of_a_calibration_are_checked(calibration, match):
    """These keys place the optical axis on another sensor (correct reads them), so a wrong
    type is refused when the lens is made, not used as 1 um or as garbage later."""
    with pytest.raises(ValueError, match=match):
        Lens(21.0, calibration=calibration)


def test_other_calibration_keys_stay_free_form_and_good_ones_load():
    lens = Lens(21.0, calibration={"center_rc": [250.5, 320.0], "pixel_pitch_um": 5.5,
                                   "image_size_px": [640, 512], "image_shape_px": [512, 640],
                                   "notes": True, "x": "free"})
    assert lens.calibration["notes"] is True


def test_a_lens_file_with_a_pitch_as_text_is_refused(tmp_path, cli):
    (tmp_path / "l.toml").write_text('[lens]\nexit_pupil_mm = 21.0\n[calibration]\n'
                                     'pixel_pitch_um = "100"\n')
    err = refused_in_one_line(cli("shift", "--lens", "l.toml", "--f-number", "2.8", "--cra", "5",
                        cwd=tmp_path))
    assert "pixel_pitch_um must be a number, got text" in err


TINY_H = ["1e-310", "-1e-310", "5e-324", "1e-30", "-0.0009"]


@pytest.mark.parametrize("h", TINY_H)
@pytest.mark.parametrize("circles", ["one", "second of two"])
def test_a_vignetting_distance_next_to_zero_is_refused_and_zero_is_a_stop(h, circles):
    """|h| below a micron overflowed the onset arctan((P - R) / |h|) and the discs' crossings
    (a warning per pixel, NaN onsets in a calibration); h = 0 is a stop, which never cuts a
    pupil smaller than itself."""
    import warnings

    first = [] if circles == "one" else [(7.4236, 16.991)]
    k = len(first) + 1
    with pytest.raises(ValueError, match=rf"circle {k} distance_mm \(h\) must be 0 \(a stop\) or"
                                         r" at least 0\.001 mm"):
        Lens(21.0, [*first, (9.0, float(h))], 0.06, 1.3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stop = Lens(21.0, [*first, (9.0, 0.0)], 0.06, 1.3)
        near = Lens(21.0, [*first, (9.0, 1e-3)], 0.06, 1.3)
        assert stop.circle_onsets_cra_deg(8.0)[-1] == np.inf  # P > R: never cuts
        assert near.circle_onsets_cra_deg(8.0)[-1] == pytest.approx(89.99, abs=0.01)
        assert np.all(np.isfinite(near.relative_illumination(1.4, [0.0, 10.0, 20.0])))


@pytest.mark.parametrize("form", ["single", "tables"])
def test_a_lens_file_with_a_vignetting_distance_next_to_zero_is_refused(tmp_path, form, cli):
    text = (lens_text(vignetting_distance_mm="1e-310") if form == "single" else
            "[lens]\nexit_pupil_mm = 21.0\n[[lens.vignetting]]\nradius_mm = 7.4\n"
            "distance_mm = 16.9\n[[lens.vignetting]]\nradius_mm = 9.0\ndistance_mm = 1e-310\n")
    (tmp_path / "lens.toml").write_text(text)
    key = "vignetting_distance_mm" if form == "single" else r"circle 2 distance_mm \(h\)"
    with pytest.raises(ValueError, match=rf"{key} must be 0 \(a stop\) or at least 0\.001"):
        Lens.load(tmp_path / "lens.toml")
    rc, _, err = cli("shift", "--lens", tmp_path / "lens.toml", "--f-number", "2", "--cra",
                     "10", "--cwl-nm", "700", "--n-eff", "1.7")
    assert_refused(rc, err, "lens.toml", "0.001")
    assert "overflow" not in err


def test_discs_with_centres_next_to_each_other_overlap_without_a_warning():
    """A crossing of two discs whose centres lie 1e-300 mm apart is far outside them: the
    area is the coincident discs' (it overflowed with a warning, per pixel)."""
    import warnings

    from snapcorr.optics import discs
    from snapcorr.optics.aperture import overlap_area_mm2

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for apart in (1e-300, 5e-324):
            assert overlap_area_mm2([3.0, 7.4], [0.0, apart]) == pytest.approx(9 * np.pi)
            b = discs.boundary([3.0, 7.4, 9.0], [0.0, apart, 2 * apart])
            assert np.all(np.isfinite(b.u)) and np.all(np.isfinite(b.y))
        lens = Lens(21.0, [(7.4236, 16.991), (9.0, 30.0)], 0.06, 1.3)
        assert lens.relative_illumination(1.4, [1e-300, 0.0]) == pytest.approx([1.0, 1.0])


def _circles(n):
    return [(5.0 + i * 1e-3, 17.0 + i * 0.01) for i in range(n)]


@pytest.mark.parametrize("form", ["tables", "inline"])
def test_a_lens_file_with_more_circles_than_a_lens_has_is_refused(tmp_path, form, cli):
    """The optics' cost grows with the square of the circle count: 1000 circles in a 50 kB
    profile took gigabytes and minutes before any output. Nine, one past the bound, are
    refused on reading, in one line naming the file and the bound; eight load."""
    def text(n):
        head = "[lens]\nexit_pupil_mm = 21.0\nmagnification = 0.06\npupil_magnification = 1.3\n"
        if form == "inline":
            return head + "vignetting = [" + ", ".join(f"[{P}, {h}]" for P, h in _circles(n)) \
                + "]\n"
        return head + "".join(f"[[lens.vignetting]]\nradius_mm = {P}\ndistance_mm = {h}\n"
                              for P, h in _circles(n))

    (tmp_path / "ok.toml").write_text(text(8))
    assert len(Lens.load(tmp_path / "ok.toml").vignetting) == 8
    (tmp_path / "many.toml").write_text(text(9))
    with pytest.raises(ValueError, match=r"many\.toml: vignetting holds 9 circles; at most 8"):
        Lens.load(tmp_path / "many.toml")
    err = refused_in_one_line(cli("shift", "--lens", "many.toml", "--f-number", "2", "--cra",
                                  "10", cwd=tmp_path))
    assert "many.toml" in err and "9 circles" in err and "at most 8" in err


def test_more_circles_than_a_lens_has_are_refused_by_every_entry():
    """Lens() (a list or an endless iterator, read no further than the bound) and the
    functions taking circles as lists (P_mm, dv_mm) or discs (radii): each refuses the list
    naming its argument."""
    import itertools

    from snapcorr.optics import aperture, discs, goossens2019

    with pytest.raises(ValueError, match="vignetting holds 9 circles; at most 8"):
        Lens(21.0, _circles(9))
    with pytest.raises(ValueError, match="vignetting holds more than 8 circles"):
        Lens(21.0, itertools.repeat((5.0, 17.0)))
    assert len(Lens(21.0, _circles(8)).vignetting) == 8
    P = [5.0] * 9
    dv = [0.1 * i for i in range(9)]
    for call in (lambda: aperture.gamma(1.0, 3.0, 0.5, P, dv),
                 lambda: aperture.vignetted_area_mm2(3.0, P, dv),
                 lambda: aperture.max_radius_mm(3.0, 0.5, P, dv),
                 lambda: aperture.min_radius_mm(3.0, 0.5, P, dv),
                 lambda: goossens2019.kernel(-1.0, 700.0, 1.7, 21.0, 3.0, 0.5, P, dv),
                 lambda: goossens2019.mean_shift_contour(700.0, 1.7, 21.0, 3.0, 0.5, P, dv),
                 lambda: goossens2019.mean_shift_riemann(700.0, 1.7, 21.0, 3.0, 0.5, P, dv)):
        with pytest.raises(ValueError, match="P_mm holds 9 circles; at most 8"):
            call()
    r, c = [3.0] * 11, [0.01 * i for i in range(11)]
    with pytest.raises(ValueError, match="radii_mm holds 11 discs; at most 10"):
        aperture.overlap_area_mm2(r, c)
    for call in (lambda: discs.boundary(r, c), lambda: discs.arc_half_angle(1.0, 0.0, r, c),
                 lambda: discs.extreme_radii(0.0, r, c)):
        with pytest.raises(ValueError, match="radii holds 11 discs; at most 10"):
            call()


@pytest.mark.parametrize("body", [
    '[lens]\nexit_pupil_mm = "' + "x" * 100_000 + '"\n',
    '[lens]\nexit_pupil_mm = 21.0\nvignetting = ["' + "v" * 100_000 + '"]\n',
], ids=["exit_pupil_mm", "vignetting"])
def test_text_of_100_kb_in_a_lens_file_is_quoted_as_an_excerpt(tmp_path, cli, body):
    (tmp_path / "l.toml").write_text(body)
    err = refused_in_one_line(cli("shift", "--lens", "l.toml", "--f-number", "2.8", "--cra",
                                  "5", cwd=tmp_path))
    assert len(err) < 400, err[:500]
