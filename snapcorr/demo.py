"""``snapcorr demo``: the main job on the lens and experiment of Goossens et al. 2019.

1. The optics on the bundled Edmund Optics 16 mm profile: the kernel-mean shift of 700 nm
   filters over the field at f/1.4-f/8 by the three models (Eq. 6, exact ideal aperture,
   vignetted aperture) and the relative illumination (``mean_shift.png``, ``.csv``; the
   paper's Fig. 12, extended).
2. The paper's experiment, simulated end to end (:mod:`snapcorr.paper_experiment`): flat
   fields -> lens calibration -> a Snapscan-like cube of a colour filter on a white tile ->
   flat-fielding -> correction by both models, with the paper's metrics
   (``calibration.png``, ``lens.toml``, ``spectra.png``, ``maps.png``).

Everything is summarised in ``summary.txt``.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
from pathlib import Path

import numpy as np

from . import __version__
from ._validation import parse_json
from .data import lens_path
from .files.marks import written_by_snapcorr
from .files.outputs import check_folder_writable
from .files.png import save_png
from .files.reading import NotRegularFileError, file_kind, read_regular
from .files.safety import (
    atomic_write,
    before_moving_in,
    checked_outputs,
    last_written,
    note_checked,
)
from .optics import CORRECTION_MODELS, MEAN_SHIFT_METHODS, Lens, mean_shift

__all__ = ["run_demo"]

F_NUMBERS = (1.4, 2.0, 2.8, 4.0, 8.0)
PAPER_CRAS = (1.9, 10.3, 17.4)
CWL_NM, N_EFF = 700.0, 1.7
#: The correction models the demo plots: the ladder's rungs that are mean-shift methods.
DEMO_MODELS = tuple(m for m in CORRECTION_MODELS if m in MEAN_SHIFT_METHODS)
#: The earlier name of :data:`DEMO_MODELS`.
MODELS = DEMO_MODELS


#: Written into a demo's folder before each output is moved in, and last: the files the demo
#: wrote there (name, size and SHA-256), which a later run may replace without ``overwrite``.
#: A regular file, never followed through a link, replaced atomically.
MARKER = ".snapcorr-demo"
#: The files the demo writes into its folder (besides :data:`MARKER`).
OUTPUTS = ("mean_shift.png", "mean_shift.csv", "calibration.png", "lens.toml", "spectra.png",
           "maps.png", "summary.txt")
_CSV_HEADER = "f_number,cra_deg,asymptotic_nm,ideal_nm,vignetted_nm,relative_illumination"
#: The most read of the marker, and of a file to check it.
_MARKER_LIMIT = 1 << 16
_FILE_LIMIT = 64 << 20


def _read_marker(out):
    """The files :data:`MARKER` vouches for (``{name: [{"size", "sha256"}, ...]}``: a name
    may list the file there and the one about to replace it; an earlier version's marker
    vouches for none), or None without a marker. A marker that is not a regular file (a
    symbolic link, a FIFO, a folder...) is refused before it is opened."""
    path = out / MARKER
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return None
    not_marker = (f"{path} exists and is {{}}, not the marker snapcorr demo writes (a "
                  "regular file): remove it or choose another folder (out_dir=)")
    if not stat.S_ISREG(mode):
        raise ValueError(not_marker.format(file_kind(mode)))
    try:
        data = read_regular(path, _MARKER_LIMIT, follow_links=False)
    except NotRegularFileError:  # swapped since, or far larger than a marker
        raise ValueError(not_marker.format("not a marker-sized regular file")) from None
    except OSError as err:
        raise ValueError(f"{path}: cannot read it ({err.strerror or err}); remove it or "
                         "choose another folder (out_dir=)") from None
    try:
        doc = parse_json(data)
    except ValueError:
        return {}
    files = doc.get("files") if isinstance(doc, dict) else None
    if not isinstance(files, dict):
        return {}
    listed = {}
    for name, entries in files.items():
        entries = [entries] if isinstance(entries, dict) else entries
        if name in OUTPUTS and isinstance(entries, list):
            listed[name] = [e for e in entries if isinstance(e, dict)]
    return listed


def _entry(data):
    return {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def _vouched(path, entries):
    """Whether ``path`` is a file the marker lists (one of ``entries``: its size and
    SHA-256)."""
    entries = [e for e in entries if isinstance(e.get("size"), int)
               and e["size"] <= _FILE_LIMIT]
    if not entries:
        return False
    try:
        data = read_regular(path, _FILE_LIMIT, follow_links=False)
    except (OSError, ValueError):
        return False
    return _entry(data) in [{"size": e["size"], "sha256": e.get("sha256")} for e in entries]


def _own_mark(path):
    """``(True, "")`` if ``path`` carries the mark the demo writes into that file (a PNG's or
    TOML's snapcorr mark naming it; the table's header; the summary's first line), else
    ``(False, what it is)``."""
    if path.suffix in (".png", ".toml"):
        return written_by_snapcorr(path)
    try:
        first = read_regular(path, _FILE_LIMIT, follow_links=False, whole=False)
    except (OSError, ValueError):
        return False, "a file that cannot be read"
    first = first.split(b"\n", 1)[0].decode("utf-8", "replace").rstrip("\r")
    if path.name == "mean_shift.csv" and first == _CSV_HEADER:
        return True, ""
    if path.name == "summary.txt" and re.match(r"snapcorr \S+ demo: ", first):
        return True, ""
    return False, "a file snapcorr demo did not write"


def check_out_dir(out_dir, *, overwrite=False):
    """The demo's output folder, refused if it holds files the demo did not make.

    Everything is checked before the demo does any work. A folder that does not exist yet
    (in a folder that does: a missing parent is refused, as for every command's output),
    is empty, or holds :data:`MARKER` is fine, and what the demo writes there
    (:data:`OUTPUTS`) may replace a file only if the marker lists that very file (its size and
    SHA-256); any other file of those names only with ``overwrite=True``, and only if it
    carries snapcorr's mark (a PNG or TOML snapcorr wrote as that file, the demo's table
    header or summary line). A folder holding other files and no marker needs
    ``overwrite=True``. Anything but a regular file at one of those names, or at the marker's
    (a symbolic link, a FIFO...), is refused before it is opened. What is at each name is
    noted (:func:`snapcorr.files.safety.note_checked`): within :func:`run_demo`, a file that
    appears or changes there later is not replaced.
    """
    out = Path(out_dir)
    try:
        return _check_out_dir(out, overwrite)
    except OSError as err:  # a name too long, a loop of links: said by the option
        if isinstance(err, FileExistsError):
            raise
        raise ValueError(f"out_dir {out}: {err.strerror or type(err).__name__}; choose "
                         "another folder") from None


def _check_out_dir(out, overwrite):
    """:func:`check_out_dir`'s body."""
    if os.path.lexists(out) and not out.is_dir():
        raise ValueError(f"{out} is not a folder; choose another folder (out_dir=)")
    # the folder written in: out, or the folder it is made in, which must exist (as every
    # command's output's folder must)
    folder = out if os.path.lexists(out) else (out.parent if out.parent.parts else Path("."))
    check_folder_writable(out, "out_dir", folder=folder)  # probed, before any work
    for name in (MARKER, *OUTPUTS):  # before anything is examined: only this is replaced
        note_checked(out / name)
    if not out.is_dir():
        return out
    vouched = _read_marker(out)
    if vouched is None and not overwrite and any(out.iterdir()):
        names = sorted(p.name for p in out.iterdir())
        raise FileExistsError(
            f"{out} holds files snapcorr demo did not make ({', '.join(names[:4])}"
            f"{', ...' if len(names) > 4 else ''}); choose an empty or new folder (out_dir=), "
            "or pass overwrite=True to replace the files of the same names snapcorr wrote")
    theirs = []
    for name in OUTPUTS:
        path = out / name
        try:
            mode = os.lstat(path).st_mode
        except FileNotFoundError:
            continue
        if not stat.S_ISREG(mode):
            raise ValueError(f"{path} exists and is {file_kind(mode)}; snapcorr demo replaces "
                             "only files it wrote: move it away or choose another folder "
                             "(out_dir=)")
        if not (vouched and name in vouched and _vouched(path, vouched[name])):
            theirs.append(name)
    if theirs and not overwrite:
        them = "it" if len(theirs) == 1 else "them"
        why = ("it holds no marker" if vouched is None else
               f"its marker {MARKER} does not list {them} as the demo wrote {them}")
        raise FileExistsError(
            f"{out} holds {', '.join(theirs)}, which snapcorr demo did not write ({why}); "
            "choose an empty or new folder (out_dir=), or pass overwrite=True to replace "
            "the files of the same names snapcorr wrote")
    for name in theirs:
        ours, found = _own_mark(out / name)
        if ours and vouched and name in vouched and Path(name).suffix in (".csv", ".txt"):
            # the marker lists the file the demo wrote there, and this is not it: a table or
            # summary edited since (its first line, all the mark it has, kept)
            ours, found = False, ("not the file snapcorr demo wrote there (its marker "
                                  f"{MARKER} lists another size or digest: changed since)")
        if not ours:
            raise ValueError(f"{out / name} exists and is {found}; overwrite=True replaces "
                             "only what snapcorr wrote: move it away or choose another folder "
                             "(out_dir=)")
    return out


def _save_marker(out, listed):
    """:data:`MARKER`, atomically, listing ``listed`` (``{name: [entry, ...]}``; one entry is
    written as itself, a name without one not at all)."""
    files = {n: es[0] if len(es) == 1 else es for n, es in listed.items() if es}
    text = json.dumps({"written_by": f"snapcorr {__version__} demo", "files": files}, indent=1)
    atomic_write(out / MARKER, lambda p: p.write_text(text + "\n", encoding="utf-8"))


def _write_marker(out):
    """:data:`MARKER`, atomically, listing each output that is still the file the demo moved
    in (the same device, inode, size and time as when it was written)."""
    files = {}
    for name in OUTPUTS:
        path = out / name
        try:
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0)
                         | getattr(os, "O_NONBLOCK", 0))
        except OSError:
            continue
        with os.fdopen(fd, "rb") as fh:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode) or last_written(path) != (
                    st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns) or \
                    st.st_size > _FILE_LIMIT:
                continue  # not the file the demo wrote: not vouched for
            data = fh.read(_FILE_LIMIT + 1)
        files[name] = [_entry(data)]
    _save_marker(out, files)


