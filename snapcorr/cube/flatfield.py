"""Flat-fielding, Goossens et al. 2019 Eq. (29): ``(DN - dark) / (white - dark)``."""

from __future__ import annotations

import datetime as _dt
import warnings

import numpy as np
import xarray as xr

from .. import __version__
from .._validation import check_positive
from .model import check_cube, check_dtype

__all__ = ["MASKED_WARN_FRACTION", "MaskedWarning", "cf_attrs", "check_masked", "flatfield",
           "masked_causes", "ratio_kind"]

#: Share of masked values above which :func:`check_masked` warns.
MASKED_WARN_FRACTION = 0.5
_DTYPES = {"float32": np.float32, "float64": np.float64}


class MaskedWarning(UserWarning):
    """More than :data:`MASKED_WARN_FRACTION` of a flat-fielded cube is masked."""


def cf_attrs(name):
    """CF ``units`` and ``long_name`` of the variables snapcorr writes (``{"long_name": name}``
    for others)."""
    return {"reflectance": {"units": "1", "long_name": "reflectance"},
            "transmittance": {"units": "1", "long_name": "transmittance"},
            "mask": {"units": "1", "long_name": "value not meaningful (white <= dark, "
                     "saturated, or not finite in an input)"},
            "raw": {"long_name": "raw cube as read, unchanged", "units": "count"},
            }.get(name, {"long_name": name})


def masked_causes(saturation, option="saturation="):
    """What masks a flat field's every value, for a message (``option``: how the saturation
    level is set, where it is)."""
    sat = saturation
    return ("likely the white reference is nowhere above the dark, the cube holds no finite "
            "value" + (f", or the values reach the saturation level {sat:g}"
                       if sat is not None else "")
            + "; check the dark and white files" + (f" and {option}" if sat else ""))


def check_masked(ds, *, warn_fraction=MASKED_WARN_FRACTION):
    """Count the masked values of a :func:`flatfield` result; refuse when all are masked.

    Computes ``n_masked`` (one pass over lazy inputs). Warns (:class:`MaskedWarning`) when more
    than ``warn_fraction`` of the values are masked.

    Returns
    -------
    n_masked, total : int

    Raises
    ------
    ValueError
        Every value is masked: nothing in the result would mean anything.
    """
    n, total = int(ds["n_masked"]), int(ds["mask"].size)
    causes = masked_causes(ds.attrs.get("saturation"))
    if n == total:
        raise ValueError(f"every value of the {' x '.join(map(str, ds['mask'].shape))} cube is "
                         f"masked: {causes}")
    if n > warn_fraction * total:
        warnings.warn(f"{100 * n / total:.1f} % of the values are masked (more than "
                      f"{100 * warn_fraction:g} %): {causes}", MaskedWarning, stacklevel=2)
    return n, total


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


def _check_dtypes(dtype, raw, darks, whites):
    """The result's numpy type and the type the arithmetic is done in; refuse any other
    result type, and inputs that are not numbers.

    The differences ``DN - dark`` and ``white - dark`` are taken in float64 where any input is
    float64 or an integer wider than 16 bits: float32 holds whole numbers exactly only up to
    2**24, so counts near 4e9 would be rounded to 256 DN before they are subtracted (a
    reflectance 0.03 off for a white 4096 DN above its dark). The result is then rounded to
    ``dtype`` once, at the end."""
    if str(np.dtype(dtype)) not in _DTYPES:
        raise ValueError(f"dtype must be float32 or float64, got {dtype!r}")
    dtype = _DTYPES[str(np.dtype(dtype))]
    work = dtype
    for what, frames in (("raw", [raw]), ("dark", darks), ("white", whites)):
        for kind in {f.dtype for f in frames}:
            if not (np.issubdtype(kind, np.integer) or np.issubdtype(kind, np.floating)):
                raise TypeError(f"the {what} cube is {kind}; flat-fielding needs integer or "
                                "real digital numbers")
            if kind == np.float64 or (np.issubdtype(kind, np.integer) and kind.itemsize > 2):
                work = np.float64
    return dtype, work


