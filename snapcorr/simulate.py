"""Simulated flat fields: what a camera behind a lens records from a uniform or lamp-plaque source.

A pixel at distance ``d`` from the optical centre has the chief-ray angle
``tan(CRA) = d / x`` (Goossens et al. 2019, Eq. 8). The light it collects is set by

* optical vignetting: the part of the exit pupil (radius ``R``, Eq. 28) inside the projected
  vignetting circle (radius ``P``, centre ``h tan(CRA)``), Eq. (33)-(35) of [1]_;
* pixel vignetting: the pixel accepts light only within a cone of half-angle ``a`` about its
  normal, which on the pupil plane is the disc of radius ``x tan(a)`` centred on the pixel's foot
  ``x tan(CRA)`` -- a vignetting circle with ``h = x`` ([1]_ Sec. 2.3, [3]_);
* natural vignetting, ``cos^4(CRA)`` ([1]_ Sec. 2.3, [4]_);
* the source: an integrating sphere is uniform; a lamp and a diffuse plaque are not
  (:class:`LampPlaque`, after [2]_).

The expected signal is ``signal_electrons * V``; the recorded frame adds Poisson shot noise and
Gaussian read noise, and converts to digital numbers with a gain and a dark offset ([5]_).

References
----------
.. [1] T. Goossens, B. Geelen, A. Lambrechts, C. Van Hoof, "Vignetted-aperture correction for
   spectral cameras with integrated thin-film Fabry-Perot filters", Appl. Opt. 58, 1789-1799
   (2019), Sec. 2.3-2.4, Eq. (8), (27)-(28), (33)-(35).
.. [2] L. Hanssen, E. Shirley, H. Patrick, T. Germer, D. Allen, B. C. Johnson, H. Yoon,
   "Analysis of systematic effects in 0/45 lamp-plaque sensor calibration", CALCON 2017,
   Logan, UT (2017).
.. [3] P. B. Catrysse, B. A. Wandell, "Optical efficiency of image sensor pixels", J. Opt. Soc.
   Am. A 19, 1610-1620 (2002).
.. [4] I. C. Gardner, "Validity of the cosine-fourth-power law of illumination", J. Res. Natl.
   Bur. Stand. 39, 213-219 (1947).
.. [5] J. R. Janesick, Photon Transfer (SPIE Press, 2007).

Examples
--------
>>> from snapcorr import Lens
>>> lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
>>> expected = flat_frame((1088, 2048), 5.5, 1.4, lens, noise=False)
>>> round(float(expected[543, 1023])), round(float(expected[0, 0]))  # centre, corner
(10000, 4857)
>>> frame = flat_frame((1088, 2048), 5.5, 1.4, lens, rng=0, dtype=np.uint16)
>>> frame.dtype, bool(abs(frame[512:576, 992:1056].std() / 1e4 - 0.01) < 0.001)  # 1 % noise
(dtype('uint16'), True)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ._coords import accepts_center_rc
from ._validation import validate_method
from .optics.aperture import relative_irradiance
from .optics.chief_ray import pixel_tangents

__all__ = [
    "ILLUMINATION_METHODS",
    "METHODS",
    "Detector",
    "LampPlaque",
    "flat_frame",
    "mosaic_reflectance",
    "relative_illumination_map",
]

#: How :func:`relative_illumination_map` computes the map: ``"radial"`` on a grid of
#: ``tan(CRA)`` interpolated per pixel, ``"exact"`` every pixel's disc overlap.
ILLUMINATION_METHODS = ("radial", "exact")
#: The earlier name of :data:`ILLUMINATION_METHODS`.
METHODS = ILLUMINATION_METHODS

# Adaptive sampling of V over tan(CRA): a sub-interval is accepted when linear interpolation
# misses V at its quarter points by at most this much (10x below the promised 1e-6).
_INTERP_TOL = 1e-7
_INITIAL_INTERVALS = 256
_MAX_LEVELS = 40
_CHUNK_PIXELS = 1 << 18  # per-pixel work is done in row blocks of about this many pixels

# Hanssen et al. 2017, "E(x, y, z) = ?" slide: offsets of the FEL lamp's radiometric centre.
FEL_CALIBRATION_DISTANCE_CM = 50.0  # d_cal: FASCAL-2 irradiance calibration, on axis
_COIL_OFFSET_CM = 0.3175  # r = [x^2 + (z + 0.3175 cm)^2]^(1/2)
_RADIOMETRIC_OFFSET_CM = 0.1  # d_eff^2 = (r - 0.1 cm)^2 + y^2
_CALIBRATION_OFFSET_CM = 0.2175  # (d_cal + 0.2175 cm): d_eff on axis, 0.3175 - 0.1
_BRDF_REFERENCE_SCATTER_DEG = 45.0  # the plaque's BRDF is calibrated at 0/45
_BRDF_KEYS = (*((mu, nu) for mu in range(3) for nu in range(3) if mu or nu), "t")


# -- input checks -------------------------------------------------------------------------------
def _number(name, value, *, positive=False, nonnegative=False):
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise TypeError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if positive and v <= 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    if nonnegative and v < 0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return v


def _row_blocks(ny, nx):
    step = max(1, _CHUNK_PIXELS // nx)
    return [(r0, min(r0 + step, ny)) for r0 in range(0, ny, step)]


# -- chief-ray angle ----------------------------------------------------------------------------
def _discs(lens, f_number, pixel_acceptance_deg):
    """Radii (mm) and centre slopes (centre = slope * tan(CRA)) of the discs a pixel looks
    through: the exit pupil, the vignetting circles and the pixel's acceptance circle."""
    R = float(lens.exit_pupil_radius_mm(f_number))
    radii, slopes = [R], [0.0]
    for P, h in lens.vignetting:
        radii.append(float(P))
        slopes.append(float(h))
    if pixel_acceptance_deg is not None:
        x = float(lens.exit_pupil_mm)
        radii.append(x * math.tan(math.radians(pixel_acceptance_deg)))
        slopes.append(x)  # the acceptance cone is centred on the pixel's foot, h = x
    return R, radii, slopes


