"""The vendor's sensor calibration file (``.xml``, root element ``sensor_calibration``).

Snapshot-mosaic sensors (imec's, in XIMEA xiSpec cameras and others) ship with an XML file that
describes every filter. Two variants exist, both read here:

* **older**: ``filter_info`` holds the layout directly: ``filter_area``, ``pattern_width`` /
  ``pattern_height``, ``calibration_info`` (the response grid: start, step and count),
  ``bands/band[@pattern_position_index]`` with ``peaks/peak`` and ``response_composition/data``
  (comma-separated), ``rejection_filter/filter_response/data`` (the band-pass) and
  ``spectral_correction_info/virtual_bands/band`` with one row of ``custom_spectral_correction``
  coefficients per virtual band;
* **newer**: ``filter_info/filter_zones/filter_zone[@layout]`` holds the layout, the grid is
  ``filter_info/calibration_info/sample_points_nm[@values]`` (space-separated), each
  ``band[@index]`` has ``peaks/peak[@order, @shape]`` and ``response[@values]``;
  ``system_info/optical_components/optical_component`` lists what sits in front of every band
  (a band-pass filter) and ``system_info/spectral_correction_info/correction_matrices/
  correction_matrix`` the named matrices (``type`` reflectance or irradiance).

Conventions: band ``i`` sits at tile row ``i // pattern_width``, column ``i % pattern_width``,
the tile grid starting at the filter area's offset; a matrix's columns follow the band index.
The older format's one matrix is an irradiance matrix: its rows turn the measured responses
(band-pass included) into unit-peak Gaussians, and they sum to far less than 1, which a matrix
for flat-fielded values would not (measured on a real 5x5 NIR file: row sums 0.002-0.07).

Nothing is guessed: a missing element, a count that disagrees, a value that is not a finite
number, a layout other than MOSAIC, filters larger than a pixel or more than one filter zone
are refused in one line naming the element. The file is parsed with ``defusedxml`` (no entity
expansion, no external resources).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._validation import SENSOR_PX_MAX, check_pixel_pitch_um, shown
from ..files.reading import check_input
from .responses import (
    MIN_FWHM_STEPS,
    NOISE_FRACTION,
    VIRTUAL_REACH_FWHM,
    CorrectionMatrix,
    FilterResponses,
    Peak,
    reaching_beyond,
)

__all__ = ["MAX_FILE_BYTES", "VendorCalibration", "VendorFileWarning", "read_vendor_file"]


class VendorFileWarning(UserWarning):
    """A vendor calibration file read, with a part of it that cannot be used as it stands."""

#: Far larger than any calibration file (a 5x5 sensor's is 0.4 MB, the largest a few MB): a
#: bigger file is refused by its size before it is parsed (parsing takes about ten times the
#: file's size in memory: a 60 MB file took 580 MB and 10 s only to be refused after).
MAX_FILE_BYTES = 16 * 2**20
#: More samples than any curve of a calibration file holds (0.01 nm steps over 400-1400 nm):
#: a count or a list beyond it is refused before anything is sized by it.
MAX_SAMPLES = 100_000
#: The longest text a number is written in (``repr`` of a float is at most 24 characters),
#: with its separators: a list longer than this per value it should hold is refused before
#: it is split.
MAX_CHARS_PER_VALUE = 64
#: The attribute a file states an element's count of values in (``nr_elements="601"``).
COUNT_ATTRIBUTE = "nr_elements"
_SPLIT = re.compile(r"[,\s;]+")
#: A whole number as files write one: ASCII digits (``str.isdigit`` also takes "²").
_WHOLE = re.compile(r"-?[0-9]+")


@dataclass(frozen=True, eq=False)
class VendorCalibration:
    """What a vendor calibration file holds (see the module docstring).

    Attributes
    ----------
    path : str
    variant : {"older", "newer"}
    size_px : (int, int)
        The sensor's rows and columns.
    pixel_pitch_um : float or None
        None where the file gives 0 (unknown).
    filter_area_px : (int, int, int, int)
        Row, column, rows and columns of the filtered area on the sensor.
    mosaic_shape : (int, int)
        Tile rows and columns (pattern height, width).
    responses : FilterResponses
    matrices : tuple of CorrectionMatrix
    bit_depth : int or None
    """

    path: str
    variant: str
    size_px: tuple
    pixel_pitch_um: float | None
    filter_area_px: tuple
    mosaic_shape: tuple
    responses: FilterResponses
    matrices: tuple
    bit_depth: int | None = None


class _File:
    """The parsed tree with the file's name, for messages that say where a value is wrong."""

    def __init__(self, path):
        self.path = Path(path)

    def fail(self, message):
        raise ValueError(f"{self.path.name}: {message}")

    def child(self, el, where, *tags, required=True):
        """The child of ``el`` named one of ``tags`` (the variant's own first); refused when
        missing, or when the file states it twice (which of two values to believe is no
        reader's guess)."""
        for tag in tags:
            found = el.findall(tag)
            if len(found) > 1:
                self.fail(f"<{where}/{tag}> appears {len(found)} times; a calibration file "
                          "states it once")
            if found:
                return found[0]
        if required:
            self.fail(f"<{where}/{tags[0]}> is missing; is this a complete sensor calibration "
                      "file?")
        return None

    def present(self, el, *tags):
        """The first of ``tags`` that ``el`` holds (else the first): the name a message about
        its value gives, as the file spells it."""
        return next((t for t in tags if el.find(t) is not None), tags[0])

    def descendant(self, root, tag):
        """The one element named ``tag`` anywhere under ``root`` (None if none); refused when
        there are several."""
        found = list(root.iter(tag))
        if len(found) > 1:
            self.fail(f"<{tag}> appears {len(found)} times; a calibration file states it once")
        return found[0] if found else None

    def number(self, el, where, *tags, integer=False, minimum=None, required=True,
               default=None):
        node = self.child(el, where, *tags, required=required)
        if node is None:
            return default
        tags = (node.tag,)  # the messages below name the element the file holds
        text = (node.text or "").strip()
        if len(text) > MAX_CHARS_PER_VALUE:  # measured, not parsed: 10 MiB of digits took 1 s
            self.fail(f"<{where}/{tags[0]}> holds {len(text):,} characters, {shown(text)}: "
                      f"no number is written in more than {MAX_CHARS_PER_VALUE}")
        try:
            value = float(text) if "_" not in text else float("x")
        except ValueError:
            self.fail(f"<{where}/{tags[0]}> must be a number, got {shown(text)}")
        if not np.isfinite(value):
            self.fail(f"<{where}/{tags[0]}> must be finite, got {shown(text)}")
        if integer:
            if value != round(value):
                self.fail(f"<{where}/{tags[0]}> must be a whole number, got {shown(text)}")
            value = round(value)
        if minimum is not None and value < minimum:
            self.fail(f"<{where}/{tags[0]}> must be >= {minimum}, got {shown(text)}")
        return value

    def numbers(self, node, where, count=None, holder=None):
        """The numbers of a ``values`` attribute or of the element's text.

        The text's length is bounded before it is split and the count compared before any
        value is parsed: a list of millions of numbers is refused in the time it takes to
        measure it, not after every value is read (at most :data:`MAX_SAMPLES` values, or
        ``count``). A count the file states (``nr_elements`` of the element, or of
        ``holder``, the element that holds it: ``<response_composition nr_elements="601">
        <data>``) must be the number of values there, compared before they are parsed.
        """
        text = node.get("values")
        if text is None:
            text = node.text or ""
        most = MAX_SAMPLES if count is None else count
        if len(text) > (most + 1) * MAX_CHARS_PER_VALUE:
            self.fail(f"<{where}> holds {len(text) / 2**20:.1f} MiB of text, more than "
                      f"{most} numbers take" + ("" if count is not None else
                                                " (no calibration curve has more samples)"))
        parts = [p for p in _SPLIT.split(text.strip()) if p]
        for el, at in ((node, where), (holder, where.rpartition("/")[0])):
            if el is not None and el.get(COUNT_ATTRIBUTE) is not None:
                self._stated(el.get(COUNT_ATTRIBUTE), at, len(parts), where)
        if count is not None and len(parts) != count:
            self.fail(f"<{where}> holds {len(parts)} values, expected {count}")
        if len(parts) > MAX_SAMPLES:
            self.fail(f"<{where}> holds {len(parts)} values; no calibration curve has more "
                      f"than {MAX_SAMPLES}")
        try:
            if "_" in text:  # Python reads 1_0 as 10; no file writes numbers so
                raise ValueError
            values = np.array([float(p) for p in parts])
        except ValueError:
            bad = next(p for p in parts if not _is_float(p))
            self.fail(f"<{where}> holds {shown(bad)}, not a number")
        if values.size == 0:
            self.fail(f"<{where}> holds no numbers")
        if not np.all(np.isfinite(values)):
            self.fail(f"<{where}> holds a value that is not finite")
        return values

    def _stated(self, raw, at, found, where):
        """Refuse a count ``raw`` stated on ``<at>`` that is not the ``found`` values of
        ``<where>``: a file whose counts disagree is no file its writer finished."""
        said = f'<{at}> states {COUNT_ATTRIBUTE}="{shown(raw, quote=False)}"'
        if not _WHOLE.fullmatch(raw.strip()) or raw.strip().startswith("-"):
            self.fail(f"{said}: not a whole number >= 0")
        if len(raw.strip()) > 20 or int(raw) != found:
            self.fail(f"{said}, but <{where}> holds {found} values")

    def curve(self, values, where):
        """A transmission or response curve: not negative beyond measurement noise
        (:data:`~snapcorr.cube.responses.NOISE_FRACTION` of its largest value) and not zero
        everywhere, so that what multiplies it stays a physical response."""
        top = float(np.max(values))
        if not top >= np.finfo(float).tiny:  # a subnormal largest value is no response either
            self.fail(f"<{where}> is nowhere positive (largest value {top:g}): not a "
                      "response")
        low = float(np.min(values))
        if low < -NOISE_FRACTION * top:
            self.fail(f"<{where}> goes down to {low:g}, below -{NOISE_FRACTION:g} of its "
                      f"largest value {top:g}: a response is not negative")
        return values


