"""Quick-look figures of a flat-fielded cube and of a wavelength correction, as PNG.

:func:`plot_flatfield` shows a result of :func:`snapcorr.cube.flatfield`: one band, the
masked fraction of every band and a few pixels' spectra. :func:`plot_correction` shows a
result of :func:`snapcorr.correct.correct_cube`: one band of the cube, the chief-ray angle,
the shift of the band that moves most and mean spectra around three pixels at their nominal
and corrected wavelengths (and their virtual bands, when computed). :func:`plot_sensor` shows
a sensor's filters.

Both read only what they draw: images are subsampled with a stride to at most
:data:`MAX_PX` pixels a side and selected before they are loaded, so a dask-backed cube
larger than memory is read piece by piece. Both draw on a :class:`matplotlib.figure.Figure`
without pyplot (no global state) and write the PNG atomically.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import xarray as xr

from ._io import save_png

__all__ = ["CANDIDATES_PX", "MARKER_MAX_BANDS", "MAX_PX", "ON_AXIS_DEG", "SPECTRA_SHOWN",
           "SPECTRUM_WINDOW_PX", "plot_correction", "plot_flatfield", "plot_sensor"]

#: Largest number of pixels drawn along either side of an image.
MAX_PX = 1024
#: Side (pixels) of the square window whose mean spectrum :func:`plot_correction` draws
#: around each chosen pixel; the image's stride when that is larger (made odd, so the window
#: is centred), clipped to the image.
SPECTRUM_WINDOW_PX = 5
#: :func:`plot_correction` calls a pixel "on axis" only when its chief-ray angle is below
#: this (degrees); the pixel of lowest angle in a crop away from the axis is "lowest CRA".
ON_AXIS_DEG = 0.5
#: :func:`plot_correction` marks every band on the spectra only up to this many bands; with
#: more, the spectra are drawn as lines alone.
MARKER_MAX_BANDS = 40
#: Colour of masked (or non-finite) pixels in the images.
MASKED_COLOUR = "#ff00ff"
_DPI = 110


# --------------------------------------------------------------------------- helpers

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


# --------------------------------------------------------------------------- flat field

def _result_name(ds):
    for name in ("reflectance", "transmittance"):
        if name in ds.data_vars:
            return name
    others = [n for n, v in ds.data_vars.items()
              if set(v.dims) == {"y", "x", "band"} and n not in ("mask", "raw")]
    if not others:
        raise ValueError("not a flat-field result: no 'reflectance' or 'transmittance' "
                         "variable with dims (y, x, band); see snapcorr.cube.flatfield")
    return others[0]


def plot_flatfield(ds, path, *, overwrite=False, title=None):
    """Quick look of a flat-fielded cube, written as PNG.

    Three panels: the band nearest the middle wavelength (colour limits from the 1st and
    99th percentiles of its finite values, masked pixels in magenta), the percentage of
    masked values in every band, and the spectra of up to :data:`SPECTRA_SHOWN` pixels
    chosen by what they hold (:func:`_pick_by_content`, among at most :data:`CANDIDATES_PX`
    a side whose bands together hold no more values than the band image drawn, unmasked in
    every band where there are such): bright, spread across the field
    and with spectra that differ, with their ``(y, x)`` in the legend.

    Parameters
    ----------
    ds : xarray.Dataset
        A result of :func:`snapcorr.cube.flatfield`: ``reflectance`` or ``transmittance``
        ``(y, x, band)``, ``mask`` ``(y, x, band)`` and ``wavelength(band)`` in nm; numpy-
        or dask-backed. Only the pixels drawn are read (images at most :data:`MAX_PX`
        pixels a side, every ``stride``-th pixel).
    path : str or os.PathLike
        The PNG to write (the suffix must be ``.png``).
    overwrite : bool, optional
        Replace an existing file (default: refuse).
    title : str, optional
        The figure's title (default: the variable's name and the cube's size).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        If ``path`` does not end in ``.png``, or ``ds`` holds no flat-field result.
    FileExistsError
        If ``path`` exists and ``overwrite`` is false; nothing is written.
    """
    path = _check_path(path, overwrite)
    name = _result_name(ds)
    result = ds[name].transpose("y", "x", "band")
    ny, nx, nb = (result.sizes[d] for d in ("y", "x", "band"))
    mask = (ds["mask"].transpose("y", "x", "band") if "mask" in ds
            else ~np.isfinite(result))
    wl = _wavelengths(ds, nb)
    order = np.argsort(wl, kind="stable")
    b = _middle_band(wl)
    s = _stride(ny, nx)
    msub = mask.isel(y=slice(None, None, s), x=slice(None, None, s))
    # the candidates' stride: at most CANDIDATES_PX a side, all their bands no more values
    # than the band image drawn
    c = s * max(math.ceil(max(ny, nx) / s / CANDIDATES_PX), math.ceil(math.sqrt(nb)), 1)
    coarse = {"y": slice(None, None, c), "x": slice(None, None, c)}
    img, mimg, n_masked_band, candidates, cmask = _load(
        _image(result, s, b), _image(mask, s, b), msub.sum(("y", "x")),
        result.isel(coarse), mask.isel(coarse))
    n_sample = msub.sizes["y"] * msub.sizes["x"]
    frac = 100.0 * n_masked_band.astype(float) / max(1, n_sample)
    all_masked = bool(n_sample * nb == 0 or np.all(n_masked_band == n_sample))

    fig = _figure((15.5, 4.8))
    a_img, a_frac, a_spec = fig.subplots(1, 3, width_ratios=[1.15, 0.85, 1.0])

    # 1. the middle band
    bad = np.asarray(mimg, bool)
    empty = ("every value is masked" if all_masked
             else f"every value of band {b} is masked")
    _show(fig, a_img, img, s, bad=bad, cbar_label=_label(result, name),
          title=f"{name}, band {b} ({_num(wl[b], '.1f')} nm): "
                f"{100.0 * bad.mean() if bad.size else 0.0:.1f} % masked",
          empty=empty, bad_label="masked")

    # 2. the masked fraction per band
    _draw_masked_fraction(a_frac, wl, order, frac, n_masked_band, n_sample * nb, s)

    # 3. spectra of a few pixels chosen by what they hold: bright, different, spread out
    candidates = np.asarray(candidates, float)
    usable = ~np.asarray(cmask, bool) & np.isfinite(candidates)
    valid = usable.all(axis=2)
    if not valid.any():  # every pixel masked somewhere: those with some values
        valid = usable.any(axis=2)
    _draw_flat_spectra(a_spec, a_img, result, name, _pick_by_content(candidates, valid), c,
                       wl, order, all_masked)

    fig.suptitle(title or f"Flat-field quick look: {name}, {ny} x {nx} px, {nb} bands",
                 fontsize=12)
    return _save(fig, path)


def _draw_masked_fraction(ax, wl, order, frac, n_masked_band, n_values, s):
    """The panel of the percentage of masked values in every band."""
    ax.plot(wl[order], frac[order], "o-" if wl.size <= MARKER_MAX_BANDS else "-", ms=3, lw=1,
            color="C3")
    top = float(frac.max()) if frac.size else 0.0
    top = 100.0 if top > 20.0 else max(1.0, 1.25 * top)  # small fractions stay readable
    ax.set_ylim(-0.03 * top, 1.03 * top)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("masked values (%)")
    total = 100.0 * float(n_masked_band.sum()) / max(1, n_values)
    ax.set_title(f"masked values per band ({total:.1f} % of all)"
                 + (f"\nfrom one pixel in {s} along x and y" if s > 1 else ""),
                 fontsize=10)
    ax.grid(alpha=0.3)


#: Pixels whose spectra :func:`plot_flatfield` draws, and the most candidates along either side
#: of the image they are chosen from.
SPECTRA_SHOWN = 5
CANDIDATES_PX = 48
#: Candidates keep this share of the image's height and width from its edges, where any
#: are left.
EDGE_SHARE = 0.04


def _pick_by_content(values, valid, n=SPECTRA_SHOWN):
    """Up to ``n`` grid pixels whose spectra are worth seeing: bright (mean value at least the
    median and half the 99th percentile of the valid pixels' and at most that percentile: not
    dark, not a hot pixel), off
    the edges (:data:`EDGE_SHARE`) where there are such, and, one after another, the
    candidate farthest from those picked, in place (over the image's diagonal) plus in
    spectral angle (over the widest angle from the first): spread across the field, with
    spectra that differ. The first is the brightest candidate."""
    values = np.asarray(values, float)
    h, w = valid.shape
    if not valid.any():
        return []
    finite = np.isfinite(values)
    mean = np.where(finite, values, 0.0).sum(axis=2) / np.maximum(finite.sum(axis=2), 1)
    rows, cols = np.nonzero(valid)
    inner = ((np.minimum(rows, h - 1 - rows) >= EDGE_SHARE * h)
             & (np.minimum(cols, w - 1 - cols) >= EDGE_SHARE * w))
    if inner.any():  # not on the very edge, where a marker is hard to see
        rows, cols = rows[inner], cols[inner]
    level = mean[rows, cols]
    median, hi = np.percentile(level, [50.0, 99.0])
    keep = (level >= max(median, 0.5 * hi)) & (level <= hi)
    rows, cols, level = rows[keep], cols[keep], level[keep]
    spectra = np.nan_to_num(values[rows, cols])
    unit = spectra / np.maximum(np.linalg.norm(spectra, axis=1, keepdims=True), 1e-30)
    diagonal = max(math.hypot(h - 1, w - 1), 1.0)
    picked = [int(np.argmax(level))]
    angle_scale = None
    place = np.full(rows.size, np.inf)
    angle = np.full(rows.size, np.inf)
    while len(picked) < min(n, rows.size):
        k = picked[-1]
        place = np.minimum(place, np.hypot(rows - rows[k], cols - cols[k]) / diagonal)
        angle = np.minimum(angle, np.arccos(np.clip(unit @ unit[k], -1.0, 1.0)))
        if angle_scale is None:  # the widest angle from the first: spectra's own spread
            angle_scale = max(float(angle.max()), 1e-6)
        score = place + angle / angle_scale
        score[picked] = -np.inf
        picked.append(int(np.argmax(score)))
    return [(int(rows[k]), int(cols[k])) for k in picked]


def _draw_flat_spectra(a_spec, a_img, result, name, picked, s, wl, order, all_masked):
    """The panel of the spectra of the pixels ``picked`` (grid rows and columns of stride
    ``s``), each circled on the image."""
    ys, xs = [r * s for r, _ in picked], [c * s for _, c in picked]
    (spectra,) = _load(_points(result, ys, xs)) if picked else (np.empty((0, wl.size)),)
    shown = 0
    for k, (y, x) in enumerate(zip(ys, xs, strict=True)):
        spec = np.asarray(spectra[k], float)[order]
        if not np.any(np.isfinite(spec)):
            continue
        label = f"(y, x) = ({y}, {x})"
        a_spec.plot(wl[order], spec, "o-" if wl.size <= MARKER_MAX_BANDS else "-", ms=3,
                    lw=1.2, color=f"C{k}", label=label)
        a_img.plot(x, y, marker="o", ms=7, mfc="none", mec=f"C{k}", mew=2)
        shown += 1
    if shown:
        a_spec.legend(fontsize=8, loc="best")
    else:
        _note(a_spec, "every value is masked:\nno spectrum to show" if all_masked
              else "these pixels are masked\nin every band")
    a_spec.set_xlabel("wavelength (nm)")
    a_spec.set_ylabel(_label(result, name))
    a_spec.set_title("spectra of bright, different pixels across the field\n(gaps: masked)",
                     fontsize=10)
    a_spec.grid(alpha=0.3)


# --------------------------------------------------------------------------- correction

#: Names the chief-ray angle map goes by, in order of preference.
_CRA_NAMES = ("cra", "cra_deg")
_NOT_CUBE = {"wavelength_corrected", "resampled", "wavelength_scale", "mask", *_CRA_NAMES}


def _cube_name(ds):
    for n, v in ds.data_vars.items():
        if set(v.dims) == {"y", "x", "band"} and n not in _NOT_CUBE:
            return n
    raise ValueError("not a correction result: no input cube (a (y, x, band) variable other "
                     "than wavelength_corrected and resampled); see "
                     "snapcorr.correct.correct_cube")


def _subtitle(attrs):
    parts = []
    if "lens" in attrs:
        parts.append(f"lens {attrs['lens']}")
    if "f_number" in attrs:
        parts.append(f"f/{_num(attrs['f_number'])}")
    if "method" in attrs:
        parts.append(f"method {attrs['method']}")
    if "sensor" in attrs:
        parts.append(f"sensor {attrs['sensor']}")
    return ", ".join(parts)


def plot_correction(ds, path, *, overwrite=False, title=None):
    """Quick look of a wavelength correction, written as PNG.

    Three images side by side, their row as high as the cube's shape needs: the band of the
    input cube nearest the middle wavelength (colour limits from the 1st and 99th percentiles
    of its finite values); the chief-ray angle (deg; the first band's when it differs per
    band); the shift ``wavelength_corrected - wavelength`` (nm) of the band that moves most.
    Below them, spectra at three pixels chosen by their chief-ray angle (lowest, halfway
    between lowest and highest, highest) against the nominal wavelengths (dashed) and
    against their corrected wavelengths (solid), with the ``resampled`` spectra (dotted) when
    present; the virtual bands of the same windows against their wavelengths when the result
    has them (``virtual(y, x, virtual_band)``); and the legend in a cell of its own.

    Each spectrum is the mean over a window of :data:`SPECTRUM_WINDOW_PX` pixels a side (the
    stride when that is larger) around the chosen pixel, clipped to the image, of the values
    that are finite and not masked (``mask``); its corrected wavelengths are the mean of
    ``wavelength_corrected`` over the same values, and ``resampled`` is averaged likewise
    (its finite values). The legend gives each window's size and centre and the centre's
    chief-ray angle. The pixels are called "on axis", "mid-field" and "edge" only when the
    lowest angle is below :data:`ON_AXIS_DEG` (the optical axis is in the image); otherwise
    "lowest CRA", "middle CRA" and "highest CRA". Every band is marked on the spectra only
    up to :data:`MARKER_MAX_BANDS` bands; with more they are drawn as lines.

    Parameters
    ----------
    ds : xarray.Dataset
        A result of :func:`snapcorr.correct.correct_cube`: the input cube ``(y, x, band)``,
        ``wavelength_corrected(y, x, band)`` (a variable or a coordinate, nm), the chief-ray
        angle ``cra`` (or ``cra_deg``) ``(y, x)`` or ``(y, x, band)`` in degrees, optionally
        ``resampled`` and ``mask`` ``(y, x, band)``; numpy- or dask-backed. Only what is
        drawn is read: one band of the cube and of the corrected wavelengths (every
        ``stride``-th pixel, at most :data:`MAX_PX` a side) and the three small windows
        whose spectra are averaged.
        ``lens``, ``f_number`` and ``method`` in its attrs go into the title.
    path : str or os.PathLike
        The PNG to write (the suffix must be ``.png``).
    overwrite : bool, optional
        Replace an existing file (default: refuse).
    title : str, optional
        The figure's first title line (default: "Wavelength correction of" the cube's name);
        the lens, f-number and method follow on a second line.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        If ``path`` does not end in ``.png``, or ``ds`` lacks the cube, ``cra`` or
        ``wavelength_corrected``.
    FileExistsError
        If ``path`` exists and ``overwrite`` is false; nothing is written.
    """
    path = _check_path(path, overwrite)
    cra_name = _check_correction(ds)
    name = _cube_name(ds)
    cube = ds[name].transpose("y", "x", "band")
    corrected = ds["wavelength_corrected"].transpose("y", "x", "band")
    cra = ds[cra_name]
    ny, nx, nb = (cube.sizes[d] for d in ("y", "x", "band"))
    wl = _wavelengths(ds, nb)
    order = np.argsort(wl, kind="stable")
    b = _middle_band(wl)
    s = _stride(ny, nx)
    img, cra_img = _load(_image(cube, s, b), _image(cra, s, 0))
    cra_img = np.asarray(cra_img, float)

    picked, roles = _pick_by_cra(img, cra_img)
    ys, xs = [r * s for r, _ in picked], [c * s for _, c in picked]
    boxes = _windows(ys, xs, ny, nx, _window_half(s))
    has_resampled = "resampled" in ds.variables
    spectra = _spectra_at(ds, cube, corrected, boxes, has_resampled) if picked else []

    b_shift = _band_moving_most(spectra, wl, b)
    (shift_img,) = _load(_image(corrected, s, b_shift))
    shift_img = np.asarray(shift_img, float) - wl[b_shift]

    virtual = _virtual_means(ds, boxes) if picked else None
    fig, (a_cube, a_cra, a_shift, a_spec, a_virt, a_key) = _correction_axes(
        ny, nx, virtual is not None)
    _draw_correction_images(fig, (a_cube, a_cra, a_shift), (img, cra_img, shift_img), s,
                            _label(cube, name), f"{name}, band {b} ({_num(wl[b], '.1f')} nm)",
                            "band" in cra.dims, f"{b_shift} ({_num(wl[b_shift], '.1f')} nm)",
                            ys, xs)
    _draw_corrected_spectra(a_spec, a_key, ys, xs, boxes, spectra, wl, order, roles,
                            [cra_img[rc] for rc in picked], has_resampled, _label(cube, name))
    if virtual is not None:
        _draw_virtual(a_virt, ds["virtual"], *virtual)

    head = title or f"Wavelength correction of {name}, {ny} x {nx} px, {nb} bands"
    sub = _subtitle(ds.attrs)
    fig.suptitle(head + (f"\n{sub}" if sub else ""), fontsize=12)
    return _save(fig, path)


def _draw_correction_images(fig, axes, images, s, cube_label, cube_title, cra_per_band,
                            shift_band, ys, xs):
    """:func:`plot_correction`'s row of images: the cube's band, the chief-ray angle with the
    chosen pixels circled, and the shift of the band that moves most."""
    a_cube, a_cra, a_shift = axes
    img, cra_img, shift_img = images
    _show(fig, a_cube, img, s, cbar_label=cube_label, title=cube_title)
    cra_title = "chief-ray angle" + (" (first band)" if cra_per_band else "")
    _show(fig, a_cra, cra_img, s, robust=False, cmap="cividis", cbar_label="CRA (deg)",
          title=cra_title, bad_label=None)
    _show(fig, a_shift, shift_img, s, robust=False, cmap="magma",
          cbar_label="shift (nm)", bad_label=None,
          title=f"shift of band {shift_band}: corrected - nominal")
    for k, (y, x) in enumerate(zip(ys, xs, strict=True)):
        a_cra.plot(x, y, marker="o", ms=7, mfc="none", mec=f"C{k}", mew=2)


#: Width of :func:`plot_correction`'s figure (inches) and the height of its row of spectra.
CORRECTION_WIDTH_IN = 16.0
SPECTRA_HEIGHT_IN = 4.6


def _correction_axes(ny, nx, with_virtual):
    """The figure of :func:`plot_correction` and its axes: the three images side by side,
    their row as high as the images need (no empty band around them); below them the spectra,
    the virtual bands' spectra (or None) and the legend's own cell."""
    # an image panel is about a third of the width, less its colour bar
    image_h = min(max(0.27 * CORRECTION_WIDTH_IN * ny / max(nx, 1), 1.6), 6.0) + 0.9
    fig = _figure((CORRECTION_WIDTH_IN, image_h + SPECTRA_HEIGHT_IN + 0.7))
    grid = fig.add_gridspec(2, 3, height_ratios=[image_h, SPECTRA_HEIGHT_IN])
    images = [fig.add_subplot(grid[0, k]) for k in range(3)]
    if with_virtual:
        spec, virt = fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])
    else:
        spec, virt = fig.add_subplot(grid[1, :2]), None
    key = fig.add_subplot(grid[1, 2])
    key.set_axis_off()
    return fig, (*images, spec, virt, key)


def _virtual_means(ds, boxes):
    """The virtual bands' mean over each window (finite values), and their wavelengths; None
    without virtual bands (a ``virtual(y, x, virtual_band)`` and ``virtual_wavelength``)."""
    if "virtual" not in ds.variables or "virtual_wavelength" not in ds.variables:
        return None
    v = ds["virtual"]
    if set(v.dims) != {"y", "x", "virtual_band"}:
        return None
    v = v.transpose("y", "x", "virtual_band")
    loaded = _load(*[v.isel(y=slice(y0, y1), x=slice(x0, x1)) for y0, y1, x0, x1 in boxes])
    means = np.asarray([_nanmean(a, True) for a in loaded], float).reshape(len(boxes), -1)
    return means, np.asarray(ds["virtual_wavelength"].values, float)


def _draw_virtual(ax, virtual, means, wl):
    """The panel of the virtual bands over the same windows, in the same colours."""
    few = wl.size <= MARKER_MAX_BANDS
    o = np.argsort(wl, kind="stable")
    for k, m in enumerate(means):
        if np.any(np.isfinite(m)):
            ax.plot(wl[o], m[o], "-", color=f"C{k}", lw=1.4,
                    **({"marker": "s", "ms": 3} if few else {}))
    how = virtual.attrs.get("virtual_bands")
    ax.set_title(f"virtual bands{f' ({how})' if how else ''}: the same windows", fontsize=10)
    ax.set_xlabel("virtual band wavelength (nm)")
    ax.set_ylabel(_label(virtual, "virtual"))
    ax.grid(alpha=0.3)


def _spectra_at(ds, cube, corrected, boxes, has_resampled):
    """The window means of the cube, its corrected wavelengths and ``resampled``."""
    resampled = ds["resampled"].transpose("y", "x", "band") if has_resampled else None
    mask = ds["mask"].transpose("y", "x", "band") if _has_mask(ds, cube) else None
    return _window_means(cube, corrected, resampled, mask, boxes)


def _check_correction(ds):
    """The chief-ray angle map's name; refuse a dataset without it or wavelength_corrected."""
    cra_name = next((n for n in _CRA_NAMES if n in ds.variables), None)
    for need, have in (("wavelength_corrected", "wavelength_corrected" in ds.variables),
                       ("cra", cra_name is not None)):
        if not have:
            raise ValueError(f"not a correction result: no {need!r}; see "
                             "snapcorr.correct.correct_cube")
    return cra_name