def _exact_profile(t, R, radii, slopes, natural, pupil=(1.0, "area")):
    """V at ``tan(CRA) = t``: the discs' common area over ``pi R^2`` times cos^4(CRA), or
    for a Lambertian pupil (``pupil = (x, "cos4")``) every ray's cos^4
    (:func:`~snapcorr.optics.aperture.relative_irradiance`)."""
    t = np.asarray(t, float)
    x, weight = pupil
    v = relative_irradiance(radii, [k * t for k in slopes], x * t, x, weight=weight,
                            natural=natural)
    return np.broadcast_to(v, t.shape)


def _tangencies(radii, slopes):
    """tan(CRA) where two discs touch (outside or inside): where the area may have a kink."""
    out = []
    for i in range(len(radii)):
        for j in range(i + 1, len(radii)):
            dk = abs(slopes[i] - slopes[j])
            if dk > 0:
                out += [(radii[i] + radii[j]) / dk, abs(radii[i] - radii[j]) / dk]
    return np.asarray(out, float)


def _radial_profile(t_max, R, radii, slopes, natural, pupil=(1.0, "area")):
    """Adaptive samples ``(t, V)`` on ``[0, t_max]`` such that linear interpolation between them
    misses the exact V by at most ``_INTERP_TOL`` at the checked points."""
    kinks = _tangencies(radii, slopes)
    t = np.unique(np.concatenate([
        np.linspace(0.0, t_max, _INITIAL_INTERVALS + 1),
        kinks[(kinks > 0) & (kinks < t_max)],
    ]))
    v = _exact_profile(t, R, radii, slopes, natural, pupil)
    ts, vs = [t], [v]
    a, b, fa, fb = t[:-1], t[1:], v[:-1], v[1:]
    q = np.array([0.25, 0.5, 0.75])
    min_width = 1e-13 * max(t_max, 1.0)
    for _ in range(_MAX_LEVELS):
        if a.size == 0:
            break
        tq = a[:, None] + (b - a)[:, None] * q
        fq = _exact_profile(tq, R, radii, slopes, natural, pupil)
        ts.append(tq.ravel())
        vs.append(fq.ravel())
        err = np.max(np.abs(fq - (fa[:, None] + (fb - fa)[:, None] * q)), axis=1)
        split = (err > _INTERP_TOL) & (b - a > min_width)
        nodes_t = np.column_stack([a, tq, b])[split]
        nodes_f = np.column_stack([fa, fq, fb])[split]
        a, b = nodes_t[:, :-1].ravel(), nodes_t[:, 1:].ravel()
        fa, fb = nodes_f[:, :-1].ravel(), nodes_f[:, 1:].ravel()
    t, v = np.concatenate(ts), np.concatenate(vs)
    t, first = np.unique(t, return_index=True)
    return t, v[first]


