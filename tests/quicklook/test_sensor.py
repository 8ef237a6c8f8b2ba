"""The quick look of a sensor's filters."""


from snapcorr.cube import Sensor


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