def _is_float(text):
    try:
        float(text.replace("_", "x"))
    except ValueError:
        return False
    return True


def read_vendor_file(path) -> VendorCalibration:
    """Read a vendor sensor calibration file of either variant.

    Parameters
    ----------
    path : str or Path
        The ``.xml`` file.

    Returns
    -------
    VendorCalibration

    Raises
    ------
    FileNotFoundError
        Nothing at ``path``.
    ValueError
        Not a sensor calibration file, or one that is malformed (the message names the
        element), or a layout other than a mosaic.
    """
    from defusedxml import ElementTree
    from defusedxml.common import DefusedXmlException

    f = _File(path)
    try:
        check_input(f.path, what="sensor calibration file")
        size = f.path.stat().st_size
    except FileNotFoundError:
        raise FileNotFoundError(f"sensor calibration file not found: {f.path}") from None
    if size > MAX_FILE_BYTES:
        f.fail(f"it holds {size / 2**20:.1f} MiB, far more than any sensor calibration file "
               f"(a few MB): a file larger than {MAX_FILE_BYTES / 2**20:.0f} MiB is refused "
               "unread; is this the right file?")
    try:
        root = ElementTree.parse(f.path).getroot()
    except OSError as err:  # a path that names no real file's bytes (/proc/self/mem: EIO)
        f.fail(f"cannot read it ({err.strerror or err}); is it a calibration file on disk?")
    except ElementTree.ParseError as err:
        f.fail(f"not well-formed XML ({err})")
    except DefusedXmlException as err:
        f.fail(_unsafe_xml(err))
    if root.tag != "sensor_calibration":
        f.fail(f"root element <{shown(root.tag, quote=False)}>, expected <sensor_calibration>: "
               "not a sensor calibration file")
    info = f.child(root, "sensor_calibration", "filter_info")
    if info.find("filter_zones") is not None:
        return _newer(f, root, info)
    return _older(f, root, info)


