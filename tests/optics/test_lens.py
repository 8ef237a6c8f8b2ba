import numpy as np
import pytest
from conftest import PAPER_LENS
from numpy.testing import assert_allclose

from snapcorr import Lens


def test_exit_pupil_radius_eq27_28(edmund):
    # Goossens 2019 Eq. 30 lists R_i for f/1.4, 2, 2.8, 4 from Eq. 27-28. With the stated
    # m = 0.06, m_P = 1.3 they come out 0.033 % smaller: the printed R_i imply
    # 1 + m/m_P = 1.0458 (e.g. m_P = 1.31). Same ratio for all four, so it is a parameter
    # rounding in the paper, not a formula difference; the reference CSV uses m_P = 1.3.
    R = edmund.exit_pupil_radius_mm([1.4, 2, 2.8, 4])
    assert_allclose(R, [7.1715, 5.0201, 3.5858, 2.5100], rtol=4e-4)
    assert_allclose(
        Lens(21.0, magnification=0.06, pupil_magnification=1.31, name="x").exit_pupil_radius_mm(
            [1.4, 2, 2.8, 4]
        ),
        [7.1715, 5.0201, 3.5858, 2.5100],
        atol=5e-5,
    )


def test_onset_satisfies_eq25(edmund):
    f = np.array([1.4, 2, 2.8, 4])
    on = np.deg2rad(edmund.onset_cra_deg(f))
    assert_allclose(7.4236 - 16.991 * np.tan(on), edmund.exit_pupil_radius_mm(f), atol=1e-12)


def test_onset_cases():
    assert Lens(20.0, name="ideal").onset_cra_deg(2.0) == np.inf
    small = Lens(20.0, [(3.0, 15.0)], name="P<R")
    assert small.onset_cra_deg(1.4) == 0.0  # vignetted on axis
    assert Lens(20.0, [(30.0, 0.0)], name="h=0").onset_cra_deg(2.0) == np.inf


def test_toml_round_trip(tmp_path, edmund):
    cal = {"f_numbers": [1.4, 2.0], "method": "paper"}
    lens = Lens(**{**edmund.to_dict(), "calibration": cal})
    path = lens.save(tmp_path / "lens.toml")
    back = Lens.load(path)
    assert back == lens and back.calibration == cal
    with pytest.raises(FileExistsError):
        lens.save(path)
    lens.save(path, overwrite=True)
    assert not list(tmp_path.glob(".*.tmp"))


def test_toml_schema_keys(tmp_path):
    path = tmp_path / "l.toml"
    path.write_text(
        '[lens]\nname = "x"\nexit_pupil_mm = 21.0\nvignetting_radius_mm = 7.4236\n'
        "vignetting_distance_mm = 16.991\nmagnification = 0.06\n"
        "pupil_magnification = 1.3\n"
    )
    lens = Lens.load(path)
    assert lens.has_vignetting and lens.magnification == 0.06
    path.write_text('[lens]\nname = "x"\nexit_pupil_mm = 21.0\nfocal_mm = 16\n')
    with pytest.raises(ValueError, match="unknown key"):
        Lens.load(path)
    path.write_text('[lens]\nname = "x"\nexit_pupil_mm = 21.0\nvignetting_radius_mm = 7.0\n')
    with pytest.raises(ValueError, match="both"):
        Lens.load(path)
    path.write_text("not toml [")
    with pytest.raises(ValueError, match="TOML"):
        Lens.load(path)
    with pytest.raises(FileNotFoundError):
        Lens.load(tmp_path / "missing.toml")


@pytest.mark.parametrize("text, words", [
    ("[lens]\nexit_pupil_mm = 21.0\n[[vignetting]]\nradius_mm = 7.4\ndistance_mm = 17.0\n",
     r"\['vignetting'\].*\[\[lens.vignetting\]\]"),
    ("[lens]\nexit_pupil_mm = 21.0\n[calibraton]\ncenter_px = [1.0, 2.0]\n",
     r"\['calibraton'\]"),
    ("exit_pupil_mm = 21.0\n[lens]\nexit_pupil_mm = 21.0\n", r"\['exit_pupil_mm'\]"),
])
def test_nothing_outside_lens_and_calibration_is_read_silently(tmp_path, text, words):
    """A [[vignetting]] at the top level (not [[lens.vignetting]]) loaded as a lens without
    vignetting: 6 nm of error at CRA 15 deg, f/1.4. Every top-level table or key but [lens]
    and [calibration] is refused, sensors likewise (test_vendor.py)."""
    path = tmp_path / "l.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"unknown top-level.*{words}"):
        Lens.load(path)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(exit_pupil_mm=0),
        dict(exit_pupil_mm=np.nan),
        dict(vignetting=[(-1, 5)]),
        dict(vignetting=[(7.0, np.inf)]),
        dict(vignetting=[{"radius_mm": 7.0}]),
        dict(pupil_magnification=0),
        dict(magnification=-0.1),
    ],
)
def test_bad_lens(kwargs):
    base = dict(name="x", exit_pupil_mm=21.0)
    with pytest.raises(ValueError):
        Lens(**{**base, **kwargs})


