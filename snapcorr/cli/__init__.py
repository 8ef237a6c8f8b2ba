"""Command-line interface: a thin shell around the library.

Every expected failure becomes one line on stderr and a non-zero exit status; inputs are never
written over, outputs appear whole or not at all (also on Ctrl-C and SIGTERM).

Each command is a module of its name (``snapcorr.cli.correct`` is ``snapcorr correct``) with
``add_parser(subparsers)`` and ``run(args)``; the pieces they share are ``_options`` (option
groups; the argument types of ``_types``), ``_output`` (outputs checked and written),
``_frames`` (inputs read), ``_flats`` (the flats of ``calibrate``), ``_targets`` (a fit to a
target's cubes), ``_progress`` (progress bars) and ``_errors`` (one-line messages).
"""

from __future__ import annotations

import argparse
import sys
import textwrap
import warnings

from . import _progress, budget, calibrate, correct, demo, flatfield, pupil, sensor, shift, stream
from ._errors import (
    _message,
    _one_line_warning,
    _Parser,
    _quiet_unraisable,
    command_parser,
    option_names,
)
from ._frames import FLATFIELD_RECORD
from ._options import (
    DTYPE_HELP,
    ORIGIN_HELP,
    OVERWRITE_HELP,
    SENSOR_HELP,
    STORAGE_CHOICES,
    _center_option,
)
from ._output import RAW_COPIES
from ._targets import TARGET_TOLERANCE_HELP

__all__ = ["COMMAND_MODULES", "DTYPE_HELP", "EXAMPLES", "FLATFIELD_RECORD", "ORIGIN_HELP",
           "OVERWRITE_HELP", "RAW_COPIES", "SENSOR_HELP", "STORAGE_CHOICES",
           "TARGET_TOLERANCE_HELP", "WORKFLOW", "build_parser", "main"]

#: Each command's module, in the order ``snapcorr --help`` lists them.
COMMAND_MODULES = {"demo": demo, "sensor": sensor, "flatfield": flatfield, "stream": stream,
                   "calibrate": calibrate, "pupil": pupil, "correct": correct, "shift": shift,
                   "budget": budget}

#: Each command's examples (its --help shows its own; ``snapcorr --help`` shows all).
EXAMPLES = {name: module.EXAMPLES for name, module in COMMAND_MODULES.items()}

#: ``snapcorr --help``: the everyday path in four commands (each command's --help has more).
WORKFLOW = r"""
  snapcorr demo                           the paper's experiment, simulated end to end
  snapcorr flatfield scene.hdr --dark dark.hdr --white white.hdr --sensor snapscan_vnir \
      --out scene_ff.nc                   (DN - dark) / (white - dark)
  snapcorr calibrate --flat 2=f2.tif --flat 8=f8.tif --target-cube 2=t2_ff.nc \
      --target-cube 8=t8_ff.nc --sensor snapscan_vnir --pixel-pitch-um 5.5 --out my_lens.toml
                                          the lens, once: flats and a spectral target
  snapcorr correct scene_ff.nc --lens my_lens.toml --sensor snapscan_vnir --f-number 2 \
      --out scene_corrected.nc --plot scene_corrected.png
                                          every pixel's wavelengths
"""


class _Version(argparse.Action):
    """``--version``: the installed version, looked up only when asked (the lookup costs as
    much as importing numpy)."""

    def __call__(self, parser, namespace, values, option_string=None):
        from .. import __version__

        parser._print_message(f"snapcorr {__version__}\n", sys.stdout)
        parser.exit()


def _pair_options(parser, argv):
    """The options of ``argv``'s command that take a pair of numbers (their argument type is
    marked ``number_pair``: :mod:`._types`), as they may be typed: in full, or shortened as
    argparse allows (``--cent`` where no other option starts so)."""
    command = next((a for a in argv if not a.startswith("-")), None)
    sub = command_parser(parser, command) if command else None
    if sub is None:
        return set()
    pairs = {s for a in sub._actions if getattr(a.type, "number_pair", False)
             for s in a.option_strings}
    long = [s for a in sub._actions for s in a.option_strings if s.startswith("--")]

    def names_one_pair(prefix):  # as argparse resolves a shortened option: a single match
        matches = [o for o in long if o.startswith(prefix)]
        return len(matches) == 1 and matches[0] in pairs

    return pairs | {o[:n] for o in pairs if o.startswith("--") for n in range(3, len(o))
                    if names_one_pair(o[:n])}


def _negative_pairs(parser, argv):
    """``--center -5,5`` as ``--center=-5,5`` for every option of the command that takes a
    pair of numbers: argparse takes a value that starts with ``-`` and is not a plain number
    for an option (and refused ``--center -5,5`` as ``--center`` without its argument)."""
    options = _pair_options(parser, argv)
    out, i = [], 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--":  # what follows is no option
            out.extend(argv[i:])
            break
        value = argv[i + 1] if i + 1 < len(argv) else None
        if arg in options and value is not None and value.startswith("-") \
                and not value.startswith("--") and "," in value:
            out.append(f"{arg}={value}")
            i += 2
            continue
        out.append(arg)
        i += 1
    return out


