"""What every quick look draws with: images subsampled with a stride and loaded only where
drawn, colour limits, labels and the PNG written atomically."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import xarray as xr

from ..files.png import save_png

#: Largest number of pixels drawn along either side of an image.
MAX_PX = 1024


#: :func:`plot_correction` marks every band on the spectra only up to this many bands; with
#: more, the spectra are drawn as lines alone.
MARKER_MAX_BANDS = 40


#: Colour of masked (or non-finite) pixels in the images.
MASKED_COLOUR = "#ff00ff"


_DPI = 110


def _check_path(path, overwrite):
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"quick looks are written as PNG only: {path} should end in .png, "
                         f"not {path.suffix or 'nothing'!r}")
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass overwrite=True to replace it")
    return path


def _save(fig, path):
    return save_png(fig, path, dpi=_DPI)


def _stride(ny, nx):
    return max(1, math.ceil(max(ny, nx) / MAX_PX))


def _load(*arrays):
    """The values of DataArrays as numpy arrays, the dask-backed ones in one pass."""
    out = [None] * len(arrays)
    lazy = [i for i, a in enumerate(arrays) if a.chunks is not None]
    if lazy:
        import dask

        for i, v in zip(lazy, dask.compute(*[arrays[i].data for i in lazy]), strict=True):
            out[i] = np.asarray(v)
    for i, a in enumerate(arrays):
        if out[i] is None:
            out[i] = np.asarray(a.values)
    return out


def _image(da, stride, band=None):
    """A lazy (y, x) view of ``da`` (one band of it), every ``stride``-th pixel."""
    sl = slice(None, None, stride)
    sel = {"y": sl, "x": sl}
    if "band" in da.dims:
        sel["band"] = 0 if band is None else band
    return da.isel(sel).transpose("y", "x")


def _points(da, ys, xs):
    """A lazy (pixel, band) selection of the spectra at the pixels ``(ys[i], xs[i])``."""
    sel = da.isel(y=xr.DataArray(np.asarray(ys, int), dims="pixel"),
                  x=xr.DataArray(np.asarray(xs, int), dims="pixel"))
    return sel.transpose("pixel", ...)


def _finite(a):
    a = np.asarray(a, float)
    return a[np.isfinite(a)]


def _limits(values, robust):
    """Colour limits of the finite ``values`` (1-99 percentiles if ``robust``), or None."""
    v = _finite(values)
    if v.size == 0:
        return None
    lo, hi = (np.percentile(v, [1.0, 99.0]) if robust else (v.min(), v.max()))
    lo, hi = float(lo), float(hi)
    if not hi > lo:  # a constant image: open the range so the colour bar reads
        pad = abs(lo) * 0.05 or 1.0
        lo, hi = lo - pad, hi + pad
    return lo, hi


def _label(da, fallback):
    name = da.attrs.get("long_name") or da.name or fallback
    units = da.attrs.get("units")
    if units in (None, "", "1", "dimensionless"):  # a ratio: no unit to show
        return str(name)
    return f"{name} ({units})"


def _num(value, fmt="g"):
    try:
        return format(float(value), fmt)
    except (TypeError, ValueError, OverflowError):
        return str(value)


def _middle_band(wl):
    if wl.size == 0 or not np.all(np.isfinite(wl)):
        return wl.size // 2
    return int(np.argmin(np.abs(wl - 0.5 * (wl.min() + wl.max()))))


def _wavelengths(ds, nb):
    if "wavelength" in ds.coords or "wavelength" in ds:
        return np.asarray(ds["wavelength"].values, float)
    return np.arange(nb, dtype=float)


def _show(fig, ax, img, stride, *, bad=None, robust=True, cmap="viridis", cbar_label="",
          title="", empty="no finite values", bad_label="not finite"):
    """Draw a subsampled image in the original pixel coordinates, with a colour bar."""
    img = np.asarray(img, float)
    hidden = ~np.isfinite(img) if bad is None else (bad | ~np.isfinite(img))
    lim = _limits(img[~hidden], robust)
    h, w = img.shape
    extent = (-0.5 * stride, (w - 0.5) * stride, (h - 0.5) * stride, -0.5 * stride)
    ratio = max(h, w) / max(1, min(h, w))
    import matplotlib

    cm = matplotlib.colormaps[cmap].with_extremes(bad=MASKED_COLOUR)
    im = ax.imshow(np.ma.masked_array(img, hidden), cmap=cm, extent=extent,
                   interpolation="nearest", aspect="equal" if ratio <= 4 else "auto",
                   vmin=lim[0] if lim else 0.0, vmax=lim[1] if lim else 1.0)
    fig.colorbar(im, ax=ax, label=cbar_label, shrink=0.9)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    ax.set_title(title + (f"\none pixel in {stride} along x and y shown" if stride > 1
                          else ""), fontsize=10)
    if lim is None:
        _note(ax, empty)
    if hidden.any() and bad_label:
        from matplotlib.patches import Patch

        ax.legend(handles=[Patch(color=MASKED_COLOUR, label=bad_label)], loc="upper right",
                  fontsize=8, framealpha=0.85)
    return hidden


def _note(ax, text):
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=10,
            bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "0.5"})


def _figure(figsize):
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, layout="constrained")


def _wrapped(text, width=88):
    """A title broken into lines of at most ``width`` characters (never cut off)."""
    import textwrap

    return "\n".join(textwrap.wrap(text, width))