def _unsafe_xml(err):
    """Why an XML that ``defusedxml`` stopped is refused, in words."""
    from defusedxml.common import EntitiesForbidden, ExternalReferenceForbidden

    if isinstance(err, EntitiesForbidden):
        what = ("it declares entities (<!ENTITY ...>), text the parser would expand in "
                "place: a few such lines can grow to gigabytes")
    elif isinstance(err, ExternalReferenceForbidden):
        what = "it refers to an external file or address, which the parser would read"
    else:
        what = "it has a document type declaration (<!DOCTYPE ...>) this reader does not take"
    return (f"refused: {what}; a sensor calibration file has none: is this the "
            "vendor's file, unchanged?")


def _sensor_info(f, root, variant):
    """The sensor's size, pitch and bit depth; messages name the variant's own tags."""
    si = f.child(root, "sensor_calibration", "sensor_info")

    def tags(newer, older):
        return (newer, older) if variant == "newer" else (older, newer)

    rows = f.number(si, "sensor_info", *tags("height_px", "height"), integer=True, minimum=1)
    cols = f.number(si, "sensor_info", *tags("width_px", "width"), integer=True, minimum=1)
    for tag, n in ((f.present(si, *tags("height_px", "height")), rows),
                   (f.present(si, *tags("width_px", "width")), cols)):
        if n > SENSOR_PX_MAX:
            f.fail(f"<sensor_info/{tag}> is {n} px; no sensor is more than {SENSOR_PX_MAX} px "
                   "across")
    pitch_tag = tags("pixel_pitch_um", "pixel_pitch")
    pitch = f.number(si, "sensor_info", *pitch_tag, minimum=0, required=False, default=0.0)
    if pitch > 0:  # 0: not given
        try:
            check_pixel_pitch_um(f"<sensor_info/{f.present(si, *pitch_tag)}>", pitch)
        except ValueError as err:
            f.fail(str(err))
    from .sensor import BIT_DEPTH_MAX  # the bound a Sensor's bit_depth takes

    bits_tag = tags("bit_depth", "input_bpp")
    bits = f.number(si, "sensor_info", *bits_tag, integer=True, minimum=1, required=False)
    if bits is not None and bits > BIT_DEPTH_MAX:
        f.fail(f"<sensor_info/{f.present(si, *bits_tag)}> is {bits}: no camera's codes have "
               f"more than {BIT_DEPTH_MAX} bits")
    return (rows, cols), (float(pitch) if pitch > 0 else None), bits


