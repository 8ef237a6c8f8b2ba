"""The quick look of a wavelength correction (:func:`snapcorr.correct.correct_cube`): one band
of the cube, the chief-ray angle, the shift of the band that moves most and mean spectra
around three pixels at their nominal and corrected wavelengths (and their virtual bands)."""

from __future__ import annotations

import numpy as np

from .drawing import (
    MARKER_MAX_BANDS,
    _check_path,
    _figure,
    _image,
    _label,
    _load,
    _middle_band,
    _note,
    _num,
    _save,
    _show,
    _stride,
    _wavelengths,
)
from .picking import _pick_by_cra, _where, _window_half, _windows

#: Names the chief-ray angle map goes by, in order of preference.
_CRA_NAMES = ("cra", "cra_deg")


_NOT_CUBE = {"wavelength_corrected", "resampled", "wavelength_scale", "mask", *_CRA_NAMES}


def _cube_name(ds):
    """The correction result's input cube (:func:`~snapcorr.files.datasets.which_cube`: two
    of unknown names are refused, not the first drawn)."""
    from ..files.datasets import which_cube

    cubes = [n for n, v in ds.data_vars.items()
             if set(v.dims) == {"y", "x", "band"} and n not in _NOT_CUBE]
    if cubes:
        return which_cube("the correction result", cubes)
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


def _check_correction(ds):
    """The chief-ray angle map's name; refuse a dataset without it or wavelength_corrected."""
    cra_name = next((n for n in _CRA_NAMES if n in ds.variables), None)
    for need, have in (("wavelength_corrected", "wavelength_corrected" in ds.variables),
                       ("cra", cra_name is not None)):
        if not have:
            raise ValueError(f"not a correction result: no {need!r}; see "
                             "snapcorr.correct.correct_cube")
    return cra_name


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

