"""The lens as the filters see it: exit pupil, vignetting circles and working f-number.

References
----------
.. [1] T. Goossens et al., Appl. Opt. 58, 1789 (2019): variable-cone vignetting model
   (Sec. 2.4, Fig. 3), working f-number Eq. (27), exit-pupil radius Eq. (28),
   onset of vignetting Eq. (24)-(25) and (46).
"""

from __future__ import annotations

import functools
import itertools
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._bundled import profile_path
from .._validation import (
    F_NUMBER_MAX,
    LENGTH_MAX_MM,
    LENGTH_MIN_MM,
    MAX_VIGNETTING_CIRCLES,
    called_from_outside,
    check_disc_count,
    check_numbers,
    shown,
    warn_renamed,
)
from ..files.toml import read_toml, write_toml

__all__ = ["PUPILS", "PUPIL_RADIANCE_MODELS", "RAY_WEIGHTS", "Lens"]


def _spells_a_number(text):
    """Whether ``text`` reads as a number (a file's ``"21"``, not a lens's name)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def _finite(name, value, *, positive=False, at_most=None, unit=""):
    """``value`` as a float: finite (and, with ``positive``, at least :data:`LENGTH_MIN_MM`
    where ``at_most`` bounds a length; at most ``at_most`` in size)."""
    v = _finite_number(name, value, positive=positive)
    if at_most is not None and abs(v) > at_most:
        raise ValueError(f"{name} must be at most {at_most:g}{unit} in size (no lens's is "
                         f"larger: check the value and its unit), got {shown(value)}")
    if positive and at_most is not None and v < LENGTH_MIN_MM:
        raise ValueError(f"{name} must be at least {LENGTH_MIN_MM:g}{unit} (no lens's is "
                         f"smaller: check the value and its unit), got {shown(value)}")
    return v


def check_length_mm(name, value):
    """An exit-pupil distance or circle radius as a float: finite, from
    :data:`LENGTH_MIN_MM` to :data:`LENGTH_MAX_MM`."""
    return _finite(name, value, positive=True, at_most=LENGTH_MAX_MM, unit=" mm")


def check_distance_mm(name, value):
    """A vignetting circle's distance h as a float: finite, at most :data:`LENGTH_MAX_MM` in
    size, and 0 (a stop: a circle that does not move) or at least :data:`LENGTH_MIN_MM` in
    size. Nearer 0, a circle's onset ``arctan((P - R) / |h|)`` and its crossings with the
    other discs divide by next to nothing (1e-310 overflowed, and a fit's onsets were NaN);
    such a circle moves by less than a micron up to 45 deg, a stop, and the value is a typo
    or a unit slip."""
    v = _finite(name, value, at_most=LENGTH_MAX_MM, unit=" mm")
    if v != 0 and abs(v) < LENGTH_MIN_MM:
        raise ValueError(f"{name} must be 0 (a stop) or at least {LENGTH_MIN_MM:g} mm in size "
                         f"(nearer, it is a stop for every chief ray up to 45 deg: check the "
                         f"value and its unit), got {shown(value)}")
    return v


def _finite_number(name, value, *, positive=False):
    if isinstance(value, (bool, np.bool_)):  # TOML's `true` is not 1 mm
        raise TypeError(f"{name} must be a number, got a boolean ({shown(value)})")
    if isinstance(value, (str, bytes)):  # a TOML's "0.06" is text, as "21" is
        raise TypeError(f"{name} must be a number, got the text {shown(value)}")
    need = "a finite number > 0" if positive else "a finite number"
    try:
        v = float(value)
    except OverflowError:
        raise ValueError(f"{name} must be {need}, got {shown(value)}") from None
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, got {shown(value)}") from None
    if not math.isfinite(v) or (positive and v <= 0):
        raise ValueError(f"{name} must be {need}, got {shown(value)}")
    return v


#: Largest linear magnification m a lens profile may state: ten times life size. Past it the
#: lens is a microscope objective, whose cone the working f-number of Eq. (27) does not describe
#: (and a typo such as 1e300 is refused before any fit, not met as an optimiser's failure).
MAX_MAGNIFICATION = 10.0
#: Range of the pupil magnification m_P (exit over entrance pupil diameter) a profile may
#: state: real designs lie within about 0.3 (strong telephoto) to 4 (fish-eye retrofocus).
PUPIL_MAGNIFICATION_BOUNDS = (0.1, 10.0)


def check_magnification(value, name="magnification"):
    """m as a float: finite, >= 0 (its magnitude) and at most :data:`MAX_MAGNIFICATION`;
    ``name`` is the option or key the message names."""
    m = _finite(name, value)
    if not 0.0 <= m <= MAX_MAGNIFICATION:
        raise ValueError(f"{name} must be between 0 (focused at infinity) and "
                         f"{MAX_MAGNIFICATION:g} (its magnitude; past it the working f-number "
                         f"of Eq. 27 does not hold), got {shown(value)}")
    return m


def check_pupil_magnification(value, name="pupil_magnification"):
    """m_P as a float: finite and within :data:`PUPIL_MAGNIFICATION_BOUNDS`; ``name`` is the
    option or key the message names."""
    mp = _finite(name, value, positive=True)
    lo, hi = PUPIL_MAGNIFICATION_BOUNDS
    if not lo <= mp <= hi:
        raise ValueError(f"{name} (exit over entrance pupil diameter) must be between {lo:g} "
                         f"and {hi:g}, got {shown(value)}")
    return mp


def _check_placement(cal):
    """The ``[calibration]`` keys a correction reads to place the optical axis: centres as
    two finite numbers within :data:`~snapcorr._validation.PIXELS_MAX` pixels, the flats'
    origin on the sensor (``sensor_origin_rc``, a crop's first pixel) as two whole numbers
    from 0 to that, the pitch as a camera's, the image size as two whole numbers > 0; the
    bounds the command line's ``--center`` and ``--sensor-origin-px`` have."""
    from .._validation import PIXELS_MAX, check_integers, check_pair, check_pixel_pitch_um

    for key in ("center_rc", "center_px"):
        if key in cal:
            check_numbers(f"[calibration] {key}", cal[key])
            pair = check_pair(f"[calibration] {key}", _as_list(cal[key], key),
                              "two numbers (pixels)")
            if max(abs(v) for v in pair) > PIXELS_MAX:
                raise ValueError(f"[calibration] {key} lies {max(abs(v) for v in pair):.3g} "
                                 f"pixels out; no sensor is wider than {PIXELS_MAX:,} pixels, "
                                 f"got {shown(cal[key])}")
    if "center_rc" in cal and "center_px" in cal:  # one centre, twice: row first, x first
        (row, col), (cx, cy) = (float(v) for v in cal["center_rc"]), \
            (float(v) for v in cal["center_px"])
        if max(abs(row - cy), abs(col - cx)) > 1e-6 * max(1.0, abs(row), abs(col)):
            raise ValueError(
                f"[calibration] center_rc {shown(cal['center_rc'])} (row, column) and "
                f"center_px {shown(cal['center_px'])} (x first: column, row) disagree; keep "
                "one (center_rc), or give center_px as [column, row]")
    if cal.get("sensor_origin_rc") is not None:
        origin = cal["sensor_origin_rc"]
        check_numbers("[calibration] sensor_origin_rc", origin)
        o = check_pair("[calibration] sensor_origin_rc", _as_list(origin, "sensor_origin_rc"),
                       "a row and a column (whole pixels)")
        if min(o) < 0 or max(o) > PIXELS_MAX or any(v != round(v) for v in o):
            raise ValueError("[calibration] sensor_origin_rc (the flats' first pixel on the "
                             f"sensor) must be a row and a column, whole pixels from 0 to "
                             f"{PIXELS_MAX:,}, got {shown(origin)}")
    if "pixel_pitch_um" in cal:
        check_pixel_pitch_um("[calibration] pixel_pitch_um", cal["pixel_pitch_um"])
    sizes = {}
    for key, order in (("image_size_px", "width, height"), ("image_shape_px", "rows, columns")):
        if key in cal:
            v = check_integers(f"[calibration] {key}", _as_list(cal[key], key), PIXELS_MAX)
            if v.shape != (2,) or np.any(v <= 0):
                raise ValueError(f"[calibration] {key} must be two whole numbers > 0 "
                                 f"([{order}]), got {shown(cal[key])}")
            sizes[key] = list(v)
    if len(sizes) == 2 and sizes["image_shape_px"][::-1] != sizes["image_size_px"]:
        raise ValueError(
            f"[calibration] image_shape_px {shown(cal['image_shape_px'])} (rows, columns) "
            f"and image_size_px {shown(cal['image_size_px'])} (width, height) disagree; "
            "keep one, or give them as the same pixels")


def _as_list(value, key):
    if not isinstance(value, (list, tuple, np.ndarray)):
        raise ValueError(f"[calibration] {key} must be a list of two numbers, got "
                         f"{shown(value)}")
    return value


def _circles(vignetting):
    """``vignetting`` as a tuple of ``(P, h)`` float pairs, checked."""
    if vignetting is None:
        return ()
    if isinstance(vignetting, (str, bytes, dict)) or not hasattr(vignetting, "__iter__"):
        raise TypeError(f"vignetting must be a list of (P, h) pairs in mm, got {shown(vignetting)}")
    # at most one past the bound is read: an endless iterator is refused too
    items = list(itertools.islice(vignetting, MAX_VIGNETTING_CIRCLES + 1))
    if len(items) > MAX_VIGNETTING_CIRCLES:
        n = len(vignetting) if hasattr(vignetting, "__len__") else None
        check_disc_count("vignetting", n, what="circles", most=MAX_VIGNETTING_CIRCLES)
    if len(items) == 2 and all(isinstance(v, (int, float, np.number)) for v in items):
        raise TypeError(f"vignetting is a list of (P, h) pairs: write vignetting=[{tuple(items)}]"
                        " for one circle")
    out = []
    for i, c in enumerate(items):
        if isinstance(c, dict):
            unknown = set(c) - {"radius_mm", "distance_mm"}
            missing = {"radius_mm", "distance_mm"} - set(c)
            if unknown or missing:
                raise ValueError(f"vignetting circle {i + 1} needs exactly radius_mm and "
                                 f"distance_mm (got {shown(sorted(c), 80)})")
            c = (c["radius_mm"], c["distance_mm"])
        try:
            P, h = c
        except (TypeError, ValueError, OverflowError):
            raise TypeError(f"vignetting circle {i + 1} must be a (P, h) pair in mm, got "
                            f"{shown(c)}")\
                from None
        out.append((_finite(f"vignetting circle {i + 1} radius_mm (P)", P, positive=True,
                            at_most=LENGTH_MAX_MM, unit=" mm"),
                    check_distance_mm(f"vignetting circle {i + 1} distance_mm (h)", h)))
    return tuple(out)


#: No lens in air focuses a cone wider than a numerical aperture of 1: a working f-number of
#: 1 / (2 NA) = 0.5 at least.
MIN_WORKING_F_NUMBER = 0.5

#: How the light fills the exit pupil (:attr:`Lens.pupil_radiance`). ``"paper"``: Goossens
#: 2019 Eq. (28), a flat disc of radius ``x / (2 f_W)`` (marginal ray at ``tan(theta) = 1 /
#: (2 f_W)``), every ray weighted by its area in the pupil plane. ``"lambertian"``: an
#: aplanatic lens (the sine condition,
#: ``sin(theta) = NA = 1 / (2 f_W)``, radius ``x NA / sqrt(1 - NA^2)``) with a Lambertian
#: pupil, uniform in direction cosines: each ray weighted by ``cos^4(phi)`` per unit area of
#: the plane (Jacobian of direction cosines over the plane at ``x``). They differ on axis by
#: about 1.1 nm at f/1.4, 0.3 nm at f/2 and 0.02 nm at f/4 (1000 nm filters, n_eff 1.5).
#: ``"paper-lambertian"``: the paper's disc (radius ``x / (2 f_W)``) radiating as a
#: Lambertian surface, each ray weighted by ``cos^4(phi)`` per area: the radiometry of a flat
#: pupil of uniform radiance, whose flat fields fall off with the cos^4 of every ray, not of
#: the chief ray alone.
PUPIL_RADIANCE_MODELS = ("paper", "lambertian", "paper-lambertian")
#: How each radiance model weights a ray per unit area of the pupil plane: ``"area"``
#: (uniformly) or ``"cos4"`` (by ``cos^4(phi)``, a Lambertian pupil).
RAY_WEIGHTS = {"paper": "area", "lambertian": "cos4", "paper-lambertian": "cos4"}
#: The earlier name of :data:`PUPIL_RADIANCE_MODELS`.
PUPILS = PUPIL_RADIANCE_MODELS


@dataclass(frozen=True)
class Lens:
    """An objective lens as its filters see it: exit pupil and projected vignetting circles.

    Parameters
    ----------
    exit_pupil_mm : float
        Distance x from the sensor to the exit-pupil plane, mm.
    vignetting : sequence of (P, h), optional
        Radius P and distance h (mm) of each projected vignetting circle (variable-cone model,
        Goossens 2019 Fig. 3): circle ``i`` is centred at ``h_i tan(CRA)`` in the exit-pupil
        plane (Eq. 9). ``h`` may be any finite number: ``h > x`` and ``h < x`` are the two
        regimes of Eq. (18), ``h = x`` is pixel vignetting, ``h = 0`` a stop (a circle that does
        not move) and ``h < 0`` a circle moving against the chief ray. Empty: no optical
        vignetting. At most :data:`~snapcorr._validation.MAX_VIGNETTING_CIRCLES` (8) circles.
    magnification : float
        Linear magnification m (0: focused at infinity), its magnitude: 0 to
        :data:`MAX_MAGNIFICATION`.
    pupil_magnification : float
        Pupil magnification m_P, within :data:`PUPIL_MAGNIFICATION_BOUNDS`. A lens file whose
        ``[lens]`` table leaves out either gets the default, recorded as assumed (a
        ``[calibration.magnification]`` table): a calibration given the profile then judges
        it over a plausible range (:mod:`snapcorr.calibrate.lens.magnification`).
    name : str, optional
        Human-readable name.
    calibration : dict, optional
        Record of how the profile was obtained (the ``[calibration]`` table of a lens file),
        kept as-is through load/save. Only the keys that place the optical axis on another
        sensor are read (``center_rc``, ``center_px``, ``pixel_pitch_um``, ``image_size_px``:
        checked here); the rest is free-form.
    pupil_radiance : {"paper", "lambertian", "paper-lambertian"}
        How the light fills the exit pupil, the pupil's radiance model
        (:data:`PUPIL_RADIANCE_MODELS`); default the paper's. ``pupil`` is its earlier name
        (a keyword and an attribute, deprecated; the lens file's ``pupil`` key stays).

    Examples
    --------
    >>> lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
    >>> round(float(lens.exit_pupil_radius_mm(1.4)), 4)  # the paper's Eq. 30 prints 7.1715
    7.1691
    >>> rear = Lens(21.0, [(7.4236, 16.991), (9.0, 30.0)], 0.06, 1.3)
    >>> rear.circle_onsets_cra_deg(2.8).round(2)
    array([12.73, 10.23])
    """

    exit_pupil_mm: float
    vignetting: tuple = ()
    magnification: float = 0.0
    pupil_magnification: float = 1.0
    name: str = field(default="", kw_only=True)
    calibration: dict = field(default_factory=dict, compare=False, repr=False, kw_only=True)
    pupil_radiance: str = field(default="paper", kw_only=True)

    def __post_init__(self):
        set_ = object.__setattr__
        _check_pupil_radiance("pupil_radiance", self.pupil_radiance)
        if isinstance(self.exit_pupil_mm, str) and not _spells_a_number(self.exit_pupil_mm):
            raise TypeError(f"exit_pupil_mm must be a number, got {shown(self.exit_pupil_mm)} (the "
                            "name is a keyword argument: Lens(x, ..., name='...'))")
        set_(self, "name", str(self.name))
        set_(self, "exit_pupil_mm", _finite("exit_pupil_mm", self.exit_pupil_mm, positive=True,
                                            at_most=LENGTH_MAX_MM, unit=" mm"))
        set_(self, "vignetting", _circles(self.vignetting))
        set_(self, "magnification", check_magnification(self.magnification))
        set_(self, "pupil_magnification", check_pupil_magnification(self.pupil_magnification))
        set_(self, "calibration", dict(self.calibration or {}))
        _check_placement(self.calibration)

    # -- optics ---------------------------------------------------------------------------
    @property
    def ray_weight(self) -> str:
        """How the pupil weights a ray per unit area: ``"area"`` or ``"cos4"``
        (:data:`RAY_WEIGHTS`)."""
        return RAY_WEIGHTS[self.pupil_radiance]

    @property
    def has_vignetting(self) -> bool:
        """True if the lens has at least one vignetting circle."""
        return bool(self.vignetting)

    def working_f_number(self, f_number):
        """Working f-number, Eq. (27): ``(1 + m / m_P) * f_number``; at least
        :data:`MIN_WORKING_F_NUMBER` (a numerical aperture of 1 in air)."""
        f = np.asarray(f_number, dtype=float)
        if not np.all(np.isfinite(f)) or np.any(f <= 0):
            raise ValueError(f"f_number must be finite and > 0, got {shown(f_number)}")
        if np.any(f > F_NUMBER_MAX):
            raise ValueError(f"f_number must be at most {F_NUMBER_MAX:g} (a pinhole's is a "
                             f"few hundred), got {float(np.max(f)):g}")
        fw = (1.0 + self.magnification / self.pupil_magnification) * f
        if np.any(fw < MIN_WORKING_F_NUMBER):
            bad = float(np.min(f))
            raise ValueError(f"f/{bad:g} is below the physical limit: the working f-number "
                             f"(1 + m / m_P) f = {float(np.min(fw)):g} must be at least "
                             f"{MIN_WORKING_F_NUMBER:g} (a numerical aperture of 1 in air); "
                             "check the f-number")
        return fw

    def exit_pupil_radius_mm(self, f_number):
        """Exit-pupil radius R: ``x / (2 f_W)``, Eq. (28), for the paper's disc (``"paper"``,
        ``"paper-lambertian"``); ``x NA / sqrt(1 - NA^2)``, ``NA = 1 / (2 f_W)``, for the
        aplanatic Lambertian one (:data:`PUPIL_RADIANCE_MODELS`).
        """
        fw = self.working_f_number(f_number)
        if self.pupil_radiance != "lambertian":
            return self.exit_pupil_mm / (2.0 * fw)
        na = 1.0 / (2.0 * fw)
        if np.any(na >= 1.0):
            raise ValueError("a numerical aperture of 1 has no exit-pupil radius: the working "
                             "f-number must exceed 0.5 for the Lambertian pupil")
        return self.exit_pupil_mm * na / np.sqrt(1.0 - na * na)

    def cone_angle_deg(self, f_number):
        """Half-cone angle of the image-side light cone, ``arctan(R / x)``, degrees."""
        return np.rad2deg(np.arctan(self.exit_pupil_radius_mm(f_number) / self.exit_pupil_mm))

    def pupil_discs(self, f_number, cra_deg):
        """Radii and centres (mm, along the pixel's radial line) of the exit pupil and every
        vignetting circle, Eq. (8)-(9) and (28): ``[R, P_1, ...]`` and ``[0, h_1 tan(CRA), ...]``.
        """
        R = self.exit_pupil_radius_mm(f_number)
        t = np.tan(np.deg2rad(np.asarray(cra_deg, float)))
        if not np.all(np.isfinite(t)):
            raise ValueError("cra_deg must be finite and inside (-90, 90) degrees")
        radii = [R] + [P for P, _ in self.vignetting]
        centers = [np.zeros_like(t)] + [h * t for _, h in self.vignetting]
        return radii, centers

    def vignetting_args(self, tan_cra):
        """The circles as the ``P_mm, dv_mm`` arguments of the kernel functions
        (:mod:`~snapcorr.optics.goossens2019`) at ``tan(CRA)``: ``None, None`` without a circle,
        two arrays for one, two lists (one entry per circle) for several."""
        t = np.asarray(tan_cra, float)
        if not self.vignetting:
            return None, None
        if len(self.vignetting) == 1:
            P, h = self.vignetting[0]
            return P, h * t
        return [P for P, _ in self.vignetting], [h * t for _, h in self.vignetting]

    def describe_vignetting(self) -> str:
        """The circles in a few words: ``"P = 7.4236 mm, h = 16.991 mm"`` for one."""
        if not self.vignetting:
            return "no vignetting circle"
        if len(self.vignetting) == 1:
            P, h = self.vignetting[0]
            return f"P = {P:.6g} mm, h = {h:.6g} mm"
        return f"{len(self.vignetting)} circles (P, h) = " + ", ".join(
            f"({P:.6g}, {h:.6g})" for P, h in self.vignetting) + " mm"

    def circle_onsets_cra_deg(self, f_number):
        """Chief-ray angle where each circle starts to cut the pupil, Eq. (24)-(25) and (46).

        ``arctan((P_i - R) / |h_i|)``; 0 where ``P_i < R`` (cut on axis); ``inf`` where the circle
        never cuts (``h_i = 0`` with ``P_i >= R``). Shape ``(n_circles, *shape(f_number))``.
        """
        R = np.asarray(self.exit_pupil_radius_mm(f_number))
        out = np.empty((len(self.vignetting), *R.shape))
        for i, (P, h) in enumerate(self.vignetting):
            with np.errstate(divide="ignore", over="ignore"):
                on = np.rad2deg(np.arctan((P - R) / abs(h))) if h else np.full(R.shape, np.inf)
            out[i] = np.where(P < R, 0.0, on)
        return out

    def onset_cra_deg(self, f_number):
        """Chief-ray angle where optical vignetting starts: the first circle's onset
        (:meth:`circle_onsets_cra_deg`); ``inf`` for a lens without vignetting."""
        R = self.exit_pupil_radius_mm(f_number)
        if not self.has_vignetting:
            return np.full(np.shape(R), np.inf)[()]
        return np.min(self.circle_onsets_cra_deg(f_number), axis=0)[()]

    def is_vignetted(self, f_number, cra_deg):
        """True where a vignetting circle cuts the pupil: ``P_i < R`` or CRA past its onset."""
        cra = np.abs(np.asarray(cra_deg, float))
        shape = np.broadcast_shapes(np.shape(f_number), cra.shape)
        if not self.has_vignetting:
            return np.zeros(shape, bool)
        R = np.asarray(self.exit_pupil_radius_mm(f_number))
        # on axis a circle cuts only if it is smaller than the pupil: one of the same radius
        # (onset 0) leaves the whole pupil at CRA 0 and cuts from there on
        on_axis = np.any([P < R for P, _ in self.vignetting], axis=0)
        return np.broadcast_to(cra > self.onset_cra_deg(f_number), shape) | np.broadcast_to(
            on_axis, shape)

    def relative_illumination(self, f_number, cra_deg):
        """Fraction of the exit pupil left by the vignetting circles (optical vignetting only).

        ``A / (pi R^2)`` with ``A`` the area common to the pupil and every circle (Eq. 33-35
        for one circle, :func:`~snapcorr.optics.aperture.overlap_area_mm2` for any number); 1 for a
        lens without vignetting. Natural (cos^4) vignetting is not included.

        Examples
        --------
        >>> lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3)
        >>> lens.relative_illumination(1.4, [0.0, 10.0]).round(3)
        array([1.   , 0.766])
        """
        from . import discs
        from .aperture import overlap_area_mm2

        radii, centers = self.pupil_discs(f_number, cra_deg)
        R = radii[0]
        if not self.has_vignetting:
            return np.ones(np.broadcast_shapes(np.shape(R), centers[0].shape))[()]
        if len(self.vignetting) == 1:
            return (overlap_area_mm2(radii, centers) / (np.pi * R * R))[()]
        # Several circles: trapezoids under the chain of chords plus circular segments, all
        # positive, keep slivers near the cut-off to full relative precision.
        b = discs.boundary(radii, centers)
        rk, _, t_right, t_left = discs.arc_angles(b, radii, centers)
        area = np.where(b.hi > b.lo, 2.0 * discs.upper_area(b, rk, t_right, t_left), 0.0)
        return (area / (np.pi * R * R))[()]

    def cutoff_cra_deg(self, f_number):
        """Chief-ray angle beyond which no light passes: the first pair of discs (pupil and
        circles) to come apart, ``arctan((r_i + r_j) / |h_i - h_j|)``."""
        R = np.asarray(self.exit_pupil_radius_mm(f_number))
        discs = [(R, 0.0), *list(self.vignetting)]
        out = np.full(R.shape, np.inf)
        for i, (ri, hi) in enumerate(discs):
            for rj, hj in discs[i + 1:]:
                if hi != hj:
                    with np.errstate(over="ignore"):
                        out = np.minimum(out, np.rad2deg(np.arctan((ri + rj) / abs(hi - hj))))
        return out[()]

    # -- files ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The ``[lens]`` table as a dict: one ``[[lens.vignetting]]`` table per circle."""
        d = {"name": self.name, "exit_pupil_mm": self.exit_pupil_mm}
        if self.has_vignetting:
            d["vignetting"] = [{"radius_mm": P, "distance_mm": h} for P, h in self.vignetting]
        d["magnification"] = self.magnification
        d["pupil_magnification"] = self.pupil_magnification
        if self.pupil_radiance != "paper":  # profiles of the paper's pupil stay as they were
            d["pupil"] = self.pupil_radiance  # the file's key keeps its name
        return d

    @classmethod
    def from_dict(cls, table: dict, *, calibration: dict | None = None) -> Lens:
        """Build a lens from a ``[lens]`` table; unknown keys are an error.

        A single circle may also be given by the keys ``vignetting_radius_mm`` and
        ``vignetting_distance_mm`` (the form of earlier profiles). The key ``pupil`` (or
        ``pupil_radiance``) is :attr:`pupil_radiance`.
        """
        single = {"vignetting_radius_mm", "vignetting_distance_mm"}
        known = {"name", "exit_pupil_mm", "vignetting", "magnification", "pupil_magnification",
                 "pupil", "pupil_radiance"}
        unknown = set(table) - known - single
        if unknown:
            raise ValueError(f"unknown key(s) in [lens]: {shown(sorted(unknown), 120)}; "
                             f"valid keys are {sorted(known)} (or {sorted(single)} for one circle)")
        if "exit_pupil_mm" not in table:
            raise ValueError("[lens] is missing required key(s) ['exit_pupil_mm']")
        for key in ("name", "pupil", "pupil_radiance"):
            if key in table and not isinstance(table[key], str):
                raise ValueError(f"[lens] {key} must be text (in quotes), got "
                                 f"{shown(table[key])}")
        args = {k: v for k, v in table.items() if k not in single}
        if "pupil" in args and "pupil_radiance" in args:
            raise ValueError("give the pupil's radiance model once: [lens] pupil, or its other "
                             "name pupil_radiance")
        given = single & set(table)
        if given:
            if "vignetting" in table:
                raise ValueError("give the vignetting circles either as [[lens.vignetting]] "
                                 f"tables or as {sorted(single)}, not both")
            if given != single:
                raise ValueError(f"give both {sorted(single)} for one circle, or neither "
                                 f"(got only {sorted(given)})")
            args["vignetting"] = [(
                _finite("vignetting_radius_mm", table["vignetting_radius_mm"], positive=True),
                check_distance_mm("vignetting_distance_mm", table["vignetting_distance_mm"]))]
        if "vignetting" in args and not isinstance(args["vignetting"], list):
            raise ValueError("[lens] vignetting must be [[lens.vignetting]] tables with "
                             "radius_mm and distance_mm")
        return cls(**args, calibration=_unstated_magnifications(table, calibration or {}))

    @classmethod
    def load(cls, path) -> Lens:
        """Read a lens profile (TOML with a ``[lens]`` table and optional ``[calibration]``),
        from a file or a bundled one by name (``"edmund_optics_16mm"``).

        A value with the suffix ``.toml``, or naming a file that exists, is read as a file;
        another is the name of a bundled profile (:func:`snapcorr.data.lens_path`).
        """
        path = profile_path("lens", path)
        doc = read_toml(path, "lens", "lens profile")
        try:
            return cls.from_dict(doc["lens"], calibration=doc.get("calibration"))
        except (TypeError, ValueError, OverflowError) as err:
            raise ValueError(f"{path}: {err}") from None

    def save(self, path, *, overwrite=False) -> Path:
        """Write the profile as TOML, atomically (temporary file, then rename).

        Each circle is a ``[[lens.vignetting]]`` table. Refuses to replace an existing file
        unless ``overwrite=True``.
        """
        table = self.to_dict()
        circles = table.pop("vignetting", [])
        parts = [{"lens": table}]
        parts += [f"[[lens.vignetting]]\nradius_mm = {c['radius_mm']!r}\n"
                  f"distance_mm = {c['distance_mm']!r}\n" for c in circles]
        if self.calibration:
            parts.append({"calibration": self.calibration})
        return write_toml(path, parts, overwrite=overwrite)


def _unstated_magnifications(table, calibration):
    """``calibration`` with the record that m or m_P was not stated by the ``[lens]``
    ``table`` (the defaults 0 and 1 are then assumptions, not the lens's): the
    ``[calibration.magnification]`` table a calibration that assumed them writes
    (``assumed = true``; ``given`` says which was stated), unless one is there already."""
    stated = [k for k in ("magnification", "pupil_magnification") if k in table]
    if len(stated) == 2 or "magnification" in calibration:
        return calibration
    given = {(): "neither", ("magnification",): "m only",
             ("pupil_magnification",): "m_P only"}[tuple(stated)]
    m = table.get("magnification")
    if given == "m only" and isinstance(m, (int, float)) and not isinstance(m, bool) and m == 0:
        return calibration  # m = 0 alone is exact: f_W = f whatever m_P
    return {**calibration, "magnification": {
        "assumed": True, "given": given,
        "rule": "the lens profile states no " + " and no ".join(
            k for k in ("magnification", "pupil_magnification") if k not in stated)
        + ": the defaults (m = 0, m_P = 1) are assumed, not the lens's"}}


def _check_pupil_radiance(name, value):
    if not isinstance(value, str) or value not in PUPIL_RADIANCE_MODELS:
        raise ValueError(f"{name} must be one of {', '.join(PUPIL_RADIANCE_MODELS)}, got "
                         f"{shown(value)}")


def _pupil(self):
    """The earlier name of :attr:`Lens.pupil_radiance` (deprecated)."""
    if called_from_outside(2):
        warn_renamed("Lens.pupil", "Lens.pupil_radiance")
    return self.pupil_radiance


Lens.pupil = property(_pupil)


def _accepts_pupil(init):
    """Let ``Lens(...)`` take ``pupil=``, the earlier name of ``pupil_radiance=``. Given, it
    sets the radiance model, also through ``dataclasses.replace(lens, pupil=...)`` (which
    passes the lens's ``pupil_radiance`` too)."""

    @functools.wraps(init)
    def __init__(self, *args, pupil=None, **kwargs):
        if pupil is not None:
            outside = _outside_past_dataclasses(2)
            if outside and "pupil_radiance" in kwargs and _called_directly(2):
                raise TypeError("Lens: give the pupil's radiance model once, as "
                                "pupil_radiance=; pupil is its earlier name")
            if outside:
                warn_renamed("Lens(pupil=...)", "Lens(pupil_radiance=...)")
            _check_pupil_radiance("pupil", pupil)
            kwargs["pupil_radiance"] = pupil
        init(self, *args, **kwargs)

    return __init__


Lens.__init__ = _accepts_pupil(Lens.__init__)


def _called_directly(depth):
    """Whether the code ``depth`` frames up is not :mod:`dataclasses`."""
    return sys._getframe(depth).f_globals.get("__name__") != "dataclasses"


def _outside_past_dataclasses(depth):
    """Whether the code ``depth`` frames up, past :mod:`dataclasses` (``replace``), is outside
    snapcorr."""
    frame = sys._getframe(depth)
    while frame is not None and frame.f_globals.get("__name__") == "dataclasses":
        frame = frame.f_back
    name = frame.f_globals.get("__name__", "") if frame is not None else ""
    return not (name == "snapcorr" or name.startswith("snapcorr."))
