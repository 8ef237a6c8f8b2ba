"""ENVI cubes: a header and its data file, read and written through Spectral Python.

The header is parsed by Spectral Python and validated here (:func:`_envi_header`: sizes, data
type, interleave, byte order, keys given twice); the data are read in blocks of rows with
plain file reads (:func:`snapcorr.files.storage._from_file`), never through a whole-file
memory map. What the header says about the stored numbers (data gain / offset values,
reflectance scale factor, ``bbl``, data ignore value) is applied to a cube
(:func:`_envi_values`). snapcorr's own fields: ``snapcorr version``, ``snapcorr name``,
``snapcorr attrs = json:{...}`` and the sensor positions (:func:`_envi_position_keys`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import re
import sys
import warnings
from pathlib import Path

import numpy as np

from .._validation import parse_json, shown
from ..cube.model import POSITION_DIMS
from .attrs import JSON_PREFIX, _one_line, _version
from .reading import check_input
from .safety import atomic_write_files
from .storage import _ENVI_EXTS, FileFormat, _File, _from_file, _resolve_chunks

#: ENVI ``data type`` codes a cube can hold (ENVI also defines 6 and 9, complex).
_ENVI_DTYPES = {1: np.uint8, 2: np.int16, 3: np.int32, 4: np.float32, 5: np.float64,
                12: np.uint16, 13: np.uint32, 14: np.int64, 15: np.uint64}
_ENVI_COMPLEX = {6: "complex64", 9: "complex128"}


# -- reading ---------------------------------------------------------------------------------


@contextlib.contextmanager
def _quiet_spectral():
    """Spectral Python logs (its own handler prints to stderr) and warns about headers; the
    errors snapcorr raises say it all, so both are silenced around its calls."""
    logger = logging.getLogger("spectral")
    disabled = logger.disabled
    logger.disabled = True
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logger.disabled = disabled


def _envi_int(h, key, hdr, *, minimum, default=None, what="a whole number"):
    if key not in h:
        if default is not None:
            return default
        raise ValueError(f"{hdr}: the header has no '{key}'; add it (ENVI needs samples, "
                         "lines, bands, data type, interleave and byte order)")
    raw = h[key]
    text = raw if isinstance(raw, str) else ", ".join(map(str, raw))
    try:
        value = int(text.strip())
    except ValueError:
        value = None
    if value is None or value < minimum:
        raise ValueError(f"{hdr}: {_said(key, text)} must be {what}; fix the header")
    return value


def _said(key, value):
    """``'key = value'`` as a header gives it, the value cut (a line of megabytes is no
    better shown whole)."""
    text = (", ".join(map(str, value[:20])) if isinstance(value, (list, tuple))
            else str(value))
    return f"'{key} = {shown(text, quote=False)}'"


#: The largest ENVI header read: a header's lists (wavelengths, widths, gains, offsets, band
#: names) of a hundred thousand bands take about 8 MiB; one of 36 MiB (six million
#: wavelengths for eight bands) took 18 s and 930 MB before its count was compared.
MAX_HEADER_BYTES = 8 * 2**20


def _envi_header(hdr):
    """The header as Spectral Python parses it, validated; raises one clear line otherwise."""
    from spectral.io import envi

    try:
        size = Path(hdr).stat().st_size
    except OSError:
        size = 0  # Spectral Python's own error says what is wrong with the path
    if size > MAX_HEADER_BYTES:
        raise ValueError(f"{hdr}: the header holds {size / 2**20:.1f} MiB, more than any ENVI "
                         f"header of a cube ({MAX_HEADER_BYTES / 2**20:.0f} MiB holds a "
                         "hundred thousand bands' lists); is this the header?")
    try:
        with _quiet_spectral():
            h = envi.read_envi_header(str(hdr))
    except Exception as err:  # Spectral Python raises several types for a bad header
        msg = _one_line(err) or type(err).__name__
        raise ValueError(f"{hdr}: cannot read it as ENVI: {msg}") from None
    if h.get("file type", "").strip().lower() == "envi spectral library":
        raise ValueError(f"{hdr} is an ENVI spectral library, not an image cube")
    twice = _envi_repeated_keys(hdr)
    if twice:
        raise ValueError(f"{hdr}: the header gives {', '.join(repr(k) for k in twice)} more "
                         "than once, and readers disagree on which holds; keep one of each")
    lines = _envi_int(h, "lines", hdr, minimum=1, what="a whole number > 0")
    samples = _envi_int(h, "samples", hdr, minimum=1, what="a whole number > 0")
    bands = _envi_int(h, "bands", hdr, minimum=1, what="a whole number > 0")
    offset = _envi_int(h, "header offset", hdr, minimum=0, default=0,
                       what="a whole number >= 0")
    order = _envi_int(h, "byte order", hdr, minimum=0,
                      what="0 (little-endian) or 1 (big-endian)")
    if order not in (0, 1):
        raise ValueError(f"{hdr}: {_said('byte order', h['byte order'])} must be 0 (little-endian) "
                         "or 1 (big-endian); fix the header")
    code = _envi_int(h, "data type", hdr, minimum=0, what="an ENVI data type code")
    if code in _ENVI_COMPLEX:
        raise ValueError(f"{hdr}: 'data type = {code}' is {_ENVI_COMPLEX[code]}; a cube holds "
                         "real numbers (convert the data to its magnitude or real part)")
    if code not in _ENVI_DTYPES:
        codes = ", ".join(map(str, _ENVI_DTYPES))
        raise ValueError(f"{hdr}: {_said('data type', h['data type'])} is not an ENVI data type "
                         f"snapcorr can read ({codes}: integers and floats); fix the header")
    if "interleave" not in h:
        raise ValueError(f"{hdr}: the header has no 'interleave'; add it (bsq, bil or bip)")
    interleave = str(h["interleave"]).strip().lower()
    if interleave not in ("bsq", "bil", "bip"):
        raise ValueError(f"{hdr}: {_said('interleave', h['interleave'])} must be bsq, bil or "
                         "bip; fix the header")
    for key in ("major frame offsets", "minor frame offsets"):
        if key in h:
            vals = h[key] if isinstance(h[key], list) else [h[key]]
            if any(str(v).strip() not in ("0", "") for v in vals):
                raise ValueError(f"{hdr}: '{key}' are not supported; remove them from the "
                                 "data or the header")
    dtype = np.dtype(_ENVI_DTYPES[code]).newbyteorder(">" if order else "<")
    return {"header": h, "lines": lines, "samples": samples, "bands": bands, "offset": offset,
            "dtype": dtype, "interleave": interleave}


def _envi_repeated_keys(hdr):
    """Keys the header's text gives more than once (at the top level, case-insensitive)."""
    try:
        text = Path(hdr).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return []
    # walked as Spectral Python reads it: lines without "=" and comment lines (";") skipped,
    # a value opened by "{" running to the first line that ends in "}"
    from collections import Counter

    keys, lines = Counter(), text.splitlines()[1:]  # the first line is "ENVI"
    i, n = 0, len(lines)
    while i < n:  # one pass: a header of 40 000 keys took a minute popping from a list's front
        line, i = lines[i], i + 1
        if "=" not in line or line.startswith(";"):
            continue
        key, _, val = line.partition("=")
        keys[key.strip().lower()] += 1
        val = val.strip()
        if val.startswith("{"):
            while not val.endswith("}") and i < n:
                line, i = lines[i], i + 1
                if not line.startswith(";"):
                    val = line.strip()  # only whether the value has closed matters
    return sorted(k for k, c in keys.items() if k and c > 1)