def _layout(f, el, where):
    layout = (el.get("layout") or "MOSAIC").strip().upper()
    if layout != "MOSAIC":
        f.fail(f"<{where}> has layout {shown(layout, quote=False)}; only MOSAIC sensors are "
               "read for now")


def _area_and_tile(f, el, where, size_px):
    fa = f.child(el, where, "filter_area")
    a = f"{where}/filter_area"
    row = f.number(fa, a, "offset_y", integer=True, minimum=0)
    col = f.number(fa, a, "offset_x", integer=True, minimum=0)
    rows = f.number(fa, a, "height", integer=True, minimum=1)
    cols = f.number(fa, a, "width", integer=True, minimum=1)
    if row + rows > size_px[0] or col + cols > size_px[1]:
        f.fail(f"<{a}> ({rows} x {cols} px at row {row}, column {col}) extends beyond the "
               f"{size_px[0]} x {size_px[1]} px sensor")
    ph = f.number(el, where, "pattern_height", integer=True, minimum=1)
    pw = f.number(el, where, "pattern_width", integer=True, minimum=1)
    for tag in ("filter_height", "filter_width"):
        n = f.number(el, where, tag, integer=True, minimum=1, required=False, default=1)
        if n != 1:
            f.fail(f"<{where}/{tag}> is {n}: filters covering several pixels are not read")
    if rows < ph or cols < pw:
        f.fail(f"<{a}> ({rows} x {cols} px) is smaller than one {ph} x {pw} tile")
    return (row, col, rows, cols), (ph, pw)


