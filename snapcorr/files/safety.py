"""Safe outputs: written atomically, replacing only what was checked, never an input.

Writing
    Every output is written under a hidden temporary name next to its target (``.name.XXXX``)
    and moved in only when complete, so a crash never leaves half a file. The final move
    replaces only what was there when the target was checked: :func:`check_replaceable` (and
    the cube writers' target checks) note what is at the target then (nothing, or its device,
    inode, size and modification time, :func:`note_checked`), and the move refuses a target
    that differs. Inside :func:`checked_outputs` (a command: :func:`cleanup_on_signals` opens
    one) a note holds until the target is written, so an output that appears or changes during
    the command's work, after its checks, is never replaced; outside one, from the library's
    check to the move. A target that did not exist is moved in without replacing anything (a
    hard link, or a reserved empty folder renamed over), so a file or folder that appears there
    during the write, or a second writer of the same output, is never replaced: the write fails
    and the result is discarded. A target that existed is moved aside, compared with the one
    checked and put back if it is not the same; the new one is moved in and only then is the
    old one deleted (a failure puts the old ones back). Between the two renames the path is
    briefly absent: a replacement is safe, not atomic.
    :func:`refuse_inputs` refuses a target that is, contains or lies inside an input.

Ownership
    ``overwrite`` replaces only what snapcorr wrote: a PNG with its ``Software`` mark, a TOML
    with its first line, and cubes and results with a mark that names the file it was written
    as (see :mod:`snapcorr.files.marks`; the final move adds it, :func:`_stamp`). A target is
    examined without following it into anything but a regular file (a FIFO, device or socket
    is refused before it is opened) and only a bounded part of it is read
    (:func:`snapcorr.files.reading.read_regular`).

Interruptions
    Temporary paths are kept in a registry while they exist. Inside :func:`cleanup_on_signals`
    SIGTERM, SIGHUP and Ctrl-C (SIGINT) interrupt the main thread (``KeyboardInterrupt``), so
    ``finally`` blocks run, and on leaving it every temporary still registered is removed. An
    interrupt is never lost: one that Python drops because it came while a finalizer ran (a
    ``__del__`` run by the garbage collector in the middle of any work) is delivered again,
    and once a signal has come no output is moved in until the block is left.
"""

from __future__ import annotations

import _thread
import atexit
import contextlib
import errno
import itertools
import os
import secrets
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

from .marks import _check_content, tie_mark
from .reading import file_kind

__all__ = [
    "OutputChangedError",
    "atomic_write",
    "atomic_write_dir",
    "atomic_write_files",
    "before_moving_in",
    "checked_outputs",
    "cleanup_on_signals",
    "last_written",
    "note_checked",
    "refuse_inputs",
    "remove_path",
    "temporary_paths",
]


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


#: The letters of a temporary's random part (as :mod:`tempfile` uses; :mod:`secrets` would
#: add its import to every command's start).
_NAME_LETTERS = "abcdefghijklmnopqrstuvwxyz0123456789_"


def _make_temporary(target, *, directory=False):
    """A new hidden temporary file or folder next to ``target``, registered.

    The name is registered before the path is created: a signal's handler runs between any
    two steps (and ``_LOCK`` holds off threads only), so created first, a path whose
    registration an interruption prevented would stay behind. An interruption after the
    path was created removes it. A folder that cannot be written in is said by the target's
    name, not the temporary's (which the user never named)."""
    target = Path(target)
    if not os.path.isdir(target.parent):  # never made: a mistyped folder would be taken
        raise _unwritable_folder(target, target.parent,   # for a new one, silently
                                 FileNotFoundError(errno.ENOENT, "no such folder"))
    folder = os.path.abspath(target.parent)
    flags = os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) \
        | getattr(os, "O_CLOEXEC", 0)
    for _ in range(tempfile.TMP_MAX):
        name = "".join(_NAME_LETTERS[b % len(_NAME_LETTERS)] for b in os.urandom(8))
        tmp = os.path.join(folder, f".{target.stem}.{name}{target.suffix}")
        _register(tmp)
        try:
            if directory:
                os.mkdir(tmp, 0o700)
            else:
                os.close(os.open(tmp, flags, 0o600))
        except FileExistsError:  # another's: unregistered, never removed
            _unregister(tmp)
            continue
        except OSError as err:
            remove_path(tmp, settle_s=0)
            raise _unwritable_folder(target, target.parent, err) from None
        except BaseException:
            remove_path(tmp, settle_s=0)  # created or not: gone
            raise
        return Path(tmp)
    raise FileExistsError(errno.EEXIST, "no free temporary name next to the output",
                          str(target))


