"""The quick look of a correction: the cube, the chief-ray angle, the shift and spectra around
three pixels."""

import numpy as np
import pytest

from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor
from snapcorr.quicklook import plot_correction, plot_flatfield

from .conftest import (
    LENS,
    NX,
    NY,
    SENSOR,
    _check_png,
    _spectra_axes,
    _texts,
    _window,
    _windows_in_legend,
)


def test_correction_quicklook(corrected, figures, tmp_path):
    out = plot_correction(corrected, tmp_path / "corr.png", title="Test scene")
    _check_png(out, figures[0].get_size_inches())
    fig = figures[0]
    text = _texts(fig)
    for want in ("Test scene", "lens Edmund", "f/1.4", f"method {corrected.attrs['method']}",
                 "CRA (deg)", "shift (nm)", "x (px)", "y (px)", "on axis", "mid-field",
                 "edge", "at nominal wavelengths", "at corrected wavelengths",
                 "resampled onto nominal"):
        assert want in text, want
    # the shift shown is that of the band moving most, as the full array has it
    shift = np.abs(corrected["wavelength_corrected"].values - SENSOR.cwl_nm)
    b = int(np.argmax(shift.max(axis=(0, 1))))
    assert f"shift of band {b} " in text
    shown = fig.axes[2].images[0].get_array()
    np.testing.assert_allclose(
        shown, corrected["wavelength_corrected"].values[:, :, b] - SENSOR.cwl_nm[b],
        rtol=0, atol=1e-4)
    # three pixels by CRA: the smallest and largest angles of the field
    cra = next(corrected[n] for n in ("cra", "cra_deg") if n in corrected.variables).values
    assert f"CRA {cra.min():.2f} deg" in text and f"CRA {cra.max():.2f} deg" in text


def test_wrong_dataset_refused(flat, corrected, tmp_path):
    with pytest.raises(ValueError, match="flat-field"):
        plot_flatfield(corrected.drop_vars(["radiance", "resampled"]), tmp_path / "a.png")
    with pytest.raises(ValueError, match="correction result"):
        plot_correction(flat, tmp_path / "b.png")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("lazy", [False, True])
def test_correction_spectra_are_means_over_windows(corrected, figures, tmp_path, lazy):
    cra = corrected["cra_deg"].values
    cy, cx = np.unravel_index(np.argmin(cra), cra.shape)  # the pixel on axis
    cube = corrected["radiance"].values.astype(float)
    cube[cy + 1, cx, :] = np.nan  # a missing pixel in its window: left out
    cube[cy, cx + 1, :] = 1e6  # a masked one: left out too
    mask = np.zeros(cube.shape, bool)
    mask[cy, cx + 1, :] = True
    ds = corrected.assign(radiance=(corrected["radiance"].dims, cube),
                          mask=(corrected["radiance"].dims, mask))
    if lazy:
        ds = ds.chunk({"y": 8, "band": 1})
    plot_correction(ds, tmp_path / "corr.png")
    ax = _spectra_axes(figures[0])
    entries = _windows_in_legend(ax)
    assert [e[0] for e in entries] == ["on axis", "mid-field", "edge"]
    assert entries[0][1:] == ((cy, cx), (5, 5))
    assert entries[2][2] == (3, 3)  # the edge pixel is a corner: its window is clipped
    assert "mean of 5 x 5 px around (y, x) = " in _texts(figures[0])
    lines = ax.get_lines()
    assert len(lines) == 3 * len(entries)  # nominal, corrected, resampled for each
    wl_corr = corrected["wavelength_corrected"].values.astype(float)
    resampled = corrected["resampled"].values.astype(float)
    for k, (_, (y, x), (h, w)) in enumerate(entries):
        sy, sx = _window(y, x, NY, NX)
        assert (sy.stop - sy.start, sx.stop - sx.start) == (h, w)
        valid = np.isfinite(cube[sy, sx]) & ~mask[sy, sx]
        n = valid.sum(axis=(0, 1))
        want = np.where(valid, cube[sy, sx], 0).sum(axis=(0, 1)) / n
        want_wl = np.where(valid, wl_corr[sy, sx], 0).sum(axis=(0, 1)) / n
        nominal, at_corrected, at_resampled = lines[3 * k:3 * k + 3]
        np.testing.assert_allclose(nominal.get_xdata(), SENSOR.cwl_nm)
        np.testing.assert_allclose(nominal.get_ydata(), want, rtol=1e-6)
        o = np.argsort(want_wl)
        np.testing.assert_allclose(at_corrected.get_xdata(), want_wl[o], rtol=1e-9)
        np.testing.assert_allclose(at_corrected.get_ydata(), want[o], rtol=1e-6)
        r = resampled[sy, sx]
        n_r = np.isfinite(r).sum(axis=(0, 1))
        want_r = np.where(n_r > 0, np.nansum(r, axis=(0, 1)) / np.maximum(n_r, 1), np.nan)
        assert np.isfinite(want_r).any()
        np.testing.assert_allclose(at_resampled.get_ydata(), want_r, rtol=1e-6)
        # not the single pixel's noisy spectrum
        assert not np.allclose(nominal.get_ydata(), cube[y, x], rtol=1e-4)
    if lazy:
        assert ds["radiance"].chunks is not None


