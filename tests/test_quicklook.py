"""Quick-look figures: PNGs written atomically, readable, and drawn from what they read."""

import dask
import numpy as np
import pytest
from conftest import PAPER_LENS
from dask.callbacks import Callback
from matplotlib.image import imread

from snapcorr import quicklook
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, flatfield, make_cube
from snapcorr.quicklook import plot_correction, plot_flatfield

LENS = PAPER_LENS
SENSOR = Sensor("s", "snapscan", 40.0, np.linspace(500, 900, 5), 10.0, 1.7)
NY, NX, NB = 24, 32, 5


def _scene(ny=NY, nx=NX, nb=NB):
    """A bright disc on a dim background, brighter towards the red, with a little noise."""
    yy, xx = np.mgrid[:ny, :nx]
    disc = 200 + 600 * np.exp(-((yy - ny / 2) ** 2 + (xx - nx / 2) ** 2) / (0.1 * ny * nx))
    noise = np.random.default_rng(1).normal(0, 5, (ny, nx, nb))
    return (disc[..., None] * np.linspace(0.6, 1.2, nb) + noise).astype(np.float32)


def _flat(raw, *, white=1200.0, saturation=4095.0):
    nb = raw.shape[2]
    wl = np.linspace(500, 900, nb)
    cube = make_cube(raw, wl)
    dark = make_cube(np.full((1, raw.shape[1], nb), 10.0, np.float32), wl)
    bright = make_cube(np.full((1, raw.shape[1], nb), white, np.float32), wl)
    return flatfield(cube, dark, bright, saturation=saturation)


@pytest.fixture(scope="module")
def flat():
    raw = _scene()
    raw[2:5, 3:9] = 4095.0  # saturated: masked in every band
    return _flat(raw)


@pytest.fixture(scope="module")
def corrected():
    return correct_cube(make_cube(_scene(), SENSOR.cwl_nm), SENSOR, 1.4, LENS, resample=True)


@pytest.fixture
def figures(monkeypatch):
    """The figures the functions draw, kept as well as written."""
    kept, save = [], quicklook._save

    def keep(fig, path):
        kept.append(fig)
        return save(fig, path)

    monkeypatch.setattr(quicklook, "_save", keep)
    return kept


def _texts(fig):
    """Every piece of text in a figure: titles, labels, legends, notes."""
    out = [fig._suptitle.get_text() if fig._suptitle else ""]
    for ax in fig.axes:
        out += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
        out += [t.get_text() for t in ax.texts]
        for leg in [ax.get_legend(), *[a for a in ax.artists if hasattr(a, "get_texts")]]:
            if leg is not None:
                out += [t.get_text() for t in leg.get_texts()]
    return "\n".join(out)


def _check_png(path, size):
    img = imread(path)
    assert img.shape[:2] == (round(size[1] * 110), round(size[0] * 110))
    rgb = (img[..., :3] * 255).astype(np.uint32)
    colours = np.unique(rgb[..., 0] << 16 | rgb[..., 1] << 8 | rgb[..., 2])
    assert colours.size > 50  # images, colour bars and lines: not a blank page
    return img


def test_flatfield_quicklook(flat, figures, tmp_path):
    out = plot_flatfield(flat, tmp_path / "ff.png")
    assert out == tmp_path / "ff.png"
    _check_png(out, (15.5, 4.8))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ff.png"]  # no temporary left
    text = _texts(figures[0])
    for want in ("x (px)", "y (px)", "reflectance", "band 2 (700.0 nm)", "masked values (%)",
                 "masked"):
        assert want in text
    img_ax = figures[0].axes[0]
    assert img_ax.images[0].get_array().shape == (NY, NX)
    assert np.ma.getmaskarray(img_ax.images[0].get_array())[2:5, 3:9].all()  # masked shown
    # the spectra avoid the masked corner: no legend entry inside the saturated block
    legend = [t.get_text() for t in figures[0].axes[2].get_legend().get_texts()]
    assert len(legend) == 5
    for entry in legend:
        y, x = (int(v) for v in entry.split("= (")[1].rstrip(")").split(", "))
        assert not (2 <= y < 5 and 3 <= x < 9)


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


def test_wrong_dataset_refused(flat, corrected, tmp_path):
    with pytest.raises(ValueError, match="flat-field"):
        plot_flatfield(corrected.drop_vars(["radiance", "resampled"]), tmp_path / "a.png")
    with pytest.raises(ValueError, match="correction result"):
        plot_correction(flat, tmp_path / "b.png")
    assert list(tmp_path.iterdir()) == []


