"""uint16 CF packing in one compiled pass: clip, offset, scale, round and fill together.

xarray's CF encoding of a float array takes several passes over it (a copy, the offset, the
scale, the fill of NaN, the rounding, the cast), each the size of the array; on a stream's
frames that was as long as the whole correction. :func:`pack_uint16` gives the same codes in
one pass: the arithmetic in the values' own type, the offset subtracted and the scale divided
(not multiplied by its inverse) and the result rounded half to even, as xarray does, so a
reader unpacks the same values."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _pack(flat, offset, scale, top, out, fill):  # pragma: no cover - compiled
    zero = flat.dtype.type(0)
    half = flat.dtype.type(0.5)
    clipped = 0
    for i in range(flat.size):
        v = flat[i]
        if np.isnan(v):
            out[i] = fill
        else:
            c = (v - offset) / scale
            if c < -half or c > top + half:  # beyond the half step rounding takes to an end
                clipped += 1
            out[i] = np.uint16(np.rint(min(max(c, zero), top)))
    return clipped


def pack_uint16(values, offset, scale, top, fill, clipped=None):
    """``round(clip((values - offset) / scale, 0, top))`` as uint16, NaN as ``fill``: values
    beyond the packed range (``offset`` to ``offset + top * scale``) are stored at its ends.

    Parameters
    ----------
    values : ndarray of float32 or float64
    offset, scale : float
        The CF ``add_offset`` and ``scale_factor`` (float32, as stored), cast to the values'
        type for the arithmetic, as xarray's encoding does.
    top : int
        The largest code of a value (``valid_range``'s upper end).
    fill : int
        The code of NaN (``_FillValue``).
    clipped : list, optional
        Given, the count of values beyond the packed range by more than half a step
        (stored at its ends) and of values in all is appended to it as a pair (one per call:
        a block of a dask array). A value at an end (which float32's step may put a hair
        beyond it) is not counted.

    Returns
    -------
    ndarray of uint16, the shape of ``values``
    """
    values = np.asarray(values)
    if values.dtype not in (np.float32, np.float64):
        values = values.astype(np.float64)
    t = values.dtype.type
    flat = np.ascontiguousarray(values).reshape(-1)
    out = np.empty(flat.size, np.uint16)
    n = _pack(flat, t(offset), t(scale), t(top), out, np.uint16(fill))
    if clipped is not None:
        clipped.append((int(n), int(flat.size)))
    return out.reshape(values.shape)
