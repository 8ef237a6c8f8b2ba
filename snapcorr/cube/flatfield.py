"""Flat-fielding, Goossens et al. 2019 Eq. (29): ``(DN - dark) / (white - dark)``."""

from __future__ import annotations

import datetime as _dt

import numpy as np
import xarray as xr

from .. import __version__
from .model import check_cube

__all__ = ["flatfield"]


def _mean_frame(frames, what):
    """One cube from a cube or a sequence of cubes (averaged)."""
    if isinstance(frames, xr.DataArray):
        return check_cube(frames), 1
    frames = list(frames)
    if not frames:
        raise ValueError(f"no {what} frame given")
    first = check_cube(frames[0])
    for f in frames[1:]:
        check_cube(f)
        if f.shape != first.shape:
            raise ValueError(f"{what} frames differ in shape: {first.shape} and {f.shape}")
    if len(frames) == 1:
        return first, 1
    return xr.concat(frames, dim="frame").mean("frame"), len(frames)


def _float_dtype(*arrays):
    low = all(np.dtype(a.dtype) in (np.float16, np.float32) for a in arrays)
    return np.float32 if low else np.float64


def flatfield(raw, dark, white, *, saturation=None, name="reflectance"):
    """Flat-field a cube: ``(raw - dark) / (white - dark)`` (Goossens 2019 Eq. 29).

    Parameters
    ----------
    raw : xarray.DataArray
        The cube to correct, dims ``(y, x, band)`` (numpy- or dask-backed).
    dark, white : xarray.DataArray or sequence of them
        Dark and white references; several frames are averaged. A white (or dark) reference
        with fewer rows than ``raw`` -- a line-scan strip -- is averaged over its rows and
        broadcast along ``y``, the scan axis.
    saturation : float, optional
        Digital number at or above which ``raw`` or ``white`` is saturated.
    name : str
        Name of the result (``"reflectance"``; ``"transmittance"`` for a filter in front of a
        white target, as in Goossens Sec. 3.1).

    Returns
    -------
    xarray.Dataset
        ``name`` (NaN where masked), ``mask`` (True where the result is not meaningful: white
        <= dark, saturated, or NaN in an input), ``n_masked`` and the input ``raw`` kept as it
        was; attrs record the method, the number of frames averaged, the date and the version.
        float16/32 inputs give a float32 result, others float64.
    """
    raw = check_cube(raw)
    dark, n_dark = _mean_frame(dark, "dark")
    white, n_white = _mean_frame(white, "white")
    dtype = _float_dtype(raw, dark, white)
    refs = []
    for label, ref in (("dark", dark), ("white", white)):
        if ref.sizes["x"] != raw.sizes["x"] or ref.sizes["band"] != raw.sizes["band"]:
            raise ValueError(
                f"{label} has shape {ref.shape} but the cube {raw.shape}: x and band must match"
            )
        if not np.allclose(ref.wavelength.values, raw.wavelength.values, rtol=0, atol=1e-6):
            raise ValueError(f"{label} and the cube have different wavelengths; they must come "
                             "from the same sensor and band set")
        ref = ref.astype(dtype)
        if ref.sizes["y"] != raw.sizes["y"]:
            ref = ref.mean("y")  # a line-scan strip: broadcast along the scan axis
        refs.append(ref.drop_vars([c for c in ref.coords if c not in ("wavelength", "fwhm")]))
    d, w = refs
    r = raw.astype(dtype)
    denom = w - d
    mask = (denom <= 0) | r.isnull() | denom.isnull()
    if saturation is not None:
        mask = mask | (raw >= saturation) | (w >= saturation)
    mask = mask.transpose("y", "x", "band")
    out = ((r - d) / denom.where(denom > 0)).where(~mask).astype(dtype)
    out = out.transpose("y", "x", "band")
    attrs = {
        "method": "Goossens et al. 2019 Eq. 29: (DN - dark) / (white - dark)",
        "dark_frames": n_dark,
        "white_frames": n_white,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "snapcorr_version": __version__,
    }
    if saturation is not None:
        attrs["saturation"] = float(saturation)
    return xr.Dataset(
        {name: out, "mask": mask, "raw": raw, "n_masked": mask.sum()},
        attrs={**raw.attrs, **attrs},
    )
