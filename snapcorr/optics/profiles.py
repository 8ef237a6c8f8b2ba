"""Filter transmission profiles for simulation and tests.

Each profile is a small frozen object, callable as ``profile(wavelength_nm, aoi_deg=0.0)`` for
the transmission at an angle of incidence in collimated light, with ``cwl_nm`` and ``fwhm_nm``
attributes. :data:`FILTER_PROFILES` is the registry.

References
----------
.. [1] D. N. Mishev, K. P. Bakalova, "Multispectral imagery and interference filter effects":
   Airy transmission Eq. (1)-(3); peak ~ cos(k theta), width ~ 1/cos(k theta) with k = 2 and
   Pi-shaped curves (Eq. 8, Table 2).
.. [2] D. E. Flittner, P. N. Slater, "Stability of narrow-band filter radiometers in the
   solar-reflective range", Photogramm. Eng. Remote Sens. 57, 165 (1991): the multi-Lorentzian.
.. [3] T. Goossens et al., Appl. Opt. 58, 1789 (2019), Eq. (3)-(4): a tilt shifts the curve.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from .._validation import check_curve, check_positive
from .shift import check_n_eff, shift_nm

__all__ = ["FILTER_PROFILES", "PROFILES", "Airy", "Gaussian", "MultiLorentzian", "PiShaped",
           "Tabulated", "fwhm_of"]

#: Flittner & Slater: "the transmittance of the multi-Lorentzian is cut off at wavelengths where
#: the transmittance is below 5.0 percent of the peak value".
FWHM_CUT = 0.05


def fwhm_of(wavelength_nm, transmission):
    """Full width at half maximum of a sampled single-peaked curve (linear interpolation)."""
    w = np.asarray(wavelength_nm, float)
    t = np.asarray(transmission, float)
    half = 0.5 * t.max()
    above = np.flatnonzero(t >= half)
    i, j = above[0], above[-1]
    left = np.interp(half, [t[i - 1], t[i]], [w[i - 1], w[i]]) if i > 0 else w[0]
    right = np.interp(half, [t[j + 1], t[j]], [w[j + 1], w[j]]) if j + 1 < t.size else w[-1]
    return right - left


@dataclass(frozen=True)
class Gaussian:
    """A Gaussian passband of the given FWHM, peak ``peak``; tilts shift it by Eq. (3)
    (Goossens Eq. 4). The shape a sensor's filters are taken to have unless it says otherwise.
    """

    cwl_nm: float
    fwhm_nm: float
    n_eff: float = 1.7
    peak: float = 1.0

    def __post_init__(self):
        check_positive("cwl_nm", self.cwl_nm)
        check_positive("fwhm_nm", self.fwhm_nm)

    def __call__(self, wavelength_nm, aoi_deg=0.0):
        center = self.cwl_nm + shift_nm(self.cwl_nm, self.n_eff, aoi_deg)
        u = (np.asarray(wavelength_nm, float) - center) / self.fwhm_nm
        return self.peak * np.exp(-4.0 * np.log(2.0) * u * u)


@dataclass(frozen=True)
class Airy:
    """Fabry-Perot (Airy) transmission of a cavity, Mishev & Bakalova Eq. (1)-(2).

    ``tau = (1 - A/(1 - R)) / (1 + F sin^2(delta/2))``, ``F = 4R/(1-R)^2``,
    ``delta = (4 pi / lambda) n h sqrt(1 - sin^2(theta)/n^2) + 2 phi``. The peak of order ``m``
    sits at Eq. (3), ``lambda_m = 2 n h sqrt(1 - sin^2(theta)/n^2) / (m - phi/pi)``: the
    effective-index law with ``n_eff = n``. (Mishev writes the first factor unsquared; Born &
    Wolf's Airy formula squares it. It only scales the peak.)

    Build from a passband with :meth:`from_passband`.
    """

    n: float
    thickness_nm: float
    reflectance: float
    phase: float = 0.0
    loss: float = 0.0
    order: int = 1

    @classmethod
    def from_passband(cls, cwl_nm, fwhm_nm, n_eff=1.5, order=1, phase=0.0, loss=0.0):
        """The cavity whose order-``order`` peak at normal incidence is ``cwl_nm`` wide
        ``fwhm_nm`` (the exact FWHM of the Airy peak in wavelength).

        Parameters
        ----------
        cwl_nm : float
            Peak wavelength at normal incidence, nm.
        fwhm_nm : float
            FWHM of that peak, nm.
        n_eff : float
            Cavity index ``n`` (> 1); with Eq. (3) it is the effective index.
        order : int
            Interference order ``m`` of the peak.
        phase : float
            Reflection phase ``phi``, radians.
        loss : float
            Mirror absorptance ``A`` (scales the peak by ``1 - A / (1 - R)``).

        Returns
        -------
        Airy
        """
        n = float(check_n_eff(n_eff))
        h = (order - phase / np.pi) * cwl_nm / (2.0 * n)
        # Half maximum where F sin^2(delta/2) = 1, i.e. delta - 2 pi m = +-w with
        # sin(w/2) = 1/sqrt(F). With c = 4 pi n h and D = c / cwl, the half-maximum wavelengths
        # c/(D -+ w) are fwhm apart when fwhm w^2 + 2 c w - fwhm D^2 = 0.
        c = 4 * np.pi * n * h
        D = c / cwl_nm
        w = (np.sqrt(c * c + (fwhm_nm * D) ** 2) - c) / fwhm_nm
        F = 1.0 / np.sin(w / 2) ** 2
        # F = 4R/(1-R)^2  ->  R = (2 + F - 2 sqrt(1 + F)) / F
        R = (2.0 + F - 2.0 * np.sqrt(1.0 + F)) / F
        return cls(n, h, float(R), float(phase), float(loss), int(order))

    @property
    def cwl_nm(self):
        """Peak wavelength of the design order at normal incidence."""
        return float(self.peak_nm(0.0))

    @property
    def fwhm_nm(self):
        lam = self.cwl_nm + np.linspace(-0.2, 0.2, 40001) * self.cwl_nm / self.order
        return fwhm_of(lam, self(lam))

    def peak_nm(self, aoi_deg=0.0):
        """Peak wavelength of the design order at ``aoi_deg``, Eq. (3)."""
        s = np.sin(np.deg2rad(np.asarray(aoi_deg, float))) / self.n
        m = self.order - self.phase / np.pi
        return 2 * self.n * self.thickness_nm * np.sqrt(1 - s * s) / m

    def __call__(self, wavelength_nm, aoi_deg=0.0):
        lam = np.asarray(wavelength_nm, float)
        s = np.sin(np.deg2rad(np.asarray(aoi_deg, float))) / self.n
        delta = 4 * np.pi / lam * self.n * self.thickness_nm * np.sqrt(1 - s * s) + 2 * self.phase
        F = 4 * self.reflectance / (1 - self.reflectance) ** 2
        return (1 - self.loss / (1 - self.reflectance)) / (1 + F * np.sin(delta / 2) ** 2)


def _lorentz(lam, center, fwhm):
    return 1.0 / (1.0 + ((lam - center) / (0.5 * fwhm)) ** 2)


def _multi_lorentzian_shape(lam, k):
    return _lorentz(lam, 0.0, 16 * k) * _lorentz(lam, -4 * k, 6 * k) * _lorentz(lam, 4 * k, 6 * k)


@functools.cache
def _multi_lorentzian_unit():
    """Scale ``k`` giving the product a FWHM of 1 nm, and the product's maximum."""
    from scipy.optimize import brentq  # here: importing it costs every command 0.2-0.6 s

    def width(k):
        lam = np.linspace(-40 * k, 40 * k, 16001)
        return fwhm_of(lam, _multi_lorentzian_shape(lam, k)) - 1.0

    k = brentq(width, 0.01, 10.0, xtol=1e-13)
    # The product is slightly double-humped: normalise by its true maximum.
    lam = np.linspace(-8 * k, 8 * k, 160001)
    return k, float(_multi_lorentzian_shape(lam, k).max())


@dataclass(frozen=True)
class MultiLorentzian:
    """Flittner & Slater's multi-Lorentzian: the product of three Lorentzians, cut at 5 %.

    Their 10 nm filter is a 16 nm FWHM Lorentzian at the centre times two 6 nm FWHM Lorentzians
    at +-4 nm; wider filters use "wider FWHM and greater displacement", here the same shape
    scaled by the factor that makes the product's FWHM equal ``fwhm_nm``. Peak normalised to
    ``peak``; zero where below 5 % of it. Tilts shift the curve by Eq. (3) (Goossens Eq. 4).
    """

    cwl_nm: float
    fwhm_nm: float = 10.0
    n_eff: float = 1.7
    peak: float = 1.0
    scale: float = field(init=False)

    def __post_init__(self):
        check_positive("cwl_nm", self.cwl_nm)
        check_positive("fwhm_nm", self.fwhm_nm)
        k1, norm = _multi_lorentzian_unit()
        # every length of the shape scales with k, so k is proportional to the FWHM and the
        # maximum does not depend on it
        object.__setattr__(self, "scale", k1 * float(self.fwhm_nm))
        object.__setattr__(self, "_norm", norm)

    def __call__(self, wavelength_nm, aoi_deg=0.0):
        center = self.cwl_nm + shift_nm(self.cwl_nm, self.n_eff, aoi_deg)
        u = np.asarray(wavelength_nm, float) - center
        k = self.scale
        t = _lorentz(u, 0, 16 * k) * _lorentz(u, -4 * k, 6 * k) * _lorentz(u, 4 * k, 6 * k)
        t = t / self._norm
        return self.peak * np.where(t >= FWHM_CUT, t, 0.0)


@dataclass(frozen=True)
class PiShaped:
    """Mishev & Bakalova's Pi-shaped passband (Eq. 8, Table 2).

    A rectangle centred at the tilted peak (Eq. 3), ``width = fwhm / cos(k theta)``, height
    ``peak * cos(k theta)``: the integral transmission stays constant (their Eq. 7), ``k = 2``
    for the MKF-6 filters (measured k ~ 1.15-2.65; valid up to theta ~ 20 deg).
    """

    cwl_nm: float
    fwhm_nm: float
    n_eff: float = 1.5
    k: float = 2.0
    peak: float = 1.0

    def width_nm(self, aoi_deg=0.0):
        return self.fwhm_nm / np.cos(self.k * np.deg2rad(np.asarray(aoi_deg, float)))

    def __call__(self, wavelength_nm, aoi_deg=0.0):
        center = self.cwl_nm + shift_nm(self.cwl_nm, self.n_eff, aoi_deg)
        kt = self.k * np.deg2rad(np.asarray(aoi_deg, float))
        half = 0.5 * self.fwhm_nm / np.cos(kt)
        inside = np.abs(np.asarray(wavelength_nm, float) - center) <= half
        return np.where(inside, self.peak * np.cos(kt), 0.0)


@dataclass(frozen=True)
class Tabulated:
    """A measured curve (wavelength increasing), linearly interpolated, zero outside.

    Tilts shift it by Eq. (3) at ``cwl_nm`` (default: the curve's centroid).
    """

    wavelength_nm: np.ndarray
    transmission: np.ndarray
    n_eff: float = 1.7
    cwl_nm: float | None = None

    def __post_init__(self):
        w, t = check_curve(self.wavelength_nm, self.transmission)
        object.__setattr__(self, "wavelength_nm", w)
        object.__setattr__(self, "transmission", t)
        if self.cwl_nm is None:
            object.__setattr__(self, "cwl_nm", float(np.trapezoid(w * t, w) / np.trapezoid(t, w)))

    @property
    def fwhm_nm(self):
        return fwhm_of(self.wavelength_nm, self.transmission)

    def __call__(self, wavelength_nm, aoi_deg=0.0):
        shift = shift_nm(self.cwl_nm, self.n_eff, aoi_deg)
        return np.interp(
            np.asarray(wavelength_nm, float) - shift,
            self.wavelength_nm,
            self.transmission,
            left=0.0,
            right=0.0,
        )


#: Registry of filter-profile models: name -> class or constructor of the transmission curve.
FILTER_PROFILES = {
    "gaussian": Gaussian,
    "airy": Airy.from_passband,
    "multi_lorentzian": MultiLorentzian,
    "pi": PiShaped,
    "tabulated": Tabulated,
}
#: The earlier name of :data:`FILTER_PROFILES`.
PROFILES = FILTER_PROFILES
