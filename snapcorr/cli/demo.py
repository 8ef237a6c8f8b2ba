"""``snapcorr demo``: the paper's lens and experiment, simulated end to end."""

from __future__ import annotations

from ._options import add_command
from ._types import _path

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = ("the main job on a bundled default: calibrate the paper's lens, correct a simulated cube,"
        " write figures")

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
      snapcorr demo                       the paper's lens and experiment, simulated end to end
      snapcorr demo --out /tmp/demo       ... writing the figures elsewhere
    """


def add_parser(subparsers):
    p = add_command(subparsers, "demo", HELP, EXAMPLES)
    p.add_argument("--out", default="snapcorr-demo", type=_path,
                   help="output folder (default: %(default)s); a folder holding other files "
                   "is refused")
    p.add_argument("--overwrite", action="store_true",
                   help="write into a folder holding other files, replacing those of the "
                   "same names")
    p.set_defaults(func=run)


def run(args):
    from ..demo import run_demo

    run_demo(args.out, overwrite=args.overwrite)
    return 0

