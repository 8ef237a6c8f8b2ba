"""What every quick look draws with: PNGs written atomically and refused where they would replace
what they should not, images drawn with a stride and read by parts, masked and NaN values,
markers."""

import dask
import numpy as np
import pytest
from matplotlib.image import imread

from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, flatfield, make_cube
from snapcorr.quicklook import plot_correction, plot_flatfield

from .conftest import (
    LENS,
    NB,
    NX,
    NY,
    SENSOR,
    _check_png,
    _flat,
    _Largest,
    _scene,
    _spectra_axes,
    _spectra_legend,
    _texts,
)


@pytest.mark.parametrize("plot", [plot_flatfield, plot_correction])
def test_refusals(plot, flat, corrected, tmp_path):
    ds = flat if plot is plot_flatfield else corrected
    for name in ("out.jpg", "out.PDF", "out"):
        with pytest.raises(ValueError, match="PNG only"):
            plot(ds, tmp_path / name)
    assert list(tmp_path.iterdir()) == []
    target = tmp_path / "out.png"
    target.write_bytes(b"keep me")
    with pytest.raises(FileExistsError, match="overwrite"):
        plot(ds, target)
    with pytest.raises(ValueError, match="not a PNG image; overwrite replaces only what "
                                         "snapcorr wrote"):
        plot(ds, target, overwrite=True)  # not snapcorr's: never replaced
    assert target.read_bytes() == b"keep me"
    target.unlink()
    assert plot(ds, target) == target
    assert plot(ds, target, overwrite=True) == target  # its own: replaced
    assert imread(target).ndim == 3
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


def test_dask_inputs_read_by_parts(corrected, tmp_path):
    """Lazy inputs stay lazy, and no task holds more than one band image (float64)."""
    one_band = NY * NX * 8
    raw = make_cube(_scene(), np.linspace(500, 900, NB)).chunk({"y": 8, "band": 1})
    dark = make_cube(np.full((1, NX, NB), 10.0, np.float32), raw.wavelength.values)
    white = make_cube(np.full((1, NX, NB), 1200.0, np.float32), raw.wavelength.values)
    lazy_flat = flatfield(raw, dark, white, saturation=4095.0)
    assert lazy_flat["reflectance"].chunks is not None
    # from values in memory, so that every chunk of the input is small
    lazy_corr = corrected.compute().chunk({"y": 8, "band": 1})
    assert lazy_corr["wavelength_corrected"].chunks is not None
    with dask.config.set(scheduler="sync"), _Largest() as seen:
        plot_flatfield(lazy_flat, tmp_path / "ff.png")
        plot_correction(lazy_corr, tmp_path / "corr.png")
    assert 0 < seen.nbytes <= one_band
    assert lazy_flat["reflectance"].chunks is not None
    assert lazy_corr["wavelength_corrected"].chunks is not None
    _check_png(tmp_path / "ff.png", (15.5, 4.8))
    _check_png(tmp_path / "corr.png", (16.0, 0.27 * 16 * NY / NX + 0.9 + 4.6 + 0.7))


def test_large_images_drawn_with_a_stride(figures, tmp_path):
    raw = _scene(2100, 6, 2)
    plot_flatfield(_flat(raw), tmp_path / "tall.png")
    image = figures[0].axes[0].images[0]
    assert image.get_array().shape == (700, 2)  # one pixel in 3: at most 1024 a side
    left, right, bottom, top = image.get_extent()
    assert left == -1.5 and right == pytest.approx(4.5)
    assert bottom == pytest.approx(2098.5) and top == -1.5  # still in the cube's pixels
    assert "one pixel in 3" in _texts(figures[0])


def test_tiny_cubes(figures, tmp_path):
    raw = np.array([[[100.0, 300.0]]], np.float32)
    plot_flatfield(_flat(raw), tmp_path / "ff.png")
    sensor = Sensor("two", "snapscan", 40.0, [500.0, 900.0], 10.0, 1.7)
    ds = correct_cube(make_cube(raw, sensor.cwl_nm), sensor, 2.8, LENS)
    ds.attrs = {}  # and without provenance: a plain title
    plot_correction(ds, tmp_path / "corr.png")
    assert "(y, x) = (0, 0)" in _texts(figures[0])
    text = _texts(figures[1])
    assert "on axis: (y, x) = (0, 0)" in text
    assert "Wavelength correction of radiance, 1 x 1 px, 2 bands" in text
    assert "lens" not in text and "resampled" not in text
    for name in ("ff.png", "corr.png"):
        assert imread(tmp_path / name).ndim == 3


def test_all_masked_and_all_nan_bands(figures, tmp_path):
    raw = _scene()
    flat = _flat(raw)  # then every value masked (flatfield itself refuses such a result)
    everything = flat.assign(reflectance=flat["reflectance"] * np.nan,
                             mask=flat["mask"] | True)
    plot_flatfield(everything, tmp_path / "all.png")
    text = _texts(figures[0])
    assert "every value is masked" in text and "no spectrum to show" in text

    raw[:, :, 2] = np.nan  # the middle band, the one drawn, is NaN everywhere
    plot_flatfield(_flat(raw), tmp_path / "band.png")
    text = _texts(figures[1])
    assert "every value of band 2 is masked" in text
    assert len(figures[1].axes[2].get_legend().get_texts()) == 5  # other bands still shown

    cube = make_cube(np.full((NY, NX, NB), np.nan, np.float32), SENSOR.cwl_nm)
    plot_correction(correct_cube(cube, SENSOR, 1.4, LENS), tmp_path / "nan.png")
    text = _texts(figures[2])
    assert "no finite values" in text and "no spectrum to show" in text
    for name in ("all.png", "band.png", "nan.png"):
        assert imread(tmp_path / name).ndim == 3


@pytest.mark.parametrize(("nb", "marked"), [(NB, True), (40, True), (41, False), (150, False)])
def test_markers_only_for_few_bands(figures, tmp_path, nb, marked):
    sensor = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, nb), 10.0, 1.7)
    ds = correct_cube(make_cube(_scene(8, 10, nb), sensor.cwl_nm), sensor, 1.4, LENS,
                      resample=True)
    plot_correction(ds, tmp_path / "corr.png")
    ax = _spectra_axes(figures[0])
    markers = {line.get_marker() for line in ax.get_lines()}
    assert markers == ({".", "o", "x"} if marked else {"None"})
    legend_markers = {h.get_marker() for h in _spectra_legend(ax.figure).legend_handles}
    assert ("x" in legend_markers) == marked

