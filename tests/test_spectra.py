"""Source spectra: Wien's law, parsing of named sources, files and cube pixels, and the
paper's colour filter."""

import numpy as np
import pytest

import snapcorr.paper_experiment as paper
from snapcorr import budget, spectra
from snapcorr.calibrate import CANDIDATE_TARGETS, exit_pupil
from snapcorr.optics.profiles import MultiLorentzian


def test_blackbody_peaks_where_wien_says():
    bb = spectra.blackbody(2856.0)  # CIE illuminant A
    peak = bb.wavelength_nm[np.argmax(bb.values)]
    assert peak == pytest.approx(2.897771955e6 / 2856.0, abs=0.5)


def test_sources_parse_and_bad_sources_are_refused(tmp_path):
    assert spectra.parse_source("tungsten:3000").name == "blackbody 3000 K"
    assert "G173" in spectra.parse_source("solar:astm-g173").name
    p = tmp_path / "s.csv"
    p.write_text("wavelength_nm,value\n400,1\n500,2\n600,3\n")
    s = spectra.parse_source(str(p))
    assert s(450.0) == pytest.approx(1.5)
    np.save(tmp_path / "s.npy", np.array([[400.0, 500.0, 600.0], [1.0, 2.0, 3.0]]))
    assert spectra.read_spectrum(tmp_path / "s.npy")(450.0) == pytest.approx(1.5)
    for bad, msg in (("tungsten:hot", "temperature"), ("tungsten:-5", "> 0 and at most"),
                     ("nothing.csv", "no spectrum file"), ("sun", "unknown source"),
                     ("cube", "needs a cube"), ("tungsten:5", "emits nothing"),
                     ("solar:moon", "solar model"), ("tungsten:1e200", "at most 1e\\+06 K")):
        with pytest.raises(ValueError, match=msg):
            spectra.parse_source(bad)
    (tmp_path / "bad.txt").write_text("1 2 3\n4 5 6\n7 8 9\n")
    with pytest.raises(ValueError, match="two columns"):
        spectra.read_spectrum(tmp_path / "bad.txt")
    with pytest.raises(ValueError, match="covers"):
        budget.shift_error(spectra.Spectrum(np.array([400.0, 500.0]), np.array([1.0, 1.0])),
                           MultiLorentzian(700.0, 10.0), 1.0)


def test_cube_sources():
    from snapcorr.cube import make_cube

    data = np.ones((3, 4, 5), np.float32)
    data[1, 2] = np.linspace(1.0, 2.0, 5)
    cube = make_cube(data, [500.0, 550.0, 600.0, 650.0, 700.0])
    px = spectra.parse_source("cube:1,2", cube)
    assert px(625.0) == pytest.approx(1.625) and px(300.0) == 1.0 and px(900.0) == 2.0
    mean = spectra.parse_source("cube", cube)
    assert mean(500.0) == pytest.approx(1.0) and mean(700.0) == pytest.approx(1 + 1 / 12)
    for bad, msg in (("cube:9,9", "outside"), ("cube:a", "two pixel indices")):
        with pytest.raises(ValueError, match=msg):
            spectra.parse_source(bad, cube)


def test_read_spectrum_takes_ordinary_files(tmp_path):
    p = tmp_path / "a.txt"
    p.write_text("# wavelength, value\n400 1\n500 2\n600 3\n")
    assert spectra.read_spectrum(p)(450.0) == pytest.approx(1.5)
    p.write_text("wavelength (nm) radiance\n400;1\n500;2\n600;3\n")
    assert spectra.read_spectrum(p)(550.0) == pytest.approx(2.5)
    p.write_text("400 1\n500 2\nend of data\n")
    with pytest.raises(ValueError, match="line 3"):
        spectra.read_spectrum(p)
    for body, msg in (("400 1\n400 2\n", "increasing"), ("400 1\n500 nan\n", "NaN")):
        p.write_text(body)
        with pytest.raises(ValueError, match=msg):
            spectra.read_spectrum(p)



