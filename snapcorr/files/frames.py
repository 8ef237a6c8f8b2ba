"""Streams of raw frames: a snapshot camera films, so its data are stacks ``(frame, y, x)``.

:func:`read_frames` opens a stack lazily, one frame per dask block, from

- a ``.zarr`` store or ``.nc`` file holding a 3-D variable (frames first; a plain Zarr array
  without xarray's dimension names too), or a 3-D ``.npy``;
- a multi-page TIFF, one frame per page (read through OpenImageIO page by page);
- a folder of frames, one file each (any format :func:`~snapcorr.cube.read_frame` reads),
  taken in the order of their names (numbers in names compared as numbers, decimals and
  signs included: :func:`natural_order`; recorded as ``frame_order``); hidden files, whose
  names start with a point (``.t0.npy``), are left out.

Nothing is read until computed (only the files' headers), so memory does not grow with the
number of frames. A ``frame`` coordinate (times, say) of a ``.zarr`` or ``.nc`` is kept.
"""

from __future__ import annotations

import itertools
import re
from decimal import Decimal
from pathlib import Path

import numpy as np
import xarray as xr

from .api import read_frame
from .datasets import _IncompleteStore, _open_dataset, _refuse_missing_chunks, refuse_packed_counts
from .reading import check_input, open_image
from .registry import format_by_suffix

__all__ = ["natural_order", "read_frames"]

#: Files a folder of frames may hold (others, such as ENVI's data files, are passed over).
FRAME_SUFFIXES = (".npy", ".tif", ".tiff", ".exr", ".hdr")


#: A number in a file name: digits, with a decimal part where a point (or a comma) is followed
#: by digits, and an exponent (``1e-3``); the sign before it kept apart (whether it is a sign
#: is decided over all the names).
_NUMBER = re.compile(r"([+-]?)(\d+(?:[.,]\d+)?(?:[eE][+-]?\d+)?)")
#: Three or more groups of digits joined by points (``12.5.3``, ``1.10.0``): no decimal number;
#: each group is read as a whole number, the points as separators.
_CHAIN = re.compile(r"\d+(?:\.\d+){2,}")
#: How a folder's frames are ordered, recorded with them (``frame_order``).
FRAME_ORDER = ("by name, numbers compared as numbers, exactly (decimal points and exponents "
               "read as such, a decimal comma where every name's has as many digits after it, "
               "digits joined by several points as whole numbers where every name's groups "
               "have as many digits, digits after a point with no digit before it (t.5) where "
               "reading the point as a decimal point and as a separator give one order, or as "
               "numbers after a separator where two would be one decimal (.1, .10); a '-' "
               "or '+' before a number read as its sign only where names differ by it, and "
               "where both readings give one order); hidden files (names starting with '.') "
               "left out")


_ZERO = Decimal(0)


def _tokens(name):
    """``name`` as text and ``(sign, digits)`` pieces, the text in lower case; the groups of
    a chain of points (:data:`_CHAIN`) each a whole number. Digits of any script count
    (a full-width ten is ten)."""
    out, at = [], 0
    for chain in _CHAIN.finditer(name):
        out.extend(_number_tokens(name[at:chain.start()]))
        for k, group in enumerate(chain.group().split(".")):
            out[-1:] = [out[-1] + ("." if k else "")] if out else ["."]
            out.extend([("", group), ""])
        at = chain.end()
    rest = _number_tokens(name[at:])
    if out:
        out[-1:] = [out[-1] + rest[0]]
        out.extend(rest[1:])
        return out
    return rest


def _number_tokens(text):
    out, at = [], 0
    for m in _NUMBER.finditer(text):
        out.append(text[at:m.start()].lower())
        out.append((m.group(1), m.group(2)))
        at = m.end()
    out.append(text[at:].lower())
    return out


def _chain_widths(names):
    """Two names whose chains of points (:data:`_CHAIN`) have groups of different numbers of
    digits at one place (the ``j``-th group of the ``i``-th chain), or None: there the
    decimal and the separate readings of the points may order them differently."""
    seen = {}
    for n in names:
        for i, chain in enumerate(_CHAIN.finditer(n)):
            for j, group in enumerate(chain.group().split(".")[1:]):
                other = seen.setdefault((i, j), (len(group), n))
                if other[0] != len(group):
                    return other[1], n
    return None