@accepts_center_rc
def relative_illumination_map(shape, pixel_pitch_um, f_number, lens, *, center_rc=None,
                              center_px=None, natural_vignetting=True, pixel_acceptance_deg=None,
                              source=None, method="radial"):
    """Expected flat-field signal of every pixel relative to the optical centre, no noise.

    ``V = A / (pi R^2) * cos^4(CRA) * S``: ``A`` the area common to the exit pupil (radius
    ``R``, Eq. 28), the lens's projected vignetting circles (radius ``P_i``, centre
    ``h_i tan(CRA)``) and the pixel's acceptance circle (radius ``x tan(a)``, centre
    ``x tan(CRA)``, if given); ``S`` the source's relative signal (1 if uniform). A Lambertian
    pupil has every ray's cos^4 for ``A cos^4(CRA)`` (:func:`~.aperture.relative_irradiance`).

    Parameters
    ----------
    shape : (ny, nx)
    pixel_pitch_um : float
        Pixel pitch, micrometres.
    f_number : float
        F-number (> 0).
    lens : snapcorr.Lens
        Exit pupil distance ``x``, vignetting circles and working f-number (Eq. 27).
    center_rc, center_px : (row, col), optional
        Optical centre, pixels, row first; ``center_px=(cx, cy)`` is the deprecated x-first
        form. Default: the image centre.
    natural_vignetting : bool
        Include ``cos^4(CRA)`` (a Lambertian pupil: every ray's).
    pixel_acceptance_deg : float, optional
        Half-angle ``a`` (0 < a < 90) of the cone about its normal from which a pixel accepts
        light (pixel vignetting; default none). A cone narrower than the lens's
        (``x tan(a) < R``) lowers the signal at the optical centre too.
    source : LampPlaque or object with ``relative_signal(tan_x, tan_y)``, optional
        ``None`` is uniform (integrating sphere). It is given the tangents of each pixel's line
        of sight in object space, taken equal to the image-side chief ray's:
        ``tan_x = (j - cx) * pitch / x``, ``tan_y = (i - cy) * pitch / x``.
    method : {"radial", "exact"}
        ``"radial"``: the lens terms (of ``tan(CRA)`` only) on an adaptive 1-D grid (linear
        within 1e-7 at checked points, nodes at the discs' tangencies), interpolated per
        pixel; ``"exact"``: every pixel's disc overlap (10x slower).

    Returns
    -------
    ndarray
        float64, shape ``(ny, nx)``; 1 at the optical centre of a lens with ``P >= R``, a
        uniform source and no pixel vignetting.

    Raises
    ------
    ValueError
        For a bad shape, pitch, f-number, acceptance angle or method.

    Notes
    -----
    Focused far away, a line of sight's object-side angle is nearer ``arctan(d / f)`` than the
    ``arctan(d / x)`` used: where ``x > f`` a lamp-plaque's non-uniformity comes out too small.

    Examples
    --------
    >>> from snapcorr import Lens
    >>> lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
    >>> v = relative_illumination_map((1, 3), 2000.0, 1.4, lens, center_rc=(0, 0))
    >>> v.round(4)  # CRA 0, 5.44 and 10.78 deg
    array([[1.    , 0.8725, 0.6939]])
    >>> cra = np.rad2deg(np.arctan(2.0 / 21.0))  # 2 mm off axis, x = 21 mm
    >>> round(float(lens.relative_illumination(1.4, cra) * np.cos(np.deg2rad(cra)) ** 4), 4)
    0.8725
    """
    method = validate_method(method, ILLUMINATION_METHODS)
    if pixel_acceptance_deg is not None:
        a = _number("pixel_acceptance_deg", pixel_acceptance_deg)
        if not 0.0 < a < 90.0:
            raise ValueError(
                f"pixel_acceptance_deg must be inside (0, 90) degrees, got {pixel_acceptance_deg!r}"
                "; use None for no pixel vignetting"
            )
        pixel_acceptance_deg = a
    if source is not None and not callable(getattr(source, "relative_signal", None)):
        raise TypeError(
            "source must have a relative_signal(tan_x, tan_y) method (e.g. LampPlaque()), "
            f"or be None for a uniform source; got {type(source).__name__}"
        )
    _number("f_number", f_number, positive=True)
    tx, ty = pixel_tangents(shape, pixel_pitch_um, lens.exit_pupil_mm, center_rc=center_rc)
    ny, nx = ty.size, tx.size
    R, radii, slopes = _discs(lens, f_number, pixel_acceptance_deg)
    natural, pupil = bool(natural_vignetting), (float(lens.exit_pupil_mm), lens.ray_weight)

    if method == "radial":
        t_max = math.hypot(np.max(np.abs(tx)), np.max(np.abs(ty)))
        tg, vg = _radial_profile(t_max, R, radii, slopes, natural, pupil)
        v = np.hypot(ty[:, None], tx[None, :])
        v = np.interp(v, tg, vg)
    else:
        v = np.empty((ny, nx))
        for r0, r1 in _row_blocks(ny, nx):
            t = np.hypot(ty[r0:r1, None], tx[None, :])
            v[r0:r1] = _exact_profile(t, R, radii, slopes, natural, pupil)

    if source is not None:
        for r0, r1 in _row_blocks(ny, nx):
            v[r0:r1] *= source.relative_signal(tx[None, :], ty[r0:r1, None])
    return v