def _on_disk(out, listed):
    """``listed`` with only the entries that are the files at their names now."""
    return {n: [e for e in es if _vouched(out / n, [e])] for n, es in listed.items()}


def _marker_keeper(out):
    """``(before_move, settle)`` for a run in ``out``: ``before_move(new, target)`` lists an
    output in :data:`MARKER` before it is moved in (:func:`before_moving_in`), beside the file
    still at its name; ``settle()`` drops what is no longer there.

    Every file of the demo's at a name is so listed at every moment, however the run ends: a
    previous run's outputs (as the marker listed them when the run began) until they are
    replaced, then the new ones. A name listed whose file never came is harmless."""
    listed = _on_disk(out, _read_marker(out) or {})
    folder = os.path.realpath(out)

    def before_move(new, target):
        name = Path(target).name
        if name not in OUTPUTS or os.path.realpath(Path(target).parent) != folder:
            return
        try:
            data = read_regular(new, _FILE_LIMIT, follow_links=False)
        except (OSError, ValueError):  # not one file the marker can list: never vouched for
            return
        listed[name] = [*_on_disk(out, {name: listed.get(name, [])})[name], _entry(data)]
        _save_marker(out, listed)

    def settle():
        listed.update(_on_disk(out, listed))
        _save_marker(out, listed)

    return before_move, settle