def natural_order(names):
    """``names`` in natural order: numbers in them compared as numbers.

    Decimal parts count (``t0.25`` before ``t0.5`` before ``t1``), and so do exponents
    (``1e-3`` before ``1e-2``); numbers are compared exactly (nanosecond times of 19 digits
    stay apart). A decimal comma (``t0,25``) is read as one where every name has as many
    digits after its comma, which orders the names the same whether it is a decimal comma or
    a separator; otherwise the order is ambiguous, and refused. A ``-`` or ``+`` right
    before a number is its sign only where the names differ by it at that place (``z-0.5``,
    ``z+0``, ``z+0.5``); where every name has it (``frame-1``, ``2026-12-01``) it is a
    separator; in names of different forms (``x-1``, ``x0``, ``x1_2``) it is refused where
    reading it as a sign and as a separator give different orders. Digits joined by several
    points (``12.5.3``, ``1.10.0``) are no decimal: each group is a whole number, and names
    whose groups at one place differ in their numbers of digits are refused (there the decimal
    and the separate readings may differ). Digits after a point with no digit before it
    (``t.5``) may be a decimal (0.5) or a number after a separator (5): names are refused
    where the two readings order them differently (``t.5``, ``t.25``, ``t1``) and taken where
    they agree (``f.001``, ``f.002``) or where only one can be meant (``img.1`` ... ``img.10``,
    equal as decimals, are numbers after a separator). Digits of
    any script count (full-width, Arabic-Indic
    digits). Names whose numbers are equal but written differently (``f1``, ``f01``) are
    ambiguous, and refused.

    Parameters
    ----------
    names : sequence of str

    Returns
    -------
    list of str

    Raises
    ------
    ValueError
        Two names that compare equal.
    """
    tokens = [_tokens(n) for n in names]
    after_comma = {(n, len(d.partition(",")[2].split("e")[0].split("E")[0]))
                   for n, t in zip(names, tokens, strict=True) for _, d in t[1::2] if "," in d}
    if len({k for _, k in after_comma}) > 1:
        shown_ = sorted(after_comma, key=lambda nk: nk[1])
        raise ValueError(f"frames {shown_[0][0]!r} and {shown_[-1][0]!r}: a comma between digits "
                         "may be a decimal comma or a separator, and with different numbers of "
                         "digits after it the two orders differ; rename them (decimal points, "
                         "or zero-padded numbers)")
    differ = _chain_widths(names)
    if differ is not None:
        raise ValueError(f"frames {differ[0]!r} and {differ[1]!r}: digits joined by several "
                         "points may be decimals or numbers apart (a time 12.5.3, a version "
                         "1.10.0), and with different numbers of digits after a point the two "
                         "orders differ; rename them (zero-padded numbers)")
    signed = set()  # number places (by position in the names' pieces) whose sign varies
    for k in range(1, max((len(t) for t in tokens), default=0), 2):
        if len({t[k][0].replace("+", "") for t in tokens if len(t) > k}) > 1:
            signed.add(k)
    same_structure = len({len(t) for t in tokens}) == 1
    if signed and not same_structure:  # a sign, or a separator: refused where they disagree
        as_signs = _ordered(names, tokens, signed)
        if as_signs != _ordered(names, tokens, set()):
            raise ValueError(f"frames {as_signs[0]!r} and {as_signs[-1]!r}: a '-' or '+' "
                             "before a number may be its sign or a separator, and in names of "
                             "different forms the two orders differ; rename them (the same "
                             "form for every name)")
    order = _ordered(names, tokens, signed)
    _refuse_point_led_ambiguity(names, tokens, signed, order)
    return order


def _point_led(tokens):
    """The positions of ``tokens`` (one name's pieces) whose number follows a point with no
    digit before it (``t.5``, ``.25``): no chain's group (text ``"."`` between two numbers)
    and no sign between the point and the digits."""
    return [k for k in range(1, len(tokens), 2)
            if tokens[k - 1].endswith(".") and not tokens[k][0]
            and not (tokens[k - 1] == "." and k >= 2)]