# -- flat field ---------------------------------------------------------------------------------
def _to_dtype(dn, dtype):
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return dn.astype(dtype, copy=False)
    if dtype.kind not in "iu":
        raise ValueError(f"dtype must be a float or integer type, got {dtype}")
    info = np.iinfo(dtype)
    hi = float(info.max)
    if hi > info.max:  # 2**63 - 1 and 2**64 - 1 round up as floats; stay inside the range
        hi = float(np.nextafter(hi, 0.0))
    np.rint(dn, out=dn)
    np.clip(dn, float(info.min), hi, out=dn)
    return dn.astype(dtype)


@dataclass(frozen=True)
class Detector:
    """How a simulated camera turns light into digital numbers: signal, noise, gain, offset.

    Parameters
    ----------
    signal_electrons : float
        Mean signal at the optical centre without pixel vignetting, electrons (> 0). 1e4
        electrons means 1 % shot noise there.
    read_noise_electrons : float
        Standard deviation of the Gaussian read noise, electrons (>= 0).
    gain_electrons_per_dn : float
        Conversion gain, electrons per DN (> 0).
    dark_dn : float
        Dark offset added to every pixel, DN.
    saturation_dn : float, optional
        Values above this are set to it (full well / ADC range), DN (> 0).
    """

    signal_electrons: float = 1e4
    read_noise_electrons: float = 0.0
    gain_electrons_per_dn: float = 1.0
    dark_dn: float = 0.0
    saturation_dn: float | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "signal_electrons", _number("signal_electrons", self.signal_electrons,
                                               positive=True))
        set_(self, "read_noise_electrons", _number(
            "read_noise_electrons", self.read_noise_electrons, nonnegative=True))
        set_(self, "gain_electrons_per_dn", _number(
            "gain_electrons_per_dn", self.gain_electrons_per_dn, positive=True))
        set_(self, "dark_dn", _number("dark_dn", self.dark_dn))
        if self.saturation_dn is not None:
            set_(self, "saturation_dn", _number("saturation_dn", self.saturation_dn,
                                                positive=True))


