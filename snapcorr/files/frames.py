"""Streams of raw frames: a snapshot camera films, so its data are stacks ``(frame, y, x)``.

:func:`read_frames` opens a stack lazily, one frame per dask block, from

- a ``.zarr`` store or ``.nc`` file holding a 3-D variable (frames first; a plain Zarr array
  without xarray's dimension names too), or a 3-D ``.npy``;
- a multi-page TIFF, one frame per page (read through OpenImageIO page by page);
- a folder of frames, one file each (any format :func:`~snapcorr.cube.read_frame` reads),
  all of one format, taken in the order of their names without the suffix (numbers in names
  compared as numbers, decimals and signs included, names refused where two readings order
  them differently: :func:`natural_order`; recorded as ``frame_order``); hidden files, whose
  names start with a point (``.t0.npy``), are left out.

Nothing is read until computed (only the files' headers), so memory does not grow with the
number of frames. A ``frame`` coordinate (times, say) of a ``.zarr`` or ``.nc`` is kept.
"""

from __future__ import annotations

import itertools
import re
import unicodedata
from pathlib import Path

import numpy as np
import xarray as xr

from .api import read_frame
from .chunks import _IncompleteStore, _refuse_a_chunk_of_another_type, _refuse_missing_chunks
from .datasets import _open_dataset, refuse_packed_counts
from .reading import check_input, open_image
from .registry import format_by_suffix

__all__ = ["natural_order", "read_frames"]

#: Files a folder of frames may hold (others, such as ENVI's data files, are passed over).
FRAME_SUFFIXES = (".npy", ".tif", ".tiff", ".exr", ".hdr")


#: A number in a file name: digits, with a decimal part where a point (or a comma) is followed
#: by digits, and an exponent (``1e-3``); the sign before it kept apart (whether it is a sign
#: is decided over all the names). Possessive: a long run of digits is read once.
_NUMBER = re.compile(r"([+-]?)(\d++(?:[.,]\d++)?+(?:[eE][+-]?\d++)?+)")
#: The same without exponents: an ``e`` between digits read as a letter (``id1e2``).
_NUMBER_NO_EXPONENT = re.compile(r"([+-]?)(\d++(?:[.,]\d++)?+)")
#: Where a name may hold an exponent.
_EXPONENT = re.compile(r"\d[eE][+-]?\d")
#: A number's parts: whole digits, decimal digits, the exponent's sign and digits.
_PARTS = re.compile(r"(\d+)(?:[.,](\d+))?(?:[eE]([+-]?)(\d+))?")
#: Exponents of more digits are refused (their value is no frame's).
_MAX_EXPONENT_DIGITS = 100
#: Three or more groups of digits joined by points (``12.5.3``, ``1.10.0``): no decimal number;
#: each group is read as a whole number, the points as separators.
_CHAIN = re.compile(r"(?<!\d)\d++(?:\.\d++){2,}+")
#: How a folder's frames are ordered, recorded with them (``frame_order``).
FRAME_ORDER = ("by name without its suffix (.npy, .tif, ...: a folder holds one format), "
               "numbers compared as numbers, exactly (decimal points read as such; an 'e' "
               "between digits read as an exponent and as a letter, names refused where the "
               "two orders differ; a decimal comma where every name's has as many digits "
               "after it, digits joined by several points as whole numbers where every name's "
               "groups have as many digits, digits after a point with no digit before it (t.5) "
               "where reading the point as a decimal point and as a separator give one order, "
               "or, where every name has them, as numbers after a separator where two would be "
               "one decimal (.1, .10); a '-' or '+' before a number read as its sign where the "
               "names differ by it at that place, else as part of the text (where the names "
               "hold different counts of numbers, refused if the two readings give different "
               "orders; where they hold as many, read so without comparing them); letters "
               "compared in one Unicode form (NFKC), characters that show nothing left out; "
               "names of one number or one stem but for case refused; hidden files (names "
               "starting with '.') left out")


def _stem(name):
    """``name`` without a frame file's suffix (:data:`FRAME_SUFFIXES`, any case): a frame's
    format is no part of its place in the order."""
    at = name.rfind(".")
    return name[:at] if at >= 0 and name[at:].lower() in FRAME_SUFFIXES else name


