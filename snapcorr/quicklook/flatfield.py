"""The quick look of a flat-field result (:func:`snapcorr.cube.flatfield`): one band, the
masked fraction of every band and a few pixels' spectra."""

from __future__ import annotations

import math

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
    _points,
    _save,
    _show,
    _stride,
    _wavelengths,
)
from .picking import CANDIDATES_PX, _pick_by_content


def _result_name(ds):
    for name in ("reflectance", "transmittance"):
        if name in ds.data_vars:
            return name
    others = [n for n, v in ds.data_vars.items()
              if set(v.dims) == {"y", "x", "band"} and n not in ("mask", "raw")]
    if not others:
        raise ValueError("not a flat-field result: no 'reflectance' or 'transmittance' "
                         "variable with dims (y, x, band); see snapcorr.cube.flatfield")
    from ..files.datasets import which_cube

    return which_cube("the flat-field result", others)  # two unknown: refused, not the first


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