def _peaks(f, band, where):
    node = f.child(band, where, "peaks")
    out = []
    for k, p in enumerate(node.findall("peak")):
        w = f"{where}/peaks/peak[{k}]"
        order = p.get("order")
        out.append(Peak(f.number(p, w, "wavelength_nm"), f.number(p, w, "fwhm_nm"),
                        f.number(p, w, "QE", "qe", required=False, default=np.nan),
                        int(order) if order and _WHOLE.fullmatch(order.strip()) else None))
    if not out:
        f.fail(f"<{where}/peaks> lists no peak")
    seen = [p.wavelength_nm for p in out]
    twice = sorted({w for w in seen if seen.count(w) > 1})
    if twice:
        f.fail(f"<{where}/peaks> lists the peak at {twice[0]:g} nm twice: one band has each of "
               "its peaks once")
    for p in out:
        if np.isfinite(p.qe) and p.qe < 0:
            f.fail(f"<{where}/peaks> has a peak at {p.wavelength_nm:g} nm with QE {p.qe:g}: a "
                   "quantum efficiency is not negative")
        if not (p.fwhm_nm > 0 and 100 <= p.wavelength_nm <= 1e5):
            f.fail(f"<{where}/peaks> has a peak at {p.wavelength_nm:g} nm, FWHM "
                   f"{p.fwhm_nm:g} nm: not a wavelength in nm and a width > 0")
    return tuple(p._replace(qe=0.0) if not np.isfinite(p.qe) else p for p in out)


def _resolved(f, peaks, grid, where):
    """Refuse a peak narrower than the grid's step where it sits: the file's curve cannot
    show it, and what is sized by a band's width (the centres' and widths' fine grid) would
    grow without bound as the stated width falls. A peak wider than the whole grid is refused
    too: the curve cannot show that either, and the width would be reported as the band's."""
    typical = float(np.median(np.diff(grid)))  # one step made tiny at a peak is no licence
    span = float(grid[-1] - grid[0])
    for k, p in enumerate(peaks):
        if p.fwhm_nm > span and grid[0] <= p.wavelength_nm <= grid[-1]:  # else: outside
            f.fail(f"<{where}/peaks/peak[{k}]/fwhm_nm> is {p.fwhm_nm:g} nm, wider than the "
                   f"whole response grid ({grid[0]:g}-{grid[-1]:g} nm): the measured curve "
                   "cannot show a band so wide")
        step = max(float(np.interp(p.wavelength_nm, grid[1:], np.diff(grid))), typical)
        if p.fwhm_nm < step:
            f.fail(f"<{where}/peaks/peak[{k}]/fwhm_nm> is {p.fwhm_nm:g} nm, narrower than the "
                   f"response grid's {step:g} nm step at {p.wavelength_nm:g} nm: the measured "
                   "curve cannot show a band so narrow")


def _bands(f, bands_el, where, index_attrs, n_bands, grid, response_tag):
    by_index = {}
    for band in bands_el.findall("band"):
        raw = next((band.get(a) for a in index_attrs if band.get(a) is not None), None)
        if raw is None or not _WHOLE.fullmatch(raw.strip()) or raw.strip().startswith("-"):
            f.fail(f"a <{where}/band> has no whole-number {index_attrs[0]} attribute "
                   f"(got {shown(raw)})")
        i = int(raw)
        if i in by_index:
            f.fail(f"<{where}> lists band {i} twice")
        by_index[i] = band
    if len(by_index) != n_bands or sorted(by_index) != list(range(n_bands)):
        f.fail(f"<{where}> lists bands {sorted(by_index)[:6]}{'...' if len(by_index) > 6 else ''}"
               f" ({len(by_index)}), but a {n_bands}-band tile needs indices 0-{n_bands - 1}")
    curves, peaks = [], []
    for i in range(n_bands):
        w = f"{where}/band[{i}]"
        band = by_index[i]
        peaks.append(_peaks(f, band, w))
        _resolved(f, peaks[-1], grid, w)
        node = holder = band
        for tag in response_tag:
            holder, node = node, f.child(node, w, tag)
        where_curve = f"{w}/{'/'.join(response_tag)}"
        curves.append(f.curve(f.numbers(node, where_curve, count=grid.size,
                                        holder=holder if holder is not band else None),
                              where_curve))
    return np.array(curves), tuple(peaks)