def _envi_values(h, hdr, bands):
    """What the header says the stored numbers mean, per band: ``(gain, offset, scale, bad)``
    (value = (stored * gain + offset) / scale; ``bad`` the bands ``bbl`` marks 0), or None
    when it says nothing (the stored numbers are the values)."""
    def per_band(key, default):
        v = _envi_list(h, key, hdr)
        if v is None:
            return np.full(bands, default)
        if v.size == 1:
            return np.full(bands, float(v[0]))
        if v.size != bands:
            raise ValueError(f"{hdr}: '{key}' has {v.size} values for {bands} bands; fix the "
                             "header")
        return v

    keys = ("data gain values", "data offset values", "reflectance scale factor", "bbl")
    if not any(k in h for k in keys):
        return None
    gain, offset = per_band("data gain values", 1.0), per_band("data offset values", 0.0)
    scale = _envi_list(h, "reflectance scale factor", hdr)
    scale = 1.0 if scale is None or scale.size == 0 else float(scale[0])
    bbl = per_band("bbl", 1.0)
    if not (np.all(np.isfinite(gain)) and np.all(np.isfinite(offset))
            and math.isfinite(scale) and scale > 0 and np.all(np.isin(bbl, (0.0, 1.0)))):
        raise ValueError(f"{hdr}: the data gain / offset values, reflectance scale factor or "
                         "bbl are not finite numbers (gains and offsets), a number > 0 (the "
                         "scale factor) and 0 or 1 per band (bbl); fix the header")
    if np.any(gain == 0):
        raise ValueError(f"{hdr}: 'data gain values' is 0 for band {int(np.argmax(gain == 0))}, "
                         "which makes every value of it the band's offset: no measurement; "
                         "fix the header")
    if np.all(bbl == 0):
        raise ValueError(f"{hdr}: 'bbl' marks every band bad: nothing is left to read; fix "
                         "the header")
    if np.all(gain == 1) and np.all(offset == 0) and scale == 1 and np.all(bbl == 1):
        return None  # as stored
    return gain, offset, scale, bbl == 0