@accepts_center_rc
def flat_frame(shape, pixel_pitch_um, f_number, lens, *, center_rc=None, center_px=None,
               natural_vignetting=True, pixel_acceptance_deg=None, source=None,
               detector=None, dtype=np.float32, rng=None, noise=True):
    """A simulated flat-field frame in digital numbers (DN).

    The expected signal of a pixel is ``detector.signal_electrons * V`` electrons, with ``V``
    from :func:`relative_illumination_map`. With ``noise=True`` the electrons are drawn from a
    Poisson distribution (shot noise) and Gaussian read noise is added; then
    ``DN = electrons / gain + dark_dn``, clipped at ``saturation_dn``.

    Parameters
    ----------
    shape, pixel_pitch_um, f_number, lens, center_rc, center_px, natural_vignetting,
    pixel_acceptance_deg, source
        As for :func:`relative_illumination_map`. ``source=None`` is an integrating sphere;
        :class:`LampPlaque` is a lamp and a diffuse plaque.
    detector : Detector, optional
        Signal level, read noise, gain, dark offset and saturation (default:
        ``Detector()``, 1e4 electrons, no read noise, 1 electron per DN, no offset).
    dtype : numpy dtype
        Output type. Integer types are rounded to the nearest integer and clipped to the type's
        range (e.g. negative values to 0 for unsigned types).
    rng : None, int or numpy.random.Generator
        Random source, passed to :func:`numpy.random.default_rng`; an int seed gives a
        reproducible frame.
    noise : bool
        ``False`` returns the expected frame (no random numbers are drawn; ``rng`` and
        the read noise do not change the result).

    Returns
    -------
    ndarray
        Shape ``(ny, nx)``, type ``dtype``.

    Raises
    ------
    ValueError
        For a bad shape, pitch, f-number, signal, noise level, gain, saturation, dtype or
        acceptance angle.

    Notes
    -----
    Peak memory is about three float64 copies of the frame (2048 x 2048: ~100 MB).

    Examples
    --------
    >>> from snapcorr import Lens
    >>> camera = Detector(read_noise_electrons=30.0, gain_electrons_per_dn=2.0, dark_dn=64.0)
    >>> sphere = flat_frame((512, 512), 5.5, 2.8, Lens(21.0, name="no vignetting"),
    ...                     detector=camera, rng=7)
    >>> noise_dn = float(sphere[200:312, 200:312].std())
    >>> bool(abs(noise_dn - np.sqrt(1e4 + 30.0**2) / 2.0) < 1.5)  # 52.2 DN
    True
    """
    det = Detector() if detector is None else detector
    if not isinstance(det, Detector):
        raise TypeError(f"detector must be a snapcorr.simulate.Detector, got "
                        f"{type(det).__name__}")
    signal, read, gain = det.signal_electrons, det.read_noise_electrons, det.gain_electrons_per_dn
    dark, sat = det.dark_dn, det.saturation_dn
    out_dtype = np.dtype(dtype)
    if out_dtype.kind not in "fiu":
        raise ValueError(f"dtype must be a float or integer type, got {out_dtype}")

    v = relative_illumination_map(
        shape, pixel_pitch_um, f_number, lens, center_rc=center_rc,
        natural_vignetting=natural_vignetting, pixel_acceptance_deg=pixel_acceptance_deg,
        source=source,
    )
    v *= signal  # expected electrons
    if noise:
        gen = np.random.default_rng(rng)
        electrons = gen.poisson(v).astype(np.float64)
        if read > 0:
            gen.standard_normal(out=v)  # v is no longer needed: reuse it for the read noise
            v *= read
            electrons += v
        v = electrons
    v /= gain
    v += dark
    if sat is not None:
        np.minimum(v, sat, out=v)
    return _to_dtype(v, out_dtype)


# -- lamp and plaque ----------------------------------------------------------------------------
def _brdf_coefficients(brdf):
    if not isinstance(brdf, Mapping):
        raise TypeError(f"brdf must be a mapping {{(mu, nu): c, 't': c_t}}, got {brdf!r}")
    out = {}
    for key, value in brdf.items():
        if key not in _BRDF_KEYS:
            raise ValueError(
                f"unknown brdf key {key!r}; valid keys are (mu, nu) with mu, nu in 0..2, not "
                "both 0, and 't' for c_t"
            )
        out[_BRDF_KEYS[_BRDF_KEYS.index(key)]] = _number(f"brdf[{key!r}]", value)
    return out