def build_parser():
    parser = _Parser(
        prog="snapcorr",
        description="Wavelength correction for spectral cameras with thin-film "
        "Fabry-Perot filters (Goossens et al. 2019).",
        epilog="a session (snapcorr COMMAND --help shows each command's options and "
        "examples):\n" + textwrap.indent(textwrap.dedent(WORKFLOW).strip("\n"), "  "),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action=_Version, nargs=0,
                        help="show the version number and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    for module in COMMAND_MODULES.values():
        module.add_parser(sub)
    return parser


def _local_scheduler(args):
    """Dask's threads for the command's work, named as a function
    (:func:`snapcorr._threads.dask_threads`: otherwise dask imports :mod:`dask.distributed`
    at a process's first compute only to look for a client). A command given ``--scheduler
    ADDRESS`` runs on the cluster's client instead, so there nothing is set."""
    if getattr(args, "scheduler", None):
        import contextlib

        return contextlib.nullcontext()
    from .._threads import dask_threads

    return dask_threads(import_dask=True)


def _noting_moves(moved):
    """A :func:`~snapcorr.files.safety.before_moving_in` hook that notes, for each finished
    output about to be moved in, its final name and what the finished temporary is (device,
    inode: a move keeps them), in ``moved``."""
    import os

    def note(new, target):
        try:
            st = os.lstat(new)
        except OSError:
            return
        moved.append((target, (st.st_dev, st.st_ino)))

    return note


def _kept(moved):
    """The final names of ``moved`` (:func:`_noting_moves`) under which the finished output
    is now, complete: it was moved in before the interruption, and is kept."""
    import os

    kept = []
    for target, identity in moved:
        try:
            st = os.lstat(target)
        except OSError:
            continue
        if (st.st_dev, st.st_ino) == identity and str(target) not in kept:
            kept.append(str(target))
    return kept


def _interrupted(command, moved):
    """What an interruption of ``command`` left: unfinished outputs removed, and the outputs
    already complete under their final names kept (:func:`_kept`)."""
    kept = _kept(moved)
    if not kept:
        return f"snapcorr {command}: interrupted; unfinished outputs were removed"
    names = ", ".join(kept)
    were = "was complete and was kept" if len(kept) == 1 else "were complete and were kept"
    return (f"snapcorr {command}: interrupted; only unfinished outputs were removed: {names} "
            f"{were}")


def main(argv=None):
    from ..files.safety import before_moving_in, cleanup_on_signals

    parser = build_parser()
    argv = _negative_pairs(parser, sys.argv[1:] if argv is None else list(argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # usage errors and --help: argparse has printed them
        return exit_.code
    if not getattr(args, "command", None):
        parser.print_help()
        return 0
    _progress._SHOW_PROGRESS = (False if getattr(args, "quiet", False) else
                      True if getattr(args, "progress", False) else None)
    moved = []  # the outputs moved in, to tell an interruption's kept outputs
    try:
        with cleanup_on_signals(), before_moving_in(_noting_moves(moved)), \
                warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.showwarning = _one_line_warning
            _center_option(args)
            with _local_scheduler(args):
                return args.func(args)
    except (ValueError, TypeError, OverflowError, OSError, KeyError) as err:
        options = option_names(command_parser(parser, args.command) or parser)
        print(f"snapcorr {args.command}: error: {_message(err, options)}", file=sys.stderr)
        return 1
    except Exception as err:  # a codec's own error type on an input's damaged chunk
        from ..files.chunks import damaged_input, damaged_input_said

        text = " ".join(str(err).split())
        if not damaged_input(text):
            raise
        print(f"snapcorr {args.command}: error: {damaged_input_said(err, text)}",
              file=sys.stderr)
        if argv is None:  # the command line's process: zarr's reads left pending are said
            import logging  # when collected, not worth a line

            logging.getLogger("asyncio").setLevel(logging.CRITICAL)
        return 1
    except KeyboardInterrupt:
        # Libraries interrupted mid-write (h5netcdf, zarr's threads) may fail again when their
        # half-closed objects are collected; Python would print those as "Exception ignored"
        # tracebacks. The unfinished outputs are already removed: say it once, quietly, with
        # those complete under their final names before the interruption, which are kept.
        import signal

        # finishing: a second Ctrl-C waits (for the command line; a caller of main(argv) in a
        # Python session gets its handlers back)
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        hook, sys.unraisablehook = sys.unraisablehook, _quiet_unraisable
        print(_interrupted(args.command, moved), file=sys.stderr)
        if argv is not None:
            signal.signal(signal.SIGINT, previous)
            sys.unraisablehook = hook
        return 130
    finally:
        _progress._SHOW_PROGRESS = None


if __name__ == "__main__":
    sys.exit(main())
