"""TOML documents: read with clear errors, written atomically with snapcorr's mark.

The first line of a TOML snapcorr writes is its mark (``# written by snapcorr ...``), tied
to the file's name and content (:func:`snapcorr.files.marks.toml_mark`), so that
``overwrite`` replaces only snapcorr's own.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

from .marks import toml_mark
from .outputs import check_replaceable
from .reading import check_input, read_regular
from .safety import atomic_write

__all__ = ["read_toml", "write_toml"]

#: Larger than any TOML snapcorr reads (a lens profile or sensor description is a few kB, a
#: calibration's record with it some tens): a bigger file is refused by its size before it is
#: parsed.
MAX_TOML_BYTES = 4 * 2**20
#: Deeper than any table or array of a snapcorr TOML nests (a lens file's reaches 4): past it
#: the parser and every reader after it recurse once per level (5000 levels overflowed
#: Python's stack inside the parser).
MAX_TOML_DEPTH = 32


def read_toml(path, table, what, *, others=("calibration",)):
    """The parsed TOML document at ``path``, which must hold ``[table]`` and nothing else at
    the top level but ``others``; clear errors.

    Parameters
    ----------
    path : str or Path
        A regular file of UTF-8 TOML.
    table : str
        Name of the top-level table the document must hold.
    what : str
        What the file holds, for the messages ("lens calibration", ...).
    others : tuple of str
        The other top-level tables allowed. Anything else (a misspelled table, a table meant
        to sit inside ``[table]``, a key outside it) is refused: read leniently, a
        ``[[vignetting]]`` written at the top level gave a lens without vignetting.

    Returns
    -------
    dict
        The whole document.

    Raises
    ------
    FileNotFoundError
        Nothing at ``path``.
    ValueError
        Not a regular file, not valid UTF-8 TOML, or no ``[table]``.
    """
    path = Path(path)
    try:
        check_input(path, what=what)
        size = path.stat().st_size
        if size > MAX_TOML_BYTES:
            raise ValueError(_too_large(path, size, what))
        data = read_regular(path, MAX_TOML_BYTES)
        text = data.decode("utf-8")
        if text.startswith("\ufeff"):  # a byte-order mark some editors write: not TOML's
            text = text[1:]
        doc = tomllib.loads(text)
    except FileNotFoundError:
        raise FileNotFoundError(f"{what} not found: {path}") from None
    except OSError as err:  # bytes that cannot be read (/proc/self/mem: EIO)
        raise ValueError(f"{path}: cannot read it ({err.strerror or err})") from None
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path} is not valid TOML: {err}") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path} is not valid TOML: not UTF-8 text") from None
    except RecursionError:  # arrays or inline tables nested thousands deep
        raise ValueError(_too_deep(path, what)) from None
    if _too_nested(doc):
        raise ValueError(_too_deep(path, what))
    if table not in doc:
        raise ValueError(f"{path} has no [{table}] table")
    if not isinstance(doc[table], dict):
        kind = ("an array of tables ([[" + table + "]])" if isinstance(doc[table], list)
                else f"a {type(doc[table]).__name__} value")
        raise ValueError(f"{path}: {table} is {kind}; a {what} holds one [{table}] table")
    for name in others:
        if name in doc and not isinstance(doc[name], dict):
            raise ValueError(f"{path}: {name} is not a table; write it [{name}]")
    extra = sorted(set(doc) - {table, *others})
    if extra:
        hint = "".join(f" ([[{k}]] inside it is written [[{table}.{k}]])" for k in extra
                       if isinstance(doc[k], list))
        raise ValueError(f"{path}: unknown top-level table(s) or key(s) {extra}; a {what} "
                         f"holds [{table}]{hint}"
                         + "".join(f" and optionally [{o}]" for o in others))
    return doc


def _too_large(path, size, what):
    return (f"{path} holds {size / 2**20:.1f} MiB; a {what} is a few kB, and a TOML larger "
            f"than {MAX_TOML_BYTES / 2**20:g} MiB is refused unread: is this the right file?")


def _too_deep(path, what):
    return (f"{path}: its arrays or tables nest more than {MAX_TOML_DEPTH} levels deep; a "
            f"{what} nests a few: is this the right file?")


def _too_nested(doc):
    """Whether the tables and arrays of ``doc`` nest deeper than :data:`MAX_TOML_DEPTH` (the
    document itself is level 1), walked without recursion."""
    stack = [(doc, 1)]
    while stack:
        value, level = stack.pop()
        if level > MAX_TOML_DEPTH:
            return True
        items = value.values() if isinstance(value, dict) else value
        stack.extend((v, level + 1) for v in items if isinstance(v, (dict, list)))
    return False



def write_toml(path, doc, *, overwrite=False):
    """Write ``doc`` as TOML atomically, refusing to replace a file unless ``overwrite``.

    ``doc`` is a dict, or a list of parts written one after another: dicts, and strings of
    TOML written as they are (an array of tables such as ``[[lens.vignetting]]`` in block
    form, which tomli_w would write inline).

    Parameters
    ----------
    path : str or Path
        The target file.
    doc : dict or list of (dict or str)
        The document, or its parts in order.
    overwrite : bool
        Replace an existing file that snapcorr wrote (else ``FileExistsError``; a file it
        did not write is never replaced).

    Returns
    -------
    Path
        ``path``.
    """
    import tomli_w

    path = Path(path)
    if os.path.lexists(path) and not overwrite:
        raise FileExistsError(f"{path} exists; pass overwrite=True to replace it")
    check_replaceable(path)
    parts = doc if isinstance(doc, list) else [doc]
    body = "\n".join(p if isinstance(p, str) else tomli_w.dumps(p) for p in parts)
    text = toml_mark(path.name, body) + body
    return atomic_write(path, lambda tmp: tmp.write_bytes(text.encode("utf-8")))
