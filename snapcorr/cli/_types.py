"""Argument types of the commands' options: pixel pairs, f-numbers and ``F_NUMBER=PATH``
pairs, wavelength lists, positive and bounded numbers, each refusing what no camera or lens
has with the range, as a usage error naming the option."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from .._validation import (
    F_NUMBER_MAX,
    LENGTH_MAX_MM,
    LENGTH_MIN_MM,
    PIXELS_MAX,
    WAVELENGTH_NM_RANGE,
    check_f_number,
    check_pack_range,
    check_positive,
)

_MAX_PX = PIXELS_MAX


#: The most wavelengths a list may give (a step of 0.01 nm over 100 nm-10 um).
_MAX_WAVELENGTHS = 1_000_000


def _path(value):
    """A path argument; an empty one (an unset shell variable, ``""``) is refused rather than
    read as the current folder."""
    if not str(value).strip():
        raise argparse.ArgumentTypeError("an empty path (an unset shell variable?); give a "
                                         "file or folder")
    return Path(value)


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
    parse.number_pair = True  # a negative first number is its value (cli._negative_pairs)
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


_pack_range_arg.number_pair = True  # LO < 0 is its value, not an option (cli._negative_pairs)


def _number(text):
    """A command-line string as a float (NaN for text that is not one, refused after)."""
    try:
        return float(text)
    except (TypeError, ValueError, OverflowError):
        return float("nan")


def _numeric_text(value):
    """A command-line string as a float, refused as itself where it is no number (``True``
    and ``''`` were said to be NaN)."""
    v = _number(value)
    if math.isnan(v) and str(value).strip().lower() not in ("nan", "+nan", "-nan"):
        raise argparse.ArgumentTypeError(f"expected a number, got {value!r}")
    return v


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


#: ``--exit-pupil-mm`` and ``--vignetting-distance-mm``: a distance from the sensor, mm, within
#: a lens's bounds (a micron: below it the optics divide by next to nothing).
_distance_mm = _bounded(LENGTH_MIN_MM, LENGTH_MAX_MM, "a distance", " mm", above=False)

def _magnification(value):
    """``--magnification``: m, finite, >= 0 and within the bound a lens profile has
    (:data:`snapcorr.optics.lens.MAX_MAGNIFICATION`), refused before anything is read."""
    from ..optics.lens import check_magnification

    try:
        return check_magnification(_numeric_text(value), "m")
    except (TypeError, ValueError) as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _pupil_magnification(value):
    """``--pupil-magnification``: m_P, finite, > 0 and within
    :data:`snapcorr.optics.lens.PUPIL_MAGNIFICATION_BOUNDS`."""
    from ..optics.lens import check_pupil_magnification

    try:
        return check_pupil_magnification(_numeric_text(value), "m_P")
    except (TypeError, ValueError) as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _in_wavelength_range(what, v, value):
    """Refuse ``v`` (``what``: ``"START"``, ``"wavelength"``), nm, outside
    :data:`~snapcorr._validation.WAVELENGTH_NM_RANGE`, the wavelengths snapcorr accepts."""
    lo, hi = WAVELENGTH_NM_RANGE
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{what} must be a finite number of nm, got {value!r}")
    if v > hi:
        raise argparse.ArgumentTypeError(
            f"{what} {v:g} nm is beyond the longest wavelength snapcorr accepts, {hi:g} nm "
            f"(wavelengths are {lo:g}-{hi:g} nm), got {value!r}")
    if v < lo:
        raise argparse.ArgumentTypeError(
            f"{what} {v:g} nm is below the shortest wavelength snapcorr accepts, {lo:g} nm "
            f"(wavelengths are {lo:g}-{hi:g} nm), got {value!r}")


def _wavelength_range(value):
    """``START:STOP:STEP``, nm, inclusive of STOP when it falls on a step."""
    try:
        start, stop, step = (float(v) for v in value.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NM,NM,... or START:STOP:STEP in nm, got "
                                         f"{value!r}") from None
    _in_wavelength_range("START", start, value)
    _in_wavelength_range("STOP", stop, value)
    if not (math.isfinite(step) and step > 0):
        raise argparse.ArgumentTypeError(f"STEP must be a finite number > 0 nm, got {value!r}")
    if stop < start:
        raise argparse.ArgumentTypeError(f"STOP {stop:g} nm is below START {start:g} nm, got "
                                         f"{value!r}")
    if stop == start:  # a range of no width: the one wavelength, whatever the step
        return np.array([start])
    count = (stop - start) / step + 1
    if not count <= _MAX_WAVELENGTHS:
        raise argparse.ArgumentTypeError(
            f"{value!r} gives {count:.3g} wavelengths; at most {_MAX_WAVELENGTHS:,} "
            "(is the step in nm?)")
    values = np.arange(start, stop + 0.5 * step, step)
    if np.unique(values).size != values.size:
        raise argparse.ArgumentTypeError(
            f"STEP {step:g} nm is too fine to tell wavelengths near {stop:g} nm apart, got "
            f"{value!r}")
    return values


def _wavelength_list(value):
    """``NM,NM,...`` or ``START:STOP:STEP`` (inclusive of STOP when it falls on a step), each
    wavelength within :data:`~snapcorr._validation.WAVELENGTH_NM_RANGE`."""
    if ":" in value:
        return _wavelength_range(value)
    try:
        values = np.array([float(v) for v in value.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NM,NM,... or START:STOP:STEP in nm, got "
                                         f"{value!r}") from None
    for v in values:
        _in_wavelength_range("wavelength", v, value)
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
