"""Compatibility re-exports: attribute encoding lives in :mod:`snapcorr.files.attrs`."""

from snapcorr.cube.model import POSITION_DIMS as POSITION_DIMS
from snapcorr.files.attrs import JSON_PREFIX as JSON_PREFIX
from snapcorr.files.attrs import _decode_positions as _decode_positions
from snapcorr.files.attrs import _encode_positions as _encode_positions
from snapcorr.files.attrs import _encode_value as _encode_value
from snapcorr.files.attrs import _json_attrs as _json_attrs
from snapcorr.files.attrs import _json_default as _json_default
from snapcorr.files.attrs import _mark as _mark
from snapcorr.files.attrs import _one_line as _one_line
from snapcorr.files.attrs import _positions as _positions
from snapcorr.files.attrs import _to_json as _to_json
from snapcorr.files.attrs import _version as _version
from snapcorr.files.attrs import decode_attrs as decode_attrs
from snapcorr.files.attrs import encode_attrs as encode_attrs
from snapcorr.files.marks import _mark_matches as _mark_matches
from snapcorr.files.marks import _tied_mark as _tied_mark

_MOVED_TO = "snapcorr.files.attrs"