def _grid_from_range(f, ci, where):
    start = f.number(ci, where, "measurement_range_start_nm", "wavelength_start_nm")
    step = f.number(ci, where, "measurement_resolution_nm", "wavelength_resolution_nm")
    n = f.number(ci, where, "nr_measurements", "nr_data_points", integer=True, minimum=3)
    if not step > 0:
        f.fail(f"<{where}> gives a step of {step:g} nm; it must be > 0")
    if n > MAX_SAMPLES or n > f.path.stat().st_size // 2:
        f.fail(f"<{where}/{f.present(ci, 'nr_measurements', 'nr_data_points')}> is {n}: more "
               "samples than the file holds room for "
               f"(at most {min(MAX_SAMPLES, f.path.stat().st_size // 2)})")
    grid = start + step * np.arange(n)
    end = f.number(ci, where, "measurement_range_end_nm", "wavelength_end_nm", required=False)
    if end is not None and abs(grid[-1] - end) > 1e-6 * max(1.0, abs(end)):
        f.fail(f"<{where}>: {n} samples from {start:g} nm in steps of {step:g} nm end at "
               f"{grid[-1]:g} nm, not at the stated {end:g} nm")
    return grid


def _older(f, root, info):
    size, pitch, bits = _sensor_info(f, root, "older")
    _layout(f, info, "filter_info")
    area, tile = _area_and_tile(f, info, "filter_info", size)
    grid = _grid_from_range(f, f.child(info, "filter_info", "calibration_info"),
                            "filter_info/calibration_info")
    n_bands = tile[0] * tile[1]
    curves, peaks = _bands(f, f.child(info, "filter_info", "bands"), "filter_info/bands",
                           ("pattern_position_index", "index"), n_bands, grid,
                           ("response_composition", "data"))
    system, name = np.ones(grid.size), "none"
    rej = f.child(info, "filter_info", "rejection_filter", required=False)
    if rej is not None:
        where = "filter_info/rejection_filter"
        holder = f.child(rej, where, "filter_response")
        node = f.child(holder, where, "data")
        values = f.curve(f.numbers(node, f"{where}/filter_response/data", holder=holder),
                         f"{where}/filter_response/data")
        if f.child(rej, where, "wavelength_start_nm", required=False) is not None:
            own = _grid_from_range(f, rej, where)
            if values.size != own.size:
                f.fail(f"<{where}/filter_response/data> holds {values.size} values, its grid "
                       f"{own.size}")
            system = _on_grid(f, own, values, grid, where)
        elif values.size == grid.size:
            system = values
        else:
            f.fail(f"<{where}/filter_response/data> holds {values.size} values, the response "
                   f"grid {grid.size}")
        kind = f.child(rej, where, "type", required=False)
        name = (kind.text or "").strip() if kind is not None and kind.text else "band-pass"
    responses = _responses(f, grid, curves, system, peaks, name)
    matrices = ()
    sci = f.descendant(root, "spectral_correction_info")
    if sci is not None and f.child(sci, "spectral_correction_info", "virtual_bands",
                                   required=False) is not None:
        fwhm = f.number(sci, "spectral_correction_info", "fwhm_virtual_filters_nm",
                        required=False, default=np.nan)
        matrices = (_older_matrix(f, sci, n_bands, fwhm, grid),)
    _matrices_on_grid(f, matrices, grid, "spectral_correction_info/virtual_bands")
    return VendorCalibration(str(f.path), "older", size, pitch, area, tile, responses,
                             matrices, bits)


