"""The pieces the commands' parsers share: option groups (output, progress, centre, virtual
bands, a target fit), the checks of options that go together, and the argument types of
:mod:`._types` (pixel pairs, f-numbers, wavelength lists, positive and bounded numbers),
which the commands take from here."""

from __future__ import annotations

import argparse
import sys
import textwrap

from ._types import (  # noqa: F401 (the commands take their argument types from here)
    _center_arg,
    _center_rc_arg,
    _distance_mm,
    _f_number,
    _flat_arg,
    _magnification,
    _origin_arg,
    _pack_range_arg,
    _positive,
    _pupil_magnification,
    _wavelength_list,
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
                         f"--source {message}" if message.startswith(f"{value}:") else
                         f"--source {value}: {message}") from None


def _sensor(value):
    """``--sensor``: a sensor description (.toml, vendor .xml) or a bundled one by name."""
    from ..cube import Sensor

    return Sensor.load(value)


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
    """``args.center_rc``, the optical centre ``(row, col)`` (None if not given), from
    ``--center ROW,COL`` or the deprecated ``--center-px CX,CY`` (said on stderr; giving both is
    an error)."""
    args.center_rc = getattr(args, "center", None)
    if getattr(args, "center_px", None) is not None:
        if args.center_rc is not None:
            raise ValueError("give the optical centre once: --center ROW,COL (--center-px "
                             "CX,CY is its old x-first form)")
        cx, cy = args.center_px
        print(f"snapcorr {args.command}: --center-px CX,CY is deprecated and will be removed; "
              f"give --center ROW,COL (here --center {cy:g},{cx:g})", file=sys.stderr)
        args.center_rc = (cy, cx)


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