class _Largest(Callback):
    """The largest result of any dask task computed while active."""

    def __init__(self):
        super().__init__()
        self.nbytes = 0

    def _posttask(self, key, result, dsk, state, worker_id):
        self.nbytes = max(self.nbytes, int(getattr(result, "nbytes", 0)))


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


# -- the spectra panel of plot_correction: window means, honest roles, markers --------------

def _spectra_axes(fig):
    return next(ax for ax in fig.axes if ax.get_title().startswith("spectra by chief-ray"))


def _spectra_legend(fig):
    """The spectra panel's legend (in a cell of its own, beside the spectra)."""
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    return next(leg for leg in legends
                if any(t.get_text() == "at nominal wavelengths" for t in leg.get_texts()))


def _windows_in_legend(ax):
    """(role, (y0, y1, x0, x1), (y, x)) of every pixel entry in the spectra panel's legend."""
    out = []
    for entry in (t.get_text() for t in _spectra_legend(ax.figure).get_texts()):
        if "(y, x)" not in entry:
            continue
        role, rest = entry.split(": ", 1)
        y, x = (int(v) for v in rest.split("= (")[1].split(")")[0].split(", "))
        h = w = 1
        if rest.startswith("mean of "):
            h, w = (int(v) for v in rest[len("mean of "):].split(" px")[0].split(" x "))
        out.append((role, (y, x), (h, w)))
    return out


def _window(y, x, ny, nx, half=2):
    return slice(max(0, y - half), min(ny, y + half + 1)), slice(max(0, x - half),
                                                                   min(nx, x + half + 1))


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


def test_window_follows_the_stride():
    assert quicklook._window_half(1) == 2 and quicklook._window_half(5) == 2
    assert quicklook._window_half(6) == 3 and quicklook._window_half(11) == 5
    assert quicklook._windows([0, 10, 23], [31, 10, 0], NY, NX, 2) == [
        (0, 3, 29, 32), (8, 13, 8, 13), (21, 24, 0, 3)]


def _shifted_cra(ds, by):
    return ds.assign(cra_deg=ds["cra_deg"] + by)


@pytest.mark.parametrize(("shift", "roles"), [
    (0.0, ["on axis", "mid-field", "edge"]),
    (3.8, ["lowest CRA", "middle CRA", "highest CRA"]),  # a crop away from the axis
    ("just below", ["on axis", "mid-field", "edge"]),
    ("at", ["lowest CRA", "middle CRA", "highest CRA"]),
])
def test_on_axis_only_near_the_axis(corrected, figures, tmp_path, shift, roles):
    low = float(corrected["cra_deg"].min())
    by = {"just below": quicklook.ON_AXIS_DEG - low - 1e-3,
          "at": quicklook.ON_AXIS_DEG - low}.get(shift, shift)
    ds = _shifted_cra(corrected, by)
    plot_correction(ds, tmp_path / "corr.png")
    entries = _windows_in_legend(_spectra_axes(figures[0]))
    assert [e[0] for e in entries] == roles
    text = _texts(figures[0])
    assert f"CRA {float(ds['cra_deg'].min()):.2f} deg" in text
    if roles[0] != "on axis":
        for word in ("on axis", "mid-field", "edge"):
            assert word not in text, word


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


def _legend_pixels(ax):
    return [tuple(int(v) for v in t.get_text().split("= (")[1].rstrip(")").split(", "))
            for t in ax.get_legend().get_texts()]


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


def test_sensor_quicklook_fits_the_wavelengths_and_cuts_no_title(figures, tmp_path):
    """A vendor file whose responses lie at 455-635 nm on a 400-1000 nm grid: the axis spans
    the responses (and a margin), and every title lies inside the picture."""
    import vendorfiles

    from snapcorr.quicklook import plot_sensor

    sensor = Sensor.load(vendorfiles.write_newer(tmp_path / "imec.xml", vendorfiles.imec_4x4()))
    out = plot_sensor(sensor, tmp_path / "s.png")
    fig = figures[0]
    assert len(fig.axes) == 1 + len(sensor.matrices)
    lo, hi = min(sensor.cwl_nm), max(sensor.cwl_nm)
    for ax in fig.axes:
        left, right = ax.get_xlim()
        assert 430 < left < lo and hi < right < 680, (left, right)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()  # laid out as written
    renderer = canvas.get_renderer()
    width, height = fig.bbox.width, fig.bbox.height
    for ax in fig.axes:
        box = ax.title.get_window_extent(renderer)
        assert 0 <= box.x0 and box.x1 <= width and box.y1 <= height, ax.get_title()
    assert out.exists()


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
