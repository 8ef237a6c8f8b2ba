"""Errors in the command line's own terms, each one line."""

import argparse
import io

import pytest

from snapcorr.cli._errors import _message, _one_line_warning, _Parser


def test_library_terms_become_options_and_lines_join():
    err = ValueError("virtual_wavelengths_nm and virtual_fwhm_nm\n   are not both\tgiven; "
                     "pass overwrite=True")
    assert _message(err) == ("--virtual-wavelengths and --virtual-fwhm-nm are not both given; "
                             "pass --overwrite")


def test_a_usage_error_is_one_line_pointing_to_help(capsys):
    parser = _Parser(prog="snapcorr probe")
    parser.add_argument("--n", type=int)
    with pytest.raises(SystemExit) as exit_:
        parser.parse_args(["--n", "x"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.endswith("(see snapcorr probe --help)\n"), err
    assert isinstance(parser, argparse.ArgumentParser)


def test_a_warning_is_one_line(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr("sys.stderr", err)
    _one_line_warning(UserWarning("pass overwrite=True\nto replace"), UserWarning, "f.py", 1)
    assert err.getvalue() == "snapcorr: warning: pass --overwrite to replace\n"