def _unwritable_folder(target, folder, err, option=None):
    """The error for ``target`` whose ``folder`` cannot be written in (``err``, the
    ``OSError`` met), naming the ``option`` that gave it if there is one."""
    named = f"{option} {target}" if option else str(target)
    why = err.strerror or type(err).__name__
    if isinstance(err, NotADirectoryError) or (os.path.lexists(folder)
                                               and not os.path.isdir(folder)):
        return ValueError(f"{named}: {folder} is not a folder; choose an output path in one")
    if not os.path.lexists(folder):  # ENOENT in a folder that exists (/proc): cannot write
        return ValueError(f"{named}: the folder {folder} does not exist; create it first")
    return ValueError(f"{named}: cannot write in the folder {folder} ({why}); choose a folder "
                      "you can write in")


def _probe_folder(folder):
    """Create and remove a hidden file in ``folder``: whether a file can be written there,
    found by doing it (permission bits say nothing for root, nor for a read-only mount or an
    access-control list). Raises the ``OSError`` met."""
    with _LOCK:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".snapcorr-probe.")
        os.close(fd)
        _register(tmp)
    try:
        os.remove(tmp)
    finally:
        _unregister(tmp)


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
    """``(device, inode, size, mtime)`` of what is at ``path`` (a link itself), or None if
    nothing is. The size and modification time tell a new file from an old one whose inode
    number was reused, or one rewritten in place; a rename keeps them."""
    try:
        st = os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


class OutputChangedError(FileExistsError):
    """The output path changed while the output was written, or since it was checked:
    nothing was replaced."""


def _changed(target, now):
    what = "appeared" if now else "changed"
    return OutputChangedError(
        errno.EEXIST, f"{target} {what} while the output was written (another program, or a "
        "second snapcorr writing the same output?); nothing there was replaced and the new "
        "output was discarded: write again, or choose another name", str(target))


def _changed_since_check(target, checked, now):
    if checked is None:
        what = "appeared after snapcorr checked its outputs"
    elif now is None:
        what = "was removed or moved after snapcorr checked it"
    else:
        what = "changed after snapcorr checked it"
    return OutputChangedError(
        f"{target} {what} (another program, or a second snapcorr writing the same output?); "
        "nothing there was replaced: write again, or choose another name")


# -- what each target was when it was checked ------------------------------------------------

#: Target key -> (its :func:`_state` when checked, the :func:`checked_outputs` scope noting it
#: or None). The final move of a write replaces only that state.
_CHECKED: dict[str, tuple] = {}
#: The scopes open now (innermost last).
_SCOPES: list[int] = []
_SCOPE_IDS = itertools.count(1)
#: Target key -> its state right after snapcorr moved it in (the most recent writes).
_WRITTEN: dict[str, tuple] = {}
_WRITTEN_KEEP = 4096


def _target_key(path):
    """A target's key: its folder resolved (symbolic links, ``..``, the working folder), its
    own name as given (a link there is the target itself, never followed)."""
    parent, name = os.path.split(os.path.abspath(os.fspath(path)))
    with contextlib.suppress(OSError, RuntimeError, ValueError):
        parent = os.path.realpath(parent)
    return os.path.join(parent, name)


@contextlib.contextmanager
def checked_outputs():
    """A command's outputs held to what its checks found until they are written.

    Inside the block, what :func:`note_checked` notes (through :func:`check_replaceable` and
    the cube writers' target checks) is kept until the target is written: a later check, and
    the final move, refuse a target that differs (it appeared, changed or went away during
    the command's work: another program, or a second snapcorr writing it). On leaving, the
    notes of the block's targets not written are forgotten. Blocks nest.
    :func:`cleanup_on_signals` opens one.

    Examples
    --------
    >>> from snapcorr.files.safety import checked_outputs, note_checked
    >>> with checked_outputs():
    ...     note_checked("result_that_does_not_exist.nc")  # nothing there
    """
    with _LOCK:
        scope = next(_SCOPE_IDS)
        _SCOPES.append(scope)
    try:
        yield
    finally:
        with _LOCK:
            _SCOPES.remove(scope)
            for key in [k for k, (_, s) in _CHECKED.items() if s == scope]:
                del _CHECKED[key]


def note_checked(path):
    """Note what is at the output ``path`` now (nothing, or its device, inode, size and
    modification time) as what its write may replace, and return it.

    A target noted before is compared: inside :func:`checked_outputs` a difference raises
    :class:`OutputChangedError` (the target appeared or changed after the command checked
    it); outside one, a note left by a write that never happened is replaced. Call it when a
    target is checked, before its content is examined.

    Raises
    ------
    OutputChangedError
        Inside :func:`checked_outputs`: the target is not what it was when first checked.
    """
    key, now = _target_key(path), _state(path)
    with _LOCK:
        scope = _SCOPES[-1] if _SCOPES else None
        noted = _CHECKED.get(key)
        if noted is not None and noted[0] != now and noted[1] is not None:
            raise _changed_since_check(path, noted[0], now)
        if noted is None or noted[0] != now:
            _CHECKED[key] = (now, scope)
        elif noted[1] is None and scope is not None:
            _CHECKED[key] = (now, scope)  # held for the command from now on
    return now


