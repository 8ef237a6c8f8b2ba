"""The demo's pieces that are cheap to check without running it (the CLI test runs it)."""

from types import SimpleNamespace

import numpy as np

import snapcorr.paper_experiment as paper
from snapcorr import spectra
from snapcorr.calibrate import CANDIDATE_TARGETS, exit_pupil


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


def test_every_map_has_axis_and_colour_bar_labels():
    cwl = np.array([650.0, 700.0, 750.0])
    cra = np.hypot(*np.mgrid[-3:3:8j, -4:4:10j])
    vig = {"cra_deg": SimpleNamespace(values=cra),
           "wavelength_corrected": SimpleNamespace(
               values=cwl - 0.05 * cra[..., None] ** 2)}
    fig = paper._maps_figure(vig, cwl)
    panels = [ax for ax in fig.axes if ax.images]
    assert len(panels) == 2
    for ax in panels:
        assert ax.get_xlabel() == "x (px)"
        assert ax.get_ylabel() == "y (px)"
        bar = ax.images[0].colorbar
        assert bar is not None
        label = bar.ax.get_ylabel()
        assert label.endswith(("(deg)", "(nm)")), label
    assert [ax.images[0].colorbar.ax.get_ylabel() for ax in panels] == [
        "chief-ray angle (deg)", "wavelength shift (nm)"]
