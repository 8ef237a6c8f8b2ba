"""A textured scene placed on a mosaic sensor behind a lens, every pixel through its own
responses: the raw flat-fielded frame, the true bands and the true Gaussian virtual bands.

An independent simulator (it does not import snapcorr). The scene is ``msfasim.abundances``
(a smooth blend, disks and bars with sharp edges, fine stripes and a checkerboard of 1-3 px
cells, blurred by 0.6 px) of reflectances the virtual bands' prior was not fitted to
(PROSPECT-D leaves, prosail's soils and their mixtures, ``mosaicsim``), with smooth shading.
It is laid on the sensor at a given corner; each pixel's chief-ray angle is its distance from
the optical centre over the exit-pupil distance, ``tan CRA = d / x`` (the sensor's centre is the
optical centre), and its band's response is the pupil-weighted sum over the vignetted exit
pupil of the whole measured curve scaled by each ray, ``T_b(lambda / a)``,
``a = sqrt(1 - sin^2 phi / n_eff^2)``, times the band-pass (``mosaicsim.responses``; computed
here at chief-ray angles ``CRA_STEP_DEG`` apart or closer, linearly interpolated between). A pixel
keeps only the band its tile puts there, plus Gaussian noise; the flat-fielded value is the
response-weighted mean of the reflectance (equal-energy light). The truth of a virtual band is
the unit-peak Gaussian's weighted mean of the same reflectance at the same pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import mosaicsim as ms
import msfasim
import numpy as np
from spectralsim import pupil_samples

#: Chief-ray angle step (deg) of the exact responses; pixels between are interpolated
#: linearly (the shift is smooth in the angle: 0.25 deg steps leave under 0.001 nm at 17 deg).
CRA_STEP_DEG = 0.25


@dataclass(frozen=True)
class Camera:
    """A mosaic sensor behind a lens: what the simulator needs, nothing of snapcorr."""

    grid: np.ndarray  # (n,) nm
    curves: np.ndarray  # (bands, n): measured, without the band-pass
    bandpass: np.ndarray  # (n,)
    band_at: np.ndarray  # (tile rows, tile cols): band index at (row - r0) % n, (col - c0) % m
    tile_origin: tuple  # sensor (row, col) where the tile grid starts
    size_px: tuple  # sensor (rows, cols)
    pitch_um: float
    lens: object  # flatsim.LensTruth
    f_number: float
    n_eff: float
    virtual_nm: np.ndarray  # the virtual bands' centres
    virtual_fwhm_nm: np.ndarray  # and widths

    def cra_deg(self, rows, cols):
        """Chief-ray angle of sensor pixels, degrees (optical centre at the sensor's centre)."""
        cy, cx = (self.size_px[0] - 1) / 2, (self.size_px[1] - 1) / 2
        d_mm = np.hypot(np.asarray(rows, float) - cy, np.asarray(cols, float) - cx)
        return np.degrees(np.arctan(d_mm * self.pitch_um * 1e-3 / self.lens.exit_pupil_mm))


def responses(cam: Camera, cra_deg, nodes=(48, 24)):
    """Every band's response at chief-ray angle ``cra_deg``: ``mosaicsim.responses``'s model
    (``S sum_j w_j T_b(lambda / a_j)``), its interpolation done for all bands at once."""
    d = cam.lens.exit_pupil_mm * np.tan(np.deg2rad(cra_deg))
    u, v, w = pupil_samples(cam.lens, cam.f_number, d, theta_nodes=nodes[0], r_nodes=nodes[1])
    t2 = ((u - d) ** 2 + v**2) / cam.lens.exit_pupil_mm**2
    a = np.sqrt(1.0 - t2 / (1.0 + t2) / cam.n_eff**2)
    g = cam.grid
    x = g[None, :] / a[:, None]  # (rays, n): where each ray reads every curve
    j = np.clip(np.searchsorted(g, x) - 1, 0, g.size - 2)
    t = (x - g[j]) / (g[j + 1] - g[j])
    wk = np.where((x >= g[0]) & (x <= g[-1]), (w / w.sum())[:, None], 0.0)
    at = np.arange(g.size)[None, :] * g.size + j  # M[row, j]: response = curves @ M.T
    M = (np.bincount(at.ravel(), (wk * (1 - t)).ravel(), g.size**2)
         + np.bincount((at + 1).ravel(), (wk * t).ravel(), g.size**2)).reshape(g.size, g.size)
    return (cam.curves @ M.T) * cam.bandpass


def gaussians(cam: Camera):
    """The virtual bands' unit-peak Gaussians on the grid, ``(virtual, n)``."""
    u = (cam.grid[None] - cam.virtual_nm[:, None]) / cam.virtual_fwhm_nm[:, None]
    return np.exp(-4 * np.log(2) * u**2)


def scene_spectra(k, seed):
    """``k`` reflectances (400-1000 nm, 1 nm) the prior was not fitted to: PROSPECT-D leaves,
    prosail's soils and their mixtures."""
    half = (k + 1) // 2
    return np.concatenate([ms.leaves(half, seed), ms.soils_and_mixtures(k - half, seed + 7)])


@dataclass(frozen=True)
class Placed:
    """A scene on the sensor: ``raw`` (rows, cols) flat-fielded values with noise, ``bands``
    (rows, cols, bands) the true value of every band at every pixel, ``virtual`` (rows, cols,
    virtual) the true Gaussian virtual bands, ``cra_deg`` (rows, cols), ``origin`` the sensor
    (row, col) of the first pixel."""

    raw: np.ndarray
    bands: np.ndarray
    virtual: np.ndarray
    cra_deg: np.ndarray
    origin: tuple


def place(cam: Camera, weights, spectra, shade, origin, noise, seed, nodes=(48, 24)):
    """The scene of abundances ``weights`` (rows, cols, k) of ``spectra`` (k, n), times
    ``shade`` (rows, cols), with its first pixel at sensor ``origin`` (row, col).

    Parameters
    ----------
    cam : Camera
    weights : ndarray, shape (rows, cols, k)
    spectra : ndarray, shape (k, n)
    shade : ndarray, shape (rows, cols)
    origin : (int, int)
    noise : float
        Standard deviation of the flat-fielded values' Gaussian noise.
    seed : int
    nodes : (int, int)
        Pupil quadrature nodes (angular, radial).

    Returns
    -------
    Placed
    """
    rows, cols, _ = weights.shape
    r = origin[0] + np.arange(rows)
    c = origin[1] + np.arange(cols)
    cra = cam.cra_deg(r[:, None], c[None, :])
    lo, hi = float(cra.min()), float(cra.max())
    knots = np.linspace(lo, hi, max(2, int(np.ceil((hi - lo) / CRA_STEP_DEG)) + 1))
    per = np.stack([ms.band_values(responses(cam, k, nodes), spectra) for k in knots])
    # (knot, k, bands): each spectrum's band values at the knot, interpolated per pixel
    i = np.clip(np.searchsorted(knots, cra) - 1, 0, knots.size - 2)
    t = ((cra - knots[i]) / (knots[i + 1] - knots[i]))[..., None]
    lo_v = np.einsum("yxk,yxkb->yxb", weights, per[i])
    hi_v = np.einsum("yxk,yxkb->yxb", weights, per[i + 1])
    bands = ((1 - t) * lo_v + t * hi_v) * shade[..., None]
    G = gaussians(cam)
    virtual = (weights @ (spectra @ G.T / G.sum(axis=1))) * shade[..., None]
    n, m = cam.band_at.shape
    own = cam.band_at[(r[:, None] - cam.tile_origin[0]) % n, (c[None, :] - cam.tile_origin[1]) % m]
    raw = np.take_along_axis(bands, own[..., None], axis=2)[..., 0]
    raw = raw + noise * np.random.default_rng(seed).standard_normal(raw.shape)
    return Placed(raw, bands, virtual, cra, tuple(int(v) for v in origin))


def textured_scene(shape, k, seed):
    """Abundances, spectra and shading of a textured scene (``msfasim``'s layout)."""
    rng = np.random.default_rng(seed + 1)
    weights = msfasim.abundances(shape, k, seed)
    rows, cols = shape
    yy, xx = np.mgrid[0:rows, 0:cols] / max(rows, cols)
    shade = 0.8 + 0.2 * np.cos(2 * np.pi * (xx * rng.uniform(0.3, 1) + yy * rng.uniform(0.3, 1)))
    return weights, scene_spectra(k, seed), shade


def block_means(a, size=16):
    """Means of ``size`` x ``size`` blocks of ``(rows, cols, ...)``, whole blocks only."""
    rows, cols = (a.shape[0] // size) * size, (a.shape[1] // size) * size
    a = a[:rows, :cols]
    return a.reshape(rows // size, size, cols // size, size, *a.shape[2:]).mean(axis=(1, 3))


def dead_leaves(shape, k, seed, r_min_px=1.0, r_max_px=None, blur_px=0.6):
    """Abundances ``(rows, cols, k)`` of a dead-leaves scene (Lee, Mumford & Huang 2001; the
    texture chart of ISO 19567-2 and Cao, Guichard & Hornung 2010): opaque disks of random
    spectra falling on each other until the field is covered, radii distributed as ``r^-3``
    between ``r_min_px`` and ``r_max_px`` (scale invariant, as natural images are), blurred
    by ``blur_px`` (a lens's)."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    rows, cols = shape
    r_max = max(rows, cols) / 6 if r_max_px is None else r_max_px
    label = np.full(shape, -1)
    yy, xx = np.mgrid[0:rows, 0:cols]
    while (label < 0).any():  # the disks fall from the front: a pixel keeps its first disk
        u = rng.uniform()
        r = 1.0 / np.sqrt((1 - u) / r_min_px**2 + u / r_max**2)  # density r^-3 on [min, max]
        cy, cx = rng.uniform(-r, rows + r), rng.uniform(-r, cols + r)
        y0, y1 = max(int(cy - r), 0), min(int(cy + r) + 2, rows)
        x0, x1 = max(int(cx - r), 0), min(int(cx + r) + 2, cols)
        if y0 >= y1 or x0 >= x1:
            continue
        sub = label[y0:y1, x0:x1]
        inside = ((yy[y0:y1, x0:x1] - cy) ** 2 + (xx[y0:y1, x0:x1] - cx) ** 2 <= r * r)
        sub[inside & (sub < 0)] = rng.integers(k)
    w = (label[..., None] == np.arange(k)).astype(float)
    return gaussian_filter(w, sigma=(blur_px, blur_px, 0))


def vendor_like_matrix(cam: Camera, ridge=1e-3):
    """A correction matrix made as a vendor makes one, for flat-fielded values: the least-
    squares combination of the bands' responses at normal incidence (unit area, band-pass
    included) closest to each unit-area Gaussian target, with a ridge of ``ridge`` times the
    responses' mean power, rows scaled so a flat spectrum stays flat."""
    R = cam.curves * cam.bandpass
    R = R / R.sum(axis=1, keepdims=True)
    G = gaussians(cam)
    G = G / G.sum(axis=1, keepdims=True)
    gram = R @ R.T
    C = np.linalg.solve(gram + ridge * np.trace(gram) / gram.shape[0] * np.eye(gram.shape[0]),
                        R @ G.T).T
    return C / C.sum(axis=1, keepdims=True)
