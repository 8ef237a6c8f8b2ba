"""The pieces the commands' parsers share: argument types (pixel pairs, f-number pairs,
wavelength lists, positive numbers), option groups (output, progress, centre, virtual bands,
a target fit) and the checks of options that go together."""

from __future__ import annotations

import argparse
import math
import sys
import textwrap
from pathlib import Path

import numpy as np

from .._validation import (
    F_NUMBER_MAX,
    LENGTH_MAX_MM,
    MAGNIFICATION_MAX,
    check_f_number,
    check_pack_range,
    check_positive,
)


def _examples(examples):
    """A command's examples as its --help shows them, under ``examples:``."""
    text = textwrap.dedent(examples).strip("\n") + "\n"
    return "examples:\n" + textwrap.indent(text, "  ")


def add_command(subparsers, name, help_, examples):
    """The parser of the command ``name``: ``help_`` is its line in ``snapcorr --help`` and the
    start of its own, which ends in its ``examples``."""
    return subparsers.add_parser(name, help=help_, description=help_, epilog=_examples(examples),
                                 formatter_class=argparse.RawDescriptionHelpFormatter)


def _lens(value):
    """``--lens``: a lens profile (.toml) or a bundled one by name."""
    from ..optics import Lens

    return Lens.load(value)


def _source(value, cube=None):
    """``--source``: the scene's spectrum (:func:`snapcorr.spectra.parse_source`), a refusal
    naming the option."""
    from ..spectra import parse_source

    try:
        return parse_source(value, cube)
    except (ValueError, OSError) as err:
        message = str(err)
        raise ValueError(message if message.startswith("--source") else
                         f"--source {value}: {message}") from None


def _sensor(value):
    """``--sensor``: a sensor description (.toml, vendor .xml) or a bundled one by name."""
    from ..cube import Sensor

    return Sensor.load(value)


#: Pixel positions further out than this are a typo: no sensor is this wide.
_MAX_PX = 1_000_000


#: The most wavelengths a list may give (a step of 0.01 nm over 100 nm-10 um).
_MAX_WAVELENGTHS = 1_000_000


def _pair_arg(what, names, *, integer=False):
    def parse(value):
        try:
            a, b = (float(v) for v in value.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {names} in pixels, got {value!r}") \
                from None
        if not (math.isfinite(a) and math.isfinite(b)):
            raise argparse.ArgumentTypeError(f"the {what} must be finite, got {value!r}")
        if max(abs(a), abs(b)) > _MAX_PX:
            raise argparse.ArgumentTypeError(f"the {what} lies {max(abs(a), abs(b)):.3g} "
                                             f"pixels out; no sensor is wider than {_MAX_PX:,} "
                                             f"pixels, got {value!r}")
        if integer:
            if a != round(a) or b != round(b) or a < 0 or b < 0:
                raise argparse.ArgumentTypeError(f"the {what} is whole pixels >= 0, got "
                                                 f"{value!r}")
            return int(a), int(b)
        return a, b
    return parse


_center_arg = _pair_arg("centre", "CX,CY")


_center_rc_arg = _pair_arg("centre", "ROW,COL")


_origin_arg = _pair_arg("origin", "ROW,COL", integer=True)


def _pack_range_arg(value):
    """``--pack-range LO,HI``: two numbers, checked by
    :func:`~snapcorr._validation.check_pack_range` (finite, LO < HI, a range CF packing can
    hold)."""
    try:
        lo, hi = (float(v) for v in value.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO,HI (two numbers), got {value!r}") \
            from None
    try:  # finite LO < HI, and what the float32 CF packing can hold
        return check_pack_range("--pack-range", lo, hi)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err).removeprefix("--pack-range ")) from None


def _number(text):
    """A command-line string as a float (NaN for text that is not one, refused after)."""
    try:
        return float(text)
    except (TypeError, ValueError, OverflowError):
        return float("nan")


def _positive(value):
    try:
        return check_positive("value", _number(value))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {value!r}") \
            from None


def _f_number(value):
    """``--f-number F``: a finite number > 0 and at most
    :data:`~snapcorr._validation.F_NUMBER_MAX` (the lens's own lower limit is checked with
    the lens)."""
    try:
        return check_f_number("value", _number(value))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an f-number, a finite number > 0 and at "
                                         f"most {F_NUMBER_MAX:g}, got {value!r}") from None


def _bounded(low, high, what, unit="", *, above=True):
    """An argument type: a finite number above ``low`` (or from it, ``above=False``) and at
    most ``high``, ``what`` in the message (``"a magnification"``)."""
    def parse(value):
        v = _number(value)
        if not (math.isfinite(v) and (v > low if above else v >= low) and v <= high):
            raise argparse.ArgumentTypeError(
                f"expected {what}, a finite number {'>' if above else '>='} {low:g} and at "
                f"most {high:g}{unit}, got {value!r}")
        return v
    return parse


