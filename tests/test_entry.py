"""The command line's entry point: a Ctrl-C while it loads is one line, not a traceback."""

import signal
import subprocess
import sys
import types

from snapcorr import _entry


class _Interrupting(types.ModuleType):
    def __getattr__(self, name):
        raise KeyboardInterrupt


def test_a_ctrl_c_while_the_command_line_loads_is_one_line(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "snapcorr.cli", _Interrupting("snapcorr.cli"))
    assert _entry.main() == 130
    assert capsys.readouterr().err == "snapcorr: interrupted\n"


def test_a_ctrl_c_while_the_parser_is_built_in_a_real_process():
    """SIGINT delivered from inside the parser's construction (outside the command's own
    handler): status 130, one line, no traceback."""
    code = ("import os, signal, sys\n"
            "import snapcorr.cli as cli\n"
            "real = cli.build_parser\n"
            "def interrupted():\n"
            "    os.kill(os.getpid(), signal.SIGINT)\n"
            "    return real()\n"
            "cli.build_parser = interrupted\n"
            "sys.argv = ['snapcorr', '--help']\n"
            "from snapcorr._entry import main\n"
            "sys.exit(main())\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 130, res.stderr
    assert res.stderr == "snapcorr: interrupted\n"


def test_once_the_command_returned_a_ctrl_c_ends_the_process_without_a_traceback(monkeypatch):
    monkeypatch.setattr(sys, "argv", ["snapcorr", "--version"])
    before = signal.getsignal(signal.SIGINT)
    try:
        assert _entry.main() == 0
        assert signal.getsignal(signal.SIGINT) is signal.SIG_DFL
    finally:
        signal.signal(signal.SIGINT, before)