@dataclass(frozen=True)
class LampPlaque:
    """A 0/45 lamp-plaque source: an FEL lamp shining on a diffuse plaque (Hanssen et al. 2017).

    Geometry (lengths in cm): the geometric centre of the lamp's coils is the origin, ``z`` is
    the lamp's axis towards the plaque, which lies in the plane ``z = lamp_distance_cm`` facing
    the lamp; its centre is on the axis. The camera is at
    ``plaque centre + camera_distance_cm * (sin v, 0, -cos v)`` (``v = view_angle_deg``, in the
    ``x-z`` plane) and looks at the plaque centre. A pixel's line of sight has the direction
    ``e_z + tan_x e_x + tan_y e_y`` in the camera frame ``e_z = (-sin v, 0, cos v)``,
    ``e_x = (cos v, 0, sin v)``, ``e_y = (0, 1, 0)``: positive ``tan_x`` looks at the part of the
    plaque nearer the camera.

    Parameters
    ----------
    lamp_distance_cm : float
        Lamp (coil centre) to plaque, cm; 50 is the FEL calibration distance ``d_cal``.
    camera_distance_cm : float
        Camera to plaque centre, cm.
    view_angle_deg : float
        Angle between the plaque normal and the camera's axis, in (0, 90) degrees.
    brdf : mapping
        Coefficients of the BRDF ratio about 0/45: ``{(mu, nu): c_mu_nu}`` with mu, nu in 0..2
        (not both 0) and ``"t"`` for ``c_t``. Empty (default): a Lambertian plaque, ratio 1.

    Notes
    -----
    Irradiance at the plaque point ``(x, y, z)`` (the slide "E(x, y, z) = ?" of [1]_)::

        E = E_cal ((d_cal + 0.2175 cm) / d_eff)^2 cos(theta_i)
        r = [x^2 + (z + 0.3175 cm)^2]^(1/2),   d_eff^2 = (r - 0.1 cm)^2 + y^2

    The slide prints the distance ratio the other way up, ``(d_eff / (d_cal + 0.2175 cm))^2``,
    which would make the irradiance grow with distance, against the slide's own "validation of
    the 1/r^2 law"; both give ``E_cal`` at the calibration distance. The inverse-square form is
    used here. The lamp's angular intensity factor ``(I(x, y, z) / I(0, 0, z))_GSF`` is measured
    data not given in [1]_ and is left out (taken as 1). ``theta_i`` is taken from the direction
    of the coils' geometric centre.

    BRDF ratio about the 0/45 geometry ([1]_, "Parametrization of ratio")::

        g = 1 + sum_{mu, nu} c_mu_nu l_i^mu l_s^nu + c_t t_s^2
        l_s = sin(theta_s) - sin(45 deg),  l_i = sin(theta_i) cos(phi_r),
        t_s = sin(theta_i) sin(phi_r)

    with the slide's direction vectors ``q_i = (c_xi, c_yi, -|c_zi|)`` (incident light, as it
    travels) and ``q_s = (c_xs, c_ys, |c_zs|)`` (towards the camera) in the plaque's frame, so
    ``l_i = (c_xi c_xs + c_yi c_ys) / sin(theta_s)``: ``phi_r = 0`` when the light travels
    towards the camera's side of the plaque normal. The slide does not fix the zero of
    ``phi_r``; with the other convention (incident direction pointing back to the lamp) the
    odd powers of ``l_i`` change sign. Where the line of sight is along the plaque normal
    (``theta_s = 0``) ``phi_r`` is measured from the ``x`` axis.

    The power on a pixel is ``d_omega A cos(theta_pixel) sec(theta_s) E g BRDF(0/45)
    cos(theta_s)`` ([1]_, "Power delivered to pixel"): ``cos(theta_s)`` and ``sec(theta_s)``
    cancel and ``cos(theta_pixel)`` belongs to the camera (natural vignetting), so relative to
    an integrating sphere the signal is ``E g``.

    References
    ----------
    .. [1] L. Hanssen et al. (NIST), "Analysis of systematic effects in 0/45 lamp-plaque sensor
       calibration", CALCON 2017, Logan, UT (2017).

    Examples
    --------
    >>> source = LampPlaque()
    >>> float(source.relative_signal(0.0, 0.0))
    1.0
    >>> source.relative_signal([-0.2, 0.2], 0.0).round(4)  # the near side is brighter
    array([0.839 , 0.9226])
    >>> round(float(source.irradiance_ratio(0.0, 0.0)), 12)  # E = E_cal at d_cal
    1.0
    """

    lamp_distance_cm: float = FEL_CALIBRATION_DISTANCE_CM
    camera_distance_cm: float = 50.0
    view_angle_deg: float = 45.0
    brdf: Mapping = field(default_factory=dict, hash=False)

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "lamp_distance_cm",
             _number("lamp_distance_cm", self.lamp_distance_cm, positive=True))
        set_(self, "camera_distance_cm",
             _number("camera_distance_cm", self.camera_distance_cm, positive=True))
        v = _number("view_angle_deg", self.view_angle_deg)
        if not 0.0 < v < 90.0:
            raise ValueError(f"view_angle_deg must be inside (0, 90) degrees, got {v!r}")
        set_(self, "view_angle_deg", v)
        set_(self, "brdf", _brdf_coefficients(self.brdf))

    # -- geometry -------------------------------------------------------------------------------
    def _camera(self):
        v = math.radians(self.view_angle_deg)
        return math.sin(v), math.cos(v), self.camera_distance_cm

    def plaque_point(self, tan_x, tan_y):
        """Where the line of sight ``(tan_x, tan_y)`` meets the plaque: ``(x_cm, y_cm)``.

        Raises ValueError if a line of sight runs parallel to or away from the plaque
        (``tan_x <= -cot(view_angle)``).
        """
        tx, ty = np.broadcast_arrays(np.asarray(tan_x, float), np.asarray(tan_y, float))
        s, c, L = self._camera()
        wz = c + tx * s  # z component of e_z + tan_x e_x + tan_y e_y
        if np.any(wz <= 0):
            raise ValueError(
                f"some lines of sight (tan_x <= {-c / s:.4g}) never reach the plaque seen at "
                f"{self.view_angle_deg:g} deg; use a narrower field or a smaller view angle"
            )
        # Camera at (L s, 0, D - L c); the ray reaches z = D after travelling L c / wz.
        lam = L * c / wz
        return L * s + lam * (tx * c - s), lam * ty

    def irradiance_ratio(self, x_cm, y_cm):
        """Irradiance at the plaque point ``(x, y)`` over the calibrated ``E_cal``, inverse-square
        form, angular intensity factor 1 (see Notes of the class)."""
        x, y = np.asarray(x_cm, float), np.asarray(y_cm, float)
        z = self.lamp_distance_cm
        r = np.hypot(x, z + _COIL_OFFSET_CM)
        d_eff2 = (r - _RADIOMETRIC_OFFSET_CM) ** 2 + y * y
        cos_i = z / np.sqrt(x * x + y * y + z * z)
        return (FEL_CALIBRATION_DISTANCE_CM + _CALIBRATION_OFFSET_CM) ** 2 / d_eff2 * cos_i

    def brdf_ratio(self, x_cm, y_cm):
        """BRDF at the plaque point ``(x, y)`` towards the camera over BRDF(0/45), ``g``."""
        x, y = np.broadcast_arrays(np.asarray(x_cm, float), np.asarray(y_cm, float))
        if not self.brdf:
            return np.ones(x.shape)[()]
        s, c, L = self._camera()
        z = self.lamp_distance_cm
        # Incident direction (lamp -> point) and scatter direction (point -> camera); their
        # components along the plaque are the slide's (c_xi, c_yi) and (c_xs, c_ys).
        ni = np.sqrt(x * x + y * y + z * z)
        cxi, cyi = x / ni, y / ni
        dx, dy, dz = L * s - x, -y, L * c
        ns = np.sqrt(dx * dx + dy * dy + dz * dz)
        cxs, cys = dx / ns, dy / ns
        sin_s = np.hypot(cxs, cys)
        on_normal = sin_s == 0
        with np.errstate(divide="ignore", invalid="ignore"):
            ux = np.where(on_normal, 1.0, cxs / sin_s)
            uy = np.where(on_normal, 0.0, cys / sin_s)
        l_i = cxi * ux + cyi * uy
        t_s = cxi * uy - cyi * ux
        l_s = sin_s - math.sin(math.radians(_BRDF_REFERENCE_SCATTER_DEG))
        g = np.ones(x.shape)
        for key, coef in self.brdf.items():
            g = g + (coef * t_s**2 if key == "t" else coef * l_i ** key[0] * l_s ** key[1])
        return g[()]

    def relative_signal(self, tan_x, tan_y):
        """Signal of the pixel whose line of sight is ``(tan_x, tan_y)`` over that of the pixel
        on the camera's axis: ``(E g)(point) / (E g)(plaque centre)``.

        ``tan_x, tan_y`` are the object-space direction relative to the camera's axis (see the
        class docstring); :func:`flat_frame` takes them equal to the image-side chief ray.
        """
        x, y = self.plaque_point(tan_x, tan_y)
        on_axis = self.irradiance_ratio(0.0, 0.0) * self.brdf_ratio(0.0, 0.0)
        return (self.irradiance_ratio(x, y) * self.brdf_ratio(x, y) / on_axis)[()]


