"""The demo's pieces that are cheap to check without running it (the CLI test runs it)."""

from types import SimpleNamespace

import numpy as np

import snapcorr.paper_experiment as paper


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
