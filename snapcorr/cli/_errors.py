"""Errors as the command line says them: one line, in its own terms (its options, not the
library's parameter names)."""

from __future__ import annotations

import argparse
import errno
import re
import sys

#: Library parameter names as the command line spells them, for error messages.
_CLI_TERMS = {
    "pass wavelength_nm": "give --sensor SENSOR.toml (its cwl_nm are the wavelengths)",
    "virtual_wavelengths_nm": "--virtual-wavelengths",
    "virtual_fwhm_nm": "--virtual-fwhm-nm",
    "overwrite=True": "--overwrite",
    "a packing range goes with": "--pack-range goes with",
    "but wavelength_nm gives": "but the --sensor has",
    "(read a 2-D frame with read_frame)": "(a 2-D raw frame of a mosaic camera is read with "
                                          "that camera's --sensor, whose layout is mosaic)",
    "read it with read_cube, or save the one band you need": "give the camera's raw 2-D "
                                                             "frame, or save the one band you "
                                                             "need as a file of its own",
}


#: How the library's checks (:mod:`snapcorr._validation`) begin a message about an argument:
#: with its keyword's name, then one of these, or the value itself (``target_fwhm_nm 0.5 nm
#: is narrower ...``).
_CHECK_VERBS = re.compile(r"\s+(?:must\b|repeats\b|=|[-+]?[0-9.]|\()|\s+\S+:\s")

#: Library keywords an option sets under another name (its ``dest``): ``center_rc`` is set by
#: ``--center``, the demo's ``out_dir`` by ``--out``.
_KEYWORD_DESTS = {"center_rc": "center", "out_dir": "out"}

#: The units a library keyword carries and an option may leave out (``cra_deg`` is set by
#: ``--cra``, ``cra_max_deg`` by ``--cra-max``): CONTRIBUTING's names of quantities.
_UNITS = ("_deg", "_nm", "_mm", "_um", "_px", "_pct")


def option_names(parser):
    """``{keyword: option}`` of a command's parser: the library keyword each option sets
    (its ``dest``, and the dest with a unit where the option leaves the unit out) and the
    option as it is typed, ``{"n_eff": "--n-eff", "cra_deg": "--cra"}``."""
    options = {a.dest: max(a.option_strings, key=len) for a in parser._actions
               if a.option_strings and a.dest not in ("help", argparse.SUPPRESS)
               and max(a.option_strings, key=len).startswith("--")}
    with_units = {dest + unit: option for dest, option in options.items()
                  if not dest.endswith(_UNITS) for unit in _UNITS}
    aliases = {k: options[d] for k, d in _KEYWORD_DESTS.items() if d in options}
    return {**{k: v for k, v in {**with_units, **aliases}.items() if k not in options},
            **options}


#: A flat-field reference as the library names it: ``dark``, ``white frame 2 of 3``, ``the
#: white reference``.
_REFERENCE = re.compile(r"^(?P<the>the )?(?P<label>dark|white)(?: frame (?P<k>\d+) of \d+)?"
                        r"(?P<rest>(?: reference)?\b)")


def name_references(message, files):
    """A library message about a flat-field reference (``white frame 2 of 2 and the cube
    ...``) naming the option and the file instead (``--white w2.hdr and the cube ...``);
    ``files`` is ``{"dark": [paths], "white": [paths]}`` as the options gave them."""
    m = _REFERENCE.match(message)
    if m is None or not files.get(m["label"]):
        return message
    paths = files[m["label"]]
    if message[m.end():].startswith(" frames "):  # the frames of one option among themselves
        return f"--{m['label']} frames ({', '.join(map(str, paths))})" + message[m.end() + 7:]
    k = int(m["k"]) - 1 if m["k"] else 0
    name = f"--{m['label']}" + (f" {paths[k]}" if len(paths) == 1 or m["k"] else "")
    return (m["the"] or "") + name + m["rest"] + message[m.end():]


