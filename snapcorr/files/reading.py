"""Inputs checked before they are opened, and read only so far.

:func:`check_input` refuses, before anything opens it, a path that is missing, a loop of
symbolic links, a FIFO, socket or device (reading a FIFO would wait forever), or a folder
where a file is expected (and a file where a folder, a Zarr store, is expected).
:func:`read_regular` reads a bounded part of a regular file without ever opening anything
else; :func:`open_image` opens an image through OpenImageIO with its values as stored.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from pathlib import Path

__all__ = ["MAX_TABLE_BYTES", "NotRegularFileError", "check_input", "check_table_size",
           "file_kind", "open_image", "read_regular"]



#: The longest name of one file or folder most file systems take, in bytes.
NAME_MAX = 255


def _path_max():
    """The longest path the file system takes, in bytes (4096 where it does not say)."""
    try:
        return int(os.pathconf("/", "PC_PATH_MAX"))
    except (OSError, ValueError, AttributeError):
        return 4096


def _short(path, keep=120):
    """A path of more than ``keep`` characters as its start and end."""
    if len(path) <= keep:
        return path
    return f"{path[:keep // 2]}...({len(path) - keep:,} characters)...{path[-keep // 2:]}"


def too_long_said(path):
    """What is too long in ``path`` (``ENAMETOOLONG``): one of its names, or the whole path
    (every name short enough), with the path shortened, for a message."""
    name = str(path)
    longest = len(os.fsencode(max(Path(name).parts, key=len, default="")))
    if longest > NAME_MAX:
        return (f"{_short(name)}: a name in this path is too long for the file system (at "
                f"most {NAME_MAX} bytes a name, {longest} here); give a shorter one")
    return (f"{_short(name)}: this path is too long for the file system (at most "
            f"{_path_max()} bytes, {len(os.fsencode(name)):,} here, every name in it short "
            "enough); give a shorter one, or work from a folder nearer the file")


def file_kind(mode):
    """What a ``st_mode`` describes, in words ("a regular file", "a FIFO (named pipe)", ...)."""
    for test, name in ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a folder"),
                       (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISLNK, "a symbolic link")):
        if test(mode):
            return name
    return "not a regular file"


#: The largest text table read (a spectrum, a filter's measured shape): two columns of a
#: million rows take about 20 MB; a 64 MB one took 830 MB and 24 s before it was refused.
MAX_TABLE_BYTES = 16 * 2**20


def check_table_size(path, what="table"):
    """Refuse a text table larger than :data:`MAX_TABLE_BYTES` before it is read."""
    size = Path(path).stat().st_size
    if size > MAX_TABLE_BYTES:
        raise ValueError(f"{path}: the {what} holds {size / 2**20:.1f} MiB of text, more than "
                         f"{MAX_TABLE_BYTES / 2**20:.0f} MiB (a million rows of two numbers "
                         "take about 20 MB): resample it, or is this the right file?")


def check_input(path, *, directory=False, what="file"):
    """``path`` as a ``Path`` if it names an existing regular file (a folder when
    ``directory``); otherwise an error that says what was found, raised before anything opens
    the path.

    Parameters
    ----------
    path : str or Path
    directory : bool
        The input is a folder (a Zarr store) rather than a file.
    what : str
        What the path should hold, for the messages ("cube", "flat field", ...).

    Raises
    ------
    FileNotFoundError
        Nothing at ``path`` (or a symbolic link to nothing).
    ValueError
        A loop of symbolic links, a FIFO, socket or device, a folder where a file is expected
        or a file where a folder is expected, or a path that cannot be examined.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise ValueError(f"{path}: a loop of symbolic links; point the link at the {what} "
                             "itself") from None
        if err.errno in (errno.ENOENT, errno.ENOTDIR):
            if os.path.islink(path):
                raise FileNotFoundError(f"no such file: {path} (a symbolic link to "
                                        f"{os.readlink(path)}, which does not exist)") from None
            raise FileNotFoundError(f"no such file: {path}") from None
        raise ValueError(f"{path}: cannot examine it: {err.strerror}") from None
    mode = st.st_mode
    if directory:
        if not stat.S_ISDIR(mode):
            raise ValueError(f"{path} is {file_kind(mode)}, but a {path.suffix or what} store "
                             "is a folder; give the store's folder")
        _check_store_entries(path, what if "folder" in what else f"{what} store")
        return path
    if stat.S_ISDIR(mode):
        raise ValueError(f"{path} is a folder, but a {what} in this format is a single file "
                         "(only a .zarr store is a folder); give the file")
    if not stat.S_ISREG(mode):
        raise ValueError(f"{path} is {file_kind(mode)}, not a regular file; snapcorr reads "
                         f"a {what} only from a regular file (copy the data into one first)")
    return path