def _folded(name):
    """``name``'s stem as the order reads it: one Unicode form for letters written either
    way (``è`` as one character, as most systems write it, or as ``e`` and an accent, as
    macOS does; a ligature ``ﬁ`` as ``fi``), characters that show nothing (a zero-width
    space) left out, in lower case."""
    text = unicodedata.normalize("NFKC", _stem(name))
    return "".join(c for c in text if unicodedata.category(c) != "Cf").casefold()


def _difference(a, b):
    """What two names of one stem but for case (``f1.npy``, ``F1.tif``), or for how their
    letters are written, differ by."""
    if a.lower() == b.lower():
        return "case"
    if _stem(a).lower() != _stem(b).lower() and _folded(a) == _folded(b):
        return ("how their characters are written (one Unicode form or another, or one "
                "that shows nothing)")
    return "their suffix" if _stem(a) == _stem(b) else "their suffix and case"


def _tokens(name, number=_NUMBER):
    """``name`` as text and ``(sign, digits)`` pieces, the text in lower case, numbers found
    by ``number``; the groups of a chain of points (:data:`_CHAIN`) each a whole number.
    Digits of any script count (a full-width ten is ten)."""
    out, at = [], 0
    for chain in _CHAIN.finditer(name):
        out.extend(_number_tokens(name[at:chain.start()], number))
        for k, group in enumerate(chain.group().split(".")):
            out[-1:] = [out[-1] + ("." if k else "")] if out else ["."]
            out.extend([("", group), ""])
        at = chain.end()
    rest = _number_tokens(name[at:], number)
    if out:
        out[-1:] = [out[-1] + rest[0]]
        out.extend(rest[1:])
        return out
    return rest


def _number_tokens(text, number):
    out, at = [], 0
    for m in number.finditer(text):
        out.append(text[at:m.start()].lower())
        out.append((m.group(1), m.group(2)))
        at = m.end()
    out.append(text[at:].lower())
    return out


def _ascii(digits):
    """Digits of any script as ASCII ones."""
    return digits if digits.isascii() else "".join(str(unicodedata.decimal(c)) for c in digits)


#: A digit's complement (9 - d): a negative number's digits, so that larger ones sort first.
_COMPLEMENT = str.maketrans("0123456789", "9876543210")


def _magnitude(digits, name):
    """The value of ``digits`` (``12``, ``0,25``, ``1e-3``), exactly, as a key that sorts as
    the numbers do: ``(0,)`` for zero, else ``(1, exponent, significant digits)``, the
    exponent that of the first significant digit; no number is ever built, so that neither
    a long run of digits nor a large exponent costs more than reading it."""
    m = _PARTS.fullmatch(digits)
    whole, fraction = _ascii(m.group(1)), _ascii(m.group(2) or "")
    every = whole + fraction
    significant = every.lstrip("0")
    lead = len(every) - len(significant)
    significant = significant.rstrip("0")
    if not significant:
        return (0,)
    exponent = 0
    if m.group(4) is not None:
        written = _ascii(m.group(4)).lstrip("0")
        if len(written) > _MAX_EXPONENT_DIGITS:
            raise ValueError(f"frame {name!r}: an exponent of {len(written)} digits is no "
                             "frame's number; rename it")
        exponent = int(written or "0") * (-1 if m.group(3) == "-" else 1)
    return (1, len(whole) - lead - 1 + exponent, significant)


def _negated(magnitude):
    """The key of ``-x`` from that of ``x`` (:func:`_magnitude`); -0 is 0."""
    if magnitude == (0,):
        return magnitude
    _, exponent, significant = magnitude
    return (-1, -exponent, significant.translate(_COMPLEMENT) + ":")  # ':' after the digits


def _chain_widths(names):
    """Two names whose chains of points (:data:`_CHAIN`) have groups of different numbers of
    digits at one place (the ``j``-th group of the ``i``-th chain), or None: there the
    decimal and the separate readings of the points may order them differently."""
    seen = {}
    for n in names:
        for i, chain in enumerate(_CHAIN.finditer(_folded(n))):
            for j, group in enumerate(chain.group().split(".")[1:]):
                other = seen.setdefault((i, j), (len(group), n))
                if other[0] != len(group):
                    return other[1], n
    return None