def _apply_envi_values(data, values, ignore):
    """The stored numbers as the header says to read them: ``(stored * gain + offset) /
    scale``, bad bands (bbl 0) and pixels equal to the data ignore value (in stored units) NaN.
    ``data`` is a numpy or dask array, ``(y, x, band)``."""
    import dask.array as da

    gain, offset, scale, bad = values
    kind = np.result_type(data.dtype, np.float32)
    out = (data.astype(kind) * gain.astype(kind) + offset.astype(kind)) / kind.type(scale)
    if not np.any(bad) and ignore is None:
        return out
    drop = bad if ignore is None else (data == ignore) | bad
    where = da.where if isinstance(out, da.Array) else np.where
    return where(drop, kind.type(np.nan), out)


def _same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _envi_data_file(hdr, interleave):
    names = [*_ENVI_EXTS, f".{interleave}"]
    candidates = [hdr.with_suffix(e) for e in names] + \
                 [hdr.with_suffix(e.upper()) for e in names if e]
    found = []
    for c in candidates:
        if os.path.lexists(c) and not os.path.isdir(c) and c != hdr and \
                not any(_same_file(c, f) for f in found):
            found.append(c)
    if len(found) > 1:  # Spectral Python would take the first: say so rather than guess
        raise ValueError(f"{hdr}: more than one data file could be this header's ("
                         f"{', '.join(f.name for f in found)}); give the data file itself "
                         "instead of the header, or move the others away")
    if found:
        return found[0]
    looked = ", ".join(c.name for c in candidates[:len(names)])
    raise ValueError(f"{hdr}: cannot read the data: no data file next to the header (looked "
                     f"for {looked}); put the data file beside it")


#: The nominal wavelengths (nm) of an image of a correction's result whose every pixel has its
#: own (:mod:`snapcorr.files.envi_result`): a header key of snapcorr's, which other readers
#: leave alone (given as ``wavelength``, they would plot each pixel at the nominal ones), and
#: snapcorr reads as the bands' nominal wavelengths, as the result's ``.nc`` holds them.
NOMINAL_KEY = "snapcorr nominal wavelength"


def _envi_list(h, key, hdr):
    if key not in h:
        return None
    raw = h[key]
    items = raw if isinstance(raw, list) else [raw]
    try:
        return np.array([float(v) for v in items if str(v).strip() != ""])
    except ValueError:
        raise ValueError(f"{hdr}: '{key}' holds something that is not a number: "
                         f"{', '.join(map(str, items))[:80]}") from None


