"""What a sensor's calibration file says of its filters: measured responses and correction
matrices.

A snapshot-mosaic camera ships with each band's response measured on a wavelength grid (every
peak of the filter, second orders and leaks included), the response of what sits in front of
every band (a band-pass filter), and the vendor's correction matrices, which turn the physical
bands into "virtual bands" with the crosstalk removed. :class:`FilterResponses` and
:class:`CorrectionMatrix` hold them, checked and read-only; :mod:`snapcorr.cube.vendor_xml`
reads them from the vendor's file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._validation import check_wavelengths_nm, shown

__all__ = ["MATRIX_KINDS", "CorrectionMatrix", "FilterResponses", "Peak"]

#: What a correction matrix is applied to: flat-fielded values (``"reflectance"``, rows that
#: leave a flat spectrum flat) or values proportional to the light (``"irradiance"``: dark-
#: subtracted counts, radiance).
MATRIX_KINDS = ("reflectance", "irradiance")
#: A peak counts as inside the system's pass band where the system transmits at least this
#: fraction of its maximum there (a band's main peak is its strongest inside).
PASSBAND_FRACTION = 0.5
#: How far below zero a measured curve may dip, as a fraction of its largest value
#: (measurement noise about a zero baseline: a real band-pass dips to -0.0008 of 0.97).
NOISE_FRACTION = 0.01

#: The largest response (or system response) value read: squares, products with the system's
#: response and sums over a grid of up to a million samples stay finite in float64 below it.
RESPONSE_MAX = 1e100

#: The largest correction-matrix coefficient read: applied in float32 to values up to 1e6
#: and summed over a few hundred bands it stays finite; real matrices' coefficients are of
#: order 1-100.
COEFFICIENT_MAX = 1e30

#: A band's response that varies by no more than this share of its largest value over the
#: whole grid has no peak: it is no filter's.
FLAT_FRACTION = 1e-9
#: The narrowest virtual band, in steps of the responses' grid: a Gaussian narrower than
#: two samples has no area the grid can integrate (0.001 nm on a 1 nm grid has none). The
#: bound of ``--virtual-fwhm-nm`` and of a vendor file's virtual-band widths alike.
MIN_FWHM_STEPS = 2.0
#: How far a virtual band's Gaussian must lie inside the responses' grid either side of its
#: centre, in its FWHM: beyond, the bands cannot make its tails (0.2 % of its peak at 1.5).
VIRTUAL_REACH_FWHM = 1.5


def reaching_beyond(wavelength_nm, fwhm_nm, grid_nm):
    """Indices of the virtual bands (centres ``wavelength_nm``, widths ``fwhm_nm``, nm) that
    reach beyond ``grid_nm`` within :data:`VIRTUAL_REACH_FWHM` of their FWHM; a band of no
    stated width (NaN) reaches nowhere."""
    wl, fw = np.broadcast_arrays(np.asarray(wavelength_nm, float), np.asarray(fwhm_nm, float))
    grid = np.asarray(grid_nm, float)
    with np.errstate(invalid="ignore"):
        out = (wl - VIRTUAL_REACH_FWHM * fw < grid[0]) | (wl + VIRTUAL_REACH_FWHM * fw > grid[-1])
    return np.flatnonzero(out & np.isfinite(fw))


class Peak(NamedTuple):
    """One peak of a band's response, as the calibration file lists it."""

    wavelength_nm: float
    fwhm_nm: float
    qe: float
    order: int | None = None


