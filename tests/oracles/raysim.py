"""Integrating-sphere flats by counting rays through the exit pupil, for judging error bars.

A second simulator of flats, independent of snapcorr (it must not import it) and of
``tests/oracles/flatsim.py`` (which integrates half-chords by Gauss-Legendre quadrature): here
the light a pixel gets is the NUMBER of rays of a fixed square grid in the exit-pupil plane that
pass every aperture. A ray leaves the pixel for a point ``(u, v)`` of the exit-pupil plane
(``u`` along the pixel's radial line, from the axis; ``v`` across it) and passes

* the exit pupil if ``u^2 + v^2 < R^2`` with ``R = x / (2 (1 + m / m_P) F)``
  (Goossens 2019, Eq. 27-28);
* a vignetting circle ``(P, h)`` if ``(u - h tan(CRA))^2 + v^2 < P^2`` (Eq. 9: the circle
  is the aperture seen from the pixel and projected onto the pupil plane; ``h = x`` is the
  pixel's own acceptance cone).

Rays are counted row by row (rows of constant ``v``): in a row, each disc passes the grid
points inside one interval, so the count of the row is the number of grid points in the
intersection of the intervals, found with ``floor`` and ``ceil`` -- the same integer a loop
over every ray would give, without the loop (``count_rays_loop`` is that loop, for checking).
The relative illumination is the count over the count of the bare pupil on the same grid; a
pixel's signal is that times ``cos^4(CRA)``, its exposure, its gain and the sphere's level.

The counts are tabulated over ``tan(CRA)`` and interpolated to the pixels. The mean filter
shift (Goossens 2019, Eq. 3, 22) is the average over the same rays of each ray's shift,
``cwl (sqrt(1 - sin^2(phi) / n^2) - 1)`` with ``tan(phi)`` the ray's angle to the normal.
"""

from __future__ import annotations

import numpy as np

__all__ = ["count_rays", "count_rays_loop", "flats", "mean_shift_rays", "relative_illumination"]


def _circles(x, circles, m, mP, f_number):
    R = x / (2.0 * (1.0 + m / mP) * float(f_number))
    return R, [(R, 0.0)] + [(float(P), float(h)) for P, h in circles]


def count_rays(x, circles, m, mP, f_number, tan_cra, rows=6000, chunk=128):
    """Rays of a ``rows x rows`` grid over the pupil's square that pass every disc, for each
    ``tan_cra`` (array), and the count of the bare pupil."""
    t_all = np.atleast_1d(np.asarray(tan_cra, float))
    parts = [_count(x, circles, m, mP, f_number, t_all[i : i + chunk], rows)
             for i in range(0, t_all.size, chunk)]
    return np.concatenate([p[0] for p in parts]), parts[0][1]


def _count(x, circles, m, mP, f_number, t, rows):
    R, discs = _circles(x, circles, m, mP, f_number)
    d = 2.0 * R / rows
    grid = -R + (np.arange(rows) + 0.5) * d  # ray positions along u and v
    lo = np.full((t.size, rows), -np.inf)
    hi = np.full((t.size, rows), np.inf)
    for P, h in discs:
        w2 = P * P - grid * grid
        w = np.sqrt(np.clip(w2, 0.0, None))
        c = h * t[:, None]
        inside = w2 > 0
        lo = np.maximum(lo, np.where(inside, c - w, np.inf))
        hi = np.minimum(hi, np.where(inside, c + w, -np.inf))
    # grid points u_k = -R + (k + 1/2) d inside (lo, hi)
    k_lo = np.ceil((lo + R) / d - 0.5)
    k_hi = np.floor((hi + R) / d - 0.5)
    k_lo = np.clip(k_lo, 0, rows)
    k_hi = np.clip(k_hi, -1, rows - 1)
    n = np.clip(k_hi - k_lo + 1, 0, None).sum(axis=1)
    full_w = np.sqrt(np.clip(R * R - grid * grid, 0.0, None))
    f_lo = np.clip(np.ceil((R - full_w) / d - 0.5), 0, rows)
    f_hi = np.clip(np.floor((R + full_w) / d - 0.5), -1, rows - 1)
    full = float(np.clip(f_hi - f_lo + 1, 0, None).sum())
    return n, full


