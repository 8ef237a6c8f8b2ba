"""The command line's entry point (``snapcorr``, ``python -m snapcorr``).

:func:`snapcorr.cli.main` turns a Ctrl-C during a command into one line; this wraps it so a
Ctrl-C while the command line loads (its modules, its parser) does the same instead of
printing Python's traceback, and so a Ctrl-C once the command has returned (Python waiting
for a library's threads to end as it exits) ends the process at once, without the threading
module's traceback: the outputs are complete by then.
"""

import signal
import sys


def main():
    """Run the command line; its exit status."""
    try:
        from .cli import main as run

        status = run()
    except KeyboardInterrupt:  # before the command's own handler: nothing was written
        print("snapcorr: interrupted", file=sys.stderr)
        return 130
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
    return status
