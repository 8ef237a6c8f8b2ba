"""Small shared checks, and the one way a renamed argument or attribute keeps its old name."""

from __future__ import annotations

import functools
import inspect
import math
import sys
import warnings

import numpy as np

__all__ = ["REMOVAL_VERSION", "SENSOR_PX_MAX", "WAVELENGTH_NM_RANGE", "called_from_outside",
           "check_center", "check_center_rc", "check_curve", "check_integers", "check_numbers",
           "check_pack_range", "check_pair", "check_positive", "check_positive_array",
           "check_wavelengths_nm", "renamed_keywords", "shown", "validate_method",
           "warn_renamed"]

#: The release that removes the earlier names of renamed arguments and attributes.
REMOVAL_VERSION = "0.3"


#: Modules whose decorators pass a call on: their wrappers' frames are not the caller.
_PASSING_ON = {"snapcorr._validation", "snapcorr._coords"}


def called_from_outside(depth):
    """Whether the caller ``depth`` frames up is outside snapcorr (it gets the warnings); the
    wrappers of snapcorr's own decorators, stacked on one function, are looked past."""
    frame = sys._getframe(depth)
    while frame.f_code.co_name == "wrapper" and frame.f_globals.get("__name__") in _PASSING_ON:
        frame = frame.f_back
    name = frame.f_globals.get("__name__", "")
    return not (name == "snapcorr" or name.startswith("snapcorr."))


def outside_stacklevel():
    """The ``stacklevel`` that makes a warning raised by the caller of this function name the
    first line outside snapcorr (the user's call, however deep the call went inside)."""
    frame, level = sys._getframe(1), 1
    while frame is not None:
        name = frame.f_globals.get("__name__", "")
        if not (name == "snapcorr" or name.startswith("snapcorr.")):
            return level
        frame, level = frame.f_back, level + 1
    return level


def warn_renamed(old, new, *, stacklevel=3):
    """Warn (``FutureWarning``) that ``old`` is the earlier name of ``new`` and goes in
    :data:`REMOVAL_VERSION`.

    Parameters
    ----------
    old, new : str
        The earlier name and the name that replaces it, as the message shows them
        (``"origin_px"``, ``"Lens.pupil"``, ``"Lens(pupil=...)"``).
    stacklevel : int
        As for :func:`warnings.warn`, counted from here: 3 points at the code that called the
        function that calls this one.
    """
    warnings.warn(f"{old} is the earlier name of {new} and will be removed in snapcorr "
                  f"{REMOVAL_VERSION}; give {new} instead", FutureWarning, stacklevel=stacklevel)


def renamed_keywords(**renames):
    """Decorate a function whose keyword arguments were renamed, ``old="new"``: the old name
    still works, warns when given outside snapcorr (:func:`warn_renamed`), and giving both
    names is an error.

    >>> @renamed_keywords(origin_px="sensor_origin_px")
    ... def place(frame, *, sensor_origin_px=None):
    ...     return sensor_origin_px
    >>> place(None, origin_px=(1, 2))  # doctest: +SKIP
    FutureWarning: origin_px is the earlier name of sensor_origin_px ...
    """
    def decorate(func):
        sig = inspect.signature(func)

        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            for old, new in renames.items():
                if old not in kwargs:
                    continue
                if new in kwargs or new in sig.bind_partial(*args).arguments:
                    raise TypeError(f"{func.__name__}: give {new} once; {old} is its earlier "
                                    "name")
                if called_from_outside(2):
                    warn_renamed(old, new)
                kwargs[new] = kwargs.pop(old)
            return func(*args, **kwargs)

        return wrapper

    return decorate


def shown(value, limit=40, *, quote=True):
    """``repr(value)`` cut to ``limit`` characters, for messages (a 400-digit integer from a
    TOML file is no better shown whole, nor ten megabytes of digits from an XML element).

    Parameters
    ----------
    value : object
        What a message quotes; a long string is cut before its ``repr`` is taken (the time
        is the limit's, not the value's).
    limit : int
        The most characters shown, ``...`` included.
    quote : bool
        False: a string as it is, not its ``repr`` (``byte order = 2``).

    Returns
    -------
    str
    """
    if isinstance(value, str):
        cut = value[:limit + 1]
        r = repr(cut) if quote else cut
        if len(cut) <= limit and len(r) <= limit:
            return r
        return r[:limit - 3] + "..."
    r = repr(value)
    return r if len(r) <= limit else r[:limit - 3] + "..."