def _mean_shift_over_the_field(lens):
    """Part 1: the summary's lines, the CSV's rows and the figure (without pyplot, so no
    global plotting state changes) of the mean shift and relative illumination over CRA."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    cra = np.linspace(0.0, 20.0, 201)
    rows = []
    lines = [f"snapcorr {__version__} demo: {lens.name}, cwl {CWL_NM:g} nm, n_eff {N_EFF:g}",
             f"exit pupil x = {lens.exit_pupil_mm:g} mm, {lens.describe_vignetting()}, "
             f"m = {lens.magnification:g}, m_P = {lens.pupil_magnification:g}", "",
             "spread of the mean shift between CRA 1.9, 10.3 and 17.4 deg (nm):",
             f"{'f/#':>6} {'onset':>8} {'Eq. 6':>8} {'ideal':>8} {'vignetted':>10}"]
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    ax, ax2 = fig.subplots(1, 2)
    colours = colormaps["viridis"](np.linspace(0, 0.9, len(F_NUMBERS)))
    spreads = {}
    for f, colour in zip(F_NUMBERS, colours, strict=True):
        curves = {m: mean_shift(CWL_NM, N_EFF, f, cra, lens, method=m) for m in DEMO_MODELS}
        rel = lens.relative_illumination(f, cra)
        for i, c in enumerate(cra):
            rows.append((f, c, *(curves[m][i] for m in DEMO_MODELS), rel[i]))
        onset = float(lens.onset_cra_deg(f))
        spread = spreads[f] = {
            m: np.ptp(mean_shift(CWL_NM, N_EFF, f, PAPER_CRAS, lens, method=m)) for m in DEMO_MODELS
        }
        lines.append(f"{f:>6g} {onset:>7.2f}° {spread['asymptotic']:>8.2f} "
                     f"{spread['ideal']:>8.2f} {spread['vignetted']:>10.2f}")
        ax.plot(cra, curves["vignetted"], color=colour, lw=2, label=f"f/{f:g} vignetted")
        ax.plot(cra, curves["asymptotic"], color=colour, lw=1, ls="--")
        if onset < cra[-1]:
            ax.plot(onset, mean_shift(CWL_NM, N_EFF, f, onset, lens), "o", color=colour)
        ax2.plot(cra, rel, color=colour, lw=2, label=f"f/{f:g}")
    ax.set(xlabel="chief-ray angle (deg)", ylabel="mean shift of a 700 nm filter (nm)",
           title="Kernel mean: vignetted (solid), Eq. 6 (dashed), onset (dots)")
    ax2.set(xlabel="chief-ray angle (deg)", ylabel="relative illumination A / (pi R^2)",
            title="Relative illumination of the vignetted pupil (no cos^4)")
    for a in (ax, ax2):
        a.legend(fontsize=8)
        a.grid(alpha=0.3)
    first = F_NUMBERS[0]
    s1 = spreads[first]
    lines += ["", f"Reading: without vignetting the field spreads the filters by "
              f"~{s1['ideal']:.0f}-{s1['asymptotic']:.0f} nm at any f-number; the vignetting "
              f"circle cuts the oblique rays at wide apertures, so at f/{first:g} the spread is "
              f"only {s1['vignetted']:.1f} nm (Goossens et al. measured ~2 nm). Correcting with "
              "Eq. 6 there would over-correct the field edge by the difference."]
    return lines, rows, fig


def run_demo(out_dir, *, lens: Lens | None = None, echo=print, overwrite=False):
    """Run the demo; write ``mean_shift.png``, ``mean_shift.csv`` and ``summary.txt``, and the
    simulated experiment's ``calibration.png``, ``lens.toml``, ``spectra.png`` and ``maps.png``.

    Refuses, before any work, a folder holding files the demo did not make unless
    ``overwrite``, and even then files of its names snapcorr did not write
    (:func:`check_out_dir`); :data:`MARKER` lists each output before it is moved in, beside
    the previous run's file it replaces (a run cut short at any point can be run again in the
    same folder).

    Parameters
    ----------
    out_dir : str or Path
        Output folder, created if missing; the folder it is made in must exist.
    lens : Lens, optional
        The lens of part 1 (default: the bundled Edmund Optics 16 mm profile); the simulated
        experiment uses its own.
    echo : callable
        ``echo(text)`` prints progress and the summary.
    overwrite : bool
        Write into a folder holding other files, replacing files of the demo's names that
        snapcorr wrote (never others).

    Returns
    -------
    dict
        Paths of the outputs: ``figure``, ``table``, ``summary``, ``spectra``,
        ``calibration``, ``maps`` and ``lens``.
    """
    with checked_outputs():  # the folder's files held to what the checks found
        return _run(check_out_dir(out_dir, overwrite=overwrite), lens, echo)


def _run(out, lens, echo):
    out.mkdir(exist_ok=True)  # in a folder that exists (checked)
    before_move, settle = _marker_keeper(out)
    with before_moving_in(before_move):  # each output listed before it is there
        paths = _outputs(out, lens, echo, settle)
    _write_marker(out)  # at the end: only the files this run moved in and left as they are
    return paths


def _outputs(out, lens, echo, settle):
    """Write the outputs into ``out`` (``settle()`` after each step)."""
    lens = lens or Lens.load(lens_path())
    lines, rows, fig = _mean_shift_over_the_field(lens)
    figure = save_png(fig, out / "mean_shift.png", dpi=120)
    settle()

    def write_csv(p):
        np.savetxt(p, np.array(rows), delimiter=",", header=_CSV_HEADER, comments="",
                   fmt="%.6f")

    table = atomic_write(out / "mean_shift.csv", write_csv)
    settle()
    echo("\n".join(lines))
    echo("")
    echo("The paper's experiment, simulated (about half a minute) ...")
    from .paper_experiment import run as run_experiment

    exp_lines, _ = run_experiment(out, echo=echo, written=settle)
    lines += ["", "The paper's experiment, simulated end to end:", *exp_lines]
    text = "\n".join(lines) + "\n"
    summary = atomic_write(out / "summary.txt", lambda p: p.write_text(text, encoding="utf-8"))
    echo(f"wrote {', '.join(str(out / n) for n in OUTPUTS)}")
    return {"figure": figure, "table": table, "summary": summary,
            "spectra": out / "spectra.png", "calibration": out / "calibration.png",
            "maps": out / "maps.png", "lens": out / "lens.toml"}
