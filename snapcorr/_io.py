"""Safe files: inputs checked before they are opened, outputs written atomically.

Reading
    :func:`check_input` refuses, before anything opens it, a path that is missing, a loop of
    symbolic links, a FIFO, socket or device (reading a FIFO would wait forever), or a folder
    where a file is expected (and a file where a folder, a Zarr store, is expected).

Writing
    Every output is written under a hidden temporary name next to its target (``.name.XXXX``)
    and moved in only when complete, so a crash never leaves half a file. The final move
    replaces only what was there when the write began (and checked then: a PNG or TOML only
    if snapcorr wrote it): a target that
    did not exist is moved in without replacing anything (a hard link, or a reserved empty
    folder renamed over), so a file or folder that appears there during the write, or a
    second writer of the same output, is never replaced: the write fails and the result is
    discarded. A target that existed is moved aside, compared with the one checked (device,
    inode and modification time) and put back if it is not the same; the new one is moved in
    and only then is the old one deleted (a failure puts the old ones back). Between the two
    renames the path is briefly absent: a replacement is safe, not atomic.
    :func:`refuse_inputs` refuses a target that is, contains or lies inside an input.

Interruptions
    Temporary paths are kept in a registry while they exist. Inside :func:`cleanup_on_signals`
    SIGTERM and SIGHUP interrupt the main thread as Ctrl-C does (``KeyboardInterrupt``), so
    ``finally`` blocks run, and on leaving it every temporary still registered is removed.
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import os
import shutil
import signal
import stat
import tempfile
import threading
import time
import tomllib
from pathlib import Path

__all__ = [
    "atomic_write",
    "atomic_write_dir",
    "atomic_write_files",
    "check_input",
    "cleanup_on_signals",
    "file_kind",
    "read_toml",
    "refuse_inputs",
    "remove_path",
    "save_png",
    "temporary_paths",
    "write_toml",
]


# -- inputs ----------------------------------------------------------------------------------


def file_kind(mode):
    """What a ``st_mode`` describes, in words ("a regular file", "a FIFO (named pipe)", ...)."""
    for test, name in ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a folder"),
                       (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISLNK, "a symbolic link")):
        if test(mode):
            return name
    return "not a regular file"


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


# -- outputs and inputs ----------------------------------------------------------------------


def _resolved(path):
    try:
        return Path(path).resolve()
    except (OSError, RuntimeError):  # a symbolic link loop: compare the path as written
        return Path(os.path.abspath(path))


def _identity(path):
    """``(device, inode)`` of an existing path, else None."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


def refuse_inputs(targets, inputs):
    """Raise ``ValueError`` if any of ``targets`` is, contains or lies inside any of
    ``inputs`` (symbolic links resolved; a hard link to an input is the input): writing it
    would destroy an input."""
    sources = [(Path(src), _resolved(src), _identity(src)) for src in inputs
               if src is not None]
    for target in targets:
        t, ti = _resolved(target), _identity(target)
        for src, s, si in sources:
            if t == s or (ti is not None and ti == si):  # a hard link is the same file too
                raise ValueError(f"output {target} is also an input ({src}); choose another "
                                 "output path")
            if s.is_relative_to(t):
                raise ValueError(f"output {target} contains the input {src}; choose another "
                                 "output path")
            if t.is_relative_to(s):
                raise ValueError(f"output {target} lies inside the input {src}; choose another "
                                 "output path")


# -- the registry of temporary paths ---------------------------------------------------------

_LOCK = threading.RLock()
#: Temporary paths that exist now (str -> None, in creation order).
_TEMPORARY: dict[str, None] = {}
#: Temporary paths removed after a failure: a worker thread still finishing (dask, zarr) may
#: create them again, so they are checked once more when the interpreter exits.
_REMOVED: dict[str, None] = {}


def temporary_paths():
    """The temporary paths registered now (a list of absolute ``Path``)."""
    with _LOCK:
        return [Path(p) for p in _TEMPORARY]


def _key(path):
    """A registry key: the absolute path, so that a change of working folder cannot make it
    name another file."""
    return os.path.abspath(os.fspath(path))


def _register(path):
    with _LOCK:
        _TEMPORARY[_key(path)] = None


def _unregister(path):
    with _LOCK:
        _TEMPORARY.pop(_key(path), None)