def _read_envi(hdr, data_file, chunks, what="cube"):
    """The cube of an ENVI header (``data_file`` its data when given, else found next to it);
    ``chunks`` None (read whole), a dict by dim or :class:`~snapcorr.files.storage._Rows`."""
    p = _envi_header(hdr)
    h = p["header"]
    data_file = data_file or _envi_data_file(hdr, p["interleave"])
    try:
        check_input(data_file, what="ENVI data file")
    except FileNotFoundError as err:
        raise ValueError(f"{hdr}: cannot read the data: {err}") from None
    except ValueError as err:
        raise ValueError(f"{hdr}: cannot read the data: {err}") from None
    try:
        with open(data_file, "rb"):
            pass
    except OSError as err:
        raise ValueError(f"{hdr}: cannot read its data file {data_file.name}: "
                         f"{err.strerror or err}; check that it is readable (chmod u+r)") from None
    rows, cols, bands, dtype = p["lines"], p["samples"], p["bands"], p["dtype"]
    expected = p["offset"] + rows * cols * bands * dtype.itemsize
    size = os.path.getsize(data_file)
    if size != expected:
        raise ValueError(
            f"{hdr}: the data file {data_file.name} has {size} bytes but the header "
            f"({rows} x {cols} x {bands}, {dtype.name}, offset {p['offset']}) needs "
            f"{expected}; it is truncated or the header does not describe it"
        )
    _check_byte_order(hdr, data_file, dtype, p["offset"], rows * cols * bands)
    ignore = None
    if "data ignore value" in h:
        try:
            ignore = float(h["data ignore value"])
        except (TypeError, ValueError, OverflowError):
            said = _said("data ignore value", h["data ignore value"])
            raise ValueError(f"{hdr}: {said} is not a number; fix the header") from None
    values = _envi_values(h, hdr, bands)
    if values is not None and what != "cube":
        raise ValueError(f"{hdr}: its data gain / offset values, reflectance scale factor or "
                         f"bbl change the stored numbers, and a {what} is used as stored (its "
                         "saturation is in stored numbers; flat-fielding cancels a gain and "
                         "offset shared with the references): remove them from the header")
    # chunks="rows": blocks of the values as they come out (floats once the header's gains
    # and offsets are applied)
    shape = (rows, cols, bands)
    out = dtype if values is None else np.result_type(dtype.newbyteorder("="), np.float32)
    chunks = _resolve_chunks(chunks, shape, out)
    # Spectral Python parsed and checked the header (_envi_header); the data are read in row
    # blocks with plain file reads (blockfile), never through a whole-file memory map
    data = _from_file(data_file, dtype, shape, p["offset"], p["interleave"], chunks)
    attrs = {"source": str(hdr), "envi_interleave": p["interleave"]}
    if values is not None:  # applied as the header says, the ignored pixels NaN
        data = _apply_envi_values(data, values, ignore)
        attrs["envi_values_applied"] = ("(stored * data gain values + data offset values) / "
                                        "reflectance scale factor; bbl 0 bands and the data "
                                        "ignore value NaN")
    elif ignore is not None:
        attrs["data_ignore_value"] = ignore
    wavelength, units = _envi_list(h, "wavelength", hdr), h.get("wavelength units")
    if wavelength is None and NOMINAL_KEY in h:  # snapcorr's result: its bands' nominal ones
        wavelength, units = _envi_list(h, NOMINAL_KEY, hdr), "nm"
    found = _File(hdr, "envi", data, wavelength=wavelength, units=units,
                  fwhm=_envi_list(h, "fwhm", hdr), fwhm_units=h.get("wavelength units"),
                  name=h.get("snapcorr name"))
    stored = h.get("snapcorr attrs")
    if isinstance(stored, str) and stored.startswith(JSON_PREFIX):
        try:
            decoded = parse_json(stored[len(JSON_PREFIX):])
        except ValueError:
            raise ValueError(f"{hdr}: 'snapcorr attrs' is not valid JSON") from None
        if not isinstance(decoded, dict):  # a list or a number has no attribute names
            raise ValueError(f"{hdr}: 'snapcorr attrs' must hold a JSON object "
                             f"({{\"name\": value, ...}}), got "
                             + (_JSON_KINDS.get(type(decoded), "a value") + " "
                                + shown(decoded) if decoded is not None else "null"))
        attrs.update(decoded)
    found.attrs = attrs
    for name in POSITION_DIMS:
        key = "snapcorr " + name.replace("_", " ")
        if f"{key} offset" in h:
            found.positions[name] = {"offset": _envi_numbers(h, f"{key} offset", hdr),
                                     "step": _envi_numbers(h, f"{key} step", hdr, scalar=True)}
        elif key in h:
            values = _envi_numbers(h, key, hdr)
            n = rows if name == "sensor_row" else cols
            if len(values) != n * bands:
                raise ValueError(f"{hdr}: '{key}' has {len(values)} values; {n} x {bands} "
                                 "are needed")
            found.positions[name] = {"values": np.reshape(values, (n, bands)).tolist()}
    return found


