"""Vendor sensor calibration files of both variants, written for the tests.

The newer variant is written from its description (no real file of it is at hand): the layout
in ``filter_info/filter_zones/filter_zone[@layout]``, the grid in
``filter_info/calibration_info/sample_points_nm[@values]`` (space-separated), each band's peaks
and ``response[@values]``, the optical components and the named correction matrices under
``system_info``. The older variant follows the real file in ``calibration/sensors/``. Neither
writer uses snapcorr; numbers are written with ``repr`` so they read back exactly.

The responses of the fixtures are the real imec 4 x 4 VIS ones (``tests/data``, MIT), in the
order of their rows (the ``.mat`` files do not record the tile positions).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from xml.sax.saxutils import escape

import numpy as np
from conftest import RESPONSES_MAT


@dataclass
class Fixture:
    """What a test file says: the facts a reader must give back."""

    grid: np.ndarray
    curves: np.ndarray
    peaks: list  # per band: [(wavelength, fwhm, qe), ...]
    components: list = field(default_factory=list)  # [(type, grid, values)]
    matrices: list = field(default_factory=list)  # [(name, type, wl, fwhm, coeffs)]
    size: tuple = (1088, 2048)
    pitch: float = 5.5
    area: tuple = (0, 0, 1088, 2048)  # row, col, rows, cols
    tile: tuple = (4, 4)
    layout: str = "MOSAIC"


def _n(value):
    """A number as text that reads back exactly."""
    return repr(float(value))


def _values(a, sep=" "):
    return sep.join(_n(v) for v in np.ravel(a))


def imec_4x4(passband=(460.0, 630.0)):
    """The real 4 x 4 VIS responses with a smooth band-pass of our own and one matrix of each
    type (their coefficients are arbitrary: only their reading is tested here)."""
    from scipy.io import loadmat

    mat = loadmat(RESPONSES_MAT[4])
    curves = np.asarray(mat["SpectralProfiles"], float)
    cwl = np.ravel(mat[next(k for k in mat if k.startswith("CentralWavelength"))]).astype(float)
    grid = np.arange(400.0, 1001.0)
    lo, hi = passband
    bandpass = 0.95 / ((1 + np.exp(-(grid - lo) / 2.0)) * (1 + np.exp((grid - hi) / 2.0)))
    rng = np.random.default_rng(4)
    peaks = [[(float(c), 8.0 + 0.01 * i, float(curves[i].max()))] for i, c in enumerate(cwl)]
    peaks[3].append((float(2 * cwl[3] * 0.75), 20.0, 1.5))  # a second-order leak, weaker
    wl_v = np.sort(cwl)
    matrices = [("hsi_reflectance", "reflectance", wl_v, np.full(16, 12.0),
                 rng.normal(0, 0.1, (16, 16)) + np.eye(16)),
                ("hsi_irradiance", "irradiance", wl_v, np.full(16, 12.0),
                 rng.normal(0, 0.001, (16, 16)))]
    grid_bp = np.arange(380.0, 1051.0, 0.5)
    bp = np.interp(grid_bp, grid, bandpass)
    return Fixture(grid, curves, peaks, [("bandpass", grid_bp, bp)], matrices)


def write_newer(path, fx: Fixture, *, drop=(), replace=None, extra_zone=False):
    """The newer variant; ``drop``: tags to leave out; ``replace``: {old text: new text}."""
    ph, pw = fx.tile
    r, c, n, m = fx.area
    bands = []
    for i, (curve, peaks) in enumerate(zip(fx.curves, fx.peaks, strict=True)):
        ps = "".join(
            f'<peak order="{k + 1}" shape="gaussian"><wavelength_nm>{_n(w)}</wavelength_nm>'
            f"<fwhm_nm>{_n(f)}</fwhm_nm><QE>{_n(q)}</QE><contribution>0.9</contribution>"
            f"<fit_error>0.01</fit_error></peak>" for k, (w, f, q) in enumerate(peaks))
        bands.append(f'<band index="{i}"><peaks>{ps}</peaks>'
                     f'<response values="{_values(curve)}"/></band>')
    zone = (f'<filter_zone layout="{fx.layout}"><filter_area><offset_x>{c}</offset_x>'
            f"<offset_y>{r}</offset_y><width>{m}</width><height>{n}</height></filter_area>"
            f"<pattern_width>{pw}</pattern_width><pattern_height>{ph}</pattern_height>"
            f"<bands>{''.join(bands)}</bands></filter_zone>")
    comps = "".join(
        f"<optical_component><type>{escape(t)}</type>"
        f'<sample_points_nm values="{_values(g)}"/><response values="{_values(v)}"/>'
        f"</optical_component>" for t, g, v in fx.components)
    mats = "".join(
        f"<correction_matrix><name>{escape(name)}</name><type>{kind}</type><virtual_bands>"
        + "".join(f"<virtual_band><wavelength_nm>{_n(w)}</wavelength_nm><fwhm_nm>{_n(f)}</fwhm_nm>"
                  f'<coefficients values="{_values(row)}"/></virtual_band>'
                  for w, f, row in zip(wl, fw, coeffs, strict=True))
        + "</virtual_bands></correction_matrix>" for name, kind, wl, fw, coeffs in fx.matrices)
    text = (
        '<?xml version="1.0" encoding="utf-8"?>\n<sensor_calibration version="2">'
        f"<sensor_info><width_px>{fx.size[1]}</width_px><height_px>{fx.size[0]}</height_px>"
        f"<pixel_pitch_um>{_n(fx.pitch)}</pixel_pitch_um><bit_depth>10</bit_depth></sensor_info>"
        f'<filter_info><calibration_info><sample_points_nm values="{_values(fx.grid)}"/>'
        f"</calibration_info><filter_zones>{zone}{zone if extra_zone else ''}</filter_zones>"
        "</filter_info>"
        f"<system_info><optical_components>{comps}</optical_components>"
        f"<spectral_correction_info><correction_matrices>{mats}</correction_matrices>"
        "</spectral_correction_info></system_info></sensor_calibration>\n")
    return _finish(path, text, drop, replace)


def write_older(path, fx: Fixture, *, drop=(), replace=None):
    """The older variant (one irradiance matrix, the band-pass on the response grid)."""
    ph, pw = fx.tile
    r, c, n, m = fx.area
    step = float(fx.grid[1] - fx.grid[0])
    bands = []
    for i, (curve, peaks) in enumerate(zip(fx.curves, fx.peaks, strict=True)):
        ps = "".join(f'<peak version="0" order="1"><wavelength_nm>{_n(w)}</wavelength_nm>'
                     f"<fwhm_nm>{_n(f)}</fwhm_nm><QE>{_n(q)}</QE></peak>" for w, f, q in peaks)
        bands.append(f'<band version="2" pattern_position_index="{i}" selected="true">'
                     f"<peaks>{ps}</peaks><response_composition nr_elements=\"{curve.size}\">"
                     f"<data>{_values(curve, ', ')}</data>"
                     "</response_composition></band>")
    bp = (np.interp(fx.grid, fx.components[0][1], fx.components[0][2]) if fx.components
          else np.ones(fx.grid.size))
    _, _, wl, fw, coeffs = fx.matrices[-1]
    vbs = "".join(f"<band><wavelength_nm>{_n(w)}</wavelength_nm><custom_spectral_correction>"
                  f"<data>{_values(row, ', ')}</data>"
                  "</custom_spectral_correction></band>" for w, row in zip(wl, coeffs,
                                                                           strict=True))
    text = (
        '<?xml version="1.0" encoding="utf-8"?>\n<sensor_calibration version="0">'
        f"<sensor_info><width>{fx.size[1]}</width><height>{fx.size[0]}</height>"
        f"<pixel_pitch>{_n(fx.pitch)}</pixel_pitch></sensor_info>"
        f'<filter_info version="2" layout="{fx.layout}"><filter_area><offset_x>{c}</offset_x>'
        f"<offset_y>{r}</offset_y><width>{m}</width><height>{n}</height></filter_area>"
        f"<pattern_width>{pw}</pattern_width><pattern_height>{ph}</pattern_height>"
        "<filter_width>1</filter_width><filter_height>1</filter_height>"
        f"<calibration_info><measurement_range_start_nm>{_n(fx.grid[0])}"
        "</measurement_range_start_nm>"
        f"<measurement_resolution_nm>{step!r}</measurement_resolution_nm>"
        f"<nr_measurements>{fx.grid.size}</nr_measurements></calibration_info>"
        "<spectral_correction_info><fwhm_virtual_filters_nm>"
        f"{_n(np.nanmax(fw))}</fwhm_virtual_filters_nm>"
        f"<virtual_bands>{vbs}</virtual_bands></spectral_correction_info>"
        "<rejection_filter><type>bandpass</type><filter_response>"
        f"<data>{_values(bp, ', ')}</data></filter_response>"
        f"</rejection_filter><bands>{''.join(bands)}</bands></filter_info>"
        "</sensor_calibration>\n")
    return _finish(path, text, drop, replace)


def _finish(path, text, drop, replace):
    import re

    for tag in drop:
        text, n = re.subn(rf"<{tag}\b[^>]*/>|<{tag}\b[^>]*>.*?</{tag}>", "", text, count=1,
                          flags=re.S)
        assert n == 1, f"no <{tag}> to drop"
    for old, new in (replace or {}).items():
        assert old in text, f"{old!r} not in the file"
        text = text.replace(old, new, 1)
    path.write_text(text, encoding="utf-8")
    return path