def test_bad_f_number(edmund):
    with pytest.raises(ValueError, match="f_number"):
        edmund.exit_pupil_radius_mm(0)


def test_overlap_of_two_discs_is_eq33_and_relative_illumination_uses_it():
    from snapcorr.optics.aperture import overlap_area_mm2, vignetted_area_mm2

    rng = np.random.default_rng(0)
    R, P = rng.uniform(0.5, 8, 20000), rng.uniform(0.5, 8, 20000)
    dv = rng.uniform(-12, 12, 20000)
    # includes disjoint, nested, touching-free and equal-radius pairs
    np.testing.assert_allclose(overlap_area_mm2([R, P], [0.0, dv]), vignetted_area_mm2(R, P, dv),
                               atol=1e-12)
    assert overlap_area_mm2([1.0, 1.0], [0.0, 0.0]) == pytest.approx(np.pi)
    assert overlap_area_mm2([1.0, 1.0], [0.0, 2.5]) == 0.0
    lens = PAPER_LENS
    cra = np.linspace(0, 40, 81)
    R14 = lens.exit_pupil_radius_mm(1.4)
    direct = vignetted_area_mm2(R14, 7.4236, 16.991 * np.tan(np.deg2rad(cra))) / (np.pi * R14**2)
    np.testing.assert_allclose(lens.relative_illumination(1.4, cra), direct, atol=1e-12)
    assert np.all(Lens(21.0, name="ideal").relative_illumination(2.0, cra) == 1.0)
    with pytest.raises(ValueError, match="one centre per radius"):
        overlap_area_mm2([1.0, 2.0], [0.0])


def test_several_circles_load_and_save_as_lens_vignetting_tables(tmp_path):
    path = tmp_path / "three.toml"
    path.write_text(
        "[lens]\nexit_pupil_mm = 21.0\n\n"
        "[[lens.vignetting]]\nradius_mm = 7.4236\ndistance_mm = 16.991\n\n"
        "[[lens.vignetting]]\nradius_mm = 9.0\ndistance_mm = 21.0\n\n"
        "[[lens.vignetting]]\nradius_mm = 12.0\ndistance_mm = -4.0\n")
    lens = Lens.load(path)
    assert lens.vignetting == ((7.4236, 16.991), (9.0, 21.0), (12.0, -4.0))
    assert lens.name == "" and lens.magnification == 0.0
    again = lens.save(tmp_path / "again.toml")
    assert again.read_text().count("[[lens.vignetting]]") == 3
    assert Lens.load(again) == lens
    assert Lens(21.0, vignetting=[(7.4236, 16.991), (9.0, 21.0), (12.0, -4.0)]) == lens


def test_the_single_circle_keys_still_load_and_save_in_the_new_form(tmp_path):
    old = tmp_path / "old.toml"
    old.write_text('[lens]\nname = "E"\nexit_pupil_mm = 21.0\nvignetting_radius_mm = 7.4236\n'
                   "vignetting_distance_mm = 16.991\n")
    lens = Lens.load(old)
    assert lens.vignetting == ((7.4236, 16.991),)
    text = lens.save(tmp_path / "new.toml").read_text()
    assert "[[lens.vignetting]]" in text and "vignetting_radius_mm" not in text
    both = tmp_path / "both.toml"
    both.write_text(old.read_text()
                    + "\n[[lens.vignetting]]\nradius_mm = 9.0\ndistance_mm = 30.0\n")
    with pytest.raises(ValueError, match="not both"):
        Lens.load(both)
    bad = tmp_path / "bad.toml"
    bad.write_text("[lens]\nexit_pupil_mm = 21.0\n\n[[lens.vignetting]]\nradius_mm = 9.0\n")
    with pytest.raises(ValueError, match="radius_mm and distance_mm"):
        Lens.load(bad)
    bad.write_text("[lens]\nexit_pupil_mm = 21.0\nvignetting = 3\n")
    with pytest.raises(ValueError, match=r"\[\[lens.vignetting\]\]"):
        Lens.load(bad)


