"""One convention for image coordinates: (row, col), the old x-first centre deprecated.

See snapcorr/_coords.py and CONTRIBUTING.md. The old form must keep its meaning (never a
silent swap), warn, and refuse to be mixed with the new one.
"""

import importlib
import inspect
import pkgutil
import warnings

import numpy as np
import pytest
from conftest import PAPER_LENS

import snapcorr
from snapcorr.cube import Sensor, make_cube
from snapcorr.optics import cra_map
from snapcorr.simulate import flat_frame, relative_illumination_map

ROW, COL = 7.25, 19.5  # an off-centre optical centre in a 20 x 30 image


def _public_functions():
    """Every public function of every snapcorr module (by ``__all__``)."""
    seen = {}
    for info in pkgutil.walk_packages(snapcorr.__path__, "snapcorr."):
        if info.name.endswith("__main__") or "._" in info.name:  # private modules
            continue
        mod = importlib.import_module(info.name)
        for name in getattr(mod, "__all__", []):
            obj = getattr(mod, name, None)
            if inspect.isfunction(obj):
                seen[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return seen


def test_every_public_function_taking_an_x_first_centre_takes_center_rc():
    missing = []
    for name, func in _public_functions().items():
        params = inspect.signature(func).parameters
        if "center_px" in params and "center_rc" not in params and name != \
                "snapcorr.optics.chief_ray.cra_deg":
            missing.append(name)
    assert not missing, missing


@pytest.mark.parametrize("call", [
    lambda **kw: flat_frame((20, 30), 22.0, 1.4, PAPER_LENS, noise=False, **kw),
    lambda **kw: relative_illumination_map((20, 30), 22.0, 1.4, PAPER_LENS, **kw),
    lambda **kw: cra_map((20, 30), 22.0, 21.0, **kw),
], ids=["flat_frame", "relative_illumination_map", "cra_map"])
def test_center_rc_is_the_old_centre_row_first_and_the_old_form_warns(call):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new form: no warning at all
        new = call(center_rc=(ROW, COL))
    with pytest.warns(FutureWarning, match=r"center_px is the old x-first form .* "
                                           r"center_rc=\(7\.25, 19\.5\)"):
        old = call(center_px=(COL, ROW))
    np.testing.assert_array_equal(new, old)
    # the row really is the row: the smallest angle sits at (ROW, COL)'s nearest pixel
    cra = cra_map((20, 30), 22.0, 21.0, center_rc=(ROW, COL))
    assert np.unravel_index(np.argmin(cra), cra.shape) == (7, 19)
    with pytest.raises(TypeError, match="give the optical centre once"):
        call(center_rc=(ROW, COL), center_px=(COL, ROW))


def test_the_correction_reports_and_takes_the_centre_row_first():
    from snapcorr.correct import correct_cube

    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 4), 10.0, 1.7)
    cube = make_cube(np.ones((20, 30, 4), np.float32), sensor.cwl_nm, name="reflectance")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # snapcorr's own calls never warn
        ds = correct_cube(cube, sensor, 1.4, PAPER_LENS, center_rc=(ROW, COL))
    assert ds.attrs["optical_center_rc"] == [ROW, COL]
    with pytest.warns(FutureWarning):
        old = correct_cube(cube, sensor, 1.4, PAPER_LENS, center_px=(COL, ROW))
    np.testing.assert_array_equal(ds["cra_deg"].values, old["cra_deg"].values)


def test_cli_center_is_row_first_and_center_px_says_it_is_deprecated(tmp_path, cli):
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 4), 10.0, 1.7)
    sensor.save(tmp_path / "sensor.toml")
    PAPER_LENS.save(tmp_path / "lens.toml")
    from snapcorr.cube import read_dataset, write_cube

    write_cube(make_cube(np.ones((20, 30, 4), np.float32), sensor.cwl_nm), tmp_path / "c.nc")
    common = ["correct", "c.nc", "--lens", "lens.toml", "--sensor", "sensor.toml",
              "--f-number", "2"]
    new = cli(*common, "--center", f"{ROW},{COL}", "--out", "new.nc", cwd=tmp_path)
    assert new.returncode == 0 and "deprecated" not in new.stderr, new.stderr
    old = cli(*common, "--center-px", f"{COL},{ROW}", "--out", "old.nc", cwd=tmp_path)
    assert old.returncode == 0
    assert "--center-px CX,CY is deprecated" in old.stderr and \
        f"--center {ROW:g},{COL:g}" in old.stderr
    a, b = read_dataset(tmp_path / "new.nc"), read_dataset(tmp_path / "old.nc")
    np.testing.assert_array_equal(a["cra_deg"].values, b["cra_deg"].values)
    assert f"row {ROW:g}, col {COL:g}" in new.stdout
    both = cli(*common, "--center", "1,2", "--center-px", "2,1", "--out", "x.nc",
               cwd=tmp_path)
    assert both.returncode == 1 and "give the optical centre once" in both.stderr
    assert len(both.stderr.strip().splitlines()) == 1