def natural_order(names):
    """``names`` in natural order: numbers in them compared as numbers.

    A frame file's suffix (``.npy``, ``.tif``, ``.tiff``, ``.exr``, ``.hdr``) is not
    compared: names whose stems differ only in case or not at all (``f1.npy``, ``F1.tif``)
    are refused as one frame saved twice. Decimal parts count (``t0.25`` before ``t0.5``
    before ``t1``); numbers are compared exactly (nanosecond times of 19 digits stay apart).
    An ``e`` between digits may be an exponent (``1e-3``) or a letter (a hexadecimal id):
    names are taken where the two readings give one order (``t1e-3_f1``, ``t1e-3_f2``) and
    refused where they differ (``id1d2``, ``id1e2``, ``id1f2``, and so ``exp_1e-3``,
    ``exp_1e-2``, ``exp_1`` too): a camera's names are as often ids as exposures, so such
    numbers are written without an exponent (``0.001``). A decimal comma (``t0,25``) is read
    as one where every name has as many digits after its comma, which orders the names the
    same whether it is a decimal comma or a separator; otherwise the order is ambiguous, and
    refused; so are names that a comma read as a thousands separator (``t1,000`` as 1000)
    orders otherwise (``t1,000``, ``t2,000`` beside ``t999``). A ``-`` or ``+``
    right before a number is its sign only where the names differ by it at that place
    (``z-0.5``, ``z+0``, ``z+0.5``; ``f+1`` beside ``f1`` is one number, refused); where
    every name has the same one (``frame-1``, ``2026-12-01``) it is a separator; in names of
    different forms (``x-1``, ``x0``, ``x1_2``) it is refused where reading it as a sign and
    as a separator give different orders. Digits joined by several points (``12.5.3``,
    ``1.10.0``) are no decimal: each group is a whole number, and names whose groups at one
    place differ in their numbers of digits are refused (there the decimal and the separate
    readings may differ). Digits after a point with no digit before it (``t.5``) may be a
    decimal (0.5) or a number after a separator (5): names are refused where the two
    readings order them differently (``t.5``, ``t.25``, ``t1``; and ``t.5``, ``t.50``,
    ``t.25``, ``t1``) and taken where they agree (``f.001``, ``f.002``) or where only one can
    be meant: where every name has such digits at the same place and two of them are one
    decimal (``img.1`` ... ``img.10``), they are numbers after a separator. Digits of any
    script count (full-width, Arabic-Indic digits). Names whose numbers are equal but written
    differently (``f1``, ``f01``, ``f1.0``, ``f1e3`` and ``f1000``) are ambiguous, and
    refused.

    Parameters
    ----------
    names : sequence of str

    Returns
    -------
    list of str

    Raises
    ------
    ValueError
        Two names that compare equal, or that two readings order differently.
    """
    names = list(names)
    stems = {}
    for n in sorted(names):
        if _folded(n) in stems:
            other = stems[_folded(n)]
            if other == n:
                raise ValueError(f"frame {n!r} is named twice")
            raise ValueError(f"frames {other!r} and {n!r} differ only in "
                             f"{_difference(other, n)}: one frame saved twice, or two frames "
                             "no order can tell apart; keep one of them")
        stems[_folded(n)] = n
    order = _order(names, _NUMBER)
    _refuse_thousands(names, order)
    if any(_EXPONENT.search(_folded(n)) for n in names):
        try:
            other = _order(names, _NUMBER_NO_EXPONENT)
        except ValueError:  # refused when the 'e' is a letter: no one order either
            other = None
        if other != order:
            a, b = ((order[0], order[-1]) if other is None else
                    next((x, y) for x, y in zip(order, other, strict=True) if x != y))
            raise ValueError(f"frames {a!r} and {b!r}: an 'e' between digits may be an "
                             "exponent (1e2, 100) or a letter (a hexadecimal id, 1d2, 1e2), "
                             "and the two readings order them differently; rename them "
                             "(numbers without exponents: 0.001, not 1e-3)")
    return order


#: A comma that may separate thousands: between digits, three digits after it.
_THOUSANDS = re.compile(r"(?<=\d),(?=\d{3}(?!\d))")


