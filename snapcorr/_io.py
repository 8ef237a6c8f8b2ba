"""Atomic output: write next to the target, then rename, so a crash never leaves half a file."""

from __future__ import annotations

import os
import tempfile
import tomllib
from pathlib import Path

__all__ = ["atomic_write", "read_toml", "write_toml"]


def atomic_write(path, write, *, inputs=()):
    """Call ``write(tmp_path)`` and move the result to ``path`` atomically.

    Refuses to write over any of ``inputs`` (outputs never replace an input file).
    """
    path = Path(path)
    for src in inputs:
        if Path(src).exists() and path.exists() and path.resolve() == Path(src).resolve():
            raise ValueError(f"output {path} is also an input; choose another output path")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        write(Path(tmp))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the usual permissions
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def read_toml(path, table, what):
    """The parsed TOML document at ``path``, which must hold ``[table]``; clear errors."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError:
        raise FileNotFoundError(f"{what} not found: {path}") from None
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path} is not valid TOML: {err}") from None
    if table not in doc:
        raise ValueError(f"{path} has no [{table}] table")
    return doc


def write_toml(path, doc, *, overwrite=False):
    """Write ``doc`` as TOML atomically, refusing to replace a file unless ``overwrite``."""
    import tomli_w

    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass overwrite=True to replace it")
    text = tomli_w.dumps(doc)
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