def _pick_by_cra(img, cra_img):
    """Up to three grid pixels by chief-ray angle (lowest, halfway, highest) and their roles:
    "on axis", "mid-field", "edge" when the lowest angle is below :data:`ON_AXIS_DEG`, else
    "lowest CRA", "middle CRA", "highest CRA"."""
    valid = np.isfinite(cra_img) & np.isfinite(np.asarray(img, float))
    if not valid.any():
        valid = np.isfinite(cra_img)
    picked, roles = [], []
    if valid.any():
        rows, cols = np.nonzero(valid)
        angles = cra_img[rows, cols]
        lo, hi = float(angles.min()), float(angles.max())
        names = (("on axis", "mid-field", "edge") if lo < ON_AXIS_DEG
                 else ("lowest CRA", "middle CRA", "highest CRA"))
        for role, k in zip(names, (int(np.argmin(angles)),
                                   int(np.argmin(np.abs(angles - 0.5 * (lo + hi)))),
                                   int(np.argmax(angles))), strict=True):
            rc = (int(rows[k]), int(cols[k]))
            if rc not in picked:
                picked.append(rc)
                roles.append(role)
    return picked, roles


def _window_half(stride):
    """Half the side of the averaging window: :data:`SPECTRUM_WINDOW_PX` or the stride."""
    return max(SPECTRUM_WINDOW_PX, stride) // 2