def _refuse_point_led_ambiguity(names, tokens, signed, order):
    """Refuse names whose point before digits (``t.5``, ``t.25``, ``t1``) is read as a
    decimal point and as a separator in two different orders; where the decimal reading makes
    two names equal (``img.1`` and ``img.10``) it cannot be meant, and the separator's stands.
    ``order`` is the separator reading's."""
    places = [_point_led(t) for t in tokens]
    if not any(places):
        return
    as_decimal = []
    for t, ks in zip(tokens, places, strict=True):
        t = list(t)
        for k in ks:
            digits = t[k][1]
            if digits.isdigit():
                t[k - 1], t[k] = t[k - 1][:-1], ("", "0." + digits)
        as_decimal.append(t)
    try:
        other = _ordered(names, as_decimal, signed)
    except _SameNumber:  # two names equal as decimals (img.1, img.10): no decimals, then,
        return  # but numbers after a separator, the one reading left
    if other == order:
        return
    a, b = next((x, y) for x, y in zip(order, other, strict=True) if x != y)
    raise ValueError(f"frames {a!r} and {b!r}: digits after a point with no digit before it "
                     "(t.5) may be a decimal (0.5) or a number after a separator (5), and the "
                     "two readings order them differently; rename them (t0.5, or numbers after "
                     "the point of as many digits, zero-padded)")


def _ordered(names, tokens, signed):
    """``names`` sorted by their pieces (``tokens``), a number's sign read as one at the
    places ``signed``; two names that compare equal are refused."""

    def key(t):
        out = []
        for k, piece in enumerate(t):
            if k % 2 == 0:
                out.append((0, piece, _ZERO))
                continue
            sign, digits = piece
            value = Decimal(digits.replace(",", "."))  # exact: 19-digit times stay apart
            if k in signed:
                out.append((1, "", value.copy_negate() if sign == "-" else value))
            else:  # the sign is part of the text before
                out.append((0, sign, _ZERO))
                out.append((1, "", value))
        return out

    keyed = sorted(zip((key(t) for t in tokens), names, strict=True), key=lambda kv: kv[0])
    for (k0, a), (k1, b) in itertools.pairwise(keyed):
        if k0 == k1:
            raise _SameNumber(a, b, f"frames {a!r} and {b!r} have the same number in their "
                              "names: their order is ambiguous; rename them (e.g. zero-padded "
                              "numbers) so that each name's number differs")
    return [n for _, n in keyed]


class _SameNumber(ValueError):
    """Two frame names that compare equal (``names``)."""

    def __init__(self, a, b, message):
        super().__init__(message)
        self.names = (a, b)


def _refuse_one_frame_twice(found):
    """Refuse two files of one name but for the suffix (``f1.npy`` and ``f1.tif``, in any
    case): one frame saved twice would be streamed twice, as two frames taken."""
    stems = {}
    for name in sorted(found):
        stem = Path(name).stem.lower()
        if stem in stems:
            raise ValueError(f"{stems[stem]} and {name} in the folder of frames differ only in "
                             "their suffix: one frame in two formats would be streamed twice; "
                             "keep one of them")
        stems[stem] = name