def test_a_centre_argument_of_another_name_keeps_its_old_x_first_keyword():
    """``accepts_center_rc(old=..., new=...)``: the old keyword (declared in its old place, or
    not at all) is swapped into the row-first one, warns, and refuses to be mixed with it;
    with ``many``, each centre of a sequence is swapped."""
    from snapcorr._coords import accepts_center_rc

    @accepts_center_rc(old="center", new="center_rc")
    def kept(a, center=None, *, center_rc=None):  # the old name in its old place
        return a, center, center_rc

    @accepts_center_rc(old="fix_center", new="fix_center_rc")
    def renamed(a, fix_center_rc=None):  # the old name gone from the body
        return a, fix_center_rc

    @accepts_center_rc(old="centers", new="centers_rc", many=True)
    def several(centers_rc):
        return centers_rc

    assert "fix_center" in inspect.signature(renamed).parameters
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert kept(1, center_rc=(ROW, COL)) == (1, None, (ROW, COL))
        assert renamed(1, (ROW, COL)) == (1, (ROW, COL))
        assert several([(ROW, COL)]) == [(ROW, COL)]
    with pytest.warns(FutureWarning, match=r"^center is the old x-first form .* snapcorr 0\.3.*"
                                           r"center_rc=\(7\.25, 19\.5\)"):
        assert kept(1, (COL, ROW)) == (1, None, (ROW, COL))
    with pytest.warns(FutureWarning, match=r"^fix_center is the old x-first form"):
        assert renamed(1, fix_center=(COL, ROW)) == (1, (ROW, COL))
    with pytest.warns(FutureWarning, match=r"^centers is the old x-first form"):
        assert several(centers=[(COL, ROW), (2.0, 1.0)]) == [(ROW, COL), (1.0, 2.0)]
    for call in (lambda: kept(1, (COL, ROW), center_rc=(ROW, COL)),
                 lambda: renamed(1, (ROW, COL), fix_center=(COL, ROW))):
        with pytest.raises(TypeError, match="give the optical centre once"):
            call()
    with pytest.raises(ValueError, match="two numbers"):
        renamed(1, fix_center=(1.0,))



def test_a_body_taking_the_centre_x_first_is_refused():
    """Every body inside snapcorr takes the centre row first: the decorator turns only the old
    x-first keyword into center_rc, and refuses a body that would take it x first."""
    from snapcorr._coords import accepts_center_rc

    def x_first(a, center_px=None):
        return center_px

    with pytest.raises(TypeError, match="x_first takes no center_rc"):
        accepts_center_rc(x_first)


def _centre_takers():
    """Every public function taking a row-first centre, with its centre arguments' names."""
    for name, func in sorted(_public_functions().items()):
        params = inspect.signature(func).parameters
        names = [p for p in ("center_rc", "fix_center_rc", "centers_rc") if p in params]
        if names and hasattr(func, "__wrapped__"):  # through accepts_center_rc
            yield name, func, names


@pytest.mark.parametrize("bad", [(True, 5), (5, np.bool_(False)), (np.nan, 5), (5, np.inf),
                                 ("5", 5)], ids=["bool", "numpy-bool", "nan", "inf", "text"])
def test_every_public_function_refuses_a_centre_that_is_no_pixel_position(bad):
    """A centre is checked where it comes in (accepts_center_rc), named, before any work: a
    bool is no row (True was taken as row 1), nor text, nor a non-finite number."""
    wrong = []
    for name, func, names in _centre_takers():
        for arg in names:
            required = [p for p in inspect.signature(func).parameters.values()
                        if p.default is inspect.Parameter.empty
                        and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
                        and p.name not in names]
            value = [bad] if arg == "centers_rc" else bad
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    func(**dict.fromkeys((p.name for p in required), None), **{arg: value})
                except ValueError as err:
                    if arg in str(err) and ("finite" in str(err) or "got" in str(err)):
                        continue
                    wrong.append(f"{name}({arg}=): {err}")
                    continue
                except Exception as err:  # any other failure is the finding
                    wrong.append(f"{name}({arg}=): {type(err).__name__}: {err}")
                    continue
            wrong.append(f"{name}({arg}=) accepted {bad!r}")
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize("keyword", ["center_rc", "center_px"])
def test_a_boolean_centre_is_refused_by_its_name(keyword):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ValueError, match=f"{keyword} must be two numbers.*a boolean"):
            cra_map((3, 5), 5.5, 21.0, **{keyword: (True, 5)})
