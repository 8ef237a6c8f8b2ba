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


def test_a_check_naming_a_keyword_names_the_option_instead():
    """The library's checks begin with the keyword (``n_eff must ...``); the command line
    says the option the user typed. Only a message that begins with it: a file's key is
    said after the file, and stays the file's."""
    from snapcorr._validation import check_positive
    from snapcorr.cli import build_parser
    from snapcorr.cli._errors import command_parser, option_names

    options = option_names(command_parser(build_parser(), "shift"))
    assert options["n_eff"] == "--n-eff" and options["f_number"] == "--f-number"
    with pytest.raises(ValueError) as info:
        check_positive("tolerance_nm", -1.0)
    assert _message(info.value, options) == ("--tolerance-nm must be a finite number > 0, "
                                             "got -1.0")
    for kept in ("lens.toml: n_eff must be below 5", "n_effective must be 1",
                 "the n_eff must be 1", "n_eff is 1"):
        assert _message(ValueError(kept), options) == kept
    assert _message(ValueError("n_eff = 9 is no index"), options) == "--n-eff = 9 is no index"
    assert command_parser(build_parser(), "nope") is None


def test_a_python_keyword_in_a_message_is_the_option_only_where_the_command_has_one():
    err = ValueError("the budget does not model it; name one it does with profile=: gaussian")
    assert _message(err, {"profile": "--profile"}).endswith("with --profile: gaussian")
    assert "profile=" in _message(err, {"method": "--method"})  # no --profile: not invented
    assert _message(ValueError("pass overwrite=True"), {"overwrite": "--overwrite"}) == \
        "pass --overwrite"