def _average_reference(label, frames, raw, dtype, saturation, snapshot):
    """A reference's frames averaged (a line-scan strip over its rows too), and its flags."""
    for i, f in enumerate(frames):
        name = label if len(frames) == 1 else f"{label} frame {i + 1} of {len(frames)}"
        if f.sizes["x"] != raw.sizes["x"] or f.sizes["band"] != raw.sizes["band"]:
            raise ValueError(
                f"{name} has shape {f.shape} but the cube {raw.shape}: x and band must match"
            )
        if not np.allclose(f.wavelength.values, raw.wavelength.values, rtol=0, atol=1e-6):
            raise ValueError(f"{name} and the cube have different wavelengths; they must come "
                             "from the same sensor and band set")
        if snapshot and f.sizes["y"] != raw.sizes["y"]:
            raise ValueError(f"the {name} reference has {f.sizes['y']} rows but the cube "
                             f"{raw.sizes['y']}, and the cube is a snapshot (a mosaic "
                             "sensor's: its bands sit at different rows of a tile): a "
                             "snapshot has no scan axis, so its references are cubes of the "
                             "same size and place")
        _check_same_place(label, f, raw, snapshot)
    stack = xr.concat([f.astype(dtype) for f in frames], dim="frame")
    stack = stack.drop_vars([c for c in stack.coords if c not in ("wavelength", "fwhm")])
    # Flags are taken per frame and per row before averaging, so a saturated or missing
    # value in any frame (or any row of a line-scan strip), or a reference's own ENVI data
    # ignore value, masks the pixel.
    bad = ~np.isfinite(stack)
    ignores = [f.attrs.get("data_ignore_value") for f in frames]
    if any(v is not None for v in ignores):
        ignored = xr.concat([(f == v) if v is not None else xr.zeros_like(f, bool)
                             for f, v in zip(frames, ignores, strict=True)], dim="frame")
        bad = bad | ignored.drop_vars([c for c in ignored.coords
                                       if c not in ("wavelength", "fwhm")])
    if saturation is not None and label == "white":
        bad = bad | (stack >= np.float64(saturation))
    ref, bad = stack.mean("frame", skipna=False), bad.any("frame")
    if ref.sizes["y"] > raw.sizes["y"]:
        raise ValueError(f"the {label} reference has {ref.sizes['y']} rows but the cube "
                         f"{raw.sizes['y']}: a reference is a frame of the cube's size or "
                         "a strip of fewer rows (line scan), never larger; crop it to the "
                         "cube's area")
    if ref.sizes["y"] != raw.sizes["y"]:  # a line-scan strip: broadcast along the scan axis
        ref, bad = ref.mean("y", skipna=False), bad.any("y")
    return ref, bad


def _is_snapshot(cube):
    """A cube from a mosaic (snapshot) sensor: its bands sit at different sensor rows or
    columns."""
    for coord, dim in (("sensor_row", "y"), ("sensor_col", "x")):
        if coord in cube.coords and "band" in cube[coord].dims:
            pos = np.asarray(cube[coord].transpose(dim, "band").values)
            if pos.shape[1] > 1 and np.any(pos != pos[:, :1]):
                return True
    return False


def _check_same_place(label, ref, raw, snapshot):
    """A reference must come from the cube's part of the sensor where both record it: the same
    columns always, the same rows unless it is a line-scan strip."""
    for coord, dim in (("sensor_col", "x"), ("sensor_row", "y")):
        if coord not in ref.coords or coord not in raw.coords:
            continue
        if dim == "y" and ref.sizes["y"] != raw.sizes["y"] and not snapshot:
            continue  # a strip: any rows of the scan
        a, b = (np.asarray(c[coord].transpose(dim, "band").values) for c in (ref, raw))
        if a.shape != b.shape or not np.array_equal(a, b):
            where = ("" if a.shape != b.shape else
                     " (its {:g}, the cube's {:g})".format(*(v.ravel()[np.argmax(
                         (a != b).ravel())] for v in (a, b))))
            raise ValueError(
                f"the {label} reference was taken on other sensor "
                f"{'columns' if dim == 'x' else 'rows'} than the cube{where}: a reference "
                "must cover the cube's own pixels; crop it to the cube's area (or give the one "
                "taken with it)")