def test_a_spectrum_of_one_row_is_told_it_needs_two_rows(tmp_path, cli):
    """One row was refused as ``need two columns ..., got shape (1, 2)``: it has two columns,
    it lacks a second row."""
    import numpy as np

    p = tmp_path / "one_row.csv"
    p.write_text("500 1\n")
    np.save(tmp_path / "empty.npy", np.zeros((0, 2)))
    for path, held in ((p, "one row"), (tmp_path / "empty.npy", "no row")):
        with pytest.raises(ValueError, match=rf"{held} of \(wavelength nm, value\); a spectrum "
                                             "needs at least two rows"):
            spectra.read_spectrum(path)
    res = cli("budget", "--sensor", "mosaic_4x4_vis", "--lens", "edmund_optics_16mm",
              "--f-number", "2", "--source", "one_row.csv", cwd=tmp_path)
    assert res.returncode == 1 and "needs at least two rows" in res.stderr
    assert "column" not in res.stderr and len(res.stderr.strip().splitlines()) == 1


def test_the_colour_filter_has_one_home_and_is_re_exported():
    assert paper.colour_filter is spectra.colour_filter
    assert exit_pupil.colour_filter is spectra.colour_filter
    assert CANDIDATE_TARGETS["colour filter (Goossens 2019)"] is spectra.colour_filter
    assert "colour_filter" in paper.__all__
    lam = np.array([500.0, 640.0, 760.0, 900.0])
    edge = 1.0 / (1.0 + np.exp(-(lam - 640.0) / 9.0))
    notch = 1.0 - 0.45 * np.exp(-0.5 * ((lam - 760.0) / 12.0) ** 2)
    np.testing.assert_allclose(spectra.colour_filter(lam), 0.04 + 0.9 * edge * notch,
                               rtol=0, atol=1e-15)
    assert spectra.colour_filter(700.0).shape == ()


def test_the_colour_checker_is_n_ohtas_as_colour_science_ships_it():
    """Every patch's bundled reflectance against colour-science's own copy of N. Ohta's
    measurement (to its rounding), by name and by number in reading order."""
    import colour

    sds = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    assert tuple(sds) == spectra.COLOUR_CHECKER_PATCHES
    for i, (name, sd) in enumerate(sds.items(), start=1):
        got = spectra.colour_checker(name.upper())
        np.testing.assert_allclose(got.wavelength_nm, sd.wavelengths)
        np.testing.assert_allclose(got.values, sd.values, atol=5e-5)
        assert spectra.colour_checker(i).name == f"ColorChecker {name}"


@pytest.mark.parametrize("patch, match", [("crimson", "no ColorChecker patch named 'crimson'"),
                                          (0, "numbered 1-24"), (25, "numbered 1-24"),
                                          (True, "name or number"), (15.0, "name or number")])
def test_a_patch_that_is_not_on_the_chart_is_refused(patch, match):
    with pytest.raises(ValueError, match=match):
        spectra.colour_checker(patch)


def test_a_patch_is_not_known_beyond_its_published_range():
    red = spectra.colour_checker("red")
    assert float(red(780.0)) > 0.5
    with pytest.raises(ValueError):
        red(800.0)


def test_a_spectrum_is_not_read_at_nan_or_beyond_its_range_whatever_comes_with_it():
    """NaN fails every comparison, so [NaN, 300] passed the range check of a 380-780 nm
    spectrum and gave [nan, 0.052]; NaN alone gave NaN."""
    import pytest

    from snapcorr.spectra import colour_checker

    red = colour_checker("red")
    for asked in ([np.nan, 300.0], np.nan, [500.0, np.inf]):
        with pytest.raises(ValueError, match="not a finite number"):
            red(asked)
    with pytest.raises(ValueError, match="covers 380-780 nm"):
        red([500.0, 300.0])
    assert np.isfinite(red([500.0, 600.0])).all()