def count_rays_loop(x, circles, m, mP, f_number, tan_cra, rows=200):
    """The same count, ray by ray (slow; for checking :func:`count_rays`)."""
    R, discs = _circles(x, circles, m, mP, f_number)
    d = 2.0 * R / rows
    grid = -R + (np.arange(rows) + 0.5) * d
    n = 0
    for v in grid:
        for u in grid:
            if all((u - h * tan_cra) ** 2 + v * v < P * P for P, h in discs):
                n += 1
    return n


def relative_illumination(x, circles, m, mP, f_number, tan_cra, rows=6000):
    n, full = count_rays(x, circles, m, mP, f_number, tan_cra, rows)
    return n / full


def mean_shift_rays(x, circles, m, mP, f_number, cra_deg, cwl_nm=1000.0, n_eff=1.5,
                    rows=1500):
    """Mean filter shift (nm) over the rays that pass every disc, per CRA."""
    R, discs = _circles(x, circles, m, mP, f_number)
    d = 2.0 * R / rows
    g = -R + (np.arange(rows) + 0.5) * d
    uu, vv = np.meshgrid(g, g, indexing="xy")
    out = []
    for cra in np.atleast_1d(cra_deg):
        t = np.tan(np.deg2rad(cra))
        ok = np.ones(uu.shape, bool)
        for P, h in discs:
            ok &= (uu - h * t) ** 2 + vv**2 < P * P
        if not ok.any():
            out.append(np.nan)
            continue
        r2 = (uu[ok] - x * t) ** 2 + vv[ok] ** 2  # lateral distance from the pixel's foot
        sin2 = r2 / (r2 + x * x)
        out.append(float(np.mean(cwl_nm * (np.sqrt(1.0 - sin2 / n_eff**2) - 1.0))))
    return np.array(out)


def flats(x, circles, *, m=0.0, mP=1.0, f_numbers=(2.0, 2.8, 4.0, 5.6, 11.0),
          shape=(512, 640), pitch_um=14.2, center_rc=(240.0, 350.0), noise=0.005, seed=0,
          level_dn=40000.0, exposure_spread=0.2, prnu=0.0, n_table=3000, rows=6000):
    """Flats, f-number -> 2-D array (DN, whole numbers), and the exposures drawn.

    ``center_rc``: the optical axis on the sensor, (row, column) of pixel centres. Each
    f-number's exposure is uniform in ``1 +- exposure_spread``; ``prnu``: the pixels' gain
    scatter (the same in every flat); Gaussian noise of ``noise`` times the signal.
    """
    rng = np.random.default_rng([seed, 38])
    rr, cc = np.mgrid[0 : shape[0], 0 : shape[1]]
    rho = np.hypot(rr - center_rc[0], cc - center_rc[1]) * pitch_um * 1e-3
    tan = rho / x
    cos4 = 1.0 / (1.0 + tan * tan) ** 2
    t_tab = np.linspace(0.0, float(tan.max()) * 1.0001, n_table)
    gain = 1.0 + prnu * rng.standard_normal(shape)
    fastest = min(f_numbers)
    out, exposures = {}, {}
    for f in f_numbers:
        e = 1.0 + exposure_spread * rng.uniform(-1.0, 1.0)
        exposures[f] = e
        ri = relative_illumination(x, circles, m, mP, f, t_tab, rows)
        area = (fastest / f) ** 2 * np.interp(tan, t_tab, ri)  # pupil area against the fastest
        sig = level_dn * e * gain * area * cos4
        img = sig * (1.0 + noise * rng.standard_normal(shape))
        out[f] = np.clip(np.rint(img), 0.0, 65535.0)
    return out, exposures