def flatfield(raw, dark, white, *, saturation=None, name="reflectance", dtype="float32",
              snapshot=False):
    """Flat-field a cube: ``(raw - dark) / (white - dark)`` (Goossens 2019 Eq. 29).

    Parameters
    ----------
    raw : xarray.DataArray
        The cube to correct, dims ``(y, x, band)`` (numpy- or dask-backed); or a raw mosaic
        frame ``(y, x)`` (as :func:`~snapcorr.cube.read_frame` gives it, or a 2-D array), or
        a stream of them
        ``(frame, y, x)``, flat-fielded pixel by pixel before :func:`~snapcorr.cube.demosaic`.
    dark, white : xarray.DataArray or sequence of them
        Dark and white references; several frames are averaged. A white (or dark) reference
        with fewer rows than a cube ``raw`` -- a line-scan strip -- is averaged over its rows
        and broadcast along ``y``, the scan axis; one with more rows is refused. A snapshot
        (a frame, or a cube whose bands sit at different rows of a mosaic tile) has no scan
        axis: every reference is of its size. Where a reference and the cube both record
        their sensor positions, they must be the same pixels (columns always, rows unless a
        strip). A reference's own ``data_ignore_value`` masks its pixels.
    saturation : float, optional
        Digital number at or above which ``raw`` or any white frame is saturated (> 0).
    name : str
        Name of the result (``"reflectance"``; ``"transmittance"`` for a filter in front of a
        white target, as in Goossens Sec. 3.1).
    dtype : {"float32", "float64"}
        Type of the result (float32 by default: half the memory and files of float64, and
        7 significant digits, far below any sensor's noise).
    snapshot : bool
        The cube is a snapshot sensor's (``layout = "mosaic"``) even where it records no
        positions (a bare array): its references are never taken as line-scan strips.

    Returns
    -------
    xarray.Dataset
        ``name`` (NaN where masked), ``mask`` (True where the result is not meaningful: white
        <= dark, saturated, a NaN or infinite value in any input frame, or the cube's ENVI
        ``data ignore value``), ``n_masked`` and the input ``raw`` kept as it
        was; CF ``units`` and ``long_name`` on each; attrs record the method, the number of
        frames averaged, the date and the version. For a frame (or stream), the same
        variables with its dims. For numpy inputs the mask is checked at
        once (:func:`check_masked`); for lazy ones call it before writing.
    """
    _refuse_ratios(raw, dark, white)
    if not isinstance(raw, xr.DataArray) and getattr(raw, "ndim", None) == 2:
        raw = xr.DataArray(raw, dims=("y", "x"))  # a frame as numpy or dask
    if isinstance(raw, xr.DataArray) and tuple(raw.dims) in (("y", "x"), ("frame", "y", "x")):
        return _flatfield_frames(raw, _as_frames(dark), _as_frames(white), saturation, name,
                                 dtype)
    raw = check_cube(raw)
    darks, whites = _frames(dark, "dark"), _frames(white, "white")
    dtype, work = _check_dtypes(dtype, raw, darks, whites)
    if saturation is not None:
        saturation = check_positive("saturation", saturation)
    snapshot = bool(snapshot) or _is_snapshot(raw)
    d, dark_bad = _average_reference("dark", darks, raw, work, saturation, snapshot)
    w, white_bad = _average_reference("white", whites, raw, work, saturation, snapshot)
    return _result(raw, raw, d, w, dark_bad | white_bad, saturation, name, (dtype, work),
                   (len(darks), len(whites)), frame=False)


#: Names of quantities that are already a ratio to a white: a flat field's result, not counts.
_RATIOS = ("reflectance", "transmittance")


def ratio_kind(value, *, by_units=True):
    """What a DataArray says it is where it is a flat field's result, a ratio to a white
    (``"a reflectance"``, ``"a ratio (units '1')"``): named as one of :data:`_RATIOS` (as its
    name or ``long_name``) or, with ``by_units``, in units of ``"1"`` (counts have none, or
    ``DN``; a calibration flat may be a white another tool normalised, which keeps its
    fall-off); else None."""
    if not isinstance(value, xr.DataArray):
        return None
    said = [n for n in (value.name, value.attrs.get("long_name")) if n in _RATIOS]
    if said:
        return f"a {said[0]}"
    units = str(value.attrs.get("units", "")).strip()
    return "a ratio (units '1')" if by_units and units == "1" else None


def _refuse_ratios(raw, dark, white):
    """A cube or frame that says it is a flat field's result, given as the raw, a dark or a
    white: named as one (:data:`_RATIOS`, as a name or a ``long_name``), or in units of
    ``"1"`` (a ratio: counts have none, or ``DN``). Refused, naming the argument and, of
    several frames, which (flat-fielding it again divides a ratio by counts, and every value
    comes out wrong without a masked pixel)."""
    for what, value in (("raw", raw), ("dark", dark), ("white", white)):
        values = value if isinstance(value, (list, tuple)) else [value]
        for k, v in enumerate(values, 1):
            kind = ratio_kind(v)
            if kind is None:
                continue
            source = v.attrs.get("source") or "a ratio to a white"
            label = ("the raw input" if what == "raw" else
                     f"the {what} frame {k} of {len(values)}" if len(values) > 1 else
                     f"the {what}")
            raise ValueError(f"{label} is {kind} (a flat field's result: {source}), not raw "
                             "counts: flat-field the raw frames it was made from")