def test_python_mistakes_get_a_hint():
    with pytest.raises(TypeError, match=r"vignetting=\[\(7.0, 16.0\)\]"):
        Lens(21.0, (7.0, 16.0))
    with pytest.raises(TypeError, match="name is a keyword"):
        Lens("Edmund", 21.0)
    with pytest.raises(TypeError, match="boolean"):
        Lens(21.0, [(True, 16.0)])


def test_several_circles_onsets_cutoff_and_description():
    lens = Lens(21.0, [(7.4236, 16.991), (9.0, 30.0), (6.0, 0.0)], name="three")
    R = float(lens.exit_pupil_radius_mm(2.8))
    on = lens.circle_onsets_cra_deg(2.8)
    assert on[0] == pytest.approx(np.rad2deg(np.arctan((7.4236 - R) / 16.991)))
    assert on[1] == pytest.approx(np.rad2deg(np.arctan((9.0 - R) / 30.0)))
    assert on[2] == np.inf  # a stop larger than the pupil never cuts it
    assert lens.onset_cra_deg(2.8) == pytest.approx(on[:2].min())
    assert Lens(21.0, [(3.0, 0.0)]).onset_cra_deg(2.8) == 0.0  # a stop smaller: cut on axis
    # the first pair to come apart: the two moving circles (|30 - 16.991| tan = 7.42 + 9)
    pairs = [(R + 7.4236) / 16.991, (R + 9.0) / 30.0, (7.4236 + 9.0) / (30.0 - 16.991),
             (7.4236 + 6.0) / 16.991, (9.0 + 6.0) / 30.0]
    assert lens.cutoff_cra_deg(2.8) == pytest.approx(np.rad2deg(np.arctan(min(pairs))))
    assert "3 circles" in lens.describe_vignetting()
    assert Lens(21.0).describe_vignetting() == "no vignetting circle"


def test_pupil_is_the_earlier_name_of_pupil_radiance(tmp_path):
    import dataclasses
    import warnings

    from snapcorr.optics.lens import PUPIL_RADIANCE_MODELS, PUPILS

    assert PUPILS is PUPIL_RADIANCE_MODELS
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new name: no warning
        new = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, pupil_radiance="lambertian")
        assert new.pupil_radiance == "lambertian"
        assert dataclasses.replace(new, name="x").pupil_radiance == "lambertian"
    with pytest.warns(FutureWarning, match=r"Lens\(pupil=\.\.\.\) is the earlier name of "
                                           r"Lens\(pupil_radiance=\.\.\.\).*0\.3"):
        old = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, pupil="lambertian")
    assert old == new
    with pytest.warns(FutureWarning, match=r"Lens.pupil is the earlier name of "
                                           r"Lens.pupil_radiance"):
        assert new.pupil == "lambertian"
    with pytest.warns(FutureWarning):
        assert dataclasses.replace(new, pupil="paper").pupil_radiance == "paper"
    with pytest.raises(TypeError, match="give the pupil's radiance model once"):
        Lens(21.0, pupil="paper", pupil_radiance="paper")
    with pytest.raises(ValueError, match="pupil_radiance must be one of paper, lambertian"):
        Lens(21.0, pupil_radiance="gaussian")
    # the lens file keeps its key: written and read as before
    new.save(tmp_path / "l.toml")
    assert 'pupil = "lambertian"' in (tmp_path / "l.toml").read_text()
    assert Lens.load(tmp_path / "l.toml").pupil_radiance == "lambertian"


def test_load_takes_a_bundled_lens_by_name(tmp_path):
    from snapcorr.data import lens_path

    assert Lens.load("edmund_optics_16mm") == Lens.load(lens_path())
    with pytest.raises(FileNotFoundError, match=r"no bundled lens named 'nope'; bundled "
                       r"lenses: \[.*'edmund_optics_16mm'"):
        Lens.load("nope")
    # a .toml is a file, never a bundled name: one that is missing is said so
    with pytest.raises((FileNotFoundError, ValueError), match=r"edmund_optics_16mm\.toml"):
        Lens.load(tmp_path / "edmund_optics_16mm.toml")
