"""The vignetted aperture (snapcorr.optics.aperture): one argument order, the paper's, and the
earlier module snapcorr.optics.pupil keeping its own order with a warning."""

import inspect
import warnings

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from snapcorr.optics import aperture, goossens2019, pupil

R, P = 5.0, 7.4236
D = np.linspace(0.0, 9.0, 7)  # pixel distances, mm
DV = 0.8 * D  # the circle's centre, h tan(CRA) with h < x
ORDER = ["R_mm", "d_mm", "P_mm", "dv_mm"]


def _geometry(func):
    return [p for p in inspect.signature(func).parameters if p in ORDER]


@pytest.mark.parametrize("func", [aperture.gamma, aperture.max_radius_eq44,
                                  aperture.max_radius_mm, aperture.min_radius_mm,
                                  goossens2019.kernel, goossens2019.kernel_asymptotic,
                                  goossens2019.mean_shift_contour, goossens2019.max_aoi_deg],
                         ids=lambda f: f"{f.__module__}.{f.__name__}")
def test_the_circle_geometry_runs_R_d_P_dv_everywhere(func):
    assert _geometry(func) == ORDER
    assert _geometry(aperture.eta) == ORDER[:2]


@pytest.mark.parametrize(("name", "old", "new"), [
    ("eta", (2.0, D, R), (2.0, R, D)),
    ("gamma", (2.0, D, R, DV, P), (2.0, R, D, P, DV)),
    ("max_radius_eq44", (D, R, DV, P), (R, D, P, DV)),
    ("max_radius_mm", (D, R, DV, P), (R, D, P, DV)),
    ("min_radius_mm", (D, R, DV, P), (R, D, P, DV)),
])
def test_the_earlier_module_keeps_its_order_and_warns(name, old, new):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new home: no warning
        want = getattr(aperture, name)(*new)
    with pytest.warns(FutureWarning, match=rf"snapcorr.optics.pupil.{name}\(.* is the earlier "
                                           rf"name of snapcorr.optics.aperture.{name}\(.*0\.3"):
        got = getattr(pupil, name)(*old)
    assert_array_equal(got, want)


def test_the_earlier_module_reexports_the_rest_unchanged():
    assert pupil._MOVED_TO == "snapcorr.optics.aperture"
    for name in ("nu", "vignetted_area_mm2", "overlap_area_mm2", "lens_boundary_arcs",
                 "lens_area"):
        assert getattr(pupil, name) is getattr(aperture, name)
    assert set(pupil.__all__) == set(aperture.__all__)