# -- mosaic frames of a spectral target ---------------------------------------------------------

#: Chief-ray-angle step of the table each pixel's band value is interpolated from (a band's
#: value changes smoothly with the angle: linear interpolation over 0.25 deg misses by < 1e-4
#: of a smooth target's reflectance).
MOSAIC_CRA_STEP_DEG = 0.25


def _modelled_responses(sensor):
    """A sensor's modelled filters (its profile, centres and widths) as sampled responses."""
    from .cube.responses import FilterResponses, Peak
    from .optics.bandwidth import band_profile

    cwl, fwhm = np.asarray(sensor.cwl_nm), np.asarray(sensor.fwhm_nm)
    n = np.broadcast_to(np.asarray(sensor.n_eff, float), cwl.shape)
    step = float(fwhm.min()) / 40.0
    grid = np.arange(cwl.min() - 6 * fwhm.max(), cwl.max() + 6 * fwhm.max() + step, step)
    curves = [band_profile(sensor.profile_shape, c, w, k)(grid)
              for c, w, k in zip(cwl, fwhm, n, strict=True)]
    return FilterResponses(grid, curves, np.ones(grid.size),
                           [[Peak(c, w, 1.0)] for c, w in zip(cwl, fwhm, strict=True)])


@accepts_center_rc
def mosaic_reflectance(sensor, reflectance, f_number, lens, *, center_rc=None,
                       center_px=None):
    """What every pixel of a mosaic sensor reads of a uniform target, flat-fielded: its band's
    response behind the lens, averaged over the target's reflectance.

    Each ray of a pixel's cone scales the band's whole curve (measured responses through the
    system, or the sensor's modelled filters), as in :mod:`snapcorr.optics.measured`; the
    white reference sees the same response, so the ratio is the response-weighted mean of the
    reflectance under equal-energy light. Values are tabulated over the chief-ray angle every
    :data:`MOSAIC_CRA_STEP_DEG` and interpolated to each pixel.

    Parameters
    ----------
    sensor : Sensor
        A mosaic sensor with ``size_px``, its pitch and ``n_eff``.
    reflectance : callable
        ``reflectance(wavelength_nm)`` -> values.
    f_number : float
    lens : Lens
    center_rc, center_px : (row, col), optional
        Optical centre, pixels, row first; ``center_px=(cx, cy)`` is the deprecated x-first
        form. Default: the sensor's centre.

    Returns
    -------
    ndarray, shape ``sensor.size_px``
        The flat-fielded value each pixel records (the band the tile grid puts there).
    """
    from .optics.chief_ray import cra_map
    from .optics.measured import responses_behind_lens
    from .optics.wiener import trapezoid_weights

    if sensor.layout != "mosaic" or sensor.size_px is None:
        raise ValueError("mosaic_reflectance needs a mosaic sensor with size_px")
    n_eff = sensor.require("n_eff", "simulating a mosaic behind a lens")
    pitch = sensor.require("pixel_pitch_um", "simulating a mosaic behind a lens")
    responses = sensor.responses if sensor.responses is not None else _modelled_responses(sensor)
    ny, nx = sensor.size_px
    cra = cra_map((ny, nx), pitch, lens.exit_pupil_mm, center_rc=center_rc)
    nodes = np.arange(0.0, float(cra.max()) + 2 * MOSAIC_CRA_STEP_DEG, MOSAIC_CRA_STEP_DEG)
    R = responses_behind_lens(responses, n_eff, f_number, nodes, lens)
    grid = responses.wavelength_nm
    w = trapezoid_weights(grid)
    rho = np.asarray(reflectance(grid), float)
    values = (R * rho * w).sum(axis=2) / (R * w).sum(axis=2)  # (nodes, bands)
    tr, tc = sensor.mosaic_shape
    r0, c0 = sensor.tile_origin_px
    index = np.empty((tr, tc), int)
    for b, (r, c) in enumerate(sensor.band_offset):
        index[r, c] = b
    band = index[((np.arange(ny) - r0) % tr)[:, None], ((np.arange(nx) - c0) % tc)[None, :]]
    out = np.empty((ny, nx))
    for b in range(sensor.n_bands):
        at = band == b
        out[at] = np.interp(cra[at], nodes, values[:, b])
    return out