def remove_path(path, *, timeout_s=10.0, settle_s=0.2):
    """Remove a temporary file or folder and unregister it.

    Retries for up to ``timeout_s`` while the removal fails or the path comes back within
    ``settle_s`` (a thread still writing into an interrupted output may create it again).

    Parameters
    ----------
    path : str or Path
        The file or folder (a symbolic link is removed itself, not what it points to).
    timeout_s : float
        How long to keep retrying, seconds.
    settle_s : float
        How long to wait after each removal before checking the path stays gone, seconds. When
        non-zero the path is also checked again when the interpreter exits; 0 waits not at all.

    Returns
    -------
    bool
        True when the path is gone.
    """
    path = _key(path)
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            if os.path.isdir(path) and not os.path.islink(path):
                shutil.rmtree(path)
            else:
                os.unlink(path)
        except FileNotFoundError:
            pass
        except OSError:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.02)
            continue
        time.sleep(settle_s if settle_s and time.monotonic() < deadline else 0)
        if not os.path.lexists(path) or time.monotonic() > deadline:
            break
    gone = not os.path.lexists(path)
    with _LOCK:
        if settle_s:  # removed after a failure: look again at exit
            _REMOVED[path] = None
        if gone:
            _TEMPORARY.pop(path, None)
    return gone


@atexit.register
def _remove_left_over():
    with _LOCK:
        paths = list(_TEMPORARY) + list(_REMOVED)
    for p in paths:
        if os.path.lexists(p):
            remove_path(p, timeout_s=2.0, settle_s=0)


def _make_temporary(target, *, directory=False):
    """A new hidden temporary file or folder next to ``target``, registered."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    prefix, suffix = f".{target.stem}.", target.suffix
    with _LOCK:  # registered before a signal can come between creating and registering
        if directory:
            tmp = tempfile.mkdtemp(dir=target.parent, prefix=prefix, suffix=suffix)
        else:
            fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=prefix, suffix=suffix)
            os.close(fd)
        _register(tmp)
    return Path(tmp)


def _umask():
    """The process's umask, read without changing it where the system tells it (Linux);
    elsewhere set and restored at once."""
    with contextlib.suppress(OSError, ValueError), open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    umask = os.umask(0o022)
    os.umask(umask)
    return umask


def _usual_permissions(path, directory=False):
    """mkstemp and mkdtemp create private paths; give the permissions a new file would get."""
    os.chmod(path, (0o777 if directory else 0o666) & ~_umask())


def _state(path):
    """``(device, inode, mtime)`` of what is at ``path`` (a link itself), or None if nothing
    is. The modification time tells a new file from an old one whose inode number was reused;
    a rename keeps it."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    return st.st_dev, st.st_ino, st.st_mtime_ns


class OutputChangedError(FileExistsError):
    """The output path changed while the output was written: nothing was replaced."""


def _changed(target, now):
    what = "appeared" if now else "changed"
    return OutputChangedError(
        errno.EEXIST, f"{target} {what} while the output was written (another program, or a "
        "second snapcorr writing the same output?); nothing there was replaced and the new "
        "output was discarded: write again, or choose another name", str(target))