def _message(err, options=None):
    """The exception as one line, in command-line terms; a library check's message that
    begins with a keyword one of ``options`` sets (``{keyword: option}``) names the option
    instead (``n_eff must be ...`` is ``--n-eff must be ...``). Only at the start: a message
    about a file's key begins with the file (``lens.toml: n_eff must ...``). A keyword the
    library names as Python's ``keyword=`` is the option too, where the command has one (a
    library message names no option: which a command has, only the command knows), and
    ``keyword='choice'``, ``keyword=True`` and ``keyword= (a, b)`` the option as typed
    (``--virtual-bands fitted``, ``--fit-n-eff``, ``--sensor-origin-px a,b``)."""
    if isinstance(err, OSError) and err.errno == errno.ENAMETOOLONG and err.filename:
        from ..files.reading import too_long_said

        return too_long_said(err.filename)
    message = _cut(str(err))
    message = " ".join(message.split())  # libraries' messages may span lines
    if message.startswith("Stored and computed checksum do not match"):  # zarr's crc32c
        return ("a chunk of an input Zarr store is damaged: its stored checksum does not match "
                "its bytes (a truncated or corrupted copy); copy the store again from its "
                "source")
    if re.match(r"cannot reshape array of size \d+ into shape", message):  # a Zarr chunk
        return (f"a chunk of an input Zarr store does not hold what its metadata says "
                f"({message}): a chunk copied in from another array, or its type edited; copy "
                "the store again from its source")
    for term, cli in _CLI_TERMS.items():
        message = message.replace(term, cli)
    for keyword, option in (options or {}).items():
        k = rf"(?<![\w-]){re.escape(keyword)}="
        # keyword='fitted' is the option and its choice, keyword=True the flag, keyword=
        # (row, col) the option and its pair as typed (ROW,COL)
        message = re.sub(k + r"(['\"])([\w.+-]+)\1", rf"{option} \2", message)
        message = re.sub(k + r"True\b", option, message)
        message = re.sub(k + r" \(([^(),]+), ([^(),]+)\)", rf"{option} \1,\2", message)
        message = re.sub(k + r"(?![\w(\[\"'])", option, message)
    for keyword, option in (options or {}).items():
        if message.startswith(keyword) and _CHECK_VERBS.match(message, len(keyword)):
            return option + message[len(keyword):]
    return message


#: The longest message said whole, in characters: every message of snapcorr's is far shorter
#: (a few hundred); a longer one quotes something whole (a library's, or a value read from a
#: file), and is cut before it is rewritten, so that the rewriting takes the time of this
#: many characters (ten megabytes took 33 s) and the line stays one a terminal shows.
MESSAGE_MAX = 2000


def _cut(text):
    """``text`` cut to :data:`MESSAGE_MAX` characters, saying how much was left out; its end
    is kept, where a message quoting a long value says what is wrong with it."""
    if len(text) <= MESSAGE_MAX:
        return text
    head, tail = MESSAGE_MAX * 3 // 4, MESSAGE_MAX // 4
    return (f"{text[:head]}... ({len(text) - head - tail:,} characters left out) ..."
            f"{text[-tail:]}")


def command_parser(parser, command):
    """The parser of ``command`` (a sub-command of ``parser``), or None."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices.get(command)
    return None


#: The namespace's record of the single-value options given, while it is parsed.
_GIVEN = "_options_given"


class _StoreOnce(argparse._StoreAction):
    """An option that takes one value, refused when given twice (argparse keeps the last
    without a word: ``--out a.toml --out b.toml`` wrote only b.toml), under one name or two
    (``--pupil-radiance`` and its alias ``--pupil``)."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault(_GIVEN, {})
        if self.dest in given:
            first = given[self.dest]
            said = (f"{option_string} is given twice" if first == option_string else
                    f"{first} and {option_string} are one option, given twice")
            parser.error(f"{said}: give it once")
        given[self.dest] = option_string
        super().__call__(parser, namespace, values, option_string)


class _Parser(argparse.ArgumentParser):
    """Usage errors as one line, like every other error, with where to read more; an option
    of one value given twice is one of them (:class:`_StoreOnce`)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.register("action", None, _StoreOnce)
        self.register("action", "store", _StoreOnce)

    def parse_known_args(self, args=None, namespace=None):
        namespace, rest = super().parse_known_args(args, namespace)
        namespace.__dict__.pop(_GIVEN, None)
        return namespace, rest

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _quiet_unraisable(unraisable):
    """Drop errors raised while collecting objects left behind by an interruption."""


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"snapcorr: warning: {_message(message)}", file=sys.stderr)