def read_frames(path, *, frames_per_chunk=1):
    """A stack of raw 2-D frames, lazily (module docstring).

    Parameters
    ----------
    path : str or Path
        A ``.zarr`` or ``.nc`` holding a 3-D variable, a 3-D ``.npy``, a multi-page TIFF, or a
        folder of frame files.
    frames_per_chunk : int
        Frames per dask block (each block holds whole frames).

    Returns
    -------
    xarray.DataArray
        Dims ``("frame", "y", "x")``, dask-backed, named ``"frames"``; attrs ``source`` and
        ``frame_files`` (for a folder).

    Raises
    ------
    ValueError
        No frames, frames of different sizes or types, a variable that is not 3-D, a page with
        more than one channel, or what the readers refuse.
    """
    import dask.array as da

    path = Path(path)
    per = int(frames_per_chunk)
    if per < 1:
        raise ValueError(f"frames_per_chunk must be at least 1, got {frames_per_chunk!r}")
    attrs = {"source": str(path)}
    coords = {}
    if not path.exists() and not path.is_symlink():
        raise FileNotFoundError(f"no such file or folder of frames: {path}")
    if path.is_dir() and path.suffix.lower() != ".zarr":
        check_input(path, directory=True, what="folder of frames")
        # hidden files (a viewer's or a copy's, ".t0.npy") are no frames taken
        found = {p.name: p for p in path.iterdir()
                 if p.suffix.lower() in FRAME_SUFFIXES and not p.name.startswith(".")}
        _refuse_one_frame_twice(found)
        files = [found[n] for n in natural_order(list(found))]
        for p in files:  # a frame that cannot be read is an error, never left out
            if not p.is_file():
                raise ValueError(f"{p} is not a regular file (a broken link, a folder or a "
                                 "pipe?); a folder of frames holds frame files only")
        if not files:
            raise ValueError(f"{path} holds no frame files ({', '.join(FRAME_SUFFIXES)})")
        arrays = []
        for f in files:
            frame = read_frame(f, chunks={})
            arrays.append(frame.data.rechunk(-1))
            if arrays[-1].shape != arrays[0].shape or arrays[-1].dtype != arrays[0].dtype:
                raise ValueError(f"{f} is {arrays[-1].shape[0]} x {arrays[-1].shape[1]} "
                                 f"{arrays[-1].dtype} but {files[0].name} is "
                                 f"{arrays[0].shape[0]} x {arrays[0].shape[1]} "
                                 f"{arrays[0].dtype}: every frame must match")
        data = da.stack(arrays)
        attrs["frame_files"] = [p.name for p in files]
        attrs["frame_order"] = FRAME_ORDER
    else:
        found = format_by_suffix(path.suffix)
        read_stack = _STACK_READERS.get(found.name if found is not None else None)
        if read_stack is None:
            raise ValueError(f"{path}: a stream of frames is a .zarr, .nc, .npy, multi-page "
                             ".tif or a folder of frames")
        data, coords = read_stack(path, coords)
    if 0 in data.shape:
        raise ValueError(f"{path} holds no frame ({data.shape[0]} frames of {data.shape[1]} x "
                         f"{data.shape[2]} px)")
    if data.dtype.kind not in "iuf":
        raise ValueError(f"{path} holds {data.dtype} values; frames are numbers (counts)")
    data = data.rechunk({0: per, 1: -1, 2: -1})
    return xr.DataArray(data, dims=("frame", "y", "x"), coords=coords, attrs=attrs,
                        name="frames")


def _xarray_stack(path, fmt):
    check_input(path, directory=fmt == "zarr", what="stream")
    try:
        ds = _open_dataset(path, fmt, {})
    except _IncompleteStore:
        raise
    except Exception as err:  # the libraries' own types: perhaps a plain zarr array
        if fmt != "zarr":
            raise ValueError(f"{path}: cannot read it as netcdf: {type(err).__name__}") \
                from None
        return _plain_zarr(path, err), {}
    not_frames = ("band", "wavelength", "y", "x")
    three = [v for v in ds.data_vars if ds[v].ndim == 3]
    stacks = [v for v in three if ds[v].dims[-2:] == ("y", "x")
              and ds[v].dims[0] not in not_frames]
    if len(stacks) > 1:
        raise ValueError(f"{path} holds {len(stacks)} stacks of frames ({', '.join(stacks)}); "
                         "a stream holds one (frame, y, x) variable")
    if not stacks:
        if len(three) == 1 and not set(ds[three[0]].dims) & set(not_frames):
            stacks = three  # dims of other names: frames first, then rows and columns
        else:
            found = ", ".join(f"{v} {ds[v].dims}" for v in three) or "no 3-D variable"
            raise ValueError(f"{path} holds {found}; a stream of frames is one variable of "
                             "dims (frame, y, x) (a cube's bands are not frames)")
    var = ds[stacks[0]]
    refuse_packed_counts(var, path, counts=True)
    first = var.dims[0]
    coords = {c: ("frame", var[c].values, var[c].attrs) for c in var.coords
              if var[c].dims == (first,)}
    return var.data, coords