def _responses(f, grid, curves, system, peaks, name):
    """The checked responses; what FilterResponses refuses is said with the file's name."""
    try:
        return FilterResponses(grid, curves, system, peaks, system_name=name)
    except ValueError as err:
        f.fail(str(err))


def _older_matrix(f, sci, n_bands, fwhm, grid):
    where = "spectral_correction_info/virtual_bands"
    rows, wl = [], []
    for k, band in enumerate(sci.find("virtual_bands").findall("band")):
        w = f"{where}/band[{k}]"
        wl.append(f.number(band, w, "wavelength_nm"))
        _virtual_width(f, fwhm, wl[-1], grid, "spectral_correction_info/fwhm_virtual_filters_nm")
        holder = f.child(band, w, "custom_spectral_correction")
        node = f.child(holder, f"{w}/custom_spectral_correction", "data")
        rows.append(f.numbers(node, f"{w}/custom_spectral_correction/data", count=n_bands,
                              holder=holder))
    if not rows:
        f.fail(f"<{where}> lists no virtual band")
    try:
        return CorrectionMatrix("custom", "irradiance", wl, np.full(len(wl), fwhm), rows)
    except ValueError as err:
        f.fail(str(err))


def _virtual_width(f, fwhm, wavelength_nm, grid, tag):
    """Refuse a virtual band's stated width (``<tag>``; NaN: not given) the responses' grid
    cannot make: narrower than :data:`~snapcorr.cube.responses.MIN_FWHM_STEPS` of its steps
    where the band sits (the bound a width asked for in a correction has: 1e-300 nm made
    Gaussians that overflowed and drew nothing), or wider than the whole grid."""
    if not np.isfinite(fwhm):
        return
    step = float(np.interp(wavelength_nm, grid[1:], np.diff(grid)))
    if fwhm < MIN_FWHM_STEPS * step:
        f.fail(f"<{tag}> is {fwhm:g} nm at {wavelength_nm:g} nm, narrower than the responses' "
               f"grid resolves ({MIN_FWHM_STEPS:g} of its {step:g} nm steps): a virtual band "
               f"is at least {MIN_FWHM_STEPS * step:g} nm wide there")
    span = float(grid[-1] - grid[0])
    if fwhm > span:
        f.fail(f"<{tag}> is {fwhm:g} nm, wider than the whole response grid "
               f"({grid[0]:g}-{grid[-1]:g} nm): the bands cannot make a virtual band so wide")


def _matrices_on_grid(f, matrices, grid, where):
    """Refuse a virtual band centred outside the measured responses: the matrix makes it from
    the bands, which see nothing there, and its wavelength would label the output."""
    for m in matrices:
        out = [w for w in np.asarray(m.wavelength_nm, float) if not grid[0] <= w <= grid[-1]]
        if out:
            f.fail(f"<{where}> {shown(m.name)} has a virtual band at {out[0]:g} nm, outside the "
                   f"responses' {grid[0]:g}-{grid[-1]:g} nm")
        wide = reaching_beyond(m.wavelength_nm, m.fwhm_nm, grid)
        if wide.size:  # the file is sound otherwise: its bands, responses, other matrices
            b = wide[0]
            warnings.warn(
                f"{f.path}: <{where}> {shown(m.name)} has {wide.size} virtual band(s) whose "
                f"width reaches beyond the responses' {grid[0]:g}-{grid[-1]:g} nm within "
                f"{VIRTUAL_REACH_FWHM:g} FWHM (the first at {m.wavelength_nm[b]:g} nm, FWHM "
                f"{m.fwhm_nm[b]:g} nm): the bands cannot make it so wide there, so virtual "
                "bands from it are refused unless given a narrower width", VendorFileWarning,
                stacklevel=2)


def _on_grid(f, own, values, grid, where):
    """A component's curve on the band grid; refused unless its own grid covers it."""
    if np.any(np.diff(own) <= 0):
        f.fail(f"<{where}>: its wavelengths must increase")
    if own[0] > grid[0] + 1e-9 or own[-1] < grid[-1] - 1e-9:
        f.fail(f"<{where}> covers {own[0]:g}-{own[-1]:g} nm, not the responses' "
               f"{grid[0]:g}-{grid[-1]:g} nm")
    return np.interp(grid, own, values)