#: Values sampled from an ENVI data file to check its header's byte order (at its start and
#: middle); and how much rougher, or how much less often ordinary, the stated order must read
#: than the other before it is refused.
_ORDER_SAMPLE = 32768
_ORDER_FACTOR = 20.0


def _check_byte_order(hdr, data_file, dtype, offset, n):
    """Refuse a header whose ``byte order`` is evidently the wrong one for its data: read the
    other way, a sample of floats spans under 4 decades (its magnitudes' interquartile)
    where as stated it spans over 8 or is mostly not finite (a little-endian float32 read
    big-endian gives 1e-7 beside 2e23 and +-2.4e38, NaN); a
    sample of integers is at least :data:`_ORDER_FACTOR` times smoother (the median step
    between neighbouring values: a swapped byte order turns a low byte's noise into a high
    byte's). Data that read alike either way (constant, one-byte values) are not judged."""
    if dtype.itemsize < 2 or n == 0:
        return
    take = min(_ORDER_SAMPLE, n)
    parts = []
    with open(data_file, "rb") as fh:
        for start in sorted({0, max(0, n // 2 - take // 2)}):
            fh.seek(offset + start * dtype.itemsize)
            parts.append(np.frombuffer(fh.read(take * dtype.itemsize), dtype))
    stated = np.concatenate(parts).astype(dtype.newbyteorder("="))  # the values, as stated
    other = stated.byteswap()  # the same bytes, read the other way
    if dtype.kind == "f":
        def decades(v):  # the spread of the values' magnitudes: the interquartile, in decades
            with np.errstate(all="ignore"):
                a = np.abs(v.astype(np.float64))
                a = a[np.isfinite(a) & (a > 0)]
                if a.size < 0.5 * v.size:
                    return math.inf
                q = np.percentile(np.log10(a), [25, 75])
            return float(q[1] - q[0])

        wrong = decades(stated) > 8 and decades(other) < 4
    elif dtype.kind in "iu":
        # as stated, a low byte that never changes: values shifted into the high bytes (8-bit
        # data left-aligned), which the other reading makes smooth too; not judged
        if np.unique(stated.astype(np.int64) & 0xFF).size == 1:
            return

        def rough(v):
            return float(np.median(np.abs(np.diff(v.astype(np.float64)))))

        a, b = rough(stated), rough(other)
        wrong = a > _ORDER_FACTOR * max(b, 1.0)
    else:
        return
    if wrong:
        said = "0 (little-endian)" if dtype.byteorder == "<" or (
            dtype.byteorder == "=" and sys.byteorder == "little") else "1 (big-endian)"
        raise ValueError(
            f"{hdr}: its 'byte order' {said} does not fit the data in {data_file.name}: read "
            f"that way its {dtype.name} values are "
            + ("spread over more than 8 decades" if dtype.kind == "f" else
               f"{_ORDER_FACTOR:g} times rougher than read the other way")
            + ", and read the other way they are ordinary; fix the header's 'byte order'")


#: What a JSON document that is no object holds, in JSON's words.
_JSON_KINDS = {list: "an array", str: "a string", int: "a number", float: "a number",
               bool: "true or false", type(None): "null"}


def _envi_numbers(h, key, hdr, scalar=False):
    raw = h.get(key)
    items = raw if isinstance(raw, list) else [raw]
    try:
        values = [int(v) if re.fullmatch(r"\s*[-+]?\d+\s*", str(v)) else float(v)
                  for v in items]
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{hdr}: '{key}' must hold numbers, got {raw!r:.80}") from None
    if scalar:
        if len(values) != 1:
            raise ValueError(f"{hdr}: '{key}' must be one number, got {raw!r:.80}")
        return values[0]
    return values


# -- writing ---------------------------------------------------------------------------------


def _envi_position_keys(meta):
    """The sensor positions of ``meta`` (see :func:`snapcorr.files.attrs._positions`) as ENVI
    header keys."""
    header = {}
    for name in POSITION_DIMS:
        if name in meta:
            key = "snapcorr " + name.replace("_", " ")
            spec = meta[name]
            if "offset" in spec:
                header[f"{key} offset"] = spec["offset"]
                header[f"{key} step"] = spec["step"]
            else:
                header[key] = [v for row in spec["values"] for v in row]
    return header


def _write_envi(cube, path, meta, *, interleave):
    from spectral.io import envi

    header = {"description": f"snapcorr cube {meta['name']}",
              "wavelength": meta["wavelength_nm"], "wavelength units": "nm",
              "snapcorr version": _version(), "snapcorr name": meta["name"],
              "snapcorr attrs": JSON_PREFIX + json.dumps(meta["attrs"], ensure_ascii=True)}
    if "fwhm_nm" in meta:
        header["fwhm"] = meta["fwhm_nm"]
    ignore = meta["attrs"].get("data_ignore_value")
    if isinstance(ignore, int | float) and not isinstance(ignore, bool) and math.isfinite(ignore):
        header["data ignore value"] = ignore
    header.update(_envi_position_keys(meta))
    data = np.asarray(cube.values)

    def write(folder):
        with _quiet_spectral():
            envi.save_image(str(folder / path.name), data, dtype=data.dtype,
                            interleave=interleave, ext=".raw", metadata=header, force=True)

    atomic_write_files([path.with_suffix(".raw"), path], write)


def _check_envi_writable(cube, path, interleave):
    """ENVI's limits: an interleave, a type ENVI has, no other data file its readers would
    take for the header's."""
    from spectral.io import envi

    dtype = cube.dtype
    if interleave not in ("bsq", "bil", "bip"):
        raise ValueError(f"interleave must be bsq, bil or bip, got {interleave!r}")
    if dtype.char not in envi.dtype_to_envi:
        kind = "16-bit float" if dtype == np.float16 else str(dtype)
        raise ValueError(f"ENVI has no {kind} type; convert the cube "
                         "(cube.astype('float32')) or write .exr, .nc or .zarr")
    others = [path.with_suffix(e) for e in _ENVI_EXTS if e != ".raw"]
    others = [o for o in others if os.path.lexists(o) and not os.path.isdir(o)]
    if others:
        raise ValueError(f"{others[0]} exists next to {path.name}, and ENVI readers would "
                         f"take it as the header's data instead of {path.stem}.raw; move "
                         "it away or choose another name")


def _envi_targets(path):
    """A header and its data file, ``cube.hdr`` and ``cube.raw``."""
    path = Path(path)
    return [path, path.with_suffix(".raw")]


def _read(path, data_file, chunks, what, drop_alpha):
    return _read_envi(path, data_file, chunks, what)


#: ENVI: a text header and a raw data file (its mark: the header's ``snapcorr written by``).
ENVI = FileFormat("envi", (".hdr",), _read, _write_envi, targets=_envi_targets,
                  marked_as=("envi", "envi-data"), check_writable=_check_envi_writable)
