"""What the quick looks' tests share: a scene, its flat-field result and correction, the figures
drawn, and readers of what they show."""

import numpy as np
import pytest
from conftest import PAPER_LENS
from dask.callbacks import Callback
from matplotlib.image import imread

from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, flatfield, make_cube
from snapcorr.quicklook import correction, drawing, sensor
from snapcorr.quicklook import flatfield as ql_flatfield

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
    kept, save = [], drawing._save

    def keep(fig, path):
        kept.append(fig)
        return save(fig, path)

    for module in (correction, ql_flatfield, sensor):  # each saves with drawing._save
        monkeypatch.setattr(module, "_save", keep)
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


class _Largest(Callback):
    """The largest result of any dask task computed while active."""

    def __init__(self):
        super().__init__()
        self.nbytes = 0

    def _posttask(self, key, result, dsk, state, worker_id):
        self.nbytes = max(self.nbytes, int(getattr(result, "nbytes", 0)))


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


def _shifted_cra(ds, by):
    return ds.assign(cra_deg=ds["cra_deg"] + by)


def _legend_pixels(ax):
    return [tuple(int(v) for v in t.get_text().split("= (")[1].rstrip(")").split(", "))
            for t in ax.get_legend().get_texts()]

