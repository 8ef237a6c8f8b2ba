"""Sensor descriptions: band layout, pixel pitch, filter centres and effective indices."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._io import read_toml, write_toml
from .._validation import check_integers, check_numbers, check_positive, check_wavelengths_nm

__all__ = ["LAYOUTS", "Sensor"]

#: ``snapscan``: every band of a cube pixel was exposed at the same sensor position (the sensor
#: moves behind the lens). ``mosaic``: a snapshot mosaic; each band sits at its own offset in a
#: repeating tile.
LAYOUTS = ("snapscan", "mosaic")
_KEYS = {"name", "layout", "pixel_pitch_um", "cwl_nm", "fwhm_nm", "n_eff", "mosaic_shape",
         "band_offset", "size_px", "profile"}
#: Filter shapes a sensor may name (``snapcorr.optics.PROFILES`` at normal incidence); any
#: other ``profile`` is a file of a measured shape.
PROFILE_NAMES = ("gaussian", "airy", "multi_lorentzian", "pi")


def _per_band(name, value, n_bands, *, minimum=None, strict=True):
    check_numbers(name, value)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers, got {value!r}") from None
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
    pixel_pitch_um : float
        Pixel pitch on the sensor, micrometres.
    cwl_nm : sequence of float
        Central wavelength of each band at normal, collimated incidence, nm.
    fwhm_nm : float or sequence of float
        Band widths, nm (a scalar applies to all bands).
    n_eff : float or sequence of float
        Effective refractive index of each band's filter (> 1).
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
        (``fwhm_corrected``).
    calibration : dict, optional
        Free-form record of where values came from (the ``[calibration]`` table of the file,
        e.g. an effective index fitted by ``snapcorr pupil``). Not compared.
    """

    name: str
    layout: str
    pixel_pitch_um: float
    cwl_nm: tuple
    fwhm_nm: tuple
    n_eff: tuple
    mosaic_shape: tuple | None = None
    band_offset: tuple | None = None
    size_px: tuple | None = None
    profile: str = "gaussian"
    calibration: dict = field(default_factory=dict, compare=False, repr=False, kw_only=True)

    def __post_init__(self):
        set_ = object.__setattr__
        if self.layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}, got {self.layout!r}")
        set_(self, "name", str(self.name))
        set_(self, "pixel_pitch_um", check_positive("pixel_pitch_um", self.pixel_pitch_um))
        check_numbers("cwl_nm", self.cwl_nm)
        cwl = np.atleast_1d(check_wavelengths_nm("cwl_nm", self.cwl_nm))
        if cwl.ndim != 1 or cwl.size == 0:
            raise ValueError("cwl_nm must list one central wavelength per band")
        n = cwl.size
        set_(self, "cwl_nm", _per_band("cwl_nm", cwl, n, minimum=0))
        set_(self, "fwhm_nm", _per_band("fwhm_nm", self.fwhm_nm, n, minimum=0))
        set_(self, "n_eff", _per_band("n_eff", self.n_eff, n, minimum=1))
        if self.layout == "mosaic":
            if self.mosaic_shape is None or self.band_offset is None:
                raise ValueError("a mosaic sensor needs mosaic_shape and band_offset")
            shape = tuple(int(v) for v in check_integers("mosaic_shape", self.mosaic_shape).ravel())
            if len(shape) != 2 or min(shape) < 1:
                raise ValueError(f"mosaic_shape must be [rows, cols] >= 1, got {shape}")
            off = check_integers("band_offset", self.band_offset)
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
            size = check_integers("size_px", self.size_px)
            if size.shape != (2,) or np.any(size < 1):
                raise ValueError(f"size_px must be [rows, cols], whole numbers >= 1, got "
                                 f"{self.size_px!r}")
            set_(self, "size_px", tuple(int(v) for v in size))
        set_(self, "profile", str(self.profile))
        if self.profile not in PROFILE_NAMES:
            _read_shape(self.profile)  # read and checked now: a bad file fails at load
        set_(self, "calibration", dict(self.calibration or {}))

    @property
    def field_radius_mm(self) -> float | None:
        """Distance from the image centre to its corner (mm), if ``size_px`` is known."""
        if self.size_px is None:
            return None
        rows, cols = self.size_px
        return 0.5 * float(np.hypot(rows, cols)) * self.pixel_pitch_mm

    @property
    def profile_shape(self):
        """The filters' shape as :func:`snapcorr.optics.bandwidth.band_profile` takes it: the
        name, or ``(offset_nm, transmission)`` read from the file."""
        if self.profile in PROFILE_NAMES:
            return self.profile
        return _read_shape(self.profile)

    @property
    def n_bands(self) -> int:
        return len(self.cwl_nm)

    @property
    def pixel_pitch_mm(self) -> float:
        return self.pixel_pitch_um * 1e-3

    def check_cube(self, cube, what="the cube", *, atol_nm=0.05):
        """Raise a ``ValueError`` unless ``cube`` has this sensor's bands: as many, and its
        ``wavelength`` coordinate (when it has one) within ``atol_nm`` of ``cwl_nm``.

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
            raise ValueError(f"{what} has {nb} bands, the sensor {self.name!r} {self.n_bands}; "
                             "use the sensor it was taken with")
        if "wavelength" in cube.coords:
            off = np.max(np.abs(np.asarray(cube["wavelength"].values, float)
                                - np.asarray(self.cwl_nm, float)))
            if not off <= atol_nm:
                raise ValueError(f"{what}'s wavelengths differ from the sensor {self.name!r}'s "
                                 f"(by up to {off:.3g} nm); use the matching sensor")

    def to_dict(self) -> dict:
        d = {"name": self.name, "layout": self.layout, "pixel_pitch_um": self.pixel_pitch_um,
             "cwl_nm": list(self.cwl_nm), "fwhm_nm": list(self.fwhm_nm),
             "n_eff": list(self.n_eff)}
        if self.layout == "mosaic":
            d["mosaic_shape"] = list(self.mosaic_shape)
            d["band_offset"] = [list(o) for o in self.band_offset]
        if self.size_px is not None:
            d["size_px"] = list(self.size_px)
        if self.profile != "gaussian":
            d["profile"] = self.profile
        return d

    @classmethod
    def from_dict(cls, table: dict, *, calibration: dict | None = None) -> Sensor:
        unknown = set(table) - _KEYS
        if unknown:
            raise ValueError(f"unknown key(s) in [sensor]: {sorted(unknown)}; valid keys are "
                             f"{sorted(_KEYS)}")
        missing = {"name", "layout", "pixel_pitch_um", "cwl_nm", "fwhm_nm", "n_eff"} - set(table)
        if missing:
            raise ValueError(f"[sensor] is missing required key(s) {sorted(missing)}")
        return cls(**table, calibration=calibration or {})

    @classmethod
    def load(cls, path) -> Sensor:
        """Read a sensor description (TOML with a ``[sensor]`` table)."""
        doc = read_toml(path, "sensor", "sensor description")
        table = dict(doc["sensor"])
        shape = table.get("profile")
        if isinstance(shape, str) and shape not in PROFILE_NAMES:
            table["profile"] = str(Path(path).parent / shape)  # relative to the sensor file
        try:
            return cls.from_dict(table, calibration=doc.get("calibration"))
        except (TypeError, ValueError) as err:
            raise ValueError(f"{path}: {err}") from None

    def save(self, path, *, overwrite=False) -> Path:
        """Write the description as TOML, atomically; never replaces a file unless asked."""
        doc = {"sensor": self.to_dict()}
        if self.calibration:
            doc["calibration"] = self.calibration
        return write_toml(path, doc, overwrite=overwrite)


def _read_shape(path):
    """``(offset_nm, transmission)`` of a measured filter shape, checked (cached per file)."""
    off, t = _read_shape_cached(str(Path(path).resolve()))
    return off.copy(), t.copy()


@functools.cache
def _read_shape_cached(path):
    p = Path(path)
    if p.suffix.lower() not in (".csv", ".txt", ".tsv", ".dat"):
        raise ValueError(f"profile must be one of {', '.join(PROFILE_NAMES)} or a two-column "
                         f"file (.csv, .txt), got {p.name!r}")
    if not p.is_file():
        raise FileNotFoundError(f"filter profile file not found: {p}")
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
                raise ValueError(f"{p}, line {k + 1}: not numbers: {line!r}") from None
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
