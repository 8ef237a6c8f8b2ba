"""The quick look of a flat-field result: one band, the masked fraction and a few pixels'
spectra."""

import numpy as np

from snapcorr.quicklook import plot_flatfield

from .conftest import NX, NY, _check_png, _texts


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

