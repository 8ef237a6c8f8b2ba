"""Flat-fielding, Goossens et al. 2019 Eq. (29): ``(DN - dark) / (white - dark)``."""

from __future__ import annotations

import datetime as _dt

import numpy as np
import xarray as xr

from .. import __version__
from .model import check_cube

__all__ = ["flatfield"]


def _frames(frames, what):
    """The reference frames as a list of cubes of one shape."""
    frames = [frames] if isinstance(frames, xr.DataArray) else list(frames)
    if not frames:
        raise ValueError(f"no {what} frame given")
    first = check_cube(frames[0])
    for f in frames[1:]:
        check_cube(f)
        if f.shape != first.shape:
            raise ValueError(f"{what} frames differ in shape: {first.shape} and {f.shape}")
    return frames


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
        Digital number at or above which ``raw`` or any white frame is saturated.
    name : str
        Name of the result (``"reflectance"``; ``"transmittance"`` for a filter in front of a
        white target, as in Goossens Sec. 3.1).

    Returns
    -------
    xarray.Dataset
        ``name`` (NaN where masked), ``mask`` (True where the result is not meaningful: white
        <= dark, saturated, a NaN or infinite value in any input frame, or the cube's ENVI
        ``data ignore value``), ``n_masked`` and the input ``raw`` kept as it
        was; attrs record the method, the number of frames averaged, the date and the version.
        float16/32 inputs give a float32 result, others float64.
    """
    raw = check_cube(raw)
    darks, whites = _frames(dark, "dark"), _frames(white, "white")
    dtype = _float_dtype(raw, darks[0], whites[0])
    refs, flags = [], []
    for label, frames in (("dark", darks), ("white", whites)):
        ref = frames[0]
        if ref.sizes["x"] != raw.sizes["x"] or ref.sizes["band"] != raw.sizes["band"]:
            raise ValueError(
                f"{label} has shape {ref.shape} but the cube {raw.shape}: x and band must match"
            )
        if not np.allclose(ref.wavelength.values, raw.wavelength.values, rtol=0, atol=1e-6):
            raise ValueError(f"{label} and the cube have different wavelengths; they must come "
                             "from the same sensor and band set")
        stack = xr.concat([f.astype(dtype) for f in frames], dim="frame")
        stack = stack.drop_vars([c for c in stack.coords if c not in ("wavelength", "fwhm")])
        # Flags are taken per frame and per row before averaging, so a saturated or missing
        # value in any frame (or any row of a line-scan strip) masks the pixel.
        bad = ~np.isfinite(stack)
        if saturation is not None and label == "white":
            bad = bad | (stack >= saturation)
        ref, bad = stack.mean("frame", skipna=False), bad.any("frame")
        if ref.sizes["y"] != raw.sizes["y"]:  # a line-scan strip: broadcast along the scan axis
            ref, bad = ref.mean("y", skipna=False), bad.any("y")
        refs.append(ref)
        flags.append(bad)
    d, w = refs
    r = raw.astype(dtype)
    denom = w - d
    mask = (denom <= 0) | ~np.isfinite(r) | flags[0] | flags[1]
    if saturation is not None:
        mask = mask | (raw >= saturation)
    ignore = raw.attrs.get("data_ignore_value")
    if ignore is not None:
        mask = mask | (raw == ignore)
    mask = mask.transpose("y", "x", "band")
    out = ((r - d) / denom.where(denom > 0)).where(~mask).astype(dtype)
    out = out.transpose("y", "x", "band")
    n_dark, n_white = len(darks), len(whites)
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
