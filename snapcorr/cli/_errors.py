"""Errors as the command line says them: one line, in its own terms (its options, not the
library's parameter names)."""

from __future__ import annotations

import argparse
import sys

#: Library parameter names as the command line spells them, for error messages.
_CLI_TERMS = {
    "pass wavelength_nm": "give --sensor SENSOR.toml (its cwl_nm are the wavelengths)",
    "virtual_wavelengths_nm": "--virtual-wavelengths",
    "virtual_fwhm_nm": "--virtual-fwhm-nm",
    "overwrite=True": "--overwrite",
    "but wavelength_nm gives": "but the --sensor has",
    "(read a 2-D frame with read_frame)": "(a 2-D raw frame of a mosaic camera is read with "
                                          "that camera's --sensor, whose layout is mosaic)",
}


def _message(err):
    """The exception as one line, in command-line terms."""
    message = " ".join(str(err).split())  # libraries' messages may span lines
    for term, cli in _CLI_TERMS.items():
        message = message.replace(term, cli)
    return message


class _Parser(argparse.ArgumentParser):
    """Usage errors as one line, like every other error, with where to read more."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _quiet_unraisable(unraisable):
    """Drop errors raised while collecting objects left behind by an interruption."""


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"snapcorr: warning: {_message(message)}", file=sys.stderr)

