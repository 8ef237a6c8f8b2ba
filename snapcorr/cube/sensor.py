"""Sensor descriptions: band layout, pixel pitch, filter centres and effective indices.

A sensor is described by a TOML file (``[sensor]``, see ``calibration/README.md``), by the
vendor's calibration ``.xml`` (:mod:`snapcorr.cube.vendor_xml`: measured responses, layout,
active area, correction matrices), or by a TOML that names such a file (``vendor_file``) and
adds what it lacks (``n_eff``; ``pixel_pitch_um`` where it says 0).
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._bundled import profile_path
from .._validation import (
    N_EFF_MAX,
    SENSOR_PX_MAX,
    check_integers,
    check_numbers,
    check_pixel_pitch_um,
    check_wavelengths_nm,
    renamed_keywords,
    shown,
)
from ..files.reading import check_input
from ..files.toml import read_toml, write_toml
from .responses import CorrectionMatrix, FilterResponses

__all__ = ["LAYOUTS", "VENDOR_OVERRIDES", "Sensor"]

#: ``snapscan``: every band of a cube pixel was exposed at the same sensor position (the sensor
#: moves behind the lens). ``mosaic``: a snapshot mosaic; each band sits at its own offset in a
#: repeating tile.
LAYOUTS = ("snapscan", "mosaic")
_KEYS = {"name", "layout", "pixel_pitch_um", "cwl_nm", "fwhm_nm", "n_eff", "mosaic_shape",
         "band_offset", "size_px", "profile", "filter_area_px", "bit_depth"}
#: The keys a sensor TOML naming a ``vendor_file`` may add or override.
VENDOR_OVERRIDES = ("name", "n_eff", "pixel_pitch_um", "size_px", "bit_depth")
#: A camera's digital numbers have at most this many bits.
BIT_DEPTH_MAX = 32
#: Filter shapes a sensor may name (``snapcorr.optics.FILTER_PROFILES`` at normal incidence); any
#: other ``profile`` is a file of a measured shape. ``"measured"``: each band's own measured
#: response (a vendor calibration file).
PROFILE_NAMES = ("gaussian", "airy", "multi_lorentzian", "pi")
MEASURED = "measured"
#: What the refusals say where a value the vendor's file does not give is needed.
_NEEDS = {
    "n_eff": ("its filters' effective index n_eff, which vendor calibration files do not give; "
              "give it in a sensor TOML naming the file (vendor_file = ..., n_eff = ...), from "
              "the vendor's design value or a measurement (`snapcorr pupil --fit-n-eff` fits "
              "it from cubes of a spectral target at two f-numbers, measured responses "
              "included, and its --sensor-out writes that TOML; in Python, "
              "snapcorr.calibrate.locate_pupil with fit_n_eff)"),
    "pixel_pitch_um": ("its pixel pitch, which its file gives as 0 (unknown); give "
                       "pixel_pitch_um in a sensor TOML naming the file (vendor_file = ..., "
                       "pixel_pitch_um = ...)"),
}


def _per_band(name, value, n_bands, *, minimum=None, strict=True):
    check_numbers(name, value)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be numbers, got {shown(value)}") from None
    if arr.ndim == 0:
        arr = np.full(n_bands, float(arr))
    if arr.shape != (n_bands,):
        raise ValueError(f"{name} must be a scalar or have one value per band ({n_bands}), "
                         f"got {arr.size}")
    if not np.all(np.isfinite(arr)) or (
        minimum is not None and np.any(arr <= minimum if strict else arr < minimum)
    ):
        raise ValueError(f"{name} must be finite and > {minimum}, got {arr.tolist()[:5]}...")
    return tuple(float(v) for v in arr)


@dataclass(frozen=True)
class Sensor:
    """A spectral image sensor (the ``[sensor]`` table of ``calibration/sensors/*.toml``).

    Parameters
    ----------
    name : str
    layout : {"snapscan", "mosaic"}
    pixel_pitch_um : float or None
        Pixel pitch on the sensor, micrometres; None where unknown (what needs it refuses).
    cwl_nm : sequence of float
        Central wavelength of each band at normal, collimated incidence, nm (a vendor file's
        main peaks).
    fwhm_nm : float or sequence of float
        Band widths, nm (a scalar applies to all bands).
    n_eff : float or sequence of float or None
        Effective refractive index of each band's filter (> 1); None where unknown (vendor
        files do not give it; what needs it refuses, :meth:`require`).
    mosaic_shape : (int, int), mosaic only
        Tile size in pixels (rows, columns).
    band_offset : sequence of (int, int), mosaic only
        Each band's (row, column) inside the tile.
    size_px : (int, int), optional
        The image's full size in pixels (rows, columns), centred on the optical axis: the
        field the scene budget (``snapcorr budget``) covers when no cube is given.
    profile : str
        The filters' shape: ``"gaussian"`` (default), ``"airy"``, ``"multi_lorentzian"``,
        ``"pi"``, or the path of a two-column file (offset from the band's centre in nm,
        transmission), one measured shape for every band (a relative path in a sensor file is
        relative to that file's folder). It sets each pixel's bandwidth
        (``fwhm_corrected``). ``"measured"`` for a sensor with ``responses``.
    calibration : dict, optional
        Free-form record of where values came from (the ``[calibration]`` table of the file,
        e.g. an effective index fitted by ``snapcorr pupil``). Not compared.
    responses : FilterResponses, optional
        Each band's measured response and the system's (band-pass) in front of them.
    filter_area_px : (int, int, int, int), optional, mosaic only
        Row, column, rows and columns of the filtered area on the sensor: the tile grid
        starts at its corner (default: the sensor's corner, no limit).
    matrices : tuple of CorrectionMatrix, optional
        The vendor's correction matrices to virtual bands.
    vendor_file : str, optional
        The vendor calibration file these came from (provenance; not compared).
    bit_depth : int, optional
        Bits of the camera's digital numbers (a vendor file's ``bit_depth``/``input_bpp``):
        a raw pixel at the largest code, ``2**bit_depth - 1`` (:attr:`full_scale_dn`), is
        saturated, the default saturation of flat-fielding.
    vendor_band : sequence of int, optional
        Each band's number in the file that described the sensor (the vendor's band index).
        A mosaic's bands are kept in order of wavelength (``cwl_nm`` increasing), whatever
        order the file lists them in: their tile positions, widths, indices, measured
        responses and correction-matrix columns move with them, and ``vendor_band`` says where
        each came from (set from the file's order when not given).
    """

    name: str
    layout: str
    pixel_pitch_um: float | None
    cwl_nm: tuple
    fwhm_nm: tuple
    n_eff: tuple | None
    mosaic_shape: tuple | None = None
    band_offset: tuple | None = None
    size_px: tuple | None = None
    profile: str = "gaussian"
    calibration: dict = field(default_factory=dict, compare=False, repr=False, kw_only=True)
    responses: FilterResponses | None = field(default=None, repr=False, kw_only=True)
    filter_area_px: tuple | None = field(default=None, kw_only=True)
    matrices: tuple = field(default=(), repr=False, kw_only=True)
    vendor_file: str | None = field(default=None, compare=False, kw_only=True)
    bit_depth: int | None = field(default=None, kw_only=True)
    vendor_band: tuple | None = field(default=None, kw_only=True)

    def __post_init__(self):
        set_ = object.__setattr__
        if self.layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}, got {shown(self.layout)}")
        set_(self, "name", str(self.name))
        if self.pixel_pitch_um is not None:
            set_(self, "pixel_pitch_um", check_pixel_pitch_um("pixel_pitch_um",
                                                           self.pixel_pitch_um))
        check_numbers("cwl_nm", self.cwl_nm)
        cwl = np.atleast_1d(check_wavelengths_nm("cwl_nm", self.cwl_nm))
        if cwl.ndim != 1 or cwl.size == 0:
            raise ValueError("cwl_nm must list one central wavelength per band")
        n = cwl.size
        set_(self, "cwl_nm", _per_band("cwl_nm", cwl, n, minimum=0))
        set_(self, "fwhm_nm", _per_band("fwhm_nm", self.fwhm_nm, n, minimum=0))
        if self.n_eff is not None:
            set_(self, "n_eff", _per_band("n_eff", self.n_eff, n, minimum=1))
            if max(self.n_eff) >= N_EFF_MAX:
                raise ValueError(f"n_eff must be below {N_EFF_MAX:g} (a thin-film filter's "
                                 f"effective index), got {max(self.n_eff):g}")
        if self.layout == "mosaic":
            if self.mosaic_shape is None or self.band_offset is None:
                raise ValueError("a mosaic sensor needs mosaic_shape and band_offset")
            shape = tuple(int(v) for v in check_integers("mosaic_shape", self.mosaic_shape,
                                                          SENSOR_PX_MAX).ravel())
            if len(shape) != 2 or min(shape) < 1:
                raise ValueError(f"mosaic_shape must be [rows, cols] >= 1, got {shape}")
            off = check_integers("band_offset", self.band_offset, SENSOR_PX_MAX)
            if off.shape != (n, 2):
                raise ValueError(f"band_offset must list one [row, col] per band ({n}), got "
                                 f"shape {off.shape}")
            if np.any(off < 0) or np.any(off >= np.array(shape)):
                raise ValueError(f"band_offset entries must lie inside the {shape} tile")
            if len({tuple(o) for o in off}) != n:
                raise ValueError("two bands share a band_offset")
            set_(self, "mosaic_shape", shape)
            set_(self, "band_offset", tuple(tuple(int(v) for v in o) for o in off))
        elif self.mosaic_shape is not None or self.band_offset is not None:
            raise ValueError("mosaic_shape and band_offset apply to layout = 'mosaic' only")
        if self.size_px is not None:
            size = check_integers("size_px", self.size_px, SENSOR_PX_MAX)
            if size.shape != (2,) or np.any(size < 1) or np.any(size > SENSOR_PX_MAX):
                raise ValueError(f"size_px must be [rows, cols], whole numbers 1-"
                                 f"{SENSOR_PX_MAX}, got {shown(self.size_px)}")
            set_(self, "size_px", tuple(int(v) for v in size))
            if self.layout == "mosaic" and any(t > z for t, z in zip(self.mosaic_shape,
                                                                     self.size_px, strict=True)):
                raise ValueError(f"a {self.mosaic_shape[0]} x {self.mosaic_shape[1]} tile does "
                                 f"not fit on a sensor of {self.size_px[0]} x {self.size_px[1]} "
                                 "px: check mosaic_shape and size_px")
        set_(self, "profile", str(self.profile))
        if self.bit_depth is not None:
            bits = check_integers("bit_depth", self.bit_depth, BIT_DEPTH_MAX)
            if bits.shape != () or not 1 <= int(bits) <= BIT_DEPTH_MAX:
                raise ValueError(f"bit_depth must be a whole number of bits, 1-{BIT_DEPTH_MAX}, "
                                 f"got {shown(self.bit_depth)}")
            set_(self, "bit_depth", int(bits))
        self._check_vendor_parts(n)
        self._in_wavelength_order(n)
        if self.profile not in (*PROFILE_NAMES, MEASURED):
            _read_shape(self.profile)  # read and checked now: a bad file fails at load
        set_(self, "calibration", dict(self.calibration or {}))

    def _check_vendor_parts(self, n):
        set_ = object.__setattr__
        if self.responses is not None:
            if not isinstance(self.responses, FilterResponses):
                raise TypeError("responses must be a FilterResponses")
            if self.responses.n_bands != n:
                raise ValueError(f"the measured responses have {self.responses.n_bands} bands, "
                                 f"cwl_nm {n}")
            if self.profile not in ("gaussian", MEASURED):  # gaussian: the default, unset
                raise ValueError(f"profile {shown(self.profile)} and measured responses both say "
                                 "what the filters are; the measured responses are used")
            set_(self, "profile", MEASURED)
        elif self.profile == MEASURED:
            raise ValueError("profile 'measured' needs the bands' measured responses (a vendor "
                             "calibration file)")
        matrices = tuple(self.matrices or ())
        for m in matrices:
            if not isinstance(m, CorrectionMatrix):
                raise TypeError("matrices must be CorrectionMatrix objects")
            if m.coefficients.shape[1] != n:
                raise ValueError(f"correction matrix {shown(m.name)} has {m.coefficients.shape[1]} "
                                 f"columns, the sensor {n} bands")
        set_(self, "matrices", matrices)
        if self.filter_area_px is not None:
            if self.layout != "mosaic":
                raise ValueError("filter_area_px applies to layout = 'mosaic' only")
            area = check_integers("filter_area_px", self.filter_area_px, SENSOR_PX_MAX)
            if area.shape != (4,) or np.any(area[:2] < 0) or np.any(area[2:] < 1):
                raise ValueError(f"filter_area_px must be [row, col, rows, cols] (whole "
                                 f"numbers, offsets >= 0, sizes >= 1), got "
                                 f"{shown(self.filter_area_px)}")
            if self.size_px is not None and (area[0] + area[2] > self.size_px[0]
                                             or area[1] + area[3] > self.size_px[1]):
                raise ValueError(f"filter_area_px {area.tolist()} extends beyond size_px "
                                 f"{list(self.size_px)}")
            set_(self, "filter_area_px", tuple(int(v) for v in area))

    def _in_wavelength_order(self, n):
        """A mosaic's bands put in order of wavelength, each with its place in the file that
        described it (``vendor_band``): its tile position, width, index, measured response
        and correction-matrix column moved with it, so that every cube built from a frame
        lists its bands by wavelength and the vendor's matrices give the same virtual bands."""
        set_ = object.__setattr__
        if self.vendor_band is not None:
            given = check_integers("vendor_band", self.vendor_band)
            if given.shape != (n,) or sorted(given.tolist()) != list(range(n)):
                raise ValueError(f"vendor_band must number the {n} bands 0-{n - 1}, each once, "
                                 f"got {shown(self.vendor_band)}")
            set_(self, "vendor_band", tuple(int(v) for v in given))
        if self.layout != "mosaic":
            return
        order = np.argsort(np.asarray(self.cwl_nm), kind="stable")
        vendor = np.arange(n) if self.vendor_band is None else np.asarray(self.vendor_band)
        set_(self, "vendor_band", tuple(int(v) for v in vendor[order]))
        if np.array_equal(order, np.arange(n)):
            return

        def moved(values):
            return tuple(values[i] for i in order)

        set_(self, "cwl_nm", moved(self.cwl_nm))
        set_(self, "fwhm_nm", moved(self.fwhm_nm))
        if self.n_eff is not None:
            set_(self, "n_eff", moved(self.n_eff))
        set_(self, "band_offset", moved(self.band_offset))
        r = self.responses
        if r is not None:
            set_(self, "responses", FilterResponses(r.wavelength_nm, r.curves[order], r.system,
                                                    moved(r.peaks), r.system_name))
        set_(self, "matrices", tuple(
            CorrectionMatrix(m.name, m.kind, m.wavelength_nm, m.fwhm_nm, m.coefficients[:, order])
            for m in self.matrices))

    def band_coords(self):
        """``{"vendor_band": ...}``: the coordinate a cube built from a frame carries along
        ``band`` where the file numbers the bands in another order (empty where its order is
        the wavelengths')."""
        if self.vendor_band is None or self.vendor_band == tuple(range(self.n_bands)):
            return {}
        return {"vendor_band": ("band", np.asarray(self.vendor_band, np.int32), {
            "long_name": "the band's number in the sensor's calibration file (its tile order)",
            "units": "1"})}

    def in_file_order(self, values):
        """Per-band ``values`` (in this sensor's wavelength order) in the order of the file
        that described it (the vendor's band numbers)."""
        values = list(values)
        if self.vendor_band is None:
            return values
        out = [None] * len(values)
        for v, i in zip(values, self.vendor_band, strict=True):
            out[i] = v
        return out

    def in_band_order(self, cube, mask=None, what="the cube"):
        """``cube`` (and ``mask``) with the bands in this sensor's order: a cube whose
        ``wavelength`` lists the sensor's bands in another order (the vendor's tile order, as
        files written before bands were ordered by wavelength hold them) is reordered; any
        other is returned as it is, for :meth:`check_cube` to judge.

        Parameters
        ----------
        cube : xarray.DataArray
            ``(y, x, band)`` with a ``wavelength`` coordinate, nm.
        mask : xarray.DataArray, optional
            Reordered with the cube where it has a ``band`` dim.
        what : str
            What the cube is (kept for the messages of callers).

        Returns
        -------
        (xarray.DataArray, xarray.DataArray or None)
        """
        if "wavelength" not in cube.coords or cube.sizes.get("band") != self.n_bands:
            return cube, mask
        wl = np.asarray(cube["wavelength"].values, float)
        order = np.argsort(wl, kind="stable")
        if np.array_equal(order, np.arange(wl.size)):
            return cube, mask
        if not np.max(np.abs(wl[order] - np.asarray(self.cwl_nm, float))) <= 0.05:
            return cube, mask
        if mask is not None and "band" in mask.dims:
            mask = mask.isel(band=order)
        return cube.isel(band=order), mask

    def require(self, key, what):
        """The value of ``key`` (``"n_eff"`` or ``"pixel_pitch_um"``), or a ``ValueError``
        saying that ``what`` needs it and how to give it.

        Parameters
        ----------
        key : {"n_eff", "pixel_pitch_um"}
        what : str
            What needs the value, for the message ("the wavelength correction", ...).
        """
        value = getattr(self, key)
        if value is None:
            raise ValueError(f"{what} needs the sensor {shown(self.name)} to give {_NEEDS[key]}")
        return value

    @property
    def tile_origin_px(self) -> tuple:
        """Sensor row and column where the mosaic's tile grid starts (the filter area's
        corner; (0, 0) when the sensor does not say)."""
        if self.filter_area_px is None:
            return (0, 0)
        return self.filter_area_px[:2]

    @renamed_keywords(origin_px="sensor_origin_px")
    def band_offsets_at(self, sensor_origin_px):
        """Each band's (row, column) inside a tile-sized window whose corner is the sensor
        pixel ``sensor_origin_px``: the band layout follows the origin modulo the tile.

        Parameters
        ----------
        sensor_origin_px : (int, int)
            Sensor row and column of the window's corner, anywhere on or off the tile grid.

        Returns
        -------
        ndarray of int, shape (n_bands, 2)
        """
        if self.layout != "mosaic":
            raise ValueError(f"sensor {shown(self.name)} is not a mosaic (layout "
                             f"{shown(self.layout)})")
        tile = np.array(self.mosaic_shape)
        corner = np.asarray(sensor_origin_px, dtype=np.int64)
        phase = (corner - np.array(self.tile_origin_px)) % tile
        return (np.asarray(self.band_offset) - phase) % tile

    @property
    def field_radius_mm(self) -> float | None:
        """Distance from the image centre to its corner (mm), if ``size_px`` and the pitch are
        known."""
        if self.size_px is None or self.pixel_pitch_um is None:
            return None
        rows, cols = self.size_px
        return 0.5 * float(np.hypot(rows, cols)) * self.pixel_pitch_mm

    @property
    def profile_shape(self):
        """The filters' shape as :func:`snapcorr.optics.bandwidth.band_profile` takes it: the
        name, ``(offset_nm, transmission)`` read from the file, or ``"measured"`` (each band's
        own curve, :attr:`responses`)."""
        if self.profile in (*PROFILE_NAMES, MEASURED):
            return self.profile
        return _read_shape(self.profile)

    @property
    def full_scale_dn(self) -> int | None:
        """The largest digital number, ``2**bit_depth - 1`` (None where not given)."""
        return None if self.bit_depth is None else 2 ** self.bit_depth - 1

    @property
    def n_bands(self) -> int:
        return len(self.cwl_nm)

    @property
    def pixel_pitch_mm(self) -> float:
        return self.require("pixel_pitch_um", "a position in millimetres") * 1e-3

    def check_cube(self, cube, what="the cube", *, atol_nm=0.05):
        """Raise a ``ValueError`` unless ``cube`` has this sensor's bands: as many, and its
        ``wavelength`` coordinate (when it has one) within ``atol_nm`` of ``cwl_nm``, each in
        wavelength order (a cube in the tile's order is as good as one in wavelength order:
        compared as given, one band 0.5 nm off was said to differ by 197 nm).

        Parameters
        ----------
        cube : xarray.DataArray or xarray.Dataset
            Anything with ``sizes["band"]`` and optionally a ``wavelength`` coordinate, nm.
        what : str
            What the cube is, for the message.
        atol_nm : float
            Largest difference allowed between the cube's and the sensor's wavelengths, nm.
        """
        nb = cube.sizes.get("band")
        if nb != self.n_bands:
            raise ValueError(f"{what} has {nb} bands, the sensor {shown(self.name)} "
                             f"{self.n_bands}; use the sensor it was taken with")
        if "wavelength" in cube.coords:  # in either order (the tile's, or wavelength's)
            off = np.max(np.abs(np.sort(np.asarray(cube["wavelength"].values, float))
                                - np.sort(np.asarray(self.cwl_nm, float))))
            if not off <= atol_nm:
                raise ValueError(f"{what}'s wavelengths differ from the sensor "
                                 f"{shown(self.name)}'s (by up to {off:.3g} nm); use the "
                                 "matching sensor")

    def describe(self) -> str:
        """What the description holds, as text: layout, area, bands (with their main peaks
        for measured ones), profiles and correction matrices."""
        lines = [f"{self.name}: {self.layout} sensor, {self.n_bands} bands"
                 + (f", from {Path(self.vendor_file).name}" if self.vendor_file else "")]
        size = (f"{self.size_px[1]} x {self.size_px[0]} px" if self.size_px else "size not given")
        pitch = (f"{self.pixel_pitch_um:g} um pixels" if self.pixel_pitch_um
                 else "pixel pitch not given (add pixel_pitch_um in a sensor TOML)")
        bits = ("" if self.bit_depth is None else
                f", {self.bit_depth}-bit codes (saturated at {self.full_scale_dn})")
        lines.append(f"  sensor: {size}, {pitch}{bits}")
        if self.layout == "mosaic":
            tr, tc = self.mosaic_shape
            area = "tile grid from the sensor's corner"
            if self.filter_area_px:
                r0, c0, nr, nc = self.filter_area_px
                area = f"filter area rows {r0}-{r0 + nr - 1}, columns {c0}-{c0 + nc - 1}"
            lines.append(f"  mosaic: {tr} x {tc} tile, {area}")
        n = ("not given: fit it with snapcorr pupil --fit-n-eff, or add n_eff in a sensor TOML"
             if self.n_eff is None else
             f"{min(self.n_eff):g}" + ("" if len(set(self.n_eff)) == 1
                                       else f"-{max(self.n_eff):g}"))
        lines.append(f"  n_eff: {n}")

        def span(v, fmt=".3g"):
            lo, hi = float(np.min(v)), float(np.max(v))
            return f"{lo:{fmt}}" if lo == hi else f"{lo:{fmt}}-{hi:{fmt}}"

        r = self.responses
        if r is None:
            lines.append(f"  filters: {self.profile}, FWHM {span(self.fwhm_nm)} nm")
        else:
            on = r.wavelength_nm[r.system >= 0.5 * r.system.max()]
            lines.append(f"  responses: measured, {r.wavelength_nm[0]:g}-"
                         f"{r.wavelength_nm[-1]:g} nm ({r.wavelength_nm.size} samples); in "
                         f"front of every band: {r.system_name}, above half its maximum "
                         f"{on[0]:g}-{on[-1]:g} nm")
        lines.append("  band  file  tile     centre nm  FWHM nm"
                     + ("  peaks" if r is not None else ""))
        for b in range(self.n_bands):
            tile = f"({self.band_offset[b][0]},{self.band_offset[b][1]})" if self.band_offset \
                else "-"
            peaks = f"  {len(r.peaks[b])}" if r is not None else ""
            number = self.vendor_band[b] if self.vendor_band is not None else b
            lines.append(f"  {b:4d}  {number:4d}  {tile:7s}  {self.cwl_nm[b]:9.2f}  "
                         f"{self.fwhm_nm[b]:7.2f}{peaks}")
        for m in self.matrices:
            fw = ("FWHM not given" if not np.all(np.isfinite(m.fwhm_nm))
                  else f"FWHM {span(m.fwhm_nm)} nm")
            lines.append(f"  correction matrix {m.name!r} ({m.kind}): {m.n_virtual} virtual "
                         f"bands {np.min(m.wavelength_nm):.1f}-{np.max(m.wavelength_nm):.1f} nm, "
                         f"{fw}")
        if r is not None and not self.matrices:
            lines.append("  no correction matrix: use --virtual-bands fitted or angle-aware")
        return "\n".join(lines)

    def to_dict(self, folder=None) -> dict:
        """The ``[sensor]`` table: every key, or, for a sensor read from a vendor file, the
        file (relative to ``folder`` when given) and the keys that add to or override it."""
        if self.vendor_file is not None:
            path = self.vendor_file
            if folder is not None:
                # from the folders as the system resolves them (symlinks followed): a TOML
                # written into a linked folder is read from its real place, where '..' leads
                path = os.path.relpath(os.path.realpath(path), os.path.realpath(folder))
            d = {"vendor_file": Path(path).as_posix(), "name": self.name}
            if self.n_eff is not None:
                d["n_eff"] = (self.n_eff[0] if len(set(self.n_eff)) == 1
                              else self.in_file_order(self.n_eff))
            if self.pixel_pitch_um is not None:
                d["pixel_pitch_um"] = self.pixel_pitch_um
            if self.size_px is not None:
                d["size_px"] = list(self.size_px)
            if self.bit_depth is not None:
                d["bit_depth"] = self.bit_depth
            return d
        if self.responses is not None or self.matrices:
            raise ValueError(f"the sensor {shown(self.name)} has measured responses or correction "
                             "matrices but no vendor file to name; a sensor TOML holds them only "
                             "as the vendor's file it names (vendor_file)")
        d = {"name": self.name, "layout": self.layout, "pixel_pitch_um": self.pixel_pitch_um,
             "cwl_nm": self.in_file_order(self.cwl_nm),
             "fwhm_nm": self.in_file_order(self.fwhm_nm)}
        if self.pixel_pitch_um is None:
            del d["pixel_pitch_um"]
        if self.n_eff is not None:
            d["n_eff"] = self.in_file_order(self.n_eff)
        if self.layout == "mosaic":
            d["mosaic_shape"] = list(self.mosaic_shape)
            d["band_offset"] = [list(o) for o in self.in_file_order(self.band_offset)]
            if self.filter_area_px is not None:
                d["filter_area_px"] = list(self.filter_area_px)
        if self.size_px is not None:
            d["size_px"] = list(self.size_px)
        if self.profile != "gaussian":
            d["profile"] = self.profile
        if self.bit_depth is not None:
            d["bit_depth"] = self.bit_depth
        return d

    @classmethod
    def from_dict(cls, table: dict, *, calibration: dict | None = None) -> Sensor:
        unknown = set(table) - _KEYS
        if unknown:
            raise ValueError(f"unknown key(s) in [sensor]: {shown(sorted(unknown), 120)}; "
                             f"valid keys are {sorted(_KEYS)} (or vendor_file, naming a vendor "
                             "calibration .xml)")
        missing = {"name", "layout", "pixel_pitch_um", "cwl_nm", "fwhm_nm", "n_eff"} - set(table)
        if missing:
            raise ValueError(f"[sensor] is missing required key(s) {sorted(missing)}")
        for key in ("name", "layout", "profile"):
            if key in table and not isinstance(table[key], str):
                raise ValueError(f"[sensor] {key} must be text (in quotes), got "
                                 f"{shown(table[key])}")
        return cls(**table, calibration=calibration or {})

    @classmethod
    def from_vendor(cls, path, *, name=None, n_eff=None, pixel_pitch_um=None, size_px=None,
                    calibration=None, bit_depth=None) -> Sensor:
        """A mosaic sensor from the vendor's calibration ``.xml`` (either variant).

        The bands are the file's, in its index order (band ``i`` at tile row ``i // width``,
        column ``i % width``); each band's ``cwl_nm`` and ``fwhm_nm`` are its main peak's
        (:meth:`~snapcorr.cube.responses.FilterResponses.main_peaks`), its profile the
        measured response times the system's; the tile grid starts at the filter area's
        corner.

        Parameters
        ----------
        path : str or Path
            The vendor calibration file.
        name : str, optional
            Default: the file's stem.
        n_eff : float or sequence of float, optional
            The filters' effective index, which the file does not give.
        pixel_pitch_um : float, optional
            Replaces the file's pitch (needed where the file gives 0).
        size_px : (int, int), optional
            Replaces the file's sensor size.
        calibration : dict, optional
            Provenance, as for the TOML's ``[calibration]`` table.
        bit_depth : int, optional
            Replaces the file's bit depth (a camera mode of another depth).
        """
        from .vendor_xml import read_vendor_file

        cal = read_vendor_file(path)
        peaks = cal.responses.main_peaks()
        try:
            return cls._of_vendor(cal, path, peaks, name, n_eff, pixel_pitch_um, size_px,
                                  calibration, bit_depth)
        except ValueError as err:  # a check of the sensor's values: say which file gave them
            if str(err).startswith(Path(path).name):
                raise
            raise ValueError(f"{Path(path).name}: {err} (the bands' main peaks, read from their "
                             "measured responses)" if str(err).startswith("cwl_nm") else
                             f"{Path(path).name}: {err}") from None

    @classmethod
    def _of_vendor(cls, cal, path, peaks, name, n_eff, pixel_pitch_um, size_px, calibration,
                   bit_depth):
        ph, pw = cal.mosaic_shape
        return cls(
            name=name if name is not None else Path(path).stem, layout="mosaic",
            pixel_pitch_um=pixel_pitch_um if pixel_pitch_um is not None else cal.pixel_pitch_um,
            cwl_nm=[p.wavelength_nm for p in peaks], fwhm_nm=[p.fwhm_nm for p in peaks],
            n_eff=n_eff, mosaic_shape=(ph, pw),
            band_offset=[(i // pw, i % pw) for i in range(ph * pw)],
            size_px=size_px if size_px is not None else cal.size_px,
            calibration=calibration or {}, responses=cal.responses,
            filter_area_px=cal.filter_area_px, matrices=cal.matrices,
            vendor_file=str(Path(path).resolve()),
            bit_depth=bit_depth if bit_depth is not None else cal.bit_depth)

    @classmethod
    def load(cls, path) -> Sensor:
        """Read a sensor description: a TOML with a ``[sensor]`` table, the vendor's
        calibration ``.xml``, or a TOML whose ``[sensor]`` names one (``vendor_file``,
        relative to the TOML) and adds or overrides :data:`VENDOR_OVERRIDES`; or a bundled
        description by name (``"snapscan_vnir"``).

        A value with the suffix ``.toml`` or ``.xml``, or naming a file that exists, is read as
        a file; another is the name of a bundled sensor (:func:`snapcorr.data.sensor_path`).
        """
        path = profile_path("sensor", path)
        if path.suffix.lower() == ".xml":
            return cls.from_vendor(path)
        doc = read_toml(path, "sensor", "sensor description")
        table = dict(doc["sensor"])
        try:
            if "vendor_file" in table:
                return cls._from_vendor_table(path, table, doc.get("calibration"))
            shape = table.get("profile")
            if isinstance(shape, str) and shape not in (*PROFILE_NAMES, MEASURED):
                table["profile"] = str(path.parent / shape)  # relative to the sensor file
            return cls.from_dict(table, calibration=doc.get("calibration"))
        except (TypeError, ValueError, OverflowError) as err:
            raise ValueError(f"{path}: {err}") from None

    @classmethod
    def _from_vendor_table(cls, path, table, calibration):
        vendor = table.pop("vendor_file")
        if not isinstance(vendor, str) or not vendor.strip():
            raise ValueError("vendor_file must be the path of the vendor's calibration .xml")
        unknown = sorted(set(table) - set(VENDOR_OVERRIDES))
        if unknown:
            raise ValueError(f"a sensor naming vendor_file takes its other keys from that file; "
                             f"it may add or override only {list(VENDOR_OVERRIDES)}, got "
                             f"{shown(unknown, 120)}")
        target = path.parent / vendor
        try:
            check_input(target, what="sensor calibration file")
        except ValueError as err:  # a loop of links, a folder, a device: said with the TOML
            raise ValueError(f"its vendor_file {shown(vendor)}: {err}") from None
        except FileNotFoundError:
            raise FileNotFoundError(
                f"{path}: its vendor_file {shown(vendor)} is not found (looked for "
                f"{os.path.abspath(target)}"
                + ("" if Path(vendor).is_absolute() else ", relative to the sensor file")
                + "): put the vendor's .xml there, or correct vendor_file") from None
        return cls.from_vendor(target, calibration=calibration, **table)

    def save(self, path, *, overwrite=False) -> Path:
        """Write the description as TOML, atomically; never replaces a file unless asked.
        A sensor read from a vendor file is written as a TOML naming that file."""
        table = self.to_dict(folder=Path(path).parent)
        if self.vendor_file is None:
            doc = {"sensor": table}
            if self.calibration:
                doc["calibration"] = self.calibration
            return write_toml(path, doc, overwrite=overwrite)
        import tomli_w

        # the index the vendor's file does not give: a line to fill in, and how to measure it
        how = (f"# n_eff: the filters' effective index, which {Path(self.vendor_file).name} "
               "does not give;\n# `snapcorr pupil --fit-n-eff` (target cubes at two f-numbers "
               "far apart) measures it,\n# and its --sensor-out writes this file with it\n")
        body = tomli_w.dumps({"sensor": table}) + how
        if self.n_eff is None:
            body += "# n_eff = 1.7\n"
        parts = [body]
        if self.calibration:
            parts.append(tomli_w.dumps({"calibration": self.calibration}))
        return write_toml(path, parts, overwrite=overwrite)


def _read_shape(path):
    """``(offset_nm, transmission)`` of a measured filter shape, checked (cached per file)."""
    off, t = _read_shape_cached(str(Path(path).resolve()))
    return off.copy(), t.copy()


@functools.cache
def _read_shape_cached(path):
    p = Path(path)
    if p.suffix.lower() not in (".csv", ".txt", ".tsv", ".dat"):
        raise ValueError(f"profile must be one of {', '.join(PROFILE_NAMES)} or a two-column "
                         f"file (.csv, .txt), got {shown(p.name)}")
    from ..files.reading import check_input, check_table_size

    try:
        check_input(p, what="filter profile")
    except FileNotFoundError:
        raise FileNotFoundError(f"filter profile file not found: {p}") from None
    check_table_size(p, "filter profile")
    rows = []
    for k, line in enumerate(p.read_text(errors="replace").splitlines()):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.replace(",", " ").replace(";", " ").split()
        try:
            rows.append([float(v) for v in parts])
        except ValueError:
            if rows:  # a header is allowed before the numbers only
                raise ValueError(f"{p}, line {k + 1}: not numbers: {shown(line)}") from None
    if not rows or any(len(r) != 2 for r in rows) or len(rows) < 3:
        raise ValueError(f"{p}: need two columns (offset from the band's centre, nm; "
                         "transmission) and at least 3 rows")
    off, t = np.array(rows).T
    if not (np.all(np.isfinite(off)) and np.all(np.isfinite(t)) and np.all(np.diff(off) > 0)
            and np.all(t >= 0) and t.max() > 0):
        raise ValueError(f"{p}: offsets must increase, transmissions be finite, >= 0 and not "
                         "all zero")
    if not (off[0] < 0 < off[-1]):
        raise ValueError(f"{p}: the offsets ({off[0]:g} to {off[-1]:g} nm) must be relative "
                         "to the band's centre, spanning 0")
    return off, t
