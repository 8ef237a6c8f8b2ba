"""What is checked before anything is written: the outputs, the inputs, the formats' limits.

:func:`check_outputs` checks a command's outputs before any long work: none is, holds or
lies in an input (or a file that belongs to one, :func:`_input_family`: an ENVI header's data
file, a ``.npy``'s sidecar; symbolic and hard links followed), none lies in another, none is
one of the protected files (snapcorr's bundled profiles), each has an allowed suffix and a
folder to go in, and one that exists is replaced only with ``overwrite`` and only if snapcorr
wrote it (:func:`check_replaceable`).

The cube writers check every path a format writes (:func:`_targets`) the same way, and an
existing one against the mark snapcorr ties to it (:func:`_check_targets`;
:func:`snapcorr.files.marks._written_by_snapcorr`); :func:`_check_writable` checks what a
format can hold. Each target's state is noted when it is checked: the write replaces only
that (:func:`snapcorr.files.safety.note_checked`).
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from .marks import _check_content, _written_by_snapcorr
from .reading import file_kind, too_long_said
from .registry import FILE_FORMATS, input_files
from .safety import _probe_folder, _unwritable_folder, note_checked, refuse_inputs

__all__ = ["check_folder_writable", "check_outputs", "check_replaceable"]


def _targets(fmt, path):
    """Every path the format named ``fmt`` writes: an ENVI header and its data, a ``.npy``
    and its sidecar (:attr:`~snapcorr.files.storage.FileFormat.targets`)."""
    return FILE_FORMATS[fmt].targets(path)


def _input_family(inputs):
    """The inputs with the files that belong to them
    (:func:`~snapcorr.files.registry.input_files`: an ENVI header's data file and the header of
    a data file, a ``.npy``'s sidecar; any format's, from the registry)."""
    return [p for src in inputs if src is not None for p in input_files(src)]


def _check_targets(fmt, targets, *, overwrite, inputs):
    """Refuse, before anything is written, a target that is or holds an input, or that exists
    (without ``overwrite``, or when snapcorr did not write it). What each target is now is
    noted (:func:`snapcorr.files.safety.note_checked`): the write replaces only that."""
    refuse_inputs(targets, _input_family(inputs))
    for target in targets:
        note_checked(target)
    for i, target in enumerate(targets):
        if not os.path.lexists(target):
            continue
        if not overwrite:
            raise FileExistsError(f"{target} exists; choose another name or pass "
                                  "overwrite=True")
        try:
            st = os.stat(target)
        except OSError as err:
            raise ValueError(f"{target} exists but cannot be examined ({err.strerror}); "
                             "move it away or choose another name") from None
        role = FILE_FORMATS[fmt].role(i)
        directory = role == "zarr"
        if directory != stat.S_ISDIR(st.st_mode) or not (
                stat.S_ISDIR(st.st_mode) or stat.S_ISREG(st.st_mode)):
            raise ValueError(f"{target} exists and is {file_kind(st.st_mode)}; overwrite "
                             f"replaces only a {'Zarr store' if directory else 'file'} "
                             "snapcorr wrote: move it away or choose another name")
        ours, found = _written_by_snapcorr(target, role)
        if not ours:
            raise ValueError(f"{target} exists and is {found}; overwrite replaces only what "
                             "snapcorr wrote: move it away or choose another name")


def _check_writable(fmt, cube, path, interleave):
    """The format's own limits, before anything is written
    (:attr:`~snapcorr.files.storage.FileFormat.check_writable`)."""
    check = FILE_FORMATS[fmt].check_writable
    if check is not None:
        check(cube, Path(path), interleave)


def check_replaceable(path):
    """Check an output before any work: note what is there now, nothing included (see
    :func:`note_checked`: only that may be replaced), and refuse to replace (with
    ``overwrite``) what snapcorr cannot have written.

    Refused: anything but a regular file or a folder (a FIFO, device or socket, also through
    a symbolic link; examined without opening it), and a PNG or TOML without snapcorr's mark
    naming this file. Call it for every output, whether it exists or not.

    Raises
    ------
    ValueError
        The target is refused.
    OutputChangedError
        Inside :func:`checked_outputs`: the target changed since it was first checked.
    """
    note_checked(path)
    _check_content(path)


def _protected(protected):
    """``protected`` (None, one path or several) as resolved folders."""
    if protected is None:
        return []
    if isinstance(protected, str | os.PathLike):
        protected = [protected]
    return [Path(os.path.realpath(p)) for p in protected if p is not None]


def check_folder_writable(path, option=None, *, folder=None):
    """Refuse, before any work, an output ``path`` whose folder does not exist, is not a
    folder or cannot be written in: found by creating and removing a hidden file there
    (permission bits say nothing for root, nor for a read-only mount).

    Parameters
    ----------
    path : str or Path
        The output (a file, or a Zarr store or other folder to be made in its folder).
    option : str, optional
        The option that gave it (``"--out"``), named in the message.
    folder : str or Path, optional
        The folder to write in; default: ``path``'s.

    Raises
    ------
    ValueError
        The folder is missing, not a folder, or cannot be written in; the message names the
        option, the output and the folder.
    """
    path = Path(path)
    folder = Path(folder) if folder is not None else (path.parent if path.parent.parts
                                                       else Path("."))
    try:
        if not folder.is_dir():
            raise (NotADirectoryError if os.path.lexists(folder) else FileNotFoundError)()
        _probe_folder(folder)
    except OSError as err:
        raise _unwritable_folder(path, folder, err, option) from None


def check_outputs(outputs, inputs, *, overwrite, suffixes, protected=(), names=None):
    """Refuse, before any long work, outputs that are, contain or lie in an input, that exist
    (without ``overwrite``), have the wrong suffix, or no folder to go in that can be written
    in (:func:`check_folder_writable`: each is probed before any is written).

    Parameters
    ----------
    outputs : sequence of (str or Path or None)
        The outputs of one command (None: not asked for, skipped).
    inputs : iterable of (str or Path or None)
        The files it reads (None entries are ignored).
    overwrite : bool
        Whether an existing output may be replaced (only one snapcorr wrote, ever).
    suffixes : sequence of tuple of str
        For each output, the suffixes it may end in (lower case, ``".nc"``).
    protected : str or Path or iterable of them, optional
        Folders whose existing files are never replaced (snapcorr's bundled profiles).
    names : sequence of str, optional
        For each output, the option that gives it (``"--out"``), named in a refusal of its
        folder.

    Raises
    ------
    ValueError
        An output is refused.
    FileExistsError
        An output exists and ``overwrite`` is false.
    """
    # realpath, unlike Path.resolve, does not raise on a symlink loop (the reader reports it)
    srcs = [Path(os.path.realpath(i)) for i in inputs if i is not None]
    family = _input_family([i for i in inputs if i is not None])
    folders = _protected(protected)
    seen = []
    names = [None] * len(outputs) if names is None else names
    for out, allowed, name in zip(outputs, suffixes, names, strict=True):
        if out is None:
            continue
        try:
            _check_one(Path(out), allowed, name, overwrite, srcs, family, folders, seen)
        except (ValueError, FileExistsError) as err:  # named by the option that gave it
            if name is None or str(err).startswith(name):
                raise
            raise type(err)(f"{name} {err}") from None
        except OSError as err:  # a name too long, a loop of links: said, not a traceback
            if err.errno == errno.ENAMETOOLONG:
                raise ValueError(f"{name + ' ' if name else ''}{too_long_said(out)}") from None
            raise ValueError(f"{name + ' ' if name else ''}{out}: "
                             f"{err.strerror or type(err).__name__}; choose another output "
                             "path") from None


def _check_one(out, allowed, name, overwrite, srcs, family, folders, seen):
    """:func:`check_outputs` for one output (``seen``: the outputs checked before it)."""
    res = Path(os.path.realpath(out))
    for bundled in folders:
        if res.is_relative_to(bundled) and os.path.lexists(res):
            raise ValueError(f"output {out} is one of snapcorr's bundled files "
                             f"({bundled}), never replaced; give your own a new name")
    for other, given in seen:  # two outputs of one command: neither in the other
        if res == other or res.is_relative_to(other) or other.is_relative_to(res):
            raise ValueError(f"outputs {given} and {out} are the same or one lies in the "
                             "other; give each its own path")
    seen.append((res, out))
    _refuse_sources(out, res, srcs)
    # hard links, and the files that belong to an input: before its existence is judged (a
    # hard link to the input was said to exist, or to be a file snapcorr did not write)
    refuse_inputs([out], family)
    _check_output(out, res, allowed, overwrite)
    check_folder_writable(out, name, folder=res.parent)  # probed: root passes any mode


def _refuse_sources(out, res, srcs):
    for src in srcs:
        if res == src:
            raise ValueError(f"output {out} is also an input; choose another output path")
        if src.is_relative_to(res) or res.is_relative_to(src):
            raise ValueError(f"output {out} holds or lies in the input {src}; choose "
                             "another output path")


def _check_output(out, res, allowed, overwrite):
    """One output's suffix, kind, existence and folder."""
    if out.suffix.lower() not in allowed:
        raise ValueError(f"{out}: the output must end in {' or '.join(allowed)}")
    folder = out.suffix.lower() == ".zarr"  # a zarr store is a folder, the rest files
    if out.exists() and out.is_dir() != folder:
        raise ValueError(f"{out} exists and is a {'folder' if out.is_dir() else 'file'}; "
                         "it is never replaced: choose another output path")
    if os.path.lexists(out) and not overwrite:
        raise FileExistsError(f"{out} exists; choose another name or pass overwrite=True")
    check_replaceable(out)  # notes what is there now (nothing, too): only that is replaced
