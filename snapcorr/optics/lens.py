"""The lens as the filters see it: exit pupil, vignetting circle and working f-number.

References
----------
.. [1] T. Goossens et al., Appl. Opt. 58, 1789 (2019): variable-cone vignetting model
   (Sec. 2.4, Fig. 3), working f-number Eq. (27), exit-pupil radius Eq. (28),
   onset of vignetting Eq. (24)-(25) and (46).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .._io import read_toml, write_toml

__all__ = ["Lens"]


def _finite(name, value, *, positive=False):
    if isinstance(value, (bool, np.bool_)):  # TOML's `true` is not 1 mm
        raise TypeError(f"{name} must be a number, got a boolean ({value!r})")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or (positive and v <= 0):
        need = "a finite number > 0" if positive else "a finite number"
        raise ValueError(f"{name} must be {need}, got {value!r}")
    return v


@dataclass(frozen=True)
class Lens:
    """An objective lens described by its exit pupil and (optionally) one vignetting circle.

    Parameters
    ----------
    name : str
        Human-readable name.
    exit_pupil_mm : float
        Distance x from the sensor to the exit-pupil plane, mm.
    vignetting_radius_mm, vignetting_distance_mm : float, optional
        Radius P and distance h of the projected vignetting circle (variable-cone model,
        Goossens 2019 Fig. 3). Give both, or neither for a lens without optical vignetting.
        ``h`` may be any finite number; ``h >= x`` and ``h < x`` are the two regimes of Eq. (18).
    magnification : float
        Linear magnification m (0: focused at infinity).
    pupil_magnification : float
        Pupil magnification m_P (> 0).
    calibration : dict, optional
        Free-form record of how the profile was obtained (the ``[calibration]`` table of a lens
        file). Kept as-is through load/save; not used in computations.

    Examples
    --------
    >>> lens = Lens("Edmund Optics 16 mm", 21.0, 7.4236, 16.991, 0.06, 1.3)
    >>> round(float(lens.exit_pupil_radius_mm(1.4)), 4)  # the paper's Eq. 30 prints 7.1715
    7.1691
    """

    name: str
    exit_pupil_mm: float
    vignetting_radius_mm: float | None = None
    vignetting_distance_mm: float | None = None
    magnification: float = 0.0
    pupil_magnification: float = 1.0
    calibration: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "name", str(self.name))
        set_(self, "exit_pupil_mm", _finite("exit_pupil_mm", self.exit_pupil_mm, positive=True))
        P, h = self.vignetting_radius_mm, self.vignetting_distance_mm
        if (P is None) != (h is None):
            raise ValueError(
                "give both vignetting_radius_mm (P) and vignetting_distance_mm (h), or neither "
                f"for a lens without optical vignetting (got P={P!r}, h={h!r})."
            )
        if P is not None:
            set_(self, "vignetting_radius_mm", _finite("vignetting_radius_mm", P, positive=True))
            set_(self, "vignetting_distance_mm", _finite("vignetting_distance_mm", h))
        m = _finite("magnification", self.magnification)
        if m < 0:
            raise ValueError(f"magnification must be >= 0 (its magnitude), got {m}")
        set_(self, "magnification", m)
        set_(
            self,
            "pupil_magnification",
            _finite("pupil_magnification", self.pupil_magnification, positive=True),
        )
        set_(self, "calibration", dict(self.calibration or {}))

    # -- optics ---------------------------------------------------------------------------
    @property
    def has_vignetting(self) -> bool:
        """True if the lens has a vignetting circle (P and h)."""
        return self.vignetting_radius_mm is not None

    def working_f_number(self, f_number):
        """Working f-number, Eq. (27): ``(1 + m / m_P) * f_number``."""
        f = np.asarray(f_number, dtype=float)
        if not np.all(np.isfinite(f)) or np.any(f <= 0):
            raise ValueError(f"f_number must be finite and > 0, got {f_number!r}")
        return (1.0 + self.magnification / self.pupil_magnification) * f

    def exit_pupil_radius_mm(self, f_number):
        """Exit-pupil radius R, Eq. (28): ``x / (2 f_W)``."""
        return self.exit_pupil_mm / (2.0 * self.working_f_number(f_number))

    def cone_angle_deg(self, f_number):
        """Half-cone angle of the image-side light cone, ``arctan(R / x)``, degrees."""
        return np.rad2deg(np.arctan(1.0 / (2.0 * self.working_f_number(f_number))))

    def onset_cra_deg(self, f_number):
        """Chief-ray angle where optical vignetting starts, Eq. (24)-(25) and (46).

        ``arctan((P - R) / h)``; 0 where ``P < R`` (vignetted on axis); ``inf`` for a lens
        without vignetting or where the circle never moves (``h == 0`` with ``P >= R``).
        """
        R = self.exit_pupil_radius_mm(f_number)
        if not self.has_vignetting:
            return np.full(np.shape(R), np.inf)[()]
        P, h = self.vignetting_radius_mm, self.vignetting_distance_mm
        with np.errstate(divide="ignore", over="ignore"):
            on = np.where(P < R, 0.0, np.rad2deg(np.arctan((P - R) / abs(h))) if h else np.inf)
        return on[()]

    def is_vignetted(self, f_number, cra_deg):
        """True where the vignetting circle cuts the pupil: ``P < R`` or CRA past the onset."""
        if not self.has_vignetting:
            return np.zeros(np.broadcast_shapes(np.shape(f_number), np.shape(cra_deg)), bool)
        R = self.exit_pupil_radius_mm(f_number)
        cra = np.abs(np.asarray(cra_deg, float))
        return (R > self.vignetting_radius_mm) | (cra > self.onset_cra_deg(f_number))

    def relative_illumination(self, f_number, cra_deg):
        """Fraction of the exit pupil left by the vignetting circle (optical vignetting only).

        ``A / (pi R^2)`` with ``A`` the vignetted-pupil area, Eq. (33)-(35); 1 for a lens without
        vignetting. Natural (cos^4) and pixel vignetting are not included.

        Examples
        --------
        >>> lens = Lens("Edmund Optics 16 mm", 21.0, 7.4236, 16.991, 0.06, 1.3)
        >>> lens.relative_illumination(1.4, [0.0, 10.0]).round(3)
        array([1.   , 0.766])
        """
        from .pupil import overlap_area_mm2

        R = self.exit_pupil_radius_mm(f_number)
        t = np.tan(np.deg2rad(np.asarray(cra_deg, float)))
        if not np.all(np.isfinite(t)):
            raise ValueError("cra_deg must be finite and inside (-90, 90) degrees")
        if not self.has_vignetting:
            return np.ones(np.broadcast_shapes(np.shape(R), t.shape))[()]
        area = overlap_area_mm2([R, self.vignetting_radius_mm],
                                [0.0, self.vignetting_distance_mm * t])
        return area / (np.pi * R * R)

    def cutoff_cra_deg(self, f_number):
        """Chief-ray angle beyond which the pupil is fully cut off: ``arctan((P + R) / |h|)``."""
        R = self.exit_pupil_radius_mm(f_number)
        if not self.has_vignetting or self.vignetting_distance_mm == 0:
            return np.full(np.shape(R), np.inf)[()]
        P, h = self.vignetting_radius_mm, self.vignetting_distance_mm
        with np.errstate(over="ignore"):
            return np.rad2deg(np.arctan((P + R) / abs(h)))[()]

    # -- files ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The ``[lens]`` table as a dict (optional keys left out when unset)."""
        d = {"name": self.name, "exit_pupil_mm": self.exit_pupil_mm}
        if self.has_vignetting:
            d["vignetting_radius_mm"] = self.vignetting_radius_mm
            d["vignetting_distance_mm"] = self.vignetting_distance_mm
        d["magnification"] = self.magnification
        d["pupil_magnification"] = self.pupil_magnification
        return d

    @classmethod
    def from_dict(cls, table: dict, *, calibration: dict | None = None) -> Lens:
        """Build a lens from a ``[lens]`` table; unknown keys are an error."""
        known = {f for f in asdict(cls("x", 1.0)) if f != "calibration"}
        unknown = set(table) - known
        if unknown:
            raise ValueError(
                f"unknown key(s) in [lens]: {sorted(unknown)}; valid keys are {sorted(known)}"
            )
        missing = {"name", "exit_pupil_mm"} - set(table)
        if missing:
            raise ValueError(f"[lens] is missing required key(s) {sorted(missing)}")
        return cls(**table, calibration=calibration or {})

    @classmethod
    def load(cls, path) -> Lens:
        """Read a lens profile (TOML with a ``[lens]`` table and optional ``[calibration]``)."""
        doc = read_toml(path, "lens", "lens profile")
        try:
            return cls.from_dict(doc["lens"], calibration=doc.get("calibration"))
        except (TypeError, ValueError) as err:
            raise ValueError(f"{path}: {err}") from None

    def save(self, path, *, overwrite=False) -> Path:
        """Write the profile as TOML, atomically (temporary file, then rename).

        Refuses to replace an existing file unless ``overwrite=True``.
        """
        doc = {"lens": self.to_dict()}
        if self.calibration:
            doc["calibration"] = self.calibration
        return write_toml(path, doc, overwrite=overwrite)