def _windows(ys, xs, ny, nx, half):
    """The ``(y0, y1, x0, x1)`` of a window ``2 half + 1`` pixels a side around each pixel
    ``(ys[i], xs[i])``, clipped to an image of ``ny`` by ``nx`` pixels."""
    return [(max(0, y - half), min(ny, y + half + 1), max(0, x - half), min(nx, x + half + 1))
            for y, x in zip(ys, xs, strict=True)]


def _has_mask(ds, cube):
    """``ds`` has a ``mask`` of the cube's shape (``cube``: dims ``(y, x, band)``)."""
    return ("mask" in ds.variables and set(ds["mask"].dims) == {"y", "x", "band"}
            and ds["mask"].transpose("y", "x", "band").shape == cube.shape)


def _nanmean(a, where):
    """The mean over the first two axes of ``a`` where ``where`` (NaN where nowhere)."""
    a = np.asarray(a, float)
    ok = where & np.isfinite(a)
    n = ok.sum(axis=(0, 1))
    total = np.where(ok, a, 0.0).sum(axis=(0, 1))
    return np.where(n > 0, total / np.maximum(n, 1), np.nan)


def _window_means(cube, corrected, resampled, mask, boxes):
    """Mean spectra over the windows ``boxes`` (:func:`_windows`), reading only those.

    Returns ``[values, wavelengths]`` (and ``resampled`` when given), each ``(window,
    band)``: the mean of the cube's finite, unmasked values per band; the mean of the
    corrected wavelengths over the same values; the mean of the finite resampled values.
    """
    named = {n: a for n, a in (("cube", cube), ("corrected", corrected),
                               ("resampled", resampled), ("mask", mask)) if a is not None}
    loaded = _load(*[a.isel(y=slice(y0, y1), x=slice(x0, x1))
                     for y0, y1, x0, x1 in boxes for a in named.values()])
    out = [[] for _ in range(2 + (resampled is not None))]
    for i in range(len(boxes)):
        got = dict(zip(named, loaded[i * len(named):(i + 1) * len(named)], strict=True))
        values = np.asarray(got["cube"], float)
        valid = np.isfinite(values)
        if mask is not None:
            valid &= ~np.asarray(got["mask"], bool)
        out[0].append(_nanmean(values, valid))
        out[1].append(_nanmean(got["corrected"], valid))
        if resampled is not None:
            out[2].append(_nanmean(got["resampled"], True))
    nb = cube.sizes["band"]
    return [np.asarray(o, float).reshape(len(boxes), nb) for o in out]