def _frozen(values, dtype=float):
    a = np.array(values, dtype=dtype)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class FilterResponses:
    """Every band's measured response at normal, collimated incidence, on one wavelength grid.

    Parameters
    ----------
    wavelength_nm : array_like, shape (n,)
        The grid, nm, strictly increasing.
    curves : array_like, shape (n_bands, n)
        Each band's response (the file's units, e.g. quantum efficiency in percent) without
        the system's components; all its peaks.
    system : array_like, shape (n,)
        Transmission of what is in front of every band (band-pass filter, other optical
        components multiplied together); ones when the file lists none.
    peaks : sequence of sequences of Peak
        Each band's peaks as the file lists them (at least one per band).
    system_name : str
        What ``system`` is, for provenance.

    The arrays are copied and read-only; two objects are equal when every value is.
    """

    wavelength_nm: np.ndarray
    curves: np.ndarray
    system: np.ndarray
    peaks: tuple
    system_name: str = "none"

    def __post_init__(self):
        set_ = object.__setattr__
        grid = check_wavelengths_nm("the response grid", self.wavelength_nm)
        if grid.ndim != 1 or grid.size < 3 or np.any(np.diff(grid) <= 0):
            raise ValueError("the response grid must list at least 3 increasing wavelengths")
        curves = np.asarray(self.curves, float)
        if curves.ndim != 2 or curves.shape[1] != grid.size or curves.shape[0] < 1:
            raise ValueError(f"the responses must be (bands, {grid.size}) values, got shape "
                             f"{curves.shape}")
        system = np.asarray(self.system, float)
        if system.shape != grid.shape:
            raise ValueError(f"the system's response must have {grid.size} values, got "
                             f"{system.size}")
        for name, a in (("responses", curves), ("system response", system)):
            if not np.all(np.isfinite(a)):
                raise ValueError(f"the {name} must be finite numbers")
            top = np.max(a, axis=-1)
            low = np.min(a, axis=-1)
            if not np.all(top >= np.finfo(float).tiny) or np.any(low < -NOISE_FRACTION * top):
                raise ValueError(f"the {name} must be positive somewhere and not negative "
                                 f"beyond noise ({NOISE_FRACTION:g} of the largest value)")
            if np.any(top > RESPONSE_MAX):
                raise ValueError(f"the {name} reach {float(np.max(top)):g}, beyond "
                                 f"{RESPONSE_MAX:g}: their squares and products overflow; "
                                 "no response is so large (scale them)")
        flat = np.flatnonzero(np.max(curves, axis=-1) - np.min(curves, axis=-1)
                              <= FLAT_FRACTION * np.max(curves, axis=-1))
        if flat.size:
            raise ValueError(f"band {int(flat[0])}'s response is the same at every wavelength "
                             f"of the grid ({curves[flat[0], 0]:g}): a filter's response has a "
                             "peak")
        with np.errstate(over="ignore"):
            if not np.all(np.isfinite(curves * system)):
                raise ValueError("the responses times the system's response overflow: their "
                                 "values are not a response's")
        peaks = tuple(tuple(Peak(*p) for p in band) for band in self.peaks)
        if len(peaks) != curves.shape[0] or any(len(p) == 0 for p in peaks):
            raise ValueError(f"every band needs at least one peak ({curves.shape[0]} bands, "
                             f"peaks for {len(peaks)})")
        for band in peaks:
            for p in band:
                check_wavelengths_nm("a peak's wavelength", [p.wavelength_nm])
                if not (np.isfinite(p.fwhm_nm) and p.fwhm_nm > 0 and np.isfinite(p.qe)
                        and p.qe >= 0):
                    raise ValueError(f"a peak's fwhm_nm must be > 0 and its QE finite and not "
                                     f"negative, got {p}")
        for b, band in enumerate(peaks):
            if not any(grid[0] <= p.wavelength_nm <= grid[-1] for p in band):
                where = ", ".join(f"{p.wavelength_nm:g}" for p in band)
                raise ValueError(f"band {b}: its peaks ({where} nm) all lie outside the response "
                                 f"grid ({grid[0]:g}-{grid[-1]:g} nm): the curve does not show "
                                 "the band")
        step = np.diff(grid)
        typical = float(np.median(step))
        span = float(grid[-1] - grid[0])
        for b, band in enumerate(peaks):
            for p in band:
                if p.fwhm_nm > span:  # no curve on the grid shows it; it would be reported
                    raise ValueError(f"band {b}: a peak's FWHM of {p.fwhm_nm:g} nm is wider "
                                     f"than the whole grid ({grid[0]:g}-{grid[-1]:g} nm); "
                                     "the curve cannot show a band so wide")
                # the grid's own step there, and never below its typical step: one step made
                # tiny at a peak would otherwise let its stated width size the fine grids of
                # the centre and width computations without bound
                at = max(float(np.interp(p.wavelength_nm, grid[1:], step)), typical)
                if p.fwhm_nm < at:
                    raise ValueError(f"band {b}: a peak's FWHM of {p.fwhm_nm:g} nm is narrower "
                                     f"than the grid's {at:g} nm step at {p.wavelength_nm:g} "
                                     "nm; the curve cannot show a band so narrow")
        if not np.any(curves * system > 0, axis=1).all():
            raise ValueError("a band's response is zero everywhere through the system")
        set_(self, "wavelength_nm", _frozen(grid))
        set_(self, "curves", _frozen(curves))
        set_(self, "system", _frozen(system))
        set_(self, "peaks", peaks)
        set_(self, "system_name", str(self.system_name))

    @property
    def n_bands(self) -> int:
        return self.curves.shape[0]

    @property
    def effective(self) -> np.ndarray:
        """``curves * system``: each band's response as the light reaches the pixel."""
        return self.curves * self.system

    def main_peaks(self):
        """Each band's main peak: its strongest (largest QE) inside the system's pass band
        (where the system transmits at least :data:`PASSBAND_FRACTION` of its maximum), else
        its strongest.

        Returns
        -------
        tuple of Peak
        """
        grid, system = self.wavelength_nm, self.system
        passes = system >= PASSBAND_FRACTION * system.max()
        out = []
        for band in self.peaks:
            inside = [p for p in band if passes[np.clip(np.searchsorted(grid, p.wavelength_nm),
                                                        0, grid.size - 1)]]
            out.append(max(inside or band, key=lambda p: p.qe))
        return tuple(out)

    def __eq__(self, other):
        if not isinstance(other, FilterResponses):
            return NotImplemented
        return (np.array_equal(self.wavelength_nm, other.wavelength_nm)
                and np.array_equal(self.curves, other.curves)
                and np.array_equal(self.system, other.system) and self.peaks == other.peaks
                and self.system_name == other.system_name)

    def __hash__(self):
        return hash((self.curves.tobytes(), self.system.tobytes(), self.peaks))