def _npy_stack(path):
    """A 3-D ``.npy`` (frame, y, x) read a frame at a time, never whole (a 2-D one: a stream
    of one frame)."""
    from .npy import _npy_layout
    from .storage import _from_file, _lazy_or_loaded

    check_input(path, what="stream")
    layout = _npy_layout(path)
    if layout is not None:
        shape, dtype, offset = layout
        if len(shape) not in (2, 3):
            raise ValueError(f"{path} holds a {len(shape)}-D array; a stream is (frame, y, x)")
        shape = shape if len(shape) == 3 else (1, *shape)
        return _from_file(path, dtype, shape, offset, "bip", {"y": 1, "x": -1, "band": -1})
    try:
        data = np.load(path, mmap_mode="r", allow_pickle=False)
    except Exception as err:  # numpy raises several types for a bad or empty file
        raise ValueError(f"{path}: not a numpy array file ({type(err).__name__})") from None
    if not isinstance(data, np.ndarray) or data.ndim not in (2, 3) or data.dtype.kind not in \
            "iuf":
        raise ValueError(f"{path}: a stream is a 3-D (frame, y, x) array of numbers")
    data = data if data.ndim == 3 else data[None]
    return _lazy_or_loaded(data, {"y": 1}, ("y", "x", "band"), source=path)


def _plain_zarr(path, first_error):
    """A Zarr array without xarray's dimension names."""
    import dask.array as da
    import zarr

    try:
        arr = zarr.open_array(str(path), mode="r")
    except Exception:  # the libraries' own types: neither a dataset nor an array
        raise ValueError(f"{path}: cannot read it as zarr: {type(first_error).__name__}: "
                         f"{str(first_error).splitlines()[0] if str(first_error) else ''}") \
            from None
    if arr.ndim != 3:
        raise ValueError(f"{path} holds a {arr.ndim}-D array; a stream is (frame, y, x)")
    _refuse_missing_chunks(path, [("the array", path, arr)], cf=False)  # read as stored, unmasked
    return da.from_zarr(arr)


def _page(path, index, shape, dtype):
    inp = open_image(path)
    if inp is None or not inp.seek_subimage(index, 0):
        raise ValueError(f"{path}: cannot read page {index + 1}")
    try:
        pixels = inp.read_image(index, 0, 0, 1, "unknown")
    finally:
        inp.close()
    if pixels is None:
        raise ValueError(f"{path}: cannot read page {index + 1}")
    return np.asarray(pixels, dtype=dtype).reshape(shape)


#: OpenImageIO's pixel types as numpy's.
_OIIO_TYPES = {"uint8": np.uint8, "int8": np.int8, "uint16": np.uint16, "int16": np.int16,
               "uint": np.uint32, "int": np.int32, "uint32": np.uint32, "int32": np.int32,
               "half": np.float16, "float": np.float32,
               "double": np.float64}


def _tiff_pages(path):
    """Every page of a TIFF as a lazily read frame (one channel each, all alike)."""
    import dask
    import dask.array as da
    import OpenImageIO as oiio

    check_input(path, what="stream")
    inp = open_image(path)
    if inp is None:
        raise ValueError(f"{path}: cannot read it as tiff: {oiio.geterror() or 'no image'}")
    specs = []
    try:
        while inp.seek_subimage(len(specs), 0):
            spec = inp.spec()
            specs.append((spec.height, spec.width, spec.nchannels, str(spec.format)))
    finally:
        inp.close()
    if not specs:
        raise ValueError(f"{path} holds no page")
    for i, s in enumerate(specs, start=1):
        if s[2] != 1:
            raise ValueError(f"{path}: page {i} has {s[2]} channels; a frame is one channel")
        if s != specs[0]:
            raise ValueError(f"{path}: page {i} is {s[1]} x {s[0]} {s[3]} but page 1 is "
                             f"{specs[0][1]} x {specs[0][0]} {specs[0][3]}: every frame must "
                             "match")
    shape = specs[0][:2]
    dtype = _OIIO_TYPES.get(specs[0][3])
    if dtype is None:
        raise ValueError(f"{path}: pages of {specs[0][3]} values; frames are integers or floats")
    return da.stack([da.from_delayed(dask.delayed(_page)(path, i, shape, dtype), shape, dtype)
                     for i in range(len(specs))])


def _dataset_stack(fmt):
    return lambda path, coords: _xarray_stack(path, fmt)


#: Format name -> how a stream of frames is read from one file of it: ``(data, coords)``.
_STACK_READERS = {
    "zarr": _dataset_stack("zarr"),
    "netcdf": _dataset_stack("netcdf"),
    "tiff": lambda path, coords: (_tiff_pages(path), coords),
    "npy": lambda path, coords: (_npy_stack(path), coords),
}