def _result(raw, plain, d, w, reference_bad, saturation, name, dtype, counts, *, frame):
    """``(plain - d) / (w - d)`` with its mask, the raw values kept and the provenance: the
    Dataset :func:`flatfield` returns, for a cube or for frames (``frame``); ``dtype`` is the
    result's type and the arithmetic's (:func:`_check_dtypes`)."""
    dtype, work = dtype
    r = plain.astype(work)
    denom = w - d
    mask = (denom <= 0) | ~np.isfinite(r) | reference_bad
    if saturation is not None:
        mask = mask | (plain >= np.float64(saturation))
    ignore = raw.attrs.get("data_ignore_value")
    if ignore is not None:
        mask = mask | (plain == ignore)
    mask = mask.transpose(*raw.dims)
    out = ((r - d) / denom.where(denom > 0)).where(~mask).astype(dtype).transpose(*raw.dims)
    n_dark, n_white = counts
    how = ", per pixel of the raw frame" if frame else ""
    attrs = {
        "source": f"snapcorr {__version__} flatfield",
        "method": f"Goossens et al. 2019 Eq. 29: (DN - dark) / (white - dark){how}",
        "dark_frames": n_dark,
        "white_frames": n_white,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "snapcorr_version": __version__,
    }
    if saturation is not None:
        attrs["saturation"] = float(saturation)
    origin = raw.attrs.get("source", "the raw frame" if frame else "the raw cube")
    out.attrs = {**cf_attrs(name), "source": f"(raw - dark) / (white - dark) of {origin}, "
                 f"{n_dark} dark and {n_white} white frame(s) averaged{how}"}
    mask.attrs = {**cf_attrs("mask"), "source": "white <= dark, saturation and non-finite "
                  "values in the raw, dark and white frames"}
    kept = plain.copy(deep=False)
    kept.attrs = {**cf_attrs("raw"), **raw.attrs, "source": origin}
    if frame:
        kept.attrs["long_name"] = "raw frame as read, unchanged"
    n_masked = mask.sum().assign_attrs(long_name="number of masked values", units="1")
    ds = xr.Dataset({name: out, "mask": mask, "raw": kept, "n_masked": n_masked},
                    attrs={**raw.attrs, **attrs})
    if ds[name].chunks is None:
        check_masked(ds)
    return ds


def _as_frames(refs):
    """2-D arrays among the references as (y, x) DataArrays."""
    one = not isinstance(refs, (list, tuple))
    out = [xr.DataArray(r, dims=("y", "x")) if not isinstance(r, xr.DataArray)
           and getattr(r, "ndim", None) == 2 else r for r in ([refs] if one else refs)]
    return out[0] if one else out


def _flatfield_frames(raw, dark, white, saturation, name, dtype):
    """:func:`flatfield` of raw mosaic frames ``(..., y, x)``, pixel by pixel."""
    check_dtype(raw.dtype)
    refs = {}
    for label, given in (("dark", dark), ("white", white)):
        frames = [given] if isinstance(given, xr.DataArray) else list(given)
        if not frames:
            raise ValueError(f"no {label} frame given")
        for f in frames:
            if not isinstance(f, xr.DataArray) or tuple(f.dims) != ("y", "x"):
                dims = tuple(f.dims) if isinstance(f, xr.DataArray) else type(f).__name__
                raise ValueError(f"the {label} reference of a frame is a 2-D (y, x) frame, "
                                 f"got {dims}")
            if f.shape != raw.shape[-2:]:
                raise ValueError(f"the {label} frame is {f.shape[0]} x {f.shape[1]} px but the "
                                 f"raw frame {raw.shape[-2]} x {raw.shape[-1]}: a snapshot's "
                                 "references are frames of the same size and place")
        refs[label] = frames
    dtype, work = _check_dtypes(dtype, raw, refs["dark"], refs["white"])
    if saturation is not None:
        saturation = check_positive("saturation", saturation)
    averaged = {}
    for label, frames in refs.items():
        stack = xr.concat([f.drop_vars(list(f.coords)).astype(work) for f in frames],
                          dim="ref")
        bad = ~np.isfinite(stack)
        for i, f in enumerate(frames):  # a reference's own ENVI data ignore value
            ignore = f.attrs.get("data_ignore_value")
            if ignore is not None:
                hit = (f.drop_vars(list(f.coords)) == ignore).expand_dims(ref=[i])
                bad = bad | hit.reindex(ref=range(len(frames)), fill_value=False)
        if saturation is not None and label == "white":
            bad = bad | (stack >= np.float64(saturation))
        averaged[label] = (stack.mean("ref", skipna=False), bad.any("ref"))
    (d, dark_bad), (w, white_bad) = averaged["dark"], averaged["white"]
    # the frame's own coordinates (a stream's times, say) are kept, along frame only
    plain = raw.drop_vars([c for c in raw.coords if set(raw[c].dims) - {"frame"}])
    reference_bad = ((w - d) <= 0) | dark_bad | white_bad
    share = float(reference_bad.mean())
    if share > MASKED_WARN_FRACTION:  # refused before any work on the frames
        raise ValueError(f"{100 * share:.1f} % of the pixels are masked by the references "
                         "alone: the white frame is mostly not above the dark (swapped, or "
                         "not a white?), or the references hold no finite value"
                         + (" below the saturation level" if saturation is not None else "")
                         + "; check the dark and white files")
    return _result(raw, plain, d, w, reference_bad, saturation, name, (dtype, work),
                   (len(refs["dark"]), len(refs["white"])), frame=True)