def _expected(path):
    """What the write of ``path`` may replace: the state noted when it was checked (the note
    is used up), else what is there now; refuses a target that changed since its check."""
    key, now = _target_key(path), _state(path)
    with _LOCK:
        noted = _CHECKED.pop(key, None)
    if noted is None:
        return now
    if noted[0] != now:
        raise _changed_since_check(path, noted[0], now)
    return noted[0]


def last_written(path):
    """The :func:`_state` ``(device, inode, size, mtime)`` of what snapcorr last moved in at
    ``path`` in this process, or None: a later look can tell its own file from one put there
    since."""
    with _LOCK:
        return _WRITTEN.get(_target_key(path))


def _note_written(target):
    with _LOCK:
        _WRITTEN.pop(_target_key(target), None)
        _WRITTEN[_target_key(target)] = _state(target)
        while len(_WRITTEN) > _WRITTEN_KEEP:
            del _WRITTEN[next(iter(_WRITTEN))]


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

    ``expected`` holds, for each target, the :func:`_state` of what was there when it was
    checked (None: nothing, and nothing may be replaced). Existing targets are moved aside
    and checked against it; the old ones are deleted only once every new path is in place; on
    any failure (an interruption too) the new paths are taken out and the old ones put back.
    """
    _refuse_if_interrupted()
    moves = [(Path(new), Path(target)) for new, target in moves]
    for new, target in moves:
        _check_kind(target, directory=new.is_dir())
    with _LOCK:
        hooks = list(_BEFORE_MOVE)
    for hook in hooks:  # before anything is moved: told of every name first
        for new, target in moves:
            hook(new, target)
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
                # named and listed before it is made: an interruption between the two left
                # an empty folder behind that no later run removed
                aside = target.parent / f".{target.name}.old.{secrets.token_hex(4)}"
                asides.append((aside, target))
                os.mkdir(aside, 0o700)
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
    for aside, _ in asides:  # the old ones now go: a cleanup removes what an interruption
        _register(aside)      # leaves of them
    for target in placed:
        _note_written(target)
    for aside, _ in asides:
        shutil.rmtree(aside, ignore_errors=True)
        _unregister(aside)


#: What :func:`before_moving_in` calls before each move in (innermost last).
_BEFORE_MOVE: list = []


@contextlib.contextmanager
def before_moving_in(hook):
    """Inside the block, ``hook(new, target)`` is called for every finished output just
    before it is moved in: ``new`` is the complete temporary (its mark tied), ``target`` the
    path it becomes. A file that lists what was written (the demo's marker) can so name a
    file before it is there: however the command is cut short, a file it moved in is one it
    listed. A hook that raises stops the write: nothing is moved in. Blocks nest.

    Examples
    --------
    >>> from snapcorr.files.safety import before_moving_in
    >>> with before_moving_in(lambda new, target: None):
    ...     pass
    """
    with _LOCK:
        _BEFORE_MOVE.append(hook)
    try:
        yield
    finally:
        with _LOCK:
            _BEFORE_MOVE.remove(hook)


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
    before = _expected(path)  # only what was there when it was checked may be replaced
    _check_content(path)  # again now: a PNG or TOML only if snapcorr wrote it
    tmp = _make_temporary(path, directory=directory)
    try:
        write(tmp)
        _usual_permissions(tmp, directory=directory)
        _stamp(tmp, path)
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
    before = [_expected(p) for p in paths]
    for p in paths:
        _check_content(p)
    tmp = _make_temporary(paths[0], directory=True)
    try:
        write(tmp)
        for p in paths:
            if not (tmp / p.name).is_file():
                raise ValueError(f"the writer did not produce {p.name}")
        for p in paths:
            _stamp(tmp / p.name, p)
        _replace([(tmp / p.name, p) for p in paths], before)
    finally:
        remove_path(tmp, settle_s=0)
    return paths


def _stamp(new, target):
    """Tie snapcorr's mark in the finished temporary ``new`` to the name it is moved in as
    (``target``'s), for the formats whose mark a re-save would copy; see
    :func:`snapcorr.files.marks.tie_mark`."""
    tie_mark(Path(new), Path(target).name)


# -- signals ---------------------------------------------------------------------------------

#: The signal that came inside the open :func:`cleanup_on_signals` blocks (None: none yet),
#: and the ``KeyboardInterrupt`` last raised for one (told from others when Python drops it).
_RECEIVED = None
_RAISED = None
#: How many :func:`cleanup_on_signals` blocks of the main thread are open.
_OPEN = 0


def _interrupt(signum, frame):
    global _RECEIVED, _RAISED
    _RECEIVED = signum
    _RAISED = KeyboardInterrupt(f"{signal.Signals(signum).name} received")
    raise _RAISED


def _refuse_if_interrupted():
    """Raise ``KeyboardInterrupt`` if a signal came inside the open :func:`cleanup_on_signals`
    blocks: nothing is moved in after it, even if its interrupt was swallowed (a library's
    ``except BaseException``) instead of ending the command."""
    if _RECEIVED is not None:
        raise KeyboardInterrupt(f"{signal.Signals(_RECEIVED).name} received")


def _deliver_again(signum):
    """In a thread of its own: interrupt the main thread again with ``signum`` (its handler
    runs there at its next step), unless the blocks were left meanwhile."""
    time.sleep(0.01)  # the main thread first leaves the finalizers it was in
    if _RECEIVED == signum and signal.getsignal(signum) is _interrupt:
        _thread.interrupt_main(signum)


def _lost_interrupt_hook(previous):
    """An ``unraisablehook`` that delivers again the interrupt Python dropped: raised while a
    finalizer (``__del__``, a weak reference's callback) ran, it cannot leave the finalizer
    and would otherwise be printed and forgotten, and the command would go on and write its
    outputs. Everything else goes to ``previous``."""

    def hook(unraisable):
        if _RAISED is not None and unraisable.exc_value is _RAISED and _RECEIVED is not None:
            # a thread of its own: threading's locks may be held where the finalizer ran
            _thread.start_new_thread(_deliver_again, (_RECEIVED,))
            return
        previous(unraisable)

    return hook


def _take_signals(names):
    """Install :func:`_interrupt` for the signals ``names`` and for SIGINT where Python's own
    Ctrl-C handler has it (ignored, as in a background job, it stays ignored), and the hook
    that delivers a dropped interrupt again. Returns what to restore."""
    numbers = [getattr(signal, s) for s in names if hasattr(signal, s)]
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        numbers.append(signal.SIGINT)
    previous = {s: signal.signal(s, _interrupt) for s in dict.fromkeys(numbers)}
    hook = sys.unraisablehook
    sys.unraisablehook = _lost_interrupt_hook(hook)
    return previous, (sys.unraisablehook, hook)


def _give_back_signals(previous, hooks):
    """Restore the handlers and the hook :func:`_take_signals` replaced."""
    global _RECEIVED, _RAISED
    for s, handler in previous.items():
        signal.signal(s, handler if handler is not None else signal.SIG_DFL)
    ours, hook = hooks
    if sys.unraisablehook is ours:
        sys.unraisablehook = hook
    if _OPEN == 0:
        _RECEIVED = _RAISED = None


@contextlib.contextmanager
def cleanup_on_signals(signals=("SIGTERM", "SIGHUP")):
    """Clean up temporary files however a command ends.

    Inside the block, ``signals`` (by default SIGTERM and SIGHUP) and Ctrl-C (SIGINT, where
    Python's own handler has it) raise ``KeyboardInterrupt`` in the main thread, so
    ``finally`` blocks run and atomic writes remove their temporary files. An interrupt Python
    drops (it came while a finalizer ran) is raised again, and after a signal no output is
    moved in until the block is left. On leaving, normally or by any exception, every
    temporary path registered since entering and still present is removed (files unlinked,
    folders deleted) with those signals and SIGINT ignored, and the previous handlers are
    restored. Outside the main thread the handlers are left alone and only the cleanup is
    done. The block is also a :func:`checked_outputs` scope: outputs checked in it are
    replaced only as they were checked.

    Examples
    --------
    >>> from snapcorr.files.safety import cleanup_on_signals
    >>> with cleanup_on_signals():
    ...     pass
    """
    global _OPEN
    before = set(map(str, temporary_paths()))
    main = threading.current_thread() is threading.main_thread()
    previous, hooks = {}, None
    if main:
        previous, hooks = _take_signals(signals)
        _OPEN += 1
    try:
        with checked_outputs():
            yield
    finally:
        if main:
            for s in {*previous, signal.SIGINT}:
                previous.setdefault(s, signal.getsignal(s))
                signal.signal(s, signal.SIG_IGN)
        try:
            for path in temporary_paths():
                if str(path) not in before:
                    remove_path(path)
        finally:
            if main:
                _OPEN -= 1
                _give_back_signals(previous, hooks)