def _newer(f, root, info):
    size, pitch, bits = _sensor_info(f, root, "newer")
    grid_node = f.child(f.child(info, "filter_info", "calibration_info"),
                        "filter_info/calibration_info", "sample_points_nm")
    grid = f.numbers(grid_node, "filter_info/calibration_info/sample_points_nm")
    if grid.size < 3 or np.any(np.diff(grid) <= 0):
        f.fail("<filter_info/calibration_info/sample_points_nm> must list at least 3 "
               "increasing wavelengths")
    zones = f.child(info, "filter_info", "filter_zones").findall("filter_zone")
    if len(zones) != 1:
        f.fail(f"<filter_info/filter_zones> holds {len(zones)} filter zones; one is read")
    zone, where = zones[0], "filter_info/filter_zones/filter_zone"
    _layout(f, zone, where)
    area, tile = _area_and_tile(f, zone, where, size)
    n_bands = tile[0] * tile[1]
    curves, peaks = _bands(f, f.child(zone, where, "bands"), f"{where}/bands",
                           ("index", "pattern_position_index"), n_bands, grid, ("response",))
    system, names = np.ones(grid.size), []
    si = f.descendant(root, "system_info")
    comps = (f.child(si, "system_info", "optical_components", required=False)
             if si is not None else None)
    for k, comp in enumerate(comps.findall("optical_component") if comps is not None else []):
        w = f"system_info/optical_components/optical_component[{k}]"
        own = f.numbers(f.child(comp, w, "sample_points_nm"), f"{w}/sample_points_nm")
        values = f.curve(f.numbers(f.child(comp, w, "response"), f"{w}/response",
                                   count=own.size), f"{w}/response")
        system = system * _on_grid(f, own, values, grid, w)
        kind = f.child(comp, w, "type", required=False)
        names.append((kind.text or "").strip() if kind is not None and kind.text else
                     f"component {k}")
    responses = _responses(f, grid, curves, system, peaks, " x ".join(names) or "none")
    matrices = tuple(_newer_matrix(f, m, k, n_bands, grid)
                     for k, m in enumerate(root.iter("correction_matrix")))
    names_seen = [m.name for m in matrices]
    if len(set(names_seen)) != len(names_seen):
        f.fail(f"two correction matrices share a name ({shown(names_seen, 80)})")
    _matrices_on_grid(f, matrices, grid, "correction_matrices/correction_matrix")
    return VendorCalibration(str(f.path), "newer", size, pitch, area, tile, responses,
                             matrices, bits)


def _newer_matrix(f, m, k, n_bands, grid):
    where = f"correction_matrices/correction_matrix[{k}]"
    name_node = f.child(m, where, "name")
    name = (name_node.text or "").strip() or f"matrix {k}"
    kind_node = f.child(m, where, "type")
    kind = (kind_node.text or "").strip().lower()
    if kind not in ("reflectance", "irradiance"):
        f.fail(f"<{where}/type> is {shown(kind)}; expected reflectance or irradiance")
    rows, wl, fw = [], [], []
    vbs = f.child(m, where, "virtual_bands").findall("virtual_band")
    for j, vb in enumerate(vbs):
        w = f"{where}/virtual_bands/virtual_band[{j}]"
        wl.append(f.number(vb, w, "wavelength_nm"))
        fw.append(f.number(vb, w, "fwhm_nm", required=False, default=np.nan))
        _virtual_width(f, fw[-1], wl[-1], grid, f"{w}/fwhm_nm")
        rows.append(f.numbers(f.child(vb, w, "coefficients"), f"{w}/coefficients",
                              count=n_bands))
    if not rows:
        f.fail(f"<{where}/virtual_bands> lists no virtual band")
    try:
        return CorrectionMatrix(name, kind, wl, fw, rows)
    except ValueError as err:
        f.fail(str(err))