def _move_in_new(new, target):
    """Move ``new`` to ``target`` where nothing may be replaced (FileExistsError otherwise).
    A file is hard-linked (``new`` is then unlinked by the caller); a folder is moved over an
    empty folder reserved first. Whatever fails or is interrupted, a reservation is removed
    while it is still empty (ours)."""
    if new.is_dir():
        try:
            os.mkdir(target)  # the reservation: atomic, fails if anything is there
        except FileExistsError:
            raise _changed(target, True) from None
        try:
            os.rename(new, target)  # over our own empty folder
        except BaseException as err:
            with contextlib.suppress(OSError):
                os.rmdir(target)  # only while still empty: ours
            if isinstance(err, OSError) and err.errno in (errno.ENOTEMPTY, errno.EEXIST):
                raise _changed(target, True) from None
            raise
        return
    try:
        os.link(new, target)
    except FileExistsError:
        raise _changed(target, True) from None
    except OSError as err:  # a file system without hard links: reserve the name, then rename
        if err.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV,
                             errno.EMLINK):
            raise
        try:
            os.close(os.open(target, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
        except FileExistsError:
            raise _changed(target, True) from None
        try:
            os.replace(new, target)
        except BaseException:
            with contextlib.suppress(OSError):
                if os.path.getsize(target) == 0:
                    os.unlink(target)  # our empty reservation
            raise


def _replace(moves, expected):
    """Move each ``(new, target)`` into place, replacing only what ``expected`` says.

    ``expected`` holds, for each target, the :func:`_state` of what was there when the
    write began (None: nothing, and nothing may be replaced). Existing targets are moved aside
    and checked against it; the old ones are deleted only once every new path is in place; on
    any failure (an interruption too) the new paths are taken out and the old ones put back.
    """
    moves = [(Path(new), Path(target)) for new, target in moves]
    for new, target in moves:
        _check_kind(target, directory=new.is_dir())
    # The old paths moved aside are not registered as temporaries: if anything goes wrong
    # they are put back, and a crash leaves them recoverable rather than deleted.
    asides, placed = [], []
    try:
        for (new, target), exp in zip(moves, expected, strict=True):
            if exp is None:
                _move_in_new(new, target)
                placed.append(target)  # ours from here: taken out again on any failure
                if os.path.lexists(new):  # a hard link: the temporary name goes
                    os.unlink(new)
            else:
                if _state(target) is None:
                    raise _changed(target, False)
                aside = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.old."))
                asides.append((aside, target))
                try:
                    os.rename(target, aside / target.name)
                except FileNotFoundError:  # gone since it was looked at
                    raise _changed(target, False) from None
                if _state(aside / target.name) != exp:
                    raise _changed(target, False)
                os.rename(new, target)
                placed.append(target)
            _unregister(new)
    except BaseException:
        for target in placed:  # the new ones out, the old ones back
            remove_path(target, settle_s=0)
        for aside, target in asides:
            with contextlib.suppress(OSError):
                if os.path.lexists(aside / target.name):
                    os.rename(aside / target.name, target)
                os.rmdir(aside)
        raise
    for aside, _ in asides:
        shutil.rmtree(aside, ignore_errors=True)


def _check_kind(target, *, directory):
    """Refuse to replace a folder by a file or a file by a folder (a symbolic link is
    replaced itself, never what it points to)."""
    if not os.path.lexists(target) or os.path.islink(target):
        return
    if os.path.isdir(target) != directory:
        found = file_kind(os.stat(target).st_mode)
        raise ValueError(f"{target} exists and is {found}; it is not replaced by a "
                         f"{'folder' if directory else 'file'}: move it away or choose "
                         "another name")


def atomic_write(path, write, *, inputs=()):
    """Call ``write(tmp_path)`` and move the result to ``path`` atomically.

    The temporary file is hidden, next to ``path``, registered while it exists (see
    :func:`cleanup_on_signals`) and removed if ``write`` fails or is interrupted. Refuses to
    write over, into or around any of ``inputs`` (outputs never replace an input file).

    Parameters
    ----------
    path : str or Path
        The target file; an existing file is replaced, an existing folder refused.
    write : callable
        ``write(tmp_path)`` writes the whole output to the temporary ``Path`` it is given.
    inputs : iterable of str or Path
        Input paths the target must not be, contain or lie inside (None entries are ignored).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    refuse_inputs([path], inputs)
    return _write_and_move(path, write, directory=False)


def atomic_write_dir(path, write):
    """Call ``write(tmp_folder)`` and move the folder to ``path`` (replacing an existing
    folder safely); the temporary folder is removed if ``write`` fails or is interrupted."""
    return _write_and_move(Path(path), write, directory=True)


def _write_and_move(path, write, *, directory):
    _check_kind(path, directory=directory)
    check_replaceable(path)  # again now: what may be replaced is what is there at this moment
    before = _state(path)  # only this may be replaced
    tmp = _make_temporary(path, directory=directory)
    try:
        write(tmp)
        _usual_permissions(tmp, directory=directory)
        _replace([(tmp, path)], [before])
    except BaseException:
        remove_path(tmp)
        raise
    return path


def atomic_write_files(paths, write):
    """Write files that belong together (a header and its data) and move them in together.

    ``write(folder)`` must create every name of ``paths`` (all in one folder) inside
    ``folder``, a hidden temporary folder next to them; they are then moved into place
    together (see :func:`_replace`), and the temporary folder is removed in every case.
    """
    paths = [Path(p) for p in paths]
    if len({p.parent for p in paths}) != 1:
        raise ValueError("files written together must share a folder")
    for p in paths:
        _check_kind(p, directory=False)
        check_replaceable(p)
    before = [_state(p) for p in paths]
    tmp = _make_temporary(paths[0], directory=True)
    try:
        write(tmp)
        for p in paths:
            if not (tmp / p.name).is_file():
                raise ValueError(f"the writer did not produce {p.name}")
        _replace([(tmp / p.name, p) for p in paths], before)
    finally:
        remove_path(tmp, settle_s=0)
    return paths


# -- signals ---------------------------------------------------------------------------------


def _interrupt(signum, frame):
    raise KeyboardInterrupt(f"{signal.Signals(signum).name} received")


@contextlib.contextmanager
def cleanup_on_signals(signals=("SIGTERM", "SIGHUP")):
    """Clean up temporary files however a command ends.

    Inside the block, ``signals`` (by default SIGTERM and SIGHUP; Ctrl-C, SIGINT, already
    does this) raise ``KeyboardInterrupt`` in the main thread, so ``finally`` blocks run and
    atomic writes remove their temporary files. On leaving, normally or by any exception,
    every temporary path registered since entering and still present is removed (files
    unlinked, folders deleted) with those signals and SIGINT ignored, and the previous
    handlers are restored. Outside the main thread the handlers are left alone and only the
    cleanup is done.

    Examples
    --------
    >>> from snapcorr._io import cleanup_on_signals
    >>> with cleanup_on_signals():
    ...     pass
    """
    before = set(map(str, temporary_paths()))
    numbers = [getattr(signal, s) for s in signals if hasattr(signal, s)]
    main = threading.current_thread() is threading.main_thread()
    previous = {}
    if main:
        for s in numbers:
            previous[s] = signal.signal(s, _interrupt)
    try:
        yield
    finally:
        if main:
            for s in {*numbers, signal.SIGINT}:
                previous.setdefault(s, signal.getsignal(s))
                signal.signal(s, signal.SIG_IGN)
        try:
            for path in temporary_paths():
                if str(path) not in before:
                    remove_path(path)
        finally:
            if main:
                for s, handler in previous.items():
                    signal.signal(s, handler if handler is not None else signal.SIG_DFL)


# -- TOML ------------------------------------------------------------------------------------


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
        with path.open("rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError:
        raise FileNotFoundError(f"{what} not found: {path}") from None
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path} is not valid TOML: {err}") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path} is not valid TOML: not UTF-8 text") from None
    if table not in doc:
        raise ValueError(f"{path} has no [{table}] table")
    extra = sorted(set(doc) - {table, *others})
    if extra:
        hint = "".join(f" ([[{k}]] inside it is written [[{table}.{k}]])" for k in extra
                       if isinstance(doc[k], list))
        raise ValueError(f"{path}: unknown top-level table(s) or key(s) {extra}; a {what} "
                         f"holds [{table}]{hint}"
                         + "".join(f" and optionally [{o}]" for o in others))
    return doc


#: What snapcorr writes into its own PNGs (``Software``) and TOMLs (the first line), so that
#: ``overwrite`` can tell them from a user's files.
_MARK = "snapcorr"


def save_png(fig, path, *, dpi=120, inputs=()):
    """Write a matplotlib figure as PNG atomically, marked as snapcorr's (``Software``).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or Path
        The PNG to write; one that exists is replaced only if snapcorr wrote it.
    dpi : int
    inputs : iterable of str or Path
        Input paths the PNG must not be, contain or lie inside.

    Returns
    -------
    Path
    """
    from . import __version__

    return atomic_write(path, lambda tmp: fig.savefig(
        tmp, format="png", dpi=dpi, metadata={"Software": f"{_MARK} {__version__}"}),
        inputs=inputs)


def written_by_snapcorr(path):
    """``(True, "")`` if the PNG or TOML at ``path`` carries snapcorr's mark (a lens profile
    from an earlier version: its ``[calibration] snapcorr_version``), else ``(False, what it
    is)``. Other kinds: ``(False, "a file of a kind snapcorr does not mark")``."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".png":
            from PIL import Image, UnidentifiedImageError

            try:
                with Image.open(path) as im:
                    software = str(im.info.get("Software", ""))
            except (UnidentifiedImageError, SyntaxError, ValueError):
                return False, "a file that is not a PNG image"
            if software.startswith(_MARK):
                return True, ""
            return False, "a PNG that snapcorr did not write (no 'snapcorr' Software mark)"
        if suffix == ".toml":
            text = path.read_text(encoding="utf-8", errors="replace")
            if text.startswith(f"# written by {_MARK}"):
                return True, ""
            with contextlib.suppress(tomllib.TOMLDecodeError):
                cal = tomllib.loads(text).get("calibration", {})
                if isinstance(cal, dict) and "snapcorr_version" in cal:
                    return True, ""
            return False, "a TOML file that snapcorr did not write"
    except OSError as err:
        return False, f"a file that cannot be read ({err.strerror or err})"
    except Exception:  # PIL's many errors for a file that is not an image
        return False, "a file that is not a PNG image"
    return False, "a file of a kind snapcorr does not mark"


def check_replaceable(path):
    """Refuse to replace (with ``overwrite``) a PNG or TOML that snapcorr did not write."""
    if not os.path.lexists(path) or Path(path).suffix.lower() not in (".png", ".toml"):
        return
    ours, found = written_by_snapcorr(path)
    if not ours:
        raise ValueError(f"{path} exists and is {found}; overwrite replaces only what "
                         "snapcorr wrote: move it away or choose another name")


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

    from . import __version__

    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass overwrite=True to replace it")
    check_replaceable(path)
    parts = doc if isinstance(doc, list) else [doc]
    text = f"# written by {_MARK} {__version__}\n" + "\n".join(
        p if isinstance(p, str) else tomli_w.dumps(p) for p in parts)
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
