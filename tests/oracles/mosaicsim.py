"""Flat-fielded band values of a snapshot-mosaic sensor with measured filters, behind a lens.

An independent forward model for judging virtual bands and the measured-response optics: it
does not import snapcorr. The sensor is read from a vendor calibration file with the standard
library (older variant: ``response_composition``, ``rejection_filter``, the virtual bands'
wavelengths and ``fwhm_virtual_filters_nm``); the lens is a :class:`flatsim.LensTruth` and its
vignetted pupil is sampled by :func:`spectralsim.pupil_samples`.

Model: a ray at angle ``phi`` sees every band's whole curve scaled, ``T_b(lambda / a)``,
``a = sqrt(1 - sin^2 phi / n_eff^2)``; the pixel's response is the pupil-weighted sum times
the band-pass ``S(lambda)`` (which does not move). Equal-energy light: a flat-fielded band
value is ``sum R_b rho / sum R_b`` on the file's 1 nm grid; a virtual band's true value the same
with a unit-peak Gaussian of the file's width at its wavelength.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np
from spectralsim import pupil_samples


@dataclass(frozen=True)
class MosaicFile:
    grid: np.ndarray
    curves: np.ndarray  # (bands, n)
    bandpass: np.ndarray  # (n,)
    coefficients: np.ndarray  # (virtual, bands): the file's irradiance matrix
    virtual_nm: np.ndarray
    virtual_fwhm_nm: float
    peaks_nm: np.ndarray  # each band's (first) peak


def read_older(path):
    """The older vendor variant, element by element."""
    fi = ET.parse(path).getroot().find("filter_info")
    ci = fi.find("calibration_info")
    start = float(ci.find("measurement_range_start_nm").text)
    step = float(ci.find("measurement_resolution_nm").text)
    grid = start + step * np.arange(int(ci.find("nr_measurements").text))
    bands = sorted(fi.find("bands"), key=lambda b: int(b.get("pattern_position_index")))
    curves = np.array([[float(v) for v in b.find("response_composition/data").text.split(",")]
                       for b in bands])
    bp = np.array([float(v) for v in
                   fi.find("rejection_filter/filter_response/data").text.split(",")])
    sci = fi.find("spectral_correction_info")
    vbs = sci.find("virtual_bands")
    coeffs = np.array([[float(v) for v in b.find("custom_spectral_correction/data").text.split(
        ",")] for b in vbs])
    wl = np.array([float(b.find("wavelength_nm").text) for b in vbs])
    peaks = np.array([float(b.find("peaks/peak/wavelength_nm").text) for b in bands])
    return MosaicFile(grid, curves, bp, coeffs, wl,
                      float(sci.find("fwhm_virtual_filters_nm").text), peaks)


def responses(sensor: MosaicFile, lens, f_number, cra_deg, n_eff, *, nodes=(64, 32)):
    """Every band's response at a pixel of chief-ray angle ``cra_deg`` (None: normal,
    collimated incidence), on the file's grid: ``S sum_j w_j T_b(lambda / a_bj)``, with
    ``a_bj = sqrt(1 - sin^2 phi_j / n_b^2)``; ``n_eff`` one value or one per band (in the
    file's pattern order)."""
    n = np.broadcast_to(np.asarray(n_eff, float), (sensor.curves.shape[0],))
    if cra_deg is None:
        sin2, w = np.zeros(1), np.ones(1)
    else:
        d = lens.exit_pupil_mm * np.tan(np.deg2rad(cra_deg))
        u, v, w = pupil_samples(lens, f_number, d, theta_nodes=nodes[0], r_nodes=nodes[1])
        t2 = ((u - d) ** 2 + v**2) / lens.exit_pupil_mm**2
        sin2 = t2 / (1.0 + t2)
    out = np.zeros_like(sensor.curves)
    for s2, wk in zip(sin2, w / w.sum(), strict=True):
        for b, curve in enumerate(sensor.curves):
            x = sensor.grid / np.sqrt(1.0 - s2 / n[b] ** 2)
            out[b] += wk * np.interp(x, sensor.grid, curve, left=0.0, right=0.0)
    return out * sensor.bandpass


def band_values(R, spectra):
    """Flat-fielded band values of reflectance ``spectra`` (k, n) through responses ``R``."""
    return spectra @ R.T / R.sum(axis=1)


def radial_table(sensor: MosaicFile, lens, f_number, reflectance, n_eff, *, center_rc, size,
                 pitch_um, n_nodes):
    """Every band's flat-fielded value of a uniform ``reflectance`` (``(n,)`` on the file's
    grid) at ``n_nodes`` squared distances from the axis, even in d^2 from 0 to the farthest
    corner of a ``size`` frame about ``center_rc``: ``(d2 mm^2, table (band, node))``."""
    rows, cols = size
    r_max2 = ((max(center_rc[0], rows - center_rc[0]) ** 2
               + max(center_rc[1], cols - center_rc[1]) ** 2) * (pitch_um * 1e-3) ** 2)
    d2 = np.linspace(0.0, r_max2 * 1.001, n_nodes)
    cra = np.rad2deg(np.arctan(np.sqrt(d2) / lens.exit_pupil_mm))
    values = [band_values(responses(sensor, lens, f_number, c, n_eff, nodes=(16, 8)),
                          np.asarray(reflectance, float)[None])[0] for c in cra]
    return d2, np.array(values).T


def radial_frame(d2_nodes, table, *, center_rc, size, pitch_um, tile=4):
    """The raw mosaic frame of :func:`radial_table`: band ``tile * r + c`` at row ``r``,
    column ``c`` of every tile (pattern positions in reading order), each pixel its band's
    value interpolated at its distance from the axis."""
    rr, cc = np.mgrid[0:size[0], 0:size[1]]
    d2 = ((rr - center_rc[0]) ** 2 + (cc - center_rc[1]) ** 2) * (pitch_um * 1e-3) ** 2
    band = (rr % tile) * tile + cc % tile
    raw = np.empty(size)
    for b in range(table.shape[0]):
        m = band == b
        raw[m] = np.interp(d2[m], d2_nodes, table[b])
    return raw


def virtual_truth(sensor: MosaicFile, spectra, wavelengths=None, fwhm=None):
    """The ideal virtual bands' values: Gaussian-weighted means of the spectra."""
    wl = sensor.virtual_nm if wavelengths is None else np.asarray(wavelengths, float)
    fw = sensor.virtual_fwhm_nm if fwhm is None else fwhm
    G = np.exp(-4 * np.log(2) * ((sensor.grid[None] - wl[:, None]) / fw) ** 2)
    return spectra @ G.T / G.sum(axis=1)


# -- reflectance spectra the prior was not fitted to --------------------------------------------


def leaves(n, seed):
    """PROSPECT-D leaf reflectances (prosail), biochemistry drawn over its usual ranges,
    400-1000 nm at 1 nm."""
    import prosail

    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        _, r, _ = prosail.run_prospect(
            rng.uniform(1.0, 2.5), rng.uniform(5, 80), rng.uniform(1, 20), rng.uniform(0, 1),
            rng.uniform(0.004, 0.03), rng.uniform(0.002, 0.015), ant=rng.uniform(0, 5),
            prospect_version="D")
        out.append(r[:601])
    return np.array(out)


def soils_and_mixtures(n, seed):
    """prosail's two soil spectra, scaled, and linear mixtures of them with leaves."""
    import prosail

    rng = np.random.default_rng(seed)
    soil = prosail.spectral_library.get_spectra().soil
    soils = np.array([soil.rsoil1[:601], soil.rsoil2[:601]])
    veg = leaves(n, seed + 1)
    frac = rng.uniform(0, 1, (n, 1))
    return frac * veg + (1 - frac) * soils[rng.integers(0, 2, n)] * rng.uniform(0.5, 1.6, (n, 1))


def neodymium_glass(lam):
    """A neodymium glass's transmittance from public data: colour-science's measured light
    sources (Houser et al. 2013), the neodymium incandescent lamp over the plain incandescent
    one, 380-780 nm at 5 nm, a cubic spline between, peak 0.92, held at its end values beyond.
    Its absorption bands lie at 510-530, 570-600 and 730-760 nm."""
    wl, spline = _neodymium()
    return spline(np.clip(np.asarray(lam, float), wl[0], wl[-1]))


def colour_checker_red(lam):
    """The ColorChecker's red patch (15) as BabelColor's average of 30 charts measured
    (colour-science's ``SDS_COLOURCHECKERS["BabelColor Average"]``, 380-730 nm at 10 nm; not
    the N. Ohta values snapcorr bundles), a cubic spline between, held at its end values
    beyond."""
    wl, spline = _babel_red()
    return spline(np.clip(np.asarray(lam, float), wl[0], wl[-1]))


@functools.cache
def _babel_red():
    import colour
    from scipy.interpolate import CubicSpline

    sd = colour.SDS_COLOURCHECKERS["BabelColor Average"]["red"]
    return sd.wavelengths, CubicSpline(sd.wavelengths, sd.values)


@functools.cache
def _neodymium():
    import colour
    from scipy.interpolate import CubicSpline

    wl = np.arange(380.0, 781.0, 5.0)
    nd = colour.SDS_LIGHT_SOURCES["Neodimium Incandescent"][wl]
    plain = colour.SDS_LIGHT_SOURCES["Incandescent"][wl]
    ratio = nd / plain
    return wl, CubicSpline(wl, 0.92 * ratio / ratio.max())