class NotRegularFileError(ValueError):
    """What was opened to be read is not a regular file (a FIFO, device, socket, folder...),
    or is larger than the reader accepts."""


def read_regular(path, limit, *, follow_links=True, whole=True):
    """The bytes of the regular file at ``path``, at most ``limit`` of them.

    The path is opened without waiting (a FIFO opens at once, to be refused) and examined
    through the open file, so what is read is what was examined: anything but a regular file
    raises :class:`NotRegularFileError` before a byte is read.

    Parameters
    ----------
    path : str or Path
    limit : int
        The most bytes read.
    follow_links : bool
        False: a symbolic link at ``path`` is refused rather than followed (``O_NOFOLLOW``).
    whole : bool
        True: a file larger than ``limit`` raises :class:`NotRegularFileError`; False: its
        first ``limit`` bytes are returned.

    Raises
    ------
    NotRegularFileError
        Not a regular file (a symbolic link when ``follow_links`` is False), or too large.
    OSError
        The path cannot be opened or read.
    """
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    if not follow_links:
        flags |= getattr(os, "O_NOFOLLOW", 0)
        with contextlib.suppress(OSError):
            if stat.S_ISLNK(os.lstat(path).st_mode):
                raise NotRegularFileError(f"{path} is a symbolic link, not a regular file")
    try:
        fd = os.open(path, flags)
    except OSError as err:
        if err.errno == errno.ELOOP and not follow_links:
            raise NotRegularFileError(f"{path} is a symbolic link, not a regular file") \
                from None
        raise
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise NotRegularFileError(f"{path} is {file_kind(st.st_mode)}, not a regular file")
        if whole and st.st_size > limit:
            raise NotRegularFileError(f"{path} holds {st.st_size} bytes, more than the "
                                      f"{limit} read here")
        parts, left = [], limit + (1 if whole else 0)
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            parts.append(chunk)
            left -= len(chunk)
        data = b"".join(parts)
        if whole and len(data) > limit:  # grew while it was read
            raise NotRegularFileError(f"{path} holds more than the {limit} bytes read here")
        return data
    finally:
        os.close(fd)


def _found(path):
    """``(mode, words)`` of what is at an existing ``path``, a symbolic link followed (mode
    None for a link to nothing or a loop)."""
    lst = os.lstat(path)
    if not stat.S_ISLNK(lst.st_mode):
        return lst.st_mode, file_kind(lst.st_mode)
    try:
        st = os.stat(path)
    except OSError as err:
        if err.errno == errno.ELOOP:
            return None, "a loop of symbolic links"
        return None, f"a symbolic link to {os.readlink(path)}, which does not exist"
    return st.st_mode, f"{file_kind(st.st_mode)} (a symbolic link to {os.readlink(path)})"


def _check_store_entries(path, what):
    """Every entry of a store, at any depth, must be a regular file or a folder (a symbolic
    link is judged by what it points to): reading a FIFO would wait forever, a device would
    read without end."""
    for root, dirs, files in os.walk(path):
        for name in dirs + files:
            entry = os.path.join(root, name)
            try:
                mode = os.stat(entry).st_mode
            except OSError as err:
                if os.path.islink(entry):
                    raise ValueError(f"{entry} (inside the {what} {path}) is a symbolic link "
                                     f"to {os.readlink(entry)}, which does not exist: not a "
                                     "regular file") from None
                raise ValueError(f"{entry} (inside the {what} {path}): cannot examine "
                                 f"it: {err.strerror}") from None
            if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
                raise ValueError(f"{entry} (inside the {what} {path}) is "
                                 f"{file_kind(mode)}, not a regular file; a store holds only "
                                 "files and folders: remove it or copy the store")


def open_image(path):
    """``OpenImageIO.ImageInput`` open on ``path`` with the values as stored: an unassociated
    alpha channel (PIL's RGBA and LA TIFFs) is kept as it is, where OpenImageIO by default
    multiplies every other channel by it. None if it cannot be opened (``oiio.geterror()``)."""
    import OpenImageIO as oiio

    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    return oiio.ImageInput.open(str(path), config)


def _sidecar(path):
    """The JSON sidecar of a ``.npy`` file: ``cube.npy.json``."""
    path = Path(path)
    return path.with_name(path.name + ".json")