@dataclass(frozen=True, eq=False)
class CorrectionMatrix:
    """A vendor's correction matrix: ``virtual = coefficients @ bands``.

    Parameters
    ----------
    name : str
        As the file names it (``"hsi_reflectance"``; ``"custom"`` for the older format's one).
    kind : {"reflectance", "irradiance"}
        What it is applied to (:data:`MATRIX_KINDS`).
    wavelength_nm : array_like, shape (n_virtual,)
        Each virtual band's centre, nm.
    fwhm_nm : array_like, shape (n_virtual,)
        Each virtual band's width, nm (NaN where the file does not say).
    coefficients : array_like, shape (n_virtual, n_bands)
        One row per virtual band; the columns follow the physical bands' index order.
    """

    name: str
    kind: str
    wavelength_nm: np.ndarray
    fwhm_nm: np.ndarray
    coefficients: np.ndarray

    def __post_init__(self):
        set_ = object.__setattr__
        if self.kind not in MATRIX_KINDS:
            raise ValueError(f"a correction matrix's type must be one of {MATRIX_KINDS}, got "
                             f"{shown(self.kind)}")
        wl = np.atleast_1d(np.asarray(self.wavelength_nm, float))
        if wl.ndim != 1 or wl.size == 0:
            raise ValueError(f"matrix {shown(self.name)}: virtual band wavelengths must be a "
                             "list of numbers")
        # in nm, distinct: a result's virtual bands are written with them and read back
        wl = check_wavelengths_nm("virtual band wavelengths", wl,
                                  where=f"matrix {shown(self.name)}")
        fw = np.broadcast_to(np.asarray(self.fwhm_nm, float), wl.shape)
        if np.any(fw[np.isfinite(fw)] <= 0) or np.any(np.isinf(fw)):
            raise ValueError(f"matrix {shown(self.name)}: virtual band widths must be > 0")
        c = np.asarray(self.coefficients, float)
        if c.ndim != 2 or c.shape[0] != wl.size or not np.all(np.isfinite(c)):
            raise ValueError(f"matrix {shown(self.name)}: coefficients must be finite, one row per "
                             f"virtual band ({wl.size}), got shape {c.shape}")
        if c.size and float(np.max(np.abs(c))) > COEFFICIENT_MAX:
            raise ValueError(f"matrix {shown(self.name)}: a coefficient is "
                             f"{float(np.max(np.abs(c))):g}, beyond {COEFFICIENT_MAX:g}: applied "
                             "to a band's values it overflows; no correction matrix is so large")
        set_(self, "name", str(self.name))
        set_(self, "wavelength_nm", _frozen(wl))
        set_(self, "fwhm_nm", _frozen(fw))
        set_(self, "coefficients", _frozen(c))

    @property
    def n_virtual(self) -> int:
        return self.coefficients.shape[0]

    def __eq__(self, other):
        if not isinstance(other, CorrectionMatrix):
            return NotImplemented
        return (self.name == other.name and self.kind == other.kind
                and np.array_equal(self.wavelength_nm, other.wavelength_nm)
                and np.array_equal(self.fwhm_nm, other.fwhm_nm, equal_nan=True)
                and np.array_equal(self.coefficients, other.coefficients))

    def __hash__(self):
        return hash((self.name, self.kind, self.coefficients.tobytes()))