def check_positive(name, value):
    """``value`` as a float, raising a clear ``ValueError`` unless it is a finite number > 0
    (not a boolean, not text: a command line's strings are converted where they are parsed)."""
    kind = _not_a_number(value)
    if kind:
        raise ValueError(f"{name} must be a number, got {kind} ({shown(value)})")
    try:
        v = float(value)
    except OverflowError:
        raise ValueError(f"{name} must be a finite number > 0, got {shown(value)}") from None
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {shown(value)}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {shown(value)}")
    return v


#: The largest f-number taken: a pinhole camera's is a few hundred, and past this the cone is
#: the pinhole limit already (the mean shift is the chief ray's to 1e-9 nm); far larger ones
#: (1e200) leave an exit pupil too small to compute with, and are a typo.
F_NUMBER_MAX = 1e6


#: No lens's exit pupil or vignetting circle is further than this from the sensor, nor a
#: circle wider (mm; a kilometre: a telecentric lens is x = ``inf``'s limit, reached long
#: before): a larger value is a typo or a unit slip, and 1e200 overflows the optics.
LENGTH_MAX_MM = 1e6

#: The shortest exit-pupil distance, circle radius or distance ``|h|`` of a moving vignetting
#: circle a lens has (``h = 0`` is a stop), mm (a micron): below it the optics divide by next to
#: nothing (1e-310 overflowed), and it is a typo or a unit slip.
LENGTH_MIN_MM = 1e-3

#: Pixel positions (optical centres, a crop's origin) further out than this are a typo: no
#: sensor is this wide.
PIXELS_MAX = 1_000_000

#: No lens has more projected vignetting circles than this: each is an aperture's edge (a
#: lens element's rim, the mount, a baffle) seen from the sensor, and an objective has a
#: handful; a calibration fits at most 3. The optics' cost grows with the square of the count
#: (a profile of 1000 circles took gigabytes and minutes), so a longer list is refused.
MAX_VIGNETTING_CIRCLES = 8

#: The most discs a pixel looks through: the exit pupil, :data:`MAX_VIGNETTING_CIRCLES`
#: circles and its own acceptance circle (pixel vignetting).
MAX_DISCS = MAX_VIGNETTING_CIRCLES + 2


def check_disc_count(name, n, *, what="discs", most=MAX_DISCS):
    """Refuse ``n`` (the length of the sequence ``name``) beyond ``most``: no lens has that
    many apertures (:data:`MAX_VIGNETTING_CIRCLES`). ``n`` None: more than ``most`` (an
    iterator read no further)."""
    if n is None or n > most:
        count = f"more than {most}" if n is None else n
        raise ValueError(f"{name} holds {count} {what}; at most {most} are taken (no lens has more "
                         f"than {MAX_VIGNETTING_CIRCLES} vignetting circles: a longer list is a "
                         "mistake)")


def check_f_number(name, value):
    """An f-number as a float: a finite number > 0 and at most :data:`F_NUMBER_MAX` (the
    lens's own lower limit, a numerical aperture of 1, is checked by the lens)."""
    v = check_positive(name, value)
    if v > F_NUMBER_MAX:
        raise ValueError(f"{name} must be at most {F_NUMBER_MAX:g} (a pinhole's is a few "
                         f"hundred), got {shown(value)}")
    return v


#: No sensor is more pixels across than this (the largest made are near 20 000): a size read
#: from a file beyond it is a mistake, refused before anything is sized by it.
SENSOR_PX_MAX = 100_000

#: No thin-film filter's effective index reaches this (its layers' indices stay below about 4.5).
N_EFF_MAX = 5.0
#: Pixel pitches outside this range (micrometres) are no camera's, nor a coarse grid standing
#: for one (a 2048-pixel sensor sampled 8 x 8): a typo or a unit slip.
PIXEL_PITCH_RANGE_UM = (0.1, 10000.0)


def check_pixel_pitch_um(name, value):
    """A pixel pitch in micrometres: a finite number inside :data:`PIXEL_PITCH_RANGE_UM`."""
    v = check_positive(name, value)
    lo, hi = PIXEL_PITCH_RANGE_UM
    if not lo <= v <= hi:
        raise ValueError(f"{name} = {v:g} um is no camera's pixel pitch (expected {lo:g}-{hi:g} "
                         "um, binned pixels and coarse grids included); check the unit")
    return v