def _band_moving_most(spectra, wl, b):
    """The band whose corrected wavelength moves most at the pixels read (else ``b``)."""
    # the band that moves most, from the pixels read (the shift grows with the CRA)
    if spectra:
        moved = np.abs(spectra[1] - wl[None, :])
        if np.isfinite(moved).any():
            return int(np.nanargmax(np.where(np.isfinite(moved), moved, -1.0).max(axis=0)))
    return b


def _where(box, y, x):
    """A legend's words for the window ``box`` around the pixel ``(y, x)``."""
    h, w = box[1] - box[0], box[3] - box[2]
    if h * w == 1:
        return f"(y, x) = ({y}, {x})"
    return f"mean of {h} x {w} px around (y, x) = ({y}, {x})"


def _draw_corrected_spectra(a_spec, a_key, ys, xs, boxes, spectra, wl, order, roles, cra_deg,
                            has_resampled, ylabel):
    """The panel of the windows' mean spectra at nominal and corrected wavelengths (and
    resampled), its legend in the cell ``a_key``; every band marked only up to
    :data:`MARKER_MAX_BANDS` bands."""
    from matplotlib.lines import Line2D

    few = wl.size <= MARKER_MAX_BANDS
    nominal, corrected, resampled = (({"marker": m, "ms": ms} if few else {"marker": "None"})
                                     for m, ms in ((".", 4), ("o", 3), ("x", 4)))
    handles = []
    for k, (y, x) in enumerate(zip(ys, xs, strict=True)):
        values = spectra[0][k]
        if not np.any(np.isfinite(values)):
            continue
        c = f"C{k}"
        lam = spectra[1][k]
        a_spec.plot(wl[order], values[order], "--", color=c, lw=1, **nominal)
        o = np.argsort(np.where(np.isfinite(lam), lam, np.inf), kind="stable")
        a_spec.plot(lam[o], values[o], "-", color=c, lw=1.4, **corrected)
        if has_resampled:
            a_spec.plot(wl[order], spectra[2][k][order], ":", color=c, lw=1.4, **resampled)
        handles.append(Line2D([], [], color=c, lw=2,
                              label=f"{roles[k]}: {_where(boxes[k], y, x)}, "
                                    f"CRA {cra_deg[k]:.2f} deg"))
    if handles:
        styles = [Line2D([], [], color="0.3", ls="--", label="at nominal wavelengths"),
                  Line2D([], [], color="0.3", ls="-", label="at corrected wavelengths")]
        if has_resampled:
            styles.append(Line2D([], [], color="0.3", ls=":", label="resampled onto nominal",
                                 **({"marker": "x"} if few else {})))
        # in a cell of its own, so it never hides a spectrum
        a_key.legend(handles=handles + styles, fontsize=8, ncols=1, loc="center left",
                     frameon=False)
    else:
        _note(a_spec, "no finite values around these pixels:\nno spectrum to show")
    a_spec.set_xlabel("wavelength (nm)")
    a_spec.set_ylabel(ylabel)
    a_spec.set_title("spectra by chief-ray angle (CRA): means over small windows\n"
                     "of the finite, unmasked values", fontsize=10)
    a_spec.grid(alpha=0.3)