def test_correction_quicklook_draws_virtual_bands_and_leaves_no_empty_band(figures, tmp_path):
    """A tile cube of the 5x5 vendor sensor (216 x 409 px, wide) with vendor virtual bands:
    their panel is drawn from the same windows, and under every image the next panel starts
    within half an inch (the images' row is as high as they need)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from snapcorr import data

    nir = Sensor.load(data.sensor_path("imec_5x5_nir"))
    from snapcorr.cube import mosaic_to_cube

    rng = np.random.default_rng(2)
    frame = (0.3 + 0.2 * np.linspace(0, 1, nir.size_px[1])[None, :]
             + rng.normal(0, 0.005, nir.size_px)).astype(np.float32)
    cube = mosaic_to_cube(frame, nir)  # 216 x 409 tiles of 25 bands, placed on the sensor
    ds = correct_cube(cube, nir, 2.8, LENS, virtual_bands="vendor")
    plot_correction(ds, tmp_path / "c.png")
    fig = figures[0]
    virtual = next(ax for ax in fig.axes if ax.get_title().startswith("virtual bands (vendor)"))
    assert len(virtual.lines) == len(_windows_in_legend(_spectra_axes(fig)))
    drawn = np.sort(virtual.lines[0].get_xdata())
    np.testing.assert_allclose(drawn, np.sort(ds["virtual_wavelength"].values))
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    boxes = {ax: ax.get_tightbbox(renderer) for ax in fig.axes if ax.axison}
    for ax in [ax for ax in fig.axes if ax.images]:
        below = [b.y1 for other, b in boxes.items()
                 if other is not ax and b.y1 <= boxes[ax].y0 + 1]
        gap = (boxes[ax].y0 - max(below, default=0.0)) / fig.dpi
        assert gap < 0.5, (ax.get_title(), gap)



def test_a_result_with_two_unknown_cubes_is_refused_not_the_first_drawn(flat, corrected,
                                                                       tmp_path):
    """The quick looks choose the cube as the readers do: two (y, x, band) variables of
    unknown names cannot be told apart, so neither is drawn (the first one was)."""
    name = next(n for n, v in corrected.data_vars.items()
                if set(v.dims) == {"y", "x", "band"}
                and n not in ("wavelength_corrected", "resampled", "wavelength_scale", "mask",
                              "cra", "cra_deg"))
    two = corrected.rename({name: "scene_a"})
    two["scene_b"] = two["scene_a"] * 2
    with pytest.raises(ValueError, match="scene_a, scene_b"):
        plot_correction(two, tmp_path / "c.png")
    ff = flat.rename({"reflectance": "scene_a"})
    ff["scene_b"] = ff["scene_a"] * 2
    with pytest.raises(ValueError, match="scene_a, scene_b"):
        plot_flatfield(ff, tmp_path / "f.png")
    assert not list(tmp_path.iterdir())
    # one unknown beside snapcorr's own variables is the cube
    one = corrected.rename({name: "scene_a"})
    plot_correction(one, tmp_path / "c.png")
    assert (tmp_path / "c.png").is_file()