#: ``--exit-pupil-mm`` and ``--vignetting-distance-mm``: a distance from the sensor, mm.
_distance_mm = _bounded(0, LENGTH_MAX_MM, "a distance", " mm")
#: ``--magnification``: |m|, 0 for a distant scene.
_magnification = _bounded(0, MAGNIFICATION_MAX, "a magnification", above=False)
#: ``--pupil-magnification``: m_P > 0.
_pupil_magnification = _bounded(0, MAGNIFICATION_MAX, "a pupil magnification")


def _wavelength_list(value):
    """``NM,NM,...`` or ``START:STOP:STEP`` (inclusive of STOP when it falls on a step)."""
    try:
        if ":" in value:
            start, stop, step = (float(v) for v in value.split(":"))
            if not step > 0 or not stop >= start:
                raise ValueError
            count = (stop - start) / step + 1
            if not count <= _MAX_WAVELENGTHS:
                raise argparse.ArgumentTypeError(
                    f"{value!r} gives {count:.3g} wavelengths; at most {_MAX_WAVELENGTHS:,} "
                    "(is the step in nm?)")
            values = np.arange(start, stop + 0.5 * step, step)
        else:
            values = np.array([float(v) for v in value.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NM,NM,... or START:STOP:STEP in nm, got "
                                         f"{value!r}") from None
    if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise argparse.ArgumentTypeError(f"wavelengths must be finite and > 0 nm, got {value!r}")
    return values


def _flat_arg(value):
    """``F_NUMBER=PATH`` (F_NUMBER may be written 2.8, f2.8 or f/2.8)."""
    if "=" not in value:
        raise argparse.ArgumentTypeError(f"expected F_NUMBER=PATH, got {value!r}")
    f, path = value.split("=", 1)
    f = f.strip().lower().removeprefix("f").removeprefix("/")
    try:
        fv = check_f_number("the f-number", _number(f))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{value!r}: {f!r} is not an f-number: a finite "
                                         f"number > 0 and at most {F_NUMBER_MAX:g}") from None
    if not path:
        raise argparse.ArgumentTypeError(f"{value!r}: no file after '='")
    return fv, Path(path)


def _one_per_f_number(pairs, what):
    """``{f_number: path}`` from ``F_NUMBER=PATH`` arguments; an f-number given twice is an
    error."""
    seen = {}
    for f, path in pairs:
        if f in seen:
            raise ValueError(f"f/{f:g} given twice ({seen[f]} and {path}); give one {what} per "
                             "f-number")
        seen[f] = path
    return seen


#: What ``--dtype`` may store a result's values as.
STORAGE_CHOICES = ("float32", "float16", "uint16")


DTYPE_HELP = ("type the values are stored as: float32; float16 (.zarr only, relative error "
              "4.9e-4); uint16 (.nc, .zarr: packed by CF scale_factor/add_offset that readers "
              "apply, reflectance at most 3.2e-5 from the value); raw counts are kept as they "
              "are")


SENSOR_HELP = ("sensor description (.toml), the vendor's calibration file (.xml) or a bundled "
               "sensor (snapscan_vnir, mosaic_4x4_vis, imec_5x5_nir, ...)")


OVERWRITE_HELP = "replace an existing --out (or --plot) that snapcorr wrote; never an input"


ORIGIN_HELP = ("sensor row and column of the cube's first pixel (of its tile, for a mosaic), "
               "for a crop that does not record where it sits")


def _add_output_options(p, *, input_name, derived=False, dtype=False):
    """``--compression``, ``--pack-range`` and ``--no-input`` (and ``--store-derived``,
    ``--dtype``) for a result."""
    g = p.add_argument_group("output")
    if dtype:
        g.add_argument("--dtype", default=None, choices=list(STORAGE_CHOICES),
                       help=DTYPE_HELP + " (default: the input's own type)")
    g.add_argument("--compression", default="auto", choices=["auto", "all", "none"],
                   help="auto (default): every numeric variable (.zarr: Blosc LZ4 with bit "
                   "shuffle; .nc: DEFLATE level 1 with byte shuffle), except a copy its "
                   "source compressed already; all; none")
    g.add_argument("--pack-range", type=_pack_range_arg, default=None, metavar="LO,HI",
                   help="with --dtype uint16: the values packed (default for reflectance and "
                   "transmittance: -0.5,3.5); values outside are stored as LO or HI")
    g.add_argument("--no-input", action="store_true",
                   help=f"leave out the copy of {input_name} (by default kept next to the "
                   "result); its path stays in the attributes")
    if derived:
        g.add_argument("--store-derived", action="store_true",
                       help="store wavelength_corrected and fwhm_corrected whole (about one "
                       "cube each), for readers without snapcorr; by default they are "
                       "rebuilt on reading from a compact form")


