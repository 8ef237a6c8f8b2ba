"""Integrating-sphere flat fields of a lens with 0-3 projected vignetting circles.

An independent simulator for judging lens calibration: it shares no code with ``snapcorr``
(it must not import it), so a mistake in the package's pupil geometry cannot hide itself.

Model (Goossens et al. 2019, Sec. 2.4, Eq. 8-9, 27-28, 33): the optical axis meets the sensor
at ``center_px`` (pixel (row i, column j) is centred at x = j, y = i); a pixel at ``rho`` mm
from the axis has ``tan(CRA) = rho / x`` with ``x`` the exit-pupil distance (Eq. 8). In the
exit-pupil plane, along the pixel's radial line, the exit pupil is a disc of radius
``R = x / (2 f_W)`` (Eq. 28) with ``f_W = (1 + m / m_P) f`` (Eq. 27) centred at 0, and circle
``i`` is a disc of radius ``P_i`` centred at ``h_i tan(CRA)`` (Eq. 9; ``h = x`` is pixel
vignetting, ``h < 0`` moves the other way). Light reaching the pixel is proportional to the
area common to all discs (Eq. 33 for one circle), times ``cos^4(CRA)``, times an optional
smooth source non-uniformity, times an exposure scale of each f-number.

The common area is computed here by Gauss-Legendre quadrature of the smallest half-chord
along the radial line, split at every pairwise crossing of the half-chords, with a cosine
change of variable on every piece that removes the square-root end-point singularities; it is
tabulated over ``tan(CRA)`` and interpolated to the pixels (the area depends on the radius
only). The mean filter shift over the vignetted pupil (Goossens 2019, Eq. 3 and 22) is given
by the same quadrature in two dimensions, for judging a calibrated lens against the truth.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "DEFAULT_F_NUMBERS",
    "LensTruth",
    "common_area_mm2",
    "cra_map_deg",
    "make_flats",
    "mean_shift_nm",
    "relative_illumination",
    "shot_noise_frames",
    "tile_gains",
]

#: The user's five f-numbers.
DEFAULT_F_NUMBERS = (2.0, 2.8, 4.0, 5.6, 11.0)

_NODES = 24
_GL_X, _GL_W = np.polynomial.legendre.leggauss(_NODES)


@dataclass(frozen=True)
class LensTruth:
    """The true lens: exit-pupil distance x, vignetting circles (P, h), m and m_P (mm)."""

    exit_pupil_mm: float
    circles: tuple = ()
    magnification: float = 0.0
    pupil_magnification: float = 1.0
    name: str = "truth"
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        circles = tuple((float(P), float(h)) for P, h in self.circles)
        if len(circles) > 3:
            raise ValueError("at most three vignetting circles")
        if any(P <= 0 for P, _ in circles):
            raise ValueError("circle radii must be > 0")
        object.__setattr__(self, "circles", circles)

    def working_f_number(self, f_number):
        return (1.0 + self.magnification / self.pupil_magnification) * np.asarray(f_number, float)

    def pupil_radius_mm(self, f_number):
        """R = x / (2 f_W), Eq. 27-28."""
        return self.exit_pupil_mm / (2.0 * self.working_f_number(f_number))

    def onset_tan(self, f_number):
        """tan(CRA) where each circle starts to cut the pupil (0 if it cuts on axis, inf never)."""
        R = float(self.pupil_radius_mm(f_number))
        out = []
        for P, h in self.circles:
            if P <= R:
                out.append(0.0)
            elif h == 0:
                out.append(np.inf)
            else:
                out.append((P - R) / abs(h))
        return out


def common_area_mm2(radii, centers):
    """Area common to discs centred on one line (the radial line), mm^2.

    ``radii`` and ``centres``: sequences with one entry per disc, each a scalar or an array
    (broadcast together). Gauss-Legendre quadrature of ``2 min_k sqrt(r_k^2 - (u - c_k)^2)``
    over ``u`` between the innermost disc edges, split at the points where two half-chords are
    equal, each piece mapped by ``u = a + (b - a)(1 - cos s) / 2`` so that the square-root ends
    become smooth.
    """
    arrs = np.broadcast_arrays(*[np.asarray(v, float) for v in (*radii, *centers)])
    k = len(radii)
    r = np.stack(arrs[:k])  # (k, ...)
    c = np.stack(arrs[k:])
    lo = np.max(c - r, axis=0)
    hi = np.min(c + r, axis=0)
    empty = hi <= lo
    hi_s = np.where(empty, lo, hi)
    pts = [lo, hi_s]
    for i in range(k):
        for j in range(i + 1, k):
            with np.errstate(divide="ignore", invalid="ignore"):
                u = (r[i] ** 2 - r[j] ** 2 + c[j] ** 2 - c[i] ** 2) / (2.0 * (c[j] - c[i]))
            u = np.where(np.isfinite(u), u, lo)
            pts.append(np.clip(u, lo, hi_s))
    pts = np.sort(np.stack(pts), axis=0)  # (n_pts, ...)
    s = (_GL_X + 1.0) * (np.pi / 2.0)  # nodes on [0, pi]
    ws = _GL_W * (np.pi / 2.0)
    total = np.zeros(lo.shape)
    for a, b in itertools.pairwise(pts):
        L = b - a
        u = a[..., None] + L[..., None] * (1.0 - np.cos(s)) / 2.0  # (..., nodes)
        du = L[..., None] * np.sin(s) / 2.0
        half = np.full(u.shape, np.inf)
        for q in range(k):
            rad = r[q][..., None] ** 2 - (u - c[q][..., None]) ** 2
            half = np.minimum(half, np.sqrt(np.clip(rad, 0.0, None)))
        total += np.sum(2.0 * half * du * ws, axis=-1)
    return np.where(empty, 0.0, total)[()]


def _discs(truth, f_number, tan_cra):
    t = np.asarray(tan_cra, float)
    R = float(truth.pupil_radius_mm(f_number))
    radii = [R] + [P for P, _ in truth.circles]
    centers = [np.zeros_like(t)] + [h * t for _, h in truth.circles]
    return R, radii, centers


def relative_illumination(truth, f_number, tan_cra):
    """Fraction of the exit pupil (radius R_F) left by all the circles, at these tan(CRA)."""
    R, radii, centers = _discs(truth, f_number, tan_cra)
    return common_area_mm2(radii, centers) / (np.pi * R * R)


def cra_map_deg(shape, pitch_um, center_px, exit_pupil_mm):
    """Chief-ray angle of every pixel, degrees (also returns tan(CRA))."""
    cx, cy = center_px
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    rho_mm = np.hypot(xx - cx, yy - cy) * pitch_um * 1e-3
    tan = rho_mm / exit_pupil_mm
    return np.rad2deg(np.arctan(tan)), tan


def _source(shape, amplitude, rng):
    """Smooth low-order source non-uniformity, 1 +- amplitude, the same for every f-number."""
    if not amplitude:
        return 1.0
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    u = 2 * xx / max(shape[1] - 1, 1) - 1
    v = 2 * yy / max(shape[0] - 1, 1) - 1
    a = rng.uniform(-1, 1, 5)
    s = a[0] * u + a[1] * v + a[2] * u * v + a[3] * (u * u - 1 / 3) + a[4] * (v * v - 1 / 3)
    return 1.0 + amplitude * s / max(np.abs(s).max(), 1e-12)


def make_flats(truth, f_numbers=DEFAULT_F_NUMBERS, shape=(1024, 1280), pitch_um=5.5,
               center_px=(700.0, 480.0), noise=0.005, seed=0, *, level_dn=45000.0,
               exposure_spread=0.2, dark_dn=0.0, source_amplitude=0.0, natural=True,
               poisson_gain=None, integer=True, saturation_dn=65535.0, n_table=4096,
               return_truth_maps=False):
    """Integrating-sphere flats, f-number -> 2-D float array (DN).

    Signal of a pixel: ``level_dn * e_F * (R_F / R_min)^2 * A_F(CRA) * cos^4(CRA) * S(pixel)``
    with ``A_F`` the relative illumination (common area over ``pi R_F^2``), ``R_min`` the pupil
    radius of the fastest f-number (so the fastest is ``level_dn`` on axis, slower ones darker:
    proportional to the common area), ``e_F`` an exposure scale drawn uniformly in
    ``1 +- exposure_spread`` per f-number, ``S`` a smooth source non-uniformity (amplitude
    ``source_amplitude``) common to all f-numbers. Then Gaussian noise of ``noise`` times the
    local signal (and, with ``poisson_gain`` electrons/DN, Poisson shot noise in addition),
    ``dark_dn`` added, rounding to integers, clipping at 0 and ``saturation_dn``.

    Deterministic for a given ``seed``. With ``return_truth_maps`` also returns the noiseless
    signals (without dark) and the exposure scales.
    """
    rng = np.random.default_rng(seed)
    fs = [float(f) for f in f_numbers]
    cra, tan = cra_map_deg(shape, pitch_um, center_px, truth.exit_pupil_mm)
    t_tab = np.linspace(0.0, float(tan.max()) * (1 + 1e-9) + 1e-12, n_table)
    cos4 = np.cos(np.deg2rad(cra)) ** 4 if natural else 1.0
    src = _source(shape, source_amplitude, rng)
    R_min = float(truth.pupil_radius_mm(min(fs)))
    exposures = {f: 1.0 + exposure_spread * rng.uniform(-1, 1) for f in fs}
    flats, clean = {}, {}
    for f in fs:
        R = float(truth.pupil_radius_mm(f))
        a_tab = relative_illumination(truth, f, t_tab)
        area = np.interp(tan, t_tab, a_tab)
        sig = level_dn * exposures[f] * (R / R_min) ** 2 * area * cos4 * src
        img = sig + noise * sig * rng.standard_normal(shape)
        if poisson_gain:
            img = img + (rng.poisson(np.clip(sig, 0, None) * poisson_gain) / poisson_gain - sig)
        img = img + dark_dn
        if integer:
            img = np.rint(img)
        img = np.clip(img, 0.0, saturation_dn if saturation_dn else np.inf)
        flats[f] = img
        clean[f] = sig
    if return_truth_maps:
        return flats, clean, exposures
    return flats


def mean_shift_nm(truth, cwl_nm, n_eff, f_number, cra_deg, nodes=32):
    """Mean filter shift over the vignetted exit pupil, nm (negative), Goossens 2019 Eq. 3, 22.

    Each point of the pupil plane at lateral distance ``r`` from the pixel's foot
    (``d = x tan(CRA)`` on the radial line, Eq. 8) sends a ray at ``tan(phi) = r / x``, shifted
    by ``cwl (sqrt(1 - sin^2(phi) / n^2) - 1)``; the mean is the area average over the discs'
    common region. Two-dimensional Gauss-Legendre: pieces along ``u`` as in
    :func:`common_area_mm2`, and across the chord ``v`` with the same cosine mapping.
    """
    cras = np.atleast_1d(np.asarray(cra_deg, float))
    x = truth.exit_pupil_mm
    gx, gw = np.polynomial.legendre.leggauss(nodes)
    s = (gx + 1.0) * (np.pi / 2.0)
    ws = gw * (np.pi / 2.0)
    out = np.full(cras.shape, np.nan)
    for n_i, cra in enumerate(cras):
        t = np.tan(np.deg2rad(abs(cra)))
        _, radii, centers = _discs(truth, f_number, t)
        r = np.array(radii, float)
        c = np.array([float(v) for v in centers])
        lo, hi = np.max(c - r), np.min(c + r)
        if hi <= lo:
            continue
        pts = [lo, hi]
        for i in range(len(r)):
            for j in range(i + 1, len(r)):
                if c[j] != c[i]:
                    u = (r[i] ** 2 - r[j] ** 2 + c[j] ** 2 - c[i] ** 2) / (2.0 * (c[j] - c[i]))
                    pts.append(min(max(u, lo), hi))
        pts = np.sort(pts)
        d = x * t
        num = den = 0.0
        for a, b in itertools.pairwise(pts):
            if b <= a:
                continue
            u = a + (b - a) * (1.0 - np.cos(s)) / 2.0
            du = (b - a) * np.sin(s) / 2.0 * ws
            half = np.min(np.sqrt(np.clip(r[:, None] ** 2 - (u[None] - c[:, None]) ** 2, 0,
                                          None)), axis=0)
            # across the chord: v = half * cos(s') for s' in [0, pi], dv = half sin(s') ds'
            v = half[:, None] * np.cos(s)[None, :]
            dv = half[:, None] * np.sin(s)[None, :] * ws[None, :]
            r2 = (u[:, None] - d) ** 2 + v**2
            sin2 = r2 / (r2 + x * x)
            shift = -cwl_nm * (1.0 - np.sqrt(1.0 - sin2 / n_eff**2))
            num += np.sum(du[:, None] * dv * shift)
            den += np.sum(du[:, None] * dv)
        out[n_i] = num / den
    return out if np.ndim(cra_deg) else float(out[0])


def tile_gains(shape, gains, origin_rc=(0, 0), filter_area=None, unfiltered_gain=1.0):
    """Gain of every pixel of a raw frame of a snapshot mosaic.

    ``gains``: (tile rows, tile cols), the gain of each place in the tile, the tile grid
    starting at the filter area's corner (the sensor's (0, 0) without one). The frame's first
    pixel is at sensor row and column ``origin_rc``; pixels outside ``filter_area`` (row,
    column, rows, columns on the sensor) carry no filter and have ``unfiltered_gain``.
    """
    g = np.asarray(gains, float)
    rows = origin_rc[0] + np.arange(shape[0])[:, None]
    cols = origin_rc[1] + np.arange(shape[1])[None, :]
    r0, c0 = (0, 0) if filter_area is None else filter_area[:2]
    out = g[(rows - r0) % g.shape[0], (cols - c0) % g.shape[1]]
    if filter_area is not None:
        ar, ac, an, am = filter_area
        inside = (rows >= ar) & (rows < ar + an) & (cols >= ac) & (cols < ac + am)
        out = np.where(inside, out, unfiltered_gain)
    return out


def shot_noise_frames(light, gain, electrons_per_dn=2.0, read_dn=3.0, seed=7):
    """Frames of ``light`` (f-number -> noiseless DN at gain 1, e.g. ``make_flats(...,
    return_truth_maps=True)``) times ``gain`` (an array or 1): Poisson shot noise of the
    electrons, Gaussian read noise, whole DN."""
    rng = np.random.default_rng(seed)
    return {f: np.rint(rng.poisson(np.clip(img * gain, 0, None) * electrons_per_dn)
                       / electrons_per_dn + read_dn * rng.standard_normal(np.shape(img)))
            for f, img in light.items()}