def check_positive_array(name, values, unit=""):
    """``values`` as a float array, raising a clear ``ValueError`` unless every element is a
    finite number > 0 (the array form of :func:`check_positive`).

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    values : array_like
        The numbers, any shape.
    unit : str
        Their unit, for the message ("nm", "mm", ...; "" for none).

    Returns
    -------
    ndarray
        ``values`` as float64, same shape.
    """
    try:
        v = np.asarray(values, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be numbers, got {shown(values)}") from None
    if not (np.all(np.isfinite(v)) and np.all(v > 0)):
        unit = f" ({unit})" if unit else ""
        raise ValueError(f"{name} must be finite and > 0{unit}, got {np.ravel(v)[:5].tolist()}")
    return v


def check_pair(name, value, what="two numbers"):
    """``value`` as two finite floats, or a clear ``ValueError`` saying it must be ``what``.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : iterable
        Exactly two numbers.
    what : str
        What the pair should be, for the message.

    Returns
    -------
    (float, float)
    """
    kind = _not_a_number(value)
    if kind:  # True is no pixel position, nor "5" (float() takes both)
        raise ValueError(f"{name} must be {what}, got {kind} ({shown(value)})")
    try:
        a, b = (float(c) for c in value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be {what}, got {shown(value)}") from None
    if not (math.isfinite(a) and math.isfinite(b)):
        raise ValueError(f"{name} must be finite, got {shown(value)}")
    return a, b


def check_center(center_px, name="center_px"):
    """An optical centre ``(cx, cy)`` in pixels (column, row) as two finite floats."""
    return check_pair(name, center_px, "two numbers (cx, cy) in pixels (column, row)")


def check_center_rc(center_rc, name="center_rc"):
    """An optical centre ``(row, col)`` in pixels as two finite floats."""
    return check_pair(name, center_rc, "two numbers (row, col) in pixels")


def validate_method(method, methods, what="method"):
    """Return ``method`` if it names an entry of ``methods``, else raise a helpful error.

    Parameters
    ----------
    method : str
        The name asked for.
    methods : collection of str
        The accepted names.
    what : str
        What is being chosen, for the message ("method", "model", ...).
    """
    if method not in methods:
        names = ", ".join(repr(m) for m in methods)
        raise ValueError(f"unknown {what} {method!r}; choose one of {names}")
    return method


def check_curve(wavelength_nm, transmission):
    """Return a sampled curve as float arrays, raising unless it is 1-D, of equal lengths
    (>= 2), finite, with strictly increasing wavelengths."""
    w = np.asarray(wavelength_nm, float)
    t = np.asarray(transmission, float)
    if (w.ndim != 1 or w.shape != t.shape or w.size < 2 or np.any(np.diff(w) <= 0)
            or not (np.all(np.isfinite(w)) and np.all(np.isfinite(t)))):
        raise ValueError("a transmission curve needs finite 1-D wavelength and transmission "
                         "arrays of equal length (>= 2), wavelengths strictly increasing")
    return w, t


#: Bounds of a plausible wavelength in nanometres. Values below look like micrometres (0.4-2.5)
#: or metres; values above like Angstroms or wavenumbers. Thermal-infrared filters (8-14 um)
#: stay inside.
WAVELENGTH_NM_RANGE = (100.0, 1e5)


def check_wavelengths_nm(name, values, *, where=""):
    """``values`` as a float array of wavelengths in nm, or a ``ValueError`` that says why not.

    Refuses non-finite values, values outside :data:`WAVELENGTH_NM_RANGE` (micrometres or
    metres written as nanometres: convert them, or declare the units where the format can)
    and repeated values (two bands at one wavelength cannot be told apart).

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    values : array_like
        Wavelengths, nm; repeats are refused only in a 1-D array.
    where : str
        Where the values come from (a file name, ...), prefixed to the message.

    Returns
    -------
    ndarray
        ``values`` as float64, same shape.
    """
    prefix = f"{where}: " if where else ""
    try:
        w = np.asarray(values, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{prefix}{name} must be numbers (nm), got {shown(values)}") from None
    if w.dtype == bool or np.asarray(values).dtype == bool:
        raise ValueError(f"{prefix}{name} must be numbers (nm), got booleans")
    if not np.all(np.isfinite(w)):
        raise ValueError(f"{prefix}{name} must be finite, got {w.ravel()[:5].tolist()}...")
    lo, hi = WAVELENGTH_NM_RANGE
    if w.size and (w.min() < lo or w.max() > hi):
        bad = w[(w < lo) | (w > hi)].ravel()[0]
        hint = (" (they look like micrometres: multiply by 1000, or declare the units, e.g. "
                "ENVI 'wavelength units = micrometers')" if 0.1 <= bad < lo else "")
        raise ValueError(f"{prefix}{name} must be in nanometres, {lo:g}-{hi:g}; got "
                         f"{bad:g}{hint}")
    if w.ndim == 1 and np.unique(w).size != w.size:
        values_, counts = np.unique(w, return_counts=True)
        raise ValueError(f"{prefix}{name} repeats {values_[counts > 1][:3].tolist()} nm; every "
                         "band needs its own wavelength")
    return w


def _not_a_number(value):
    """``"a boolean"`` or ``"text"`` if ``value`` (or an element) is one, else None."""
    if isinstance(value, (bool, np.bool_)):
        return "a boolean"
    if isinstance(value, (str, bytes, np.str_)):
        return "text"
    if isinstance(value, (list, tuple)):
        return next((k for k in map(_not_a_number, value) if k), None)
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "O":
            return _not_a_number(value.tolist())
        return {"b": "a boolean", "U": "text", "S": "text"}.get(value.dtype.kind)
    return None


def check_numbers(name, value):
    """Refuse booleans and text where numbers are expected (TOML's ``true`` is not 1 mm, and
    ``"1.7"`` is text, not an index); return ``value`` unchanged. Works on scalars and nested
    lists."""
    kind = _not_a_number(value)
    if kind:
        raise ValueError(f"{name} must be a number, got {kind} ({shown(value)})")
    return value


#: The largest whole number :func:`check_integers` takes unless told a bound: every integer
#: up to it is exact as a float (2**53), and far inside int64, so no cast wraps it.
INTEGER_MAX = 2**53


def check_integers(name, value, most=INTEGER_MAX):
    """``value`` (a number or nested list) as an int array, refusing booleans, numbers that
    are not whole (``4.7`` is not silently 4) and numbers larger than ``most`` in size
    (before the cast to int64: ``1e20`` cast is no number, and numpy warns of it).

    Parameters
    ----------
    name : str
        The key or argument, for the message.
    value : int or nested list of int
        The numbers.
    most : int
        The largest size taken (:data:`INTEGER_MAX` unless the caller knows a bound).

    Returns
    -------
    ndarray of int64
    """
    check_numbers(name, value)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be whole numbers, got {shown(value)}") from None
    if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
        raise ValueError(f"{name} must be whole numbers, got {shown(value)}")
    if np.any(np.abs(arr) > most):  # refused before the cast (1e20 cast to int64 is garbage)
        raise ValueError(f"{name} must be whole numbers of at most {most:,}, got "
                         f"{shown(value)}")
    return arr.astype(np.int64)


def check_pack_range(name, lo, hi, codes=65534):
    """``(lo, hi)`` as floats, refused unless ``codes`` uint16 steps between them can be
    written and read back as CF packing does it: ``scale_factor`` and ``add_offset`` are
    float32 (so both ends must be float32 numbers, and the step a normal float32, not one
    that rounds to 0 or to a subnormal), and neighbouring codes must unpack to different
    float32 values (a step finer than float32 resolves at the range's size is no packing).
    A range that passed would otherwise be stored with a step of 0 or infinity, and read back
    as one value or NaN everywhere.

    Parameters
    ----------
    name : str
        The option or argument, for the messages.
    lo, hi : float
        The range packed.
    codes : int
        Steps between ``lo`` and ``hi`` (uint16 codes 0-65534, 65535 the fill value).

    Returns
    -------
    (float, float)

    >>> check_pack_range("--pack-range", -0.5, 3.5)
    (-0.5, 3.5)
    >>> check_pack_range("--pack-range", 0, 1e-40)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: --pack-range 0,1e-40: a step of 1.5e-45 per code is below float32's ...
    """
    lo, hi = float(lo), float(hi)
    said = f"{name} {lo:.9g},{hi:.9g}"
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ValueError(f"{said}: expected finite LO < HI")
    f32 = np.finfo(np.float32)
    if max(abs(lo), abs(hi), hi - lo) > float(f32.max):  # codes * scale_factor too
        raise ValueError(f"{said}: the CF add_offset and scale_factor are float32, whose "
                         f"largest number is {float(f32.max):.3g}; give a range inside it")
    step = (hi - lo) / codes
    if step < float(f32.tiny):
        raise ValueError(f"{said}: a step of {step:.2g} per code is below float32's smallest "
                         f"normal number ({float(f32.tiny):.2g}), so the CF scale_factor "
                         "cannot hold it; give a wider range")
    if step < 2 * float(f32.eps) * max(abs(lo), abs(hi)):
        raise ValueError(f"{said}: a step of {step:.3g} per code is finer than float32 "
                         f"resolves at {max(abs(lo), abs(hi)):g} (the CF packing unpacks in "
                         "float32), so neighbouring codes read back as one value; give a "
                         "wider range, or one nearer 0")
    return lo, hi


def parse_json(text):
    """``json.loads(text)``, a nesting deeper than Python's reader goes refused as
    ``ValueError`` like any other JSON it cannot read (it raised ``RecursionError``: a file
    of 100 000 brackets gave a traceback where a malformed one gave a message)."""
    import json

    try:
        return json.loads(text)
    except RecursionError:
        raise ValueError("JSON nested too deeply to read (thousands of levels: no metadata "
                         "is)") from None
