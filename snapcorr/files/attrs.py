"""Attributes as files can hold them, and the writer's mark.

- :func:`encode_attrs` and :func:`decode_attrs`: attributes as netCDF and Zarr store them
  (strings, integers, floats and 1-D numeric arrays as themselves, everything else as a
  ``json:<JSON>`` string, :data:`JSON_PREFIX`) and back;
- :func:`_json_attrs`: attributes for a JSON document (TIFF, OpenEXR, ``.npy`` sidecars, the
  ``snapcorr attrs`` field of ENVI headers);
- sensor positions (``sensor_row``, ``sensor_col``) as an offset per band and one step, or
  every value (:func:`_encode_positions`, :func:`_decode_positions`);
- the mark every file snapcorr writes carries (:func:`_mark`, :func:`_version`), and the mark
  tied to the file it was written as (:func:`snapcorr.files.marks.tie_mark`).

See :mod:`snapcorr.files.api` for how each format holds them.
"""

from __future__ import annotations

import contextlib
import json

import numpy as np

from .._validation import parse_json
from ..cube.model import POSITION_DIMS

__all__ = ["JSON_PREFIX", "decode_attrs", "encode_attrs"]


#: Attribute values written as JSON carry this prefix.
JSON_PREFIX = "json:"


def _mark():
    """The mark of the writer: ``"snapcorr <version>"``.

    A writer puts it in (``written_by``; ENVI headers: ``snapcorr version``); when the
    finished file is moved in, it is tied to the name it is written as and to what the file
    holds (by :func:`snapcorr.files.marks.tie_mark`), so that a copy,
    or a file another program saved from it with its attributes, is not taken for
    snapcorr's own."""
    from .. import __version__

    return f"snapcorr {__version__}"


def _version():
    """snapcorr's version, as ENVI headers carry it (``snapcorr version``)."""
    from .. import __version__

    return __version__


def _one_line(text):
    """``text`` (an error's message, say) on one line."""
    return " ".join(str(text).split())


# -- attributes ------------------------------------------------------------------------------


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(type(value).__name__)


def _to_json(value, where):
    try:
        return json.dumps(value, default=_json_default, ensure_ascii=False)
    except (TypeError, ValueError) as err:
        raise TypeError(f"{where} holds a {_one_line(err)} value, which snapcorr cannot store; "
                        "convert it to a string, number, boolean, None, list or dict") from None


def _utf8(text):
    """``text`` as UTF-8 can store it: a file name's bytes that are no UTF-8 (Python holds
    them as lone surrogates, ``'fr\\udce9me.npy'``) written as escapes (``fr\\xe9me.npy``),
    where netCDF's writer failed on them after the work."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    return text


def _utf8_deep(value):
    """:func:`_utf8` of every string in lists, tuples and dicts (keys too)."""
    if isinstance(value, str):
        return _utf8(value)
    if isinstance(value, list | tuple):
        return [_utf8_deep(v) for v in value]
    if isinstance(value, dict):
        return {(_utf8(k) if isinstance(k, str) else k): _utf8_deep(v) for k, v in value.items()}
    return value


def _encode_value(value, where):
    if value is None or isinstance(value, bool | np.bool_ | list | tuple | dict):
        return JSON_PREFIX + _to_json(_utf8_deep(value), where)
    if isinstance(value, str):
        value = _utf8(value)
        return JSON_PREFIX + _to_json(value, where) if value.startswith(JSON_PREFIX) else value
    if isinstance(value, int | np.integer):
        return value if -2**63 <= int(value) < 2**63 else JSON_PREFIX + str(int(value))
    if isinstance(value, float | np.floating):
        return value
    if isinstance(value, np.ndarray):
        if value.ndim == 1 and value.size >= 2 and value.dtype.kind in "iuf":
            return value
        return JSON_PREFIX + _to_json(value.tolist(), where)
    raise TypeError(f"{where} is a {type(value).__name__} ({value!r:.60}), which snapcorr "
                    "cannot store; convert it to a string, number, boolean, None, list or dict")


def encode_attrs(attrs, where="the dataset"):
    """``attrs`` as netCDF and Zarr can store them (see the module docstring); an error names
    an attribute that cannot be stored."""
    out = {}
    for key, value in attrs.items():
        if not isinstance(key, str):
            raise TypeError(f"{where}: attribute names are strings, got {key!r}")
        out[key] = _encode_value(value, f"{where}: attribute {key!r}")
    return out


def decode_attrs(attrs):
    """Attributes as :func:`encode_attrs` had them in memory (``json:`` strings decoded)."""
    out = {}
    for key, value in attrs.items():
        if isinstance(value, bytes):
            value = value.decode("utf-8", "replace")
        if isinstance(value, str) and value.startswith(JSON_PREFIX):
            with contextlib.suppress(ValueError):
                value = parse_json(value[len(JSON_PREFIX):])
        out[key] = value
    return out


def _json_attrs(attrs, where):
    """Attributes for a JSON document (TIFF, EXR, sidecars, ENVI): checked, numpy to Python."""
    return parse_json(_to_json(dict(attrs), where))


# -- sensor positions ------------------------------------------------------------------------


def _encode_positions(values):
    """``{"offset": [...], "step": n}`` when ``values[i, b] == offset[b] + i * step`` exactly
    (integers), else ``{"values": [[...], ...]}``."""
    v = np.asarray(values)
    if v.dtype.kind in "iu":
        v = v.astype(np.int64)
        step = int(v[1, 0] - v[0, 0]) if v.shape[0] > 1 else 1
        if np.array_equal(v, v[0][None, :] + step * np.arange(v.shape[0])[:, None]):
            return {"offset": v[0].tolist(), "step": step}
    return {"values": v.tolist()}


def _decode_positions(spec, shape, name, where):
    """The ``shape`` array described by ``spec`` (from :func:`_encode_positions`)."""
    try:
        if "offset" in spec:
            offset = np.asarray(spec["offset"])
            step = np.asarray(spec.get("step", 1))
            if offset.ndim != 1 or step.ndim != 0:
                raise ValueError
            values = offset[None, :] + step * np.arange(shape[0])[:, None]
        else:
            values = np.asarray(spec["values"])
        if values.dtype.kind not in "iuf":
            raise ValueError
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{where}: {name} is not a list of sensor positions") from None
    if values.shape != tuple(shape):
        raise ValueError(f"{where}: {name} has shape {values.shape} but the cube needs "
                         f"{tuple(shape)}")
    return values.astype(np.int64 if values.dtype.kind in "iu" else np.float64)


def _positions(cube):
    return {name: _encode_positions(cube[name].values) for name in POSITION_DIMS
            if name in cube.coords}