#: The wavelength axis of :func:`plot_sensor` spans where some curve reaches this share of its
#: peak, with a margin of :data:`RESPONSE_MARGIN` of that span on each side.
RESPONSE_FLOOR = 0.02
RESPONSE_MARGIN = 0.04


def _response_span(grid, curves):
    """The wavelengths where any of ``curves`` (rows over ``grid``) reaches
    :data:`RESPONSE_FLOOR` of its own peak, widened by :data:`RESPONSE_MARGIN` and clipped to
    the grid; the whole grid when none does."""
    grid = np.asarray(grid, float)
    a = np.abs(np.atleast_2d(np.asarray(curves, float)))
    peak = np.nanmax(a, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        reached = np.any(a >= RESPONSE_FLOOR * np.where(peak > 0, peak, np.inf), axis=0)
    if not reached.any():
        return float(grid.min()), float(grid.max())
    lo, hi = float(grid[reached].min()), float(grid[reached].max())
    pad = max(RESPONSE_MARGIN * (hi - lo), 2.0)
    return max(float(grid.min()), lo - pad), min(float(grid.max()), hi + pad)


def _wrapped(text, width=88):
    """A title broken into lines of at most ``width`` characters (never cut off)."""
    import textwrap

    return "\n".join(textwrap.wrap(text, width))


def plot_sensor(sensor, path, *, overwrite=False):
    """A picture of a sensor's filters: each band's measured response through the system (or
    its modelled curve), the system's response, and what each correction matrix makes of the
    bands (its virtual bands' responses against Gaussians of their stated widths).

    Parameters
    ----------
    sensor : Sensor
    path : str or Path
        ``.png``, written atomically.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
    """
    from matplotlib import colormaps

    path = _check_path(path, overwrite)
    r = sensor.responses
    panels = 1 + (len(sensor.matrices) if r is not None else 0)
    fig = _figure((10, 3.2 * panels))
    axes = fig.subplots(panels, 1, squeeze=False)[:, 0]
    cmap = colormaps["turbo"]
    cwl = np.asarray(sensor.cwl_nm, float)
    shade = (cwl - cwl.min()) / max(float(np.ptp(cwl)), 1e-9)
    ax = axes[0]
    if r is not None:
        grid, eff = r.wavelength_nm, r.effective
        for b in range(sensor.n_bands):
            ax.plot(grid, eff[b] / np.max(eff[b]), color=cmap(shade[b]), lw=0.8)
        ax.plot(grid, r.system / np.max(r.system), "k--", lw=1.2, label=r.system_name)
        ax.legend(loc="upper right", fontsize=8)
        ax.set_title(_wrapped(f"{sensor.name}: {sensor.n_bands} measured responses through "
                              "the system (each scaled to its peak)"), fontsize=10)
        span = _response_span(grid, np.vstack([eff, *(m.coefficients @ eff
                                                       for m in sensor.matrices)]))
    else:
        from .optics.bandwidth import band_profile

        n = 1.7 if sensor.n_eff is None else sensor.n_eff
        grid = np.linspace(cwl.min() - 3 * max(sensor.fwhm_nm), cwl.max() + 3 * max(
            sensor.fwhm_nm), 2000)
        for b in range(sensor.n_bands):
            curve = band_profile(sensor.profile_shape, cwl[b], sensor.fwhm_nm[b],
                                 np.broadcast_to(n, cwl.shape)[b])(grid)
            ax.plot(grid, curve / np.max(curve), color=cmap(shade[b]), lw=0.8)
        ax.set_title(_wrapped(f"{sensor.name}: {sensor.n_bands} {sensor.profile} filters"),
                     fontsize=10)
        span = (float(grid.min()), float(grid.max()))
    ax.set_xlim(*span)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("relative response")
    for ax, m in zip(axes[1:], sensor.matrices, strict=False):
        virtual = m.coefficients @ r.effective
        for v in range(m.n_virtual):
            peak = np.max(np.abs(virtual[v])) or 1.0
            colour = cmap((m.wavelength_nm[v] - cwl.min()) / max(float(np.ptp(cwl)), 1e-9))
            ax.plot(r.wavelength_nm, virtual[v] / peak, color=colour, lw=0.8)
            if np.isfinite(m.fwhm_nm[v]):
                u = (r.wavelength_nm - m.wavelength_nm[v]) / m.fwhm_nm[v]
                ax.plot(r.wavelength_nm, np.exp(-4 * np.log(2) * u * u), color=colour, lw=0.6,
                        ls=":")
        ax.axhline(0.0, color="0.5", lw=0.5)
        ax.set_title(_wrapped(f"correction matrix {m.name!r} ({m.kind}): its virtual bands' "
                              "responses (solid) and Gaussians of their widths (dotted)"),
                     fontsize=10)
        ax.set_xlim(*span)
        ax.set_xlabel("wavelength (nm)")
        ax.set_ylabel("relative response")
    return _save(fig, path)