def _add_progress_options(p):
    """``--quiet`` and ``--progress``: the progress bars of a long command."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--quiet", action="store_true",
                   help="no progress bars (by default they show on stderr after a second of "
                   "work, when stderr is a terminal)")
    g.add_argument("--progress", action="store_true",
                   help="progress bars on stderr from the start, also when stderr is not a "
                   "terminal (a log file)")


def _add_center(p, help_text):
    """``--center ROW,COL`` and its deprecated x-first form ``--center-px CX,CY``."""
    p.add_argument("--center", type=_center_rc_arg, default=None, metavar="ROW,COL",
                   help=help_text.replace("optical centre", "optical centre (row, column)", 1))
    p.add_argument("--center-px", type=_center_arg, default=None, metavar="CX,CY",
                   help="deprecated: the optical centre x first; use --center ROW,COL")


def _center_option(args):
    """``args.center_px``, the internal (cx, cy), from ``--center ROW,COL`` or the deprecated
    ``--center-px CX,CY`` (said on stderr; giving both is an error)."""
    if getattr(args, "center_px", None) is not None:
        if args.center is not None:
            raise ValueError("give the optical centre once: --center ROW,COL (--center-px "
                             "CX,CY is its old x-first form)")
        cx, cy = args.center_px
        print(f"snapcorr {args.command}: --center-px CX,CY is deprecated and will be removed; "
              f"give --center ROW,COL (here --center {cy:g},{cx:g})", file=sys.stderr)
    elif getattr(args, "center", None) is not None:
        row, col = args.center
        args.center_px = (col, row)


def _add_virtual_options(p):
    g = p.add_argument_group("virtual bands (mosaic sensors with a vendor calibration file)")
    g.add_argument("--virtual-bands", default=None, choices=["vendor", "fitted", "angle-aware"],
                   help="also give virtual bands: the vendor's matrix, one fitted to the "
                   "measured responses, or one for each pixel's responses behind the lens")
    g.add_argument("--virtual-matrix", default=None, metavar="NAME",
                   help="the vendor matrix to apply (default: the one for flat-fielded values)")
    g.add_argument("--virtual-wavelengths", type=_wavelength_list, default=None,
                   metavar="NM,NM,...|START:STOP:STEP",
                   help="centres of fitted virtual bands (default: the vendor's)")
    g.add_argument("--virtual-fwhm-nm", type=_positive, default=None, metavar="NM",
                   help="width of fitted virtual bands (default: the vendor's)")


def _check_storage_option(args):
    """``--dtype`` and ``--pack-range`` for ``--out``'s format, before any work; ``--dtype``
    float16 or uint16 computes in float32 and stores as asked (``args.storage``)."""
    from ..files.datasets import check_storage

    dtype = getattr(args, "dtype", None)
    args.storage = dtype if dtype in ("float32", "float16", "uint16") else None
    if dtype in ("float16", "uint16"):
        args.dtype = "float32"
    suffix = args.out.suffix.lower()
    fmt = {".nc": "netcdf", ".zarr": "zarr", ".hdr": "envi"}.get(suffix)
    check_storage(args.storage, args.pack_range, fmt, what="--dtype")


def _check_virtual_options(args, sensor):
    """The virtual-band options make sense together, and for the sensor, before any work."""
    if args.virtual_bands is None and any(v is not None for v in (
            args.virtual_matrix, args.virtual_wavelengths, args.virtual_fwhm_nm)):
        raise ValueError("--virtual-matrix, --virtual-wavelengths and --virtual-fwhm-nm choose "
                         "the virtual bands: give --virtual-bands too")
    if args.virtual_matrix is not None and args.virtual_bands != "vendor":
        raise ValueError("--virtual-matrix names the vendor matrix to apply: use it with "
                         "--virtual-bands vendor")
    if args.virtual_bands == "vendor" and (args.virtual_wavelengths is not None
                                           or args.virtual_fwhm_nm is not None):
        raise ValueError("the vendor's virtual bands are the file's; --virtual-wavelengths and "
                         "--virtual-fwhm-nm set fitted or angle-aware ones")
    if args.virtual_bands in ("fitted", "angle-aware") and sensor.responses is not None:
        from ..correct.virtual import virtual_targets

        virtual_targets(sensor, args.virtual_wavelengths, args.virtual_fwhm_nm)