def _refuse_thousands(names, order):
    """Refuse names whose order read with commas as thousands separators (``t1,000`` as
    1000) is not the ``order`` read with decimal commas (``t1,000``, ``t2,000``, ``t999``)."""
    if not any(_THOUSANDS.search(n) for n in names):
        return
    joined = {_THOUSANDS.sub("", n): n for n in names}
    if len(joined) < len(names):
        return  # two names one number apart only by a comma: refused as written twice
    try:
        other = [joined[n] for n in _order(list(joined), _NUMBER)]
    except ValueError:
        return
    if other != order:
        a, b = next((x, y) for x, y in zip(order, other, strict=True) if x != y)
        raise ValueError(f"frames {a!r} and {b!r}: a comma between digits may be a decimal "
                         "comma or a thousands separator (t1,000 is 1 or 1000), and the two "
                         "readings order them differently; rename them (decimal points, or "
                         "zero-padded numbers)")


def _order(names, number):
    """``names`` in natural order, numbers found by ``number`` (with exponents or without)."""
    tokens = [_tokens(_folded(n), number) for n in names]
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
        if len({t[k][0] for t in tokens if len(t) > k}) > 1:
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
    decimal point and as a separator in two different orders. Where every name has such
    digits at the same places and the decimal reading makes two names equal (``img.1`` and
    ``img.10``) it cannot be meant, and the separator's stands; in names of different forms
    (``t.5``, ``t.50``, ``t1``) the two readings still differ, and are refused. ``order`` is
    the separator reading's."""
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
    uniform = len({(len(t), tuple(ks)) for t, ks in zip(tokens, places, strict=True)}) == 1
    try:
        other = _ordered(names, as_decimal, signed)
    except _SameNumber as err:  # two names equal as decimals (img.1, img.10): no decimals,
        if uniform:  # then, but numbers after a separator, the one reading left
            return
        a, b = err.names  # names of other forms (t1) are read either way: two orders still
    else:
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

    def key(name, t):
        out = []
        for k, piece in enumerate(t):
            if k % 2 == 0:
                out.append((0, piece, ()))
                continue
            sign, digits = piece
            value = _magnitude(digits, name)  # exact: 19-digit times stay apart
            if k in signed:
                out.append((1, "", _negated(value) if sign == "-" else value))
            else:  # the sign is part of the text before
                out.append((0, sign, ()))
                out.append((1, "", value))
        return out

    keyed = sorted(zip((key(n, t) for n, t in zip(names, tokens, strict=True)), names,
                       strict=True), key=lambda kv: kv[0])
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
    """Refuse two files of one name but for the suffix or case (``f1.npy`` and ``f1.tif``,
    ``F1.npy``): one frame saved twice would be streamed twice, as two frames taken."""
    stems = {}
    for name in sorted(found):
        stem = Path(name).stem.lower()
        if stem in stems:
            raise ValueError(f"{stems[stem]} and {name} in the folder of frames differ only in "
                             f"{_difference(stems[stem], name)}: one frame saved twice would "
                             "be streamed twice; keep one of them")
        stems[stem] = name


def _refuse_formats_mixed(path, found):
    """Refuse a folder of frames in more than one format (``.tif`` and ``.tiff`` are one): a
    camera writes one, and a file of another (a dark or a white saved beside the frames) is
    no frame taken."""
    formats = {}
    for name in sorted(found):
        formats.setdefault(format_by_suffix(Path(name).suffix).name, name)
    if len(formats) > 1:
        shown = ", ".join(f"{n} ({f})" for f, n in formats.items())
        raise ValueError(f"{path} holds frames of {len(formats)} formats ({shown}); a folder "
                         "of frames holds one format: move the others out")


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
    whole = (isinstance(frames_per_chunk, int | np.integer)
             and not isinstance(frames_per_chunk, bool | np.bool_))
    if not whole or frames_per_chunk < 1:  # 1.5 was cut to 1, True taken as 1
        raise ValueError(f"frames_per_chunk must be a whole number >= 1, got "
                         f"{frames_per_chunk!r}")
    per = int(frames_per_chunk)
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
        _refuse_formats_mixed(path, found)
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
    _refuse_a_chunk_of_another_type(path, "the array", arr)
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
