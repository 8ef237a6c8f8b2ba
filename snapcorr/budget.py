"""Radiometric error budget: how much a filter's shift changes the signal of a scene.

A wavelength shift matters only as much as the scene's spectrum changes within the filter's
band. Flittner & Slater (1991) define the signal change of a band whose passband moves from
``lambda`` to ``lambda + dlambda`` as

    ERROR(lambda, dlambda) = (P(lambda + dlambda) - P(lambda)) / P(lambda),

where ``P`` integrates the filter profile times the source spectrum. Behind a lens a pixel's
filter is not only moved but also smeared by the angular kernel (Goossens et al. 2019,
Eq. 13 and Sec. 3.4): the pixel measures ``sum_k w_k P(cwl + mu_k)`` over the kernel's bins
(:func:`~snapcorr.optics.response.kernel_bins`). A correction model places the filter at
``cwl + mean_shift``; what it leaves is the *residual*

    residual = P_pixel / P(cwl + mean_shift_model) - 1,

which for ``"none"`` is the error of not correcting at all, and which even the exact mean
(``"vignetted"``) leaves where the scene's spectrum is curved within the band (the kernel
changes the filter's shape). :func:`scene_budget` tabulates it over band and chief-ray angle;
:meth:`Budget.recommend` picks the cheapest model whose residual is below a radiometric
tolerance, :meth:`Budget.radius_mm` gives Mishev & Bakalova's radius of the field inside which
the effect stays below a tolerance, and :func:`tolerance_ranges` is Flittner & Slater's
Table 1 analysis.

References
----------
.. [1] D. E. Flittner, P. N. Slater, "Stability of narrow-band filter radiometers in the
   solar-reflective range", Photogramm. Eng. Remote Sens. 57, 165 (1991).
.. [2] D. N. Mishev, K. P. Bakalova, "Multispectral imagery and interference filter effects".
.. [3] T. Goossens et al., "Vignetted-aperture correction for spectral cameras with integrated
   thin-film Fabry-Perot filters", Appl. Opt. 58, 1789 (2019).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from ._validation import check_positive, validate_method
from .correct.core import METHODS as CORRECT_METHODS
from .optics import Lens, mean_shift
from .optics.profiles import MultiLorentzian, PiShaped
from .optics.response import kernel_bins

__all__ = [
    "MODELS",
    "PROFILES",
    "SOLAR_MODELS",
    "Budget",
    "Spectrum",
    "band_signal",
    "blackbody",
    "cube_spectrum",
    "parse_source",
    "read_spectrum",
    "relative_signal",
    "scene_budget",
    "shift_error",
    "solar",
    "tolerance_ranges",
]

#: Correction models in order of cost (``snapcorr.correct``'s, without ``"auto"``, then
#: ``"harmonised"``: the vignetted correction plus the widening to one response per band,
#: ``correct_cube(harmonise=True)``): the budget picks the first whose residual is below the
#: tolerance.
MODELS = (*(m for m in CORRECT_METHODS if m != "auto"), "harmonised")
#: Gauss-Hermite nodes of the harmonising Gaussian in the budget.
_HERMITE_NODES = 12

#: Filter-profile models for a band of given centre and FWHM.
PROFILES = {"multi_lorentzian": MultiLorentzian, "pi": PiShaped}

#: Tungsten lamps are modelled as blackbodies at their colour temperature (CIE illuminant A,
#: the incandescent lamp, is defined as Planck's law at 2856 K).
_C2_NM_K = 1.438776877e7  # second radiation constant, nm K


@dataclass(frozen=True)
class Spectrum:
    """A source spectrum sampled at increasing wavelengths (nm); any linear unit.

    Between samples it is interpolated linearly; outside the sampled range it is undefined, and
    asking for it raises ``ValueError``.
    """

    wavelength_nm: np.ndarray
    values: np.ndarray
    name: str = "spectrum"

    def __post_init__(self):
        w = np.asarray(self.wavelength_nm, float)
        v = np.asarray(self.values, float)
        if w.ndim != 1 or w.shape != v.shape or w.size < 2:
            raise ValueError(f"the spectrum {self.name!r} needs wavelengths and values of "
                             f"equal length (>= 2), got shapes {w.shape} and {v.shape}")
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(v))):
            raise ValueError(f"the spectrum {self.name!r} holds NaN or infinite values")
        if np.any(np.diff(w) <= 0):
            raise ValueError(f"the spectrum {self.name!r} needs strictly increasing "
                             "wavelengths (no repeats)")
        if np.any(v < 0) or not np.any(v > 0):
            raise ValueError(f"the spectrum {self.name!r} must be >= 0 and not all zero")
        object.__setattr__(self, "wavelength_nm", w)
        object.__setattr__(self, "values", v)

    @property
    def step_nm(self) -> float:
        return float(np.median(np.diff(self.wavelength_nm)))

    def __call__(self, wavelength_nm):
        lam = np.asarray(wavelength_nm, float)
        lo, hi = self.wavelength_nm[0], self.wavelength_nm[-1]
        if lam.size and (lam.min() < lo - 1e-9 or lam.max() > hi + 1e-9):
            raise ValueError(f"the spectrum {self.name!r} covers {lo:g}-{hi:g} nm; "
                             f"{lam.min():.4g}-{lam.max():.4g} nm is needed")
        return np.interp(lam, self.wavelength_nm, self.values)


#: Solar spectra :func:`solar` offers, each shipped offline by a maintained package.
SOLAR_MODELS = ("kurucz", "astm-g173")


def solar(model="kurucz", smoothing_nm=0.5, step_nm=0.1, range_nm=(300.0, 1100.0)) -> Spectrum:
    """The sun's spectrum.

    ``"kurucz"``: the Kurucz solar flux at 1 AU (``rms-solar``), as Flittner & Slater used it:
    a sliding average over ``smoothing_nm`` sampled every ``step_nm``. It is the sun alone,
    with the Fraunhofer lines but none of the Earth's oxygen and water-vapour bands.
    ``"astm-g173"``: the ASTM G173 global tilted irradiance at the ground (``pvlib``; 0.5 nm
    below 400 nm, 1 nm above, no smoothing), with the O2 and H2O bands (1.42 cm of water)
    but coarser lines.
    """
    validate_method(model, SOLAR_MODELS, "solar model")
    if model == "astm-g173":
        from pvlib.spectrum import get_reference_spectra

        df = get_reference_spectra(standard="ASTM G173-03")
        w = np.asarray(df.index, float)
        keep = (w >= range_nm[0] - 1) & (w <= range_nm[1] + 1)
        return Spectrum(w[keep], np.asarray(df["global"], float)[keep],
                        "sun at the ground (ASTM G173 global tilt)")
    import solar as rms_solar  # the rms-solar package
    from scipy.ndimage import uniform_filter1d

    tab = rms_solar.flux_density("Kurucz", units="W/m^2/nm", xunits="nm")
    grid = np.arange(range_nm[0], range_nm[1] + step_nm / 2, step_nm)
    values = np.interp(grid, np.asarray(tab.x, float), np.asarray(tab.y, float))
    width = max(1, round(smoothing_nm / step_nm))
    if width > 1:
        values = uniform_filter1d(values, width, mode="nearest")
    return Spectrum(grid, values, f"sun (Kurucz, {smoothing_nm:g} nm sliding average)")


def blackbody(temperature_k, wavelength_nm=None) -> Spectrum:
    """Planck's law at ``temperature_k`` (relative spectral radiance); a tungsten lamp at its
    colour temperature."""
    t = float(temperature_k)
    if not (math.isfinite(t) and t > 0):
        raise ValueError(f"a temperature must be > 0 K, got {temperature_k!r}")
    lam = np.arange(250.0, 2500.01, 0.5) if wavelength_nm is None else np.asarray(
        wavelength_nm, float)
    with np.errstate(over="ignore"):
        v = 1.0 / (lam ** 5 * np.expm1(_C2_NM_K / (lam * t)))
    if not v.max() > 0:
        raise ValueError(f"a blackbody at {t:g} K emits nothing measurable at "
                         f"{lam[0]:g}-{lam[-1]:g} nm")
    return Spectrum(lam, v / v.max(), f"blackbody {t:g} K")


def read_spectrum(path) -> Spectrum:
    """A spectrum from a text file (two columns, wavelength in nm and value; ``#`` comments;
    comma, semicolon, tab or space separated; header lines before the numbers are skipped) or
    an ``.npy`` array of shape (n, 2) or (2, n)."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"no spectrum file {str(p)!r}")
    if p.suffix == ".npy":
        a = np.load(p)
    else:
        rows = []
        for k, line in enumerate(p.read_text().splitlines(), 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            fields = [f for f in re.split(r"[,;\s]+", line) if f]
            try:
                rows.append([float(f) for f in fields])
            except ValueError:
                if rows:  # text after the data began
                    raise ValueError(f"{p}, line {k}: not numbers: {line[:60]!r}") from None
                continue  # a header line
        if not rows or any(len(r) != len(rows[0]) for r in rows):
            raise ValueError(f"{p}: need two columns of numbers (wavelength nm, value), one "
                             "row per line")
        a = np.array(rows)
    a = np.asarray(a, float)
    if a.ndim == 2 and a.shape[0] == 2 and a.shape[1] != 2:
        a = a.T
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 2:
        raise ValueError(f"{p}: need two columns (wavelength nm, value), got shape {a.shape}")
    order = np.argsort(a[:, 0])
    try:
        return Spectrum(a[order, 0], a[order, 1], p.name)
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None


def cube_spectrum(cube, y=None, x=None) -> Spectrum:
    """The spectrum of one pixel of a cube (``y``, ``x``), or its mean over all pixels.

    A cube samples the scene at its bands only: between band centres the spectrum is linear,
    so structure narrower than the band spacing is not seen; beyond the first and last band it
    is held at their values (200 nm either side), for the filters' tails.
    """
    da = cube if y is None else cube.isel(y=y, x=x)
    if y is None:
        da = da.mean(("y", "x"), skipna=True)
    v = np.asarray(da.values, float)
    w = np.asarray(cube["wavelength"].values, float)
    order = np.argsort(w)
    ok = np.isfinite(v[order])
    where = "mean" if y is None else f"pixel ({y}, {x})"
    w, v = w[order][ok], np.clip(v[order][ok], 0.0, None)
    if w.size == 0:
        raise ValueError(f"the cube's {where} spectrum has no finite value")
    w = np.concatenate([[w[0] - 200.0], w, [w[-1] + 200.0]])
    v = np.concatenate([[v[0]], v, [v[-1]]])
    return Spectrum(w, v, f"cube {where}")


def parse_source(text, cube=None) -> Spectrum:
    """``"solar"`` (or ``"solar:astm-g173"``, see :func:`solar`), ``"tungsten:TEMPERATURE_K"``
    (or ``"blackbody:..."``), ``"cube"`` (the mean spectrum of ``cube``), ``"cube:Y,X"`` (one
    of its pixels) or the path of a spectrum file."""
    t = str(text).strip()
    kind, _, arg = t.partition(":")
    if kind == "solar":
        return solar(arg or "kurucz")
    if kind in ("tungsten", "blackbody") and arg:
        try:
            temperature = float(arg)
        except ValueError:
            raise ValueError(f"{kind}: needs a temperature in K, e.g. {kind}:2856, "
                             f"got {arg!r}") from None
        return blackbody(temperature)
    if kind == "cube":
        if cube is None:
            raise ValueError(f"source {t!r} needs a cube")
        if not arg:
            return cube_spectrum(cube)
        try:
            y, x = (int(v) for v in arg.split(","))
        except ValueError:
            raise ValueError(f"cube:Y,X needs two pixel indices, got {arg!r}") from None
        if not (0 <= y < cube.sizes["y"] and 0 <= x < cube.sizes["x"]):
            raise ValueError(f"pixel ({y}, {x}) is outside the {cube.sizes['y']} x "
                             f"{cube.sizes['x']} cube")
        return cube_spectrum(cube, y, x)
    if Path(t).is_file():
        return read_spectrum(t)
    if Path(t).suffix or "/" in t or "\\" in t:
        raise ValueError(f"no spectrum file {t!r}")
    raise ValueError(f"unknown source {t!r}: use solar, solar:astm-g173, "
                     "tungsten:TEMPERATURE_K, cube, cube:Y,X or the path of a two-column "
                     "spectrum file")


@dataclass(frozen=True)
class _FilterMoments:
    """``C0(u) = int_-inf^u T`` and ``C1(u) = int_-inf^u u' T(u') du'`` of a profile in its own
    frame (``u`` = wavelength - centre), tabulated finely over its support."""

    u: np.ndarray
    c0: np.ndarray
    c1: np.ndarray

    @classmethod
    def of(cls, profile):
        """The moments of ``profile`` (cached: in its own frame a profile depends on its shape
        and width, not on its centre, so a sensor's equal bands share one table)."""
        try:
            return cls._of(dataclasses.replace(profile, cwl_nm=1000.0))
        except (TypeError, ValueError):  # not a dataclass profile: no caching
            return cls._of.__wrapped__(cls, profile)

    @classmethod
    @functools.lru_cache(maxsize=64)
    def _of(cls, profile, fine=8):
        fwhm = float(profile.fwhm_nm)
        # integrated on a grid `fine` times finer than the table, which has fwhm/5000 steps:
        # linear between its nodes, a jump of the profile (the multi-Lorentzian's 5 % cut, a
        # Pi band's edges) costs at most ~1e-5 (5e-5 for a Pi band) of P
        h = fwhm / (5000.0 * fine)
        u = np.arange(-8.0 * fwhm, 8.0 * fwhm + h / 2, h)
        t = np.asarray(profile(profile.cwl_nm + u), float)
        nz = np.flatnonzero(t > 0)
        if nz.size == 0:
            raise ValueError("the filter profile is zero everywhere")
        a = max((nz[0] - 1) // fine * fine, 0)
        b = min(-(-(nz[-1] + 2) // fine) * fine + 1, u.size)
        u, t = u[a:b], t[a:b]
        c0 = np.concatenate([[0.0], np.cumsum(0.5 * h * (t[1:] + t[:-1]))])
        ut = u * t
        c1 = np.concatenate([[0.0], np.cumsum(0.5 * h * (ut[1:] + ut[:-1]))])
        return cls(u[::fine], c0[::fine], c1[::fine])

    def at(self, u):
        """``C0(u)``, ``C1(u)`` on the uniform table (no search); ``u`` within the table.

        ``C0`` is linear between nodes and ``C1`` follows from ``dC1 = u dC0``, so both are
        exact where the profile is constant across a cell: a sharp edge in the source then
        costs nothing extra.
        """
        h = self.u[1] - self.u[0]
        pos = (u - self.u[0]) / h
        i = np.clip(pos.astype(np.int64), 0, self.u.size - 2)
        f = pos - i
        c0 = self.c0[i] + f * (self.c0[i + 1] - self.c0[i])
        c1 = self.c1[i] + 0.5 * (self.u[i] + u) * (c0 - self.c0[i])
        return c0, c1


def _lattice(source, max_knots=2_000_000):
    """``(lambda0, delta, values)`` of the source on a uniform grid holding all its knots
    (the same piecewise-linear function, exactly), or None if there is none small enough."""
    lam = source.wavelength_nm
    steps = np.diff(lam)
    delta = float(steps.min())
    ratio = steps / delta
    if np.max(np.abs(ratio - np.round(ratio))) > 1e-6:
        return None
    n = round((lam[-1] - lam[0]) / delta) + 1
    if n > max_knots:
        return None
    grid = lam[0] + np.arange(n) * delta
    return float(lam[0]), delta, np.interp(grid, lam, source.values)


def _signals_lattice(lattice, profile, moments, k_phase, q):
    """``P`` at the shifts ``(k * q + p) * delta / q`` for a source on a uniform lattice, by
    correlations: each filter position sees the same knot offsets, so the moments are looked
    up once per phase ``p``. ``k_phase`` maps each phase to its (k_min, k_max).

    Written by parts like ``_signals``: a flat source gives ``s * C0(end)`` for every shift,
    exactly (its differences and slopes are exact zeros).
    """
    lam0, delta, s = lattice
    d = delta / q
    lo, hi = moments.u[0], moments.u[-1]
    ds = np.diff(s)
    g = ds / delta  # slope of segment n (knots n, n + 1)
    out = {}
    for p, (k0, k1) in k_phase.items():
        base = profile.cwl_nm + p * d  # the filter's centre for k = 0
        v0 = lam0 - base  # offset of knot 0 from it
        m_lo = int(np.floor((lo - v0) / delta))
        m_hi = int(np.ceil((hi - v0) / delta))
        n_first, n_last = m_lo + k0, m_hi + k1  # knots needed over all k of this phase
        if n_first < 0 or n_last > s.size - 1:
            raise ValueError("the spectrum does not cover the band and its shifts")
        m = np.arange(m_lo, m_hi + 1)
        v = v0 + m * delta
        C0, C1 = moments.at(np.clip(v, lo, hi))
        nk = k1 - k0 + 1

        def corr(x, first, w, k0=k0, k1=k1, nk=nk):
            # sum_j x[first + k + j] w[j] for k = k0..k1
            return np.correlate(x[first + k0:first + k1 + w.size], w, mode="valid")[:nk]

        # segments m_lo..m_hi-1: n = m + k; interior knots m_lo+1..m_hi-1
        inner = slice(1, m.size - 1)
        # a_m = s[m+k] - g[m+k] v_m;  P = a_{m_hi-1} C0_{m_hi} - a_{m_lo} C0_{m_lo}
        #   - sum_{interior} C0_m (a_m - a_{m-1}) + sum_segments g[m+k] (C1_{m+1} - C1_m)
        last = m_hi - 1
        kk = np.arange(k0, k1 + 1)
        a_last = s[last + kk] - g[last + kk] * v[-2]
        a_first = s[m_lo + kk] - g[m_lo + kk] * v[0]
        P = a_last * C0[-1] - a_first * C0[0]
        if m.size > 2:
            # a_m - a_{m-1} = ds[m+k-1] - g[m+k] v_m + g[m+k-1] v_{m-1}
            P -= corr(ds, m_lo, C0[inner])
            P += corr(g, m_lo + 1, C0[inner] * v[inner])
            P -= corr(g, m_lo, C0[inner] * v[:-2])
        P += corr(g, m_lo, np.diff(C1))
        out[p] = P
    return out


def _signals_on_grid(source, profile, moments, j0, j1, d, lattice=False):
    """``P`` at the shifts ``j * d``, ``j = j0..j1``: by correlations where the source lies on
    a lattice whose step is a whole number of ``d`` (fast), else as ``_signals``.
    ``lattice``: ``_lattice(source)`` if already known."""
    js = np.arange(j0, j1 + 1)
    lat = _lattice(source) if lattice is False else lattice
    if lat is not None:
        q = round(lat[1] / d)
        if q > 16 and (lat[2].size - 1) * q < 2_000_000:
            # a coarse lattice: refine it to the shifts' step (the same function, exactly)
            lam0, delta, vals = lat
            n = (vals.size - 1) * q + 1
            fine = lam0 + np.arange(n) * d
            lat, q = (lam0, d, np.interp(fine, lam0 + np.arange(vals.size) * delta, vals)), 1
        if 1 <= q <= 16 and math.isclose(q * d, lat[1], rel_tol=1e-9):
            phases = {}
            for p in range(q):
                ks = (js[(js - p) % q == 0] - p) // q
                if ks.size:
                    phases[p] = (int(ks.min()), int(ks.max()))
            got = _signals_lattice(lat, profile, moments, phases, q)
            out = np.empty(js.size)
            for p, (k0, _) in phases.items():
                sel = (js - p) % q == 0
                out[sel] = got[p][(js[sel] - p) // q - k0]
            return out
    return _signals(source, profile, js * d, moments)


def _signals(source, profile, shifts, moments=None, chunk=256):
    """``P(cwl + shift) = int T(lambda - cwl - shift) S(lambda) dlambda`` for each shift,
    exact for the piecewise-linear source (each source segment against the profile's
    tabulated moments), so sharp edges in the source cost nothing extra.

    Summed by parts, ``P = sum_j C0(u_j) (a_{j-1} - a_j) + ...`` with ``a_j`` the segment's
    value at ``u = 0``: a flat source gives the same ``P`` for every shift, bit for bit.
    """
    m = _FilterMoments.of(profile) if moments is None else moments
    lo, hi = m.u[0], m.u[-1]
    lam, val = source.wavelength_nm, source.values
    shifts = np.asarray(shifts, float)
    out = np.empty(shifts.size)
    order = np.argsort(shifts, kind="stable")
    srt = shifts[order]
    for start in range(0, srt.size, chunk):
        d = srt[start:start + chunk]
        c = profile.cwl_nm + d  # the filter's centres
        need_lo, need_hi = c[0] + lo, c[-1] + hi
        if need_lo < lam[0] - 1e-9 or need_hi > lam[-1] + 1e-9:
            raise ValueError(f"the spectrum {source.name!r} covers {lam[0]:g}-{lam[-1]:g} nm; "
                             f"{need_lo:.4g}-{need_hi:.4g} nm is needed")
        i0 = max(int(np.searchsorted(lam, need_lo, "right")) - 1, 0)
        i1 = min(int(np.searchsorted(lam, need_hi, "left")) + 1, lam.size)
        kl, kv = lam[i0:i1], val[i0:i1]  # knots spanning every window of this chunk
        g = np.diff(kv) / np.diff(kl)  # segment slopes
        uk = kl[:, None] - c[None, :]  # knots in each filter's frame
        a = kv[:-1, None] - g[:, None] * uk[:-1]  # segment value at u = 0
        uc = np.clip(uk, lo, hi)
        C0, C1 = m.at(uc)
        # sum_j a_j (C0_{j+1} - C0_j) by parts, + sum_j g_j (C1_{j+1} - C1_j)
        p = a[-1] * C0[-1] - a[0] * C0[0]
        if a.shape[0] > 1:
            p -= np.sum(C0[1:-1] * (a[1:] - a[:-1]), axis=0)
        p += np.sum(g[:, None] * (C1[1:] - C1[:-1]), axis=0)
        out[order[start:start + chunk]] = p
    return out.reshape(shifts.shape)


def relative_signal(source, profile, shifts_nm):
    """``P(cwl + shift) / P(cwl)`` of a filter ``profile`` (at normal incidence) moved by each
    shift, for a ``source`` Spectrum: Flittner & Slater's P, as a ratio.

    The integral is exact for the piecewise-linear source (see ``_signals``); a flat source
    gives exactly 1 for any shift.
    """
    s = np.asarray(shifts_nm, float)
    if not np.all(np.isfinite(s)):
        raise ValueError("shifts must be finite")
    m = _FilterMoments.of(profile)
    p = _signals(source, profile, np.concatenate([[0.0], s.ravel()]), m)
    if not p[0] > 0:
        raise ValueError(f"the source {source.name!r} has no signal in the band at "
                         f"{profile.cwl_nm:g} nm")
    return (p[1:] / p[0]).reshape(s.shape)


def band_signal(source, profile, aoi_deg=0.0, *, step_nm=None):
    """``integral profile(lambda, aoi) * source(lambda) dlambda`` of a filter tilted by
    ``aoi_deg`` in collimated light (Mishev & Bakalova's ``I(theta)``; their Pi-shaped filter
    also widens and dims with the tilt). Trapezoid rule on a grid of ``step_nm`` (default: a
    200th of the FWHM, at most half the source's sampling)."""
    fwhm = float(profile.fwhm_nm)
    h = min(source.step_nm / 2, fwhm / 200) if step_nm is None else float(step_nm)
    out = []
    for a in np.atleast_1d(np.asarray(aoi_deg, float)):
        lo = profile.cwl_nm - 8 * fwhm / max(np.cos(np.deg2rad(2 * a)), 0.1) - 1.0
        lam = np.arange(lo, profile.cwl_nm + 8 * fwhm + 1.0, h)
        t = np.asarray(profile(lam, a), float)
        nz = np.flatnonzero(t > 0)
        lam = lam[max(nz[0] - 1, 0):nz[-1] + 2] if nz.size else lam[:2]
        out.append(np.trapezoid(np.asarray(profile(lam, a), float) * source(lam), lam))
    return np.asarray(out).reshape(np.shape(aoi_deg))


def shift_error(source, profile, shift_nm):
    """Flittner & Slater's ``ERROR(cwl, shift)`` as a fraction (x 100 for percent)."""
    return relative_signal(source, profile, shift_nm) - 1.0


def tolerance_ranges(source, cwl_nm, fwhm_nm, *, n_eff=1.7, profile="multi_lorentzian",
                     criteria=((1.0, 0.5), (5.0, 2.0)), search_nm=150.0, step_nm=0.1):
    """Flittner & Slater's Table 1: for each band, the range of centre positions around the
    nominal one where a shift of +-``shift`` nm changes the signal by less than ``limit_pct``.

    Centres are tried every ``step_nm`` (the shifts must be multiples of it) up to
    ``search_nm`` either side, and no further than the source reaches. Returns a list (one per
    band) of lists (one per criterion) of ``(lo, hi)`` in nm, or ``None`` where the nominal
    centre itself fails ("NA" in their table). A range that reaches the end of the search
    ends there.
    """
    validate_method(profile, PROFILES, "profile")
    cwl = np.atleast_1d(np.asarray(cwl_nm, float))
    fwhm = np.broadcast_to(np.asarray(fwhm_nm, float), cwl.shape)
    ms = []
    for shift, _ in criteria:
        m = round(shift / step_nm)
        if m < 1 or not math.isclose(m * step_nm, shift, rel_tol=1e-9):
            raise ValueError(f"a shift of {shift:g} nm is not a multiple of step_nm "
                             f"({step_nm:g} nm)")
        ms.append(m)
    m_max = max(ms)
    out = []
    for c, fw in zip(cwl, fwhm, strict=True):
        prof = PROFILES[profile](c, fw, n_eff)
        mom = _FilterMoments.of(prof)
        # centre offsets -kl..kh steps, with room for the largest shift inside the source
        room_lo = (c + mom.u[0] - source.wavelength_nm[0]) / step_nm - m_max
        room_hi = (source.wavelength_nm[-1] - c - mom.u[-1]) / step_nm - m_max
        kl = math.floor(min(search_nm / step_nm, room_lo) + 1e-9)
        kh = math.floor(min(search_nm / step_nm, room_hi) + 1e-9)
        if kl < 0 or kh < 0:
            raise ValueError(f"the source {source.name!r} does not cover the band at {c:g} nm "
                             "and its shifts")
        P = _signals_on_grid(source, prof, mom, -kl - m_max, kh + m_max, step_nm)
        idx = m_max + np.arange(kl + kh + 1)  # P[idx] at centre offsets -kl..kh
        row = []
        for m, (_, limit) in zip(ms, criteria, strict=True):
            base = P[idx]
            ok = ((np.abs(P[idx + m] / base - 1) < limit / 100)
                  & (np.abs(P[idx - m] / base - 1) < limit / 100))
            if not ok[kl]:
                row.append(None)
                continue
            bad_lo = np.flatnonzero(~ok[:kl])
            bad_hi = np.flatnonzero(~ok[kl:])
            lo = bad_lo[-1] + 1 if bad_lo.size else 0
            hi = kl + bad_hi[0] - 1 if bad_hi.size else ok.size - 1
            row.append((round(float(c + (lo - kl) * step_nm), 6),
                        round(float(c + (hi - kl) * step_nm), 6)))
        out.append(row)
    return out


@dataclass
class Budget:
    """The residual signal error of each correction model over band and chief-ray angle.

    ``data`` is an :class:`xarray.Dataset` with ``residual(model, band, cra)`` (fraction),
    ``mean_shift(model, band, cra)`` (nm), ``radius_mm(cra)`` and ``radius_px(cra)`` (image
    radius of each CRA) and the set-up in attrs.
    """

    data: xr.Dataset
    tolerance_pct: float = 0.5

    def __post_init__(self):
        self.tolerance_pct = check_positive("tolerance_pct", self.tolerance_pct)

    def _tol(self, tolerance_pct):
        if tolerance_pct is None:
            return self.tolerance_pct
        return check_positive("tolerance_pct", tolerance_pct)

    @property
    def models(self):
        return tuple(str(m) for m in self.data["model"].values)

    def worst_pct(self, model):
        """Largest |residual| over bands and the field, percent (infinite where the model
        could not be evaluated: ``harmonised`` where the widened band reaches past the
        source's end)."""
        res = np.abs(self.data["residual"].sel(model=model).values)
        return math.inf if np.isnan(res).any() else float(res.max()) * 100

    def recommend(self, tolerance_pct=None):
        """``(model, reason)``: the cheapest model whose residual stays below the tolerance
        everywhere on the field; the best model when none does."""
        tol = self._tol(tolerance_pct)
        worst = {m: self.worst_pct(m) for m in self.models}
        src = self.data.attrs["source"]
        for i, m in enumerate(self.models):
            if worst[m] <= tol:
                cheaper = ", ".join(f"{c} {worst[c]:.2g} %" for c in self.models[:i])
                return m, (f"for {src}: {m} leaves at most {worst[m]:.2g} % <= {tol:g} %"
                           + (f" (cheaper: {cheaper})" if cheaper else ""))
        best = min(worst, key=worst.get)
        return best, (f"for {src}: no model is within {tol:g} %; {best} leaves the least, "
                      f"{worst[best]:.2g} % (the kernel also changes the filter's shape, "
                      "which no shift of the wavelengths undoes)")

    def radius_mm(self, tolerance_pct=None, model="none", *, relative_to="nominal"):
        """Mishev & Bakalova's radius: the image radius (mm) inside which ``model`` leaves no
        band's signal off by more than the tolerance.

        ``relative_to="nominal"`` compares each pixel with the filter at its nominal place
        (the error of the model); ``"centre"`` with the pixel on the optical axis, as Mishev
        & Bakalova normalise their frames (what a flat field taken on axis would not
        remove). Returns ``inf`` when the tolerance holds over the whole field of the budget,
        0 when it fails on the axis already.
        """
        validate_method(relative_to, ("nominal", "centre"), "relative_to")
        tol = self._tol(tolerance_pct) / 100
        res = self.data["residual"].sel(model=model).values  # (band, cra)
        if relative_to == "centre":
            res = (1.0 + res) / (1.0 + res[:, :1]) - 1.0
        err = np.abs(res).max(axis=0)
        r = self.data["radius_mm"].values
        over = np.flatnonzero(err > tol)
        if over.size == 0:
            return math.inf
        i = over[0]
        if i == 0:
            return 0.0
        # linear between the last grid point inside and the first outside
        f = (tol - err[i - 1]) / (err[i] - err[i - 1])
        return float(r[i - 1] + f * (r[i] - r[i - 1]))

    def pixel_residual(self, cra_deg, model="none"):
        """Residual (fraction) of every pixel and band: the table interpolated at each
        pixel's CRA; ``cra_deg`` of shape (y, x) or (y, x, band)."""
        cra = np.asarray(cra_deg, float)
        grid = self.data["cra"].values
        if cra.size and (cra.min() < grid[0] - 1e-9 or cra.max() > grid[-1] + 1e-9):
            raise ValueError(f"CRAs {cra.min():.3g}-{cra.max():.3g} deg leave the budget's "
                             f"{grid[0]:.3g}-{grid[-1]:.3g} deg")
        table = self.data["residual"].sel(model=model).values  # (band, cra)
        nb = table.shape[0]
        if cra.ndim == 3 and cra.shape[2] == 1:  # one position per pixel (Snapscan)
            cra = cra[:, :, 0]
        if cra.ndim == 2:
            cra = np.broadcast_to(cra[:, :, None], (*cra.shape, nb))
        if cra.ndim != 3 or cra.shape[2] != nb:
            raise ValueError(f"cra_deg must have shape (y, x), (y, x, 1) or (y, x, {nb}), "
                             f"got {cra.shape}")
        out = np.empty(cra.shape)
        for b in range(nb):
            out[:, :, b] = np.interp(cra[:, :, b], grid, table[b])
        return xr.DataArray(out, dims=("y", "x", "band"),
                            attrs={"units": "1", "long_name": f"residual after {model}"})

    def table(self):
        """A plain-text table: per band, the worst residual of each model (percent)."""
        d = self.data
        head = f"{'band':>4} {'cwl nm':>8} " + " ".join(f"{m:>11}" for m in self.models)
        lines = [head]
        res = np.abs(d["residual"]).max("cra") * 100
        for b in range(d.sizes["band"]):
            lines.append(f"{b:>4} {float(d['wavelength'][b]):>8.2f} " + " ".join(
                f"{float(res.sel(model=m)[b]):>10.3g}%" for m in self.models))
        lines.append(f"{'all':>4} {'':>8} " + " ".join(
            f"{self.worst_pct(m):>10.3g}%" for m in self.models))
        return "\n".join(lines)

    def plot(self, path=None, tolerance_pct=None, *, overwrite=False, inputs=()):
        """Worst residual against band and against image radius, for each model.

        Without ``path`` the figure is made with pyplot (shown inline in a notebook). With
        ``path`` it is written atomically as PNG without touching pyplot's state; an existing
        file is replaced only with ``overwrite``, and never one of ``inputs``.
        """
        tol = self._tol(tolerance_pct)
        path = None if path is None else Path(path)
        if path is not None and path.exists() and not overwrite:
            raise ValueError(f"{path} exists; use overwrite=True (--overwrite) to replace it")
        if path is None:
            import matplotlib.pyplot as plt

            fig = plt.figure(figsize=(12, 4.5), layout="constrained")
        else:
            from matplotlib.figure import Figure

            fig = Figure(figsize=(12, 4.5), layout="constrained")
        a, b = fig.subplots(1, 2)
        d = self.data
        for k, m in enumerate(self.models):
            r = np.abs(d["residual"].sel(model=m)) * 100
            a.semilogy(d["wavelength"], np.maximum(r.max("cra"), 1e-6), color=f"C{k}",
                       label=m)
            b.semilogy(d["radius_mm"], np.maximum(r.max("band"), 1e-6), color=f"C{k}",
                       label=m)
        for ax in (a, b):
            ax.axhline(tol, color="k", ls=":", lw=0.8, label=f"tolerance {tol:g} %")
            ax.set_ylabel("|signal error| (%)")
            ax.grid(alpha=0.3)
        rad = self.radius_mm(tol)
        if math.isinf(rad):
            label = "uncorrected within tolerance over the whole field"
        elif rad > 0:
            label = f"uncorrected within tolerance: r < {rad:.2f} mm"
        else:
            label = "uncorrected: over the tolerance even on axis"
        b.axvline(min(rad, float(d["radius_mm"][-1])), color="C0", ls="--", lw=0.8,
                  label=label)
        a.set(xlabel="band centre (nm)", title="worst over the field")
        b.set(xlabel="image radius (mm)", title="worst over the bands")
        b.legend(fontsize=8)
        fig.suptitle(f"Signal error from the filter shift: {d.attrs['source']}, "
                     f"{d.attrs['lens']} at f/{d.attrs['f_number']:g}")
        if path is not None:
            from ._io import atomic_write

            atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"),
                         inputs=[i for i in inputs if i is not None])
        return fig


def scene_budget(sensor, lens: Lens, f_number, source, *, cra_max_deg, profile="multi_lorentzian",
                 n_cra=33, models=MODELS, tolerance_pct=0.5, kernel_step_nm=0.05,
                 shift_step_nm=0.02):
    """The residual of each correction model for every band of ``sensor`` over CRA
    0..``cra_max_deg`` behind ``lens`` at ``f_number``, for the ``source`` spectrum.

    Each band's filter is ``profile`` (``"multi_lorentzian"``, Flittner & Slater's; ``"pi"``,
    Mishev & Bakalova's rectangle) of the sensor's FWHM, moved and smeared by the kernel (the
    widening and dimming Mishev & Bakalova add for a tilted filter is :func:`band_signal`'s).
    The pixel's signal is the full kernel response (Goossens Eq. 13,
    :func:`~snapcorr.optics.response.kernel_bins`); each model's
    residual is that signal over the signal of the filter placed at the model's mean shift,
    minus 1.

    Returns
    -------
    Budget
    """
    validate_method(profile, PROFILES, "profile")
    for m in models:
        validate_method(m, MODELS, "model")
    # in order of cost, for recommend(); "none" always (the reference of radius_mm and plot)
    models = tuple(m for m in MODELS if m in models or m == "none")
    tolerance_pct = check_positive("tolerance_pct", tolerance_pct)
    if int(n_cra) < 2:
        raise ValueError(f"n_cra must be >= 2 (the axis and the field's edge), got {n_cra!r}")
    f = check_positive("f_number", f_number)
    cra_max = float(cra_max_deg)
    cutoff = float(lens.cutoff_cra_deg(f))
    if not (math.isfinite(cra_max) and 0 <= cra_max < cutoff):
        raise ValueError(f"cra_max_deg must lie in [0, {cutoff:.2f}) deg (the lens's full "
                         f"cut-off at f/{f:g}), got {cra_max_deg!r}")
    cwl = np.asarray(sensor.cwl_nm, float)
    fwhm = np.asarray(sensor.fwhm_nm, float)
    n_eff = np.asarray(sensor.n_eff, float)
    cra = np.linspace(0.0, cra_max, int(n_cra))
    ref = float(cwl.max())
    # The kernel in wavelength scales exactly with the filter's centre (Eq. 3): bins are built
    # once per (n_eff, CRA) at the largest centre and scaled to each band.
    # Likewise each model's mean shift (one curve over CRA per n_eff, scaled to each band) and
    # the kernel's bins (once per n_eff and CRA, at the largest centre).
    bins, per_model = {}, {}
    for n in np.unique(n_eff):
        bins[n] = [kernel_bins(ref, n, f, c, lens, step_nm=kernel_step_nm) for c in cra]
        per_model[n] = {m: (np.zeros(cra.size) if m == "none" else np.asarray(
            mean_shift(ref, n, f, cra, lens, method="vignetted" if m == "harmonised" else m),
            float)) for m in models}
    lat = _lattice(source)
    d = shift_step_nm if lat is None else lat[1] / math.ceil(lat[1] / shift_step_nm - 1e-9)
    nb = cwl.size
    residual = np.empty((len(models), nb, cra.size))
    shifts = np.empty((len(models), nb, cra.size))
    harmonised = "harmonised" in models
    if harmonised:  # each pixel widened to the widest response of its band in the field
        from .optics.bandwidth import response_fwhm

        width = response_fwhm(cwl, fwhm, n_eff, f, cra, lens, profile=profile)
        var = np.clip(np.nanmax(width, axis=1, keepdims=True) ** 2 - width**2, 0, None) / (
            8 * math.log(2))
        widest = np.nanargmax(width, axis=1)
        gh_x, gh_w = np.polynomial.hermite_e.hermegauss(_HERMITE_NODES)
        gh_w = gh_w / gh_w.sum()
    for b in range(nb):
        prof = PROFILES[profile](cwl[b], fwhm[b], n_eff[b])
        scale = cwl[b] / ref
        mus = [mu * scale for mu, _ in bins[n_eff[b]]]
        means = [per_model[n_eff[b]][m] * scale for m in models]
        # every shift this band needs: P on a fine grid of shifts (0 among them, as "none"
        # asks for it), in one pass over the source, then interpolated (exactly 1 for a flat
        # source)
        if harmonised:  # the kernel's points, recentred and spread by the Gaussian's nodes
            sig = np.sqrt(var[b])
            m_h = means[models.index("harmonised")]
            spread = [((mu - m_h[i])[:, None] + sig[i] * gh_x[None, :]).ravel()
                      for i, mu in enumerate(mus)]
        else:
            spread = []
        allshift = np.concatenate(mus + means + spread)
        try:
            j0 = int(np.floor(allshift.min() / d)) - 1
            j1 = int(np.ceil(allshift.max() / d)) + 1
            p = _signals_on_grid(source, prof, _FilterMoments.of(prof), j0, j1, d,
                                 lattice=lat)
        except ValueError:
            if not spread:
                raise
            # the widened band reaches past the source's end: no harmonised figure here
            spread = []
            allshift = np.concatenate(mus + means)
            j0 = int(np.floor(allshift.min() / d)) - 1
            j1 = int(np.ceil(allshift.max() / d)) + 1
            p = _signals_on_grid(source, prof, _FilterMoments.of(prof), j0, j1, d,
                                 lattice=lat)
        grid = np.arange(j0, j1 + 1) * d
        p0 = p[-j0]  # the shift 0
        if not p0 > 0:
            raise ValueError(f"the source {source.name!r} has no signal in the band at "
                             f"{cwl[b]:g} nm")
        r = np.interp(allshift, grid, p / p0)
        pos, pixel = 0, np.empty(cra.size)
        for i, (_, w) in enumerate(bins[n_eff[b]]):
            rk = r[pos:pos + w.size]
            pixel[i] = np.sum(w * rk) / np.sum(w)  # exactly 1 where every rk is 1
            pos += w.size
        for k in range(len(models)):
            rm = r[pos:pos + cra.size]
            pos += cra.size
            residual[k, b] = pixel / rm - 1.0
            shifts[k, b] = means[k]
        if harmonised and not spread:
            residual[models.index("harmonised"), b] = np.nan
        elif harmonised:
            # the harmonised value: the pixel's response, recentred on the nominal wavelength
            # and widened, against the common response (the widest pixel's, recentred)
            h = np.empty(cra.size)
            for i, (_, w) in enumerate(bins[n_eff[b]]):
                rk = r[pos:pos + w.size * gh_x.size].reshape(w.size, gh_x.size)
                # normalised by the same sums of ones: exactly 1 where every rk is 1
                h[i] = np.sum(w * (rk @ gh_w)) / np.sum(w * (np.ones_like(rk) @ gh_w))
                pos += w.size * gh_x.size
            residual[models.index("harmonised"), b] = h / h[widest[b]] - 1.0
    x = lens.exit_pupil_mm
    radius = x * np.tan(np.deg2rad(cra))
    ds = xr.Dataset(
        {"residual": (("model", "band", "cra"), residual,
                      {"units": "1", "long_name": "signal error left by the model"}),
         "mean_shift": (("model", "band", "cra"), shifts, {"units": "nm"}),
         "radius_mm": ("cra", radius, {"units": "mm", "long_name": "image radius"}),
         "radius_px": ("cra", radius / sensor.pixel_pitch_mm, {"units": "px"})},
        coords={"model": list(models), "cra": ("cra", cra, {"units": "deg"}),
                "wavelength": ("band", cwl, {"units": "nm"})},
        attrs={"source": source.name, "lens": lens.name, "f_number": f,
               "sensor": sensor.name, "profile": profile, "kernel_step_nm": kernel_step_nm},
    )
    return Budget(ds, tolerance_pct=tolerance_pct)
