"""Each command's ``--help`` shows its own examples only, and every option has help text."""

from __future__ import annotations

import argparse
import re

import pytest

SUBCOMMANDS = ("demo", "shift", "flatfield", "calibrate", "correct", "budget")


@pytest.mark.parametrize("sub", SUBCOMMANDS)
def test_help_shows_this_subcommands_examples_only(sub, cli):
    rc, out, _ = cli(sub, "--help")
    assert rc == 0
    assert "examples:" in out
    examples = out.split("examples:", 1)[1]
    assert re.search(rf"\bsnapcorr {sub}\b", examples), examples
    others = [o for o in SUBCOMMANDS if o != sub and re.search(rf"\bsnapcorr {o}\b", out)]
    assert not others, f"'snapcorr {sub} --help' shows examples of {others}"


@pytest.mark.parametrize("sub", SUBCOMMANDS)
def test_every_option_has_help_text(sub):
    from snapcorr.cli import build_parser

    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    missing = [a.dest for a in subs.choices[sub]._actions
               if not isinstance(a, argparse._HelpAction)
               and (not a.help or a.help == argparse.SUPPRESS or not a.help.strip())]
    assert not missing, f"snapcorr {sub}: options without help: {missing}"
