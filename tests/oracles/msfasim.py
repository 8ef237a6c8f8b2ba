"""Multispectral test scenes for demosaicking, and their mosaics.

An independent simulator (it does not import snapcorr): a scene is a few reflectance spectra
from public libraries (colour-science's colour samples; prosail's PROSPECT-D leaves and soils)
laid out with spatial structure -- a smooth blend across the field, disks and bars with sharp
edges, fine stripes and a checkerboard at one to three pixels, slight optical blur and smooth
shading -- seen through a real sensor's measured responses (flat-fielded: the response-weighted
mean of the reflectance, equal-energy light). The ground truth is every band at every pixel; the
mosaic keeps each pixel's own band, the one the tile puts there.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

GRID = np.arange(400.0, 1001.0)


def colour_spectra():
    """colour-science's public reflectances (ColorChecker N Ohta, CIE 1995 TCS, NIST CQS), on
    400-1000 nm, held at their last sample beyond it (380-830 nm)."""
    import colour
    from colour.quality.datasets import SDS_TCS, SDS_VS

    sets = (colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"], SDS_TCS["CIE 1995"],
            SDS_VS[next(iter(SDS_VS))])
    return np.array([np.interp(GRID, sd.wavelengths, sd.values) for d in sets
                     for sd in d.values()])


def vegetation_spectra(n=12, seed=0):
    """PROSPECT-D leaves and prosail's two soils, 400-1000 nm."""
    import prosail

    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        _, r, _ = prosail.run_prospect(
            rng.uniform(1.2, 2.2), rng.uniform(10, 70), rng.uniform(3, 15), rng.uniform(0, 0.6),
            rng.uniform(0.006, 0.02), rng.uniform(0.003, 0.01), ant=rng.uniform(0, 3),
            prospect_version="D")
        out.append(r[:601])
    soil = prosail.spectral_library.get_spectra().soil
    return np.array([*out, soil.rsoil1[:601], soil.rsoil2[:601]])


def abundances(shape, k, seed):
    """``(rows, cols, k)`` weights of ``k`` spectra summing to 1: a smooth blend of two as the
    background, then disks and bars with sharp edges, a region of fine stripes, a checkerboard
    of 1-3 px cells, slight blur (sigma 0.6 px, a lens's)."""
    rng = np.random.default_rng(seed)
    rows, cols = shape
    yy, xx = np.mgrid[0:rows, 0:cols] / max(rows, cols)
    w = np.zeros((rows, cols, k))
    t = 0.5 + 0.5 * np.sin(2 * np.pi * (0.7 * xx + 0.4 * yy) + rng.uniform(0, 6))
    w[..., 0], w[..., 1] = t, 1 - t
    for j in range(2, k):
        kind = j % 4
        if kind == 0:  # a disk
            cy, cx, r = rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9), rng.uniform(0.05, 0.15)
            inside = (yy - cy) ** 2 + (xx - cx) ** 2 < r * r
        elif kind == 1:  # an oblique bar
            angle, off, width = rng.uniform(0, np.pi), rng.uniform(0.2, 0.8), rng.uniform(0.03, 0.1)
            inside = np.abs((xx - 0.5) * np.cos(angle) + (yy - off) * np.sin(angle)) < width
        elif kind == 2:  # fine stripes inside a square
            y0, x0, s = rng.uniform(0, 0.6), rng.uniform(0, 0.6), rng.uniform(0.2, 0.35)
            period = rng.integers(2, 7)
            square = (yy >= y0) & (yy < y0 + s) & (xx >= x0) & (xx < x0 + s)
            inside = square & ((np.arange(cols)[None, :] // period) % 2 == 0)
        else:  # a checkerboard of small cells
            y0, x0, s = rng.uniform(0, 0.6), rng.uniform(0, 0.6), rng.uniform(0.15, 0.3)
            cell = rng.integers(1, 4)
            square = (yy >= y0) & (yy < y0 + s) & (xx >= x0) & (xx < x0 + s)
            check = ((np.arange(rows)[:, None] // cell + np.arange(cols)[None, :] // cell) % 2
                     == 0)
            inside = square & check
        w[inside] = 0.0
        w[inside, j] = 1.0
    w = gaussian_filter(w, sigma=(0.6, 0.6, 0))
    return w / w.sum(axis=2, keepdims=True)


def scene_bands(shape, spectra, responses, seed):
    """The ground truth: ``(rows, cols, n_bands)`` flat-fielded band values of a scene of
    ``spectra`` (``(k, 601)`` on 400-1000 nm) through ``responses`` (``(n_bands, 601)``, the
    system included), with smooth shading between 0.6 and 1."""
    rng = np.random.default_rng(seed + 1)
    k = spectra.shape[0]
    w = abundances(shape, k, seed)
    per = spectra @ responses.T / responses.sum(axis=1)  # (k, bands): each spectrum's values
    rows, cols = shape
    yy, xx = np.mgrid[0:rows, 0:cols] / max(rows, cols)
    shade = 0.8 + 0.2 * np.cos(2 * np.pi * (xx * rng.uniform(0.3, 1) + yy * rng.uniform(0.3, 1)))
    return (w @ per) * shade[..., None]


def mosaic(truth, band_at):
    """The raw frame: at each pixel, the band ``band_at[y % n, x % m]`` the tile puts there."""
    n, m = band_at.shape
    rows, cols, _ = truth.shape
    idx = band_at[np.arange(rows)[:, None] % n, np.arange(cols)[None, :] % m]
    return np.take_along_axis(truth, idx[..., None], axis=2)[..., 0]


def psnr(estimate, truth, border):
    """Peak signal-to-noise ratio (dB), the peak being the truth's largest value, over every
    band away from ``border`` pixels of the edges."""
    e, t = estimate[border:-border, border:-border], truth[border:-border, border:-border]
    mse = np.nanmean((e - t) ** 2)
    return float(10 * np.log10(np.nanmax(t) ** 2 / mse))


def sam_deg(estimate, truth, border):
    """Mean spectral angle (degrees) between estimated and true spectra, away from the edges."""
    e = estimate[border:-border, border:-border].reshape(-1, truth.shape[2])
    t = truth[border:-border, border:-border].reshape(-1, truth.shape[2])
    cos = np.sum(e * t, axis=1) / (np.linalg.norm(e, axis=1) * np.linalg.norm(t, axis=1))
    return float(np.degrees(np.nanmean(np.arccos(np.clip(cos, -1, 1)))))
