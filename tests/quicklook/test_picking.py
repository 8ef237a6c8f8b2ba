"""Which pixels' spectra a quick look shows, and the windows averaged around them."""

import numpy as np
import pytest

from snapcorr.quicklook import picking, plot_correction, plot_flatfield

from .conftest import (
    NX,
    NY,
    _flat,
    _legend_pixels,
    _shifted_cra,
    _spectra_axes,
    _texts,
    _windows_in_legend,
)


def test_window_follows_the_stride():
    assert picking._window_half(1) == 2 and picking._window_half(5) == 2
    assert picking._window_half(6) == 3 and picking._window_half(11) == 5
    assert picking._windows([0, 10, 23], [31, 10, 0], NY, NX, 2) == [
        (0, 3, 29, 32), (8, 13, 8, 13), (21, 24, 0, 3)]


@pytest.mark.parametrize(("shift", "roles"), [
    (0.0, ["on axis", "mid-field", "edge"]),
    (3.8, ["lowest CRA", "middle CRA", "highest CRA"]),  # a crop away from the axis
    ("just below", ["on axis", "mid-field", "edge"]),
    ("at", ["lowest CRA", "middle CRA", "highest CRA"]),
])
def test_on_axis_only_near_the_axis(corrected, figures, tmp_path, shift, roles):
    low = float(corrected["cra_deg"].min())
    by = {"just below": picking.ON_AXIS_DEG - low - 1e-3,
          "at": picking.ON_AXIS_DEG - low}.get(shift, shift)
    ds = _shifted_cra(corrected, by)
    plot_correction(ds, tmp_path / "corr.png")
    entries = _windows_in_legend(_spectra_axes(figures[0]))
    assert [e[0] for e in entries] == roles
    text = _texts(figures[0])
    assert f"CRA {float(ds['cra_deg'].min()):.2f} deg" in text
    if roles[0] != "on axis":
        for word in ("on axis", "mid-field", "edge"):
            assert word not in text, word


def test_flatfield_spectra_come_from_bright_different_pixels_across_the_field(figures, tmp_path):
    """A dark scene (reflectance 0.01, as a real one was at the centre and corners) with six
    bright patches of three spectra: the pixels drawn are on the patches, far apart, and show
    every spectrum, not noise around 0.01."""
    ny, nx, nb = 90, 120, 8
    refl = np.full((ny, nx, nb), 0.01)
    spectra = [np.linspace(0.3, 0.6, nb), np.linspace(0.6, 0.3, nb),
               0.45 + 0.15 * np.sin(np.linspace(0, 3 * np.pi, nb))]
    patches = [(15, 25), (15, 95), (45, 60), (75, 20), (75, 100), (45, 10)]
    yy, xx = np.mgrid[:ny, :nx]
    which = np.full((ny, nx), -1)
    for k, (cy, cx) in enumerate(patches):
        inside = (abs(yy - cy) <= 6) & (abs(xx - cx) <= 8)
        refl[inside] = spectra[k % 3]
        which[inside] = k % 3
    noise = np.random.default_rng(5).normal(0, 0.003, refl.shape)
    raw = (10 + (refl + noise) * 1190).astype(np.float32)
    plot_flatfield(_flat(raw, white=1200.0), tmp_path / "ff.png")
    picked = _legend_pixels(figures[0].axes[2])
    assert len(picked) == 5
    assert all(which[y, x] >= 0 for y, x in picked), picked  # on a bright patch each
    assert {which[y, x] for y, x in picked} == {0, 1, 2}  # every spectrum shown
    far = min(np.hypot(a[0] - b[0], a[1] - b[1]) for i, a in enumerate(picked)
              for b in picked[i + 1:])
    assert far > 20, picked  # spread out, not five pixels of one patch

