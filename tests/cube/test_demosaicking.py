"""Demosaicking a mosaic frame: accuracy on simulated scenes with real responses, each band's
own samples kept wherever the frame starts, the methods against brute-force versions of their
published equations (the PPI's own in msfa/test_mihoubi2017.py), the frame's edges, missing
values, chunked (dask) frames equal to the last bit, refusals, and the returned cube.

The band each pixel holds is worked out here from the sensor's definition alone (its tile,
band offsets and filter area), not from snapcorr's layout code.
"""

import functools
import warnings

import dask.array as da
import msfasim
import numpy as np
import pytest
import xarray as xr
from conftest import VENDOR_XML
from mosaicsim import read_older
from numpy.testing import assert_allclose, assert_array_equal
from scipy.ndimage import convolve, uniform_filter
from vendorfiles import imec_4x4

from snapcorr.cube import Sensor, mosaic_to_cube
from snapcorr.cube.demosaicking import (
    DEMOSAIC_METHODS,
    DEMOSAIC_REACH_TILES,
    demosaic,
    demosaic_array,
)
from snapcorr.cube.flatfield import MaskedWarning
from snapcorr.cube.msfa import monno2017, pseudo_panchromatic
from snapcorr.data import sensor_path

METHODS = ("nearest", "bilinear", "ppid", "ri")


@functools.cache
def bundled(name):
    return Sensor.load(sensor_path(name))


def toy(tile, offsets, *, size_px=None, area=None):
    """A small mosaic sensor of any tile, bands at the given (row, col) of the tile."""
    return Sensor(name=f"toy {tile[0]}x{tile[1]}", layout="mosaic", pixel_pitch_um=5.5,
                  cwl_nm=[450.0 + 10 * b for b in range(len(offsets))], fwhm_nm=10.0,
                  n_eff=None, mosaic_shape=tile, band_offset=offsets, size_px=size_px,
                  filter_area_px=area)


def _shuffled(n, m, seed):
    order = np.random.default_rng(seed).permutation(n * m)
    return [(int(k // m), int(k % m)) for k in order]


#: Non-square tiles, the bands in no particular order; one with a filter area that does not
#: start at the sensor's corner and ends before its far edges.
TOY_2X3 = toy((2, 3), [(1, 2), (0, 0), (1, 0), (0, 2), (0, 1), (1, 1)], size_px=(60, 62))
TOY_3X4 = toy((3, 4), _shuffled(3, 4, 7), size_px=(90, 100), area=(2, 1, 85, 93))


def sensors():
    """name -> (sensor, a sensor_origin_px inside its filter area)."""
    return {"4x4": (bundled("mosaic_4x4_vis"), (0, 0)),
            "5x5 vendor": (bundled("imec_5x5_nir"), (3, 0)),
            "2x3": (TOY_2X3, (0, 0)),
            "3x4": (TOY_3X4, (2, 1))}


def layout(sensor, shape, origin=(0, 0)):
    """From the sensor's definition: the rows and columns of a frame whose first pixel is
    sensor pixel ``origin`` that lie inside the filter area (slices of the frame), and the band
    each of those pixels holds (the tile grid starts at the filter area's corner)."""
    n, m = sensor.mosaic_shape
    ar, ac, an, am = sensor.filter_area_px or (0, 0, 1 << 30, 1 << 30)
    r, c = origin
    top, left = max(r, ar), max(c, ac)
    bottom, right = min(r + shape[0], ar + an), min(c + shape[1], ac + am)
    table = np.full((n, m), -1)
    for b, (i, j) in enumerate(sensor.band_offset):
        table[i, j] = b
    rows, cols = np.arange(top, bottom), np.arange(left, right)
    band = table[((rows - ar) % n)[:, None], ((cols - ac) % m)[None, :]]
    return (slice(top - r, bottom - r), slice(left - c, right - c)), band


def own(cube, band):
    """Every pixel's value in its own band."""
    return np.take_along_axis(np.asarray(cube), band[..., None], axis=2)[..., 0]


def first_samples(band, n_bands):
    """Each band's first sample row and column in a band map."""
    y0 = np.array([np.argwhere(band == b)[0, 0] for b in range(n_bands)])
    x0 = np.array([np.argwhere(band == b)[0, 1] for b in range(n_bands)])
    return y0, x0


def tent(n, m):
    """Brauers & Aach's bilinear kernel, (2n - 1) x (2m - 1): (1 - |i|/n)(1 - |j|/m)."""
    return np.outer(1 - np.abs(np.arange(1 - n, n)) / n, 1 - np.abs(np.arange(1 - m, m)) / m)


def sparse(values, band, b):
    """Band ``b``'s samples in place, zero elsewhere."""
    return np.where(band == b, values, 0.0)


def random_frame(shape, seed, dtype=np.float32):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.1, 1.0, shape).astype(dtype)


def with_masked_warnings(call, *args, **kwargs):
    """``call(...)`` and the MaskedWarnings it gave."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", MaskedWarning)
        out = call(*args, **kwargs)
    return out, [w for w in seen if issubclass(w.category, MaskedWarning)]


def test_the_methods_are_the_four_documented():
    assert tuple(DEMOSAIC_METHODS) == METHODS
    assert set(DEMOSAIC_REACH_TILES) == set(METHODS)


# -- accuracy on simulated scenes ------------------------------------------------------------


@functools.cache
def _responses(tile):
    """Real measured responses on 400-1000 nm: the imec 4 x 4 VIS ones (tests/data) behind
    the fixtures' band-pass, and the 5 x 5 NIR vendor file's behind its measured band-pass,
    read element by element."""
    if tile == 4:
        fx = imec_4x4()
        return fx.curves * np.interp(msfasim.GRID, fx.components[0][1], fx.components[0][2])
    mf = read_older(VENDOR_XML)
    return mf.curves * np.clip(mf.bandpass, 0, None)


@functools.cache
def _library(tile):
    colours = msfasim.colour_spectra()
    if tile == 4:
        return colours
    return np.concatenate([msfasim.vegetation_spectra(), colours[:10]])


def _scores(which, shape, seeds):
    """Mean PSNR and SAM of each method over simulated scenes of ``seeds`` (border 2 tiles)."""
    sensor, origin = sensors()[which]
    n, m = sensor.mosaic_shape
    responses, spectra = _responses(n), _library(n)
    _, band = layout(sensor, shape, origin)
    assert band.shape == shape  # the whole crop lies inside the filter area
    psnr, sam = {k: [] for k in METHODS}, {k: [] for k in METHODS}
    for seed in seeds:
        pick = np.random.default_rng(seed).choice(len(spectra), 10, replace=False)
        truth = msfasim.scene_bands(shape, spectra[pick], responses, seed).astype(np.float32)
        frame = msfasim.mosaic(truth, band[:n, :m])
        for method in METHODS:
            est = demosaic(frame, sensor, method, sensor_origin_px=origin).values
            psnr[method].append(msfasim.psnr(est, truth, 2 * n))
            sam[method].append(msfasim.sam_deg(est, truth, 2 * n))
    return {k: np.mean(v) for k, v in psnr.items()}, {k: np.mean(v) for k, v in sam.items()}


def _check_order(p, s):
    report = f"PSNR {p}, SAM {s}"
    assert p["nearest"] < p["bilinear"] < p["ppid"] < p["ri"], report
    assert p["ri"] >= p["bilinear"] + 2.0, report
    assert s["ri"] < s["bilinear"] < s["nearest"], report


#: As measured at 160 x 200 px, mean of seeds 0 and 1 (nearest, bilinear, ppid, ri):
#:   4x4: 23.4 / 26.1 / 28.0 / 28.4 dB, SAM 4.85 / 3.59 / 3.14 / 2.70 degrees
#:   5x5: 24.7 / 26.7 / 28.7 / 30.5 dB, SAM 2.53 / 1.83 / 1.54 / 1.20 degrees
@pytest.mark.parametrize("which", ["4x4", "5x5 vendor"])
def test_accuracy_on_simulated_scenes_orders_the_methods(which):
    _check_order(*_scores(which, (160, 200), (0, 1)))


@pytest.mark.slow
@pytest.mark.parametrize("which", ["4x4", "5x5 vendor"])
def test_accuracy_on_larger_scenes_orders_the_methods(which):
    _check_order(*_scores(which, (240, 320), range(6)))


# -- each band's own samples -------------------------------------------------------------------


#: (sensor, frame shape, sensor_origin_px): on and off the tile grid, crops cut by the filter
#: area on either side, and whole-sensor frames without sensor_origin_px.
OWN_CASES = {
    "4x4 on the grid": ("4x4", (37, 42), (0, 0)),
    "4x4 off the grid": ("4x4", (37, 42), (5, 7)),
    "4x4 far off": ("4x4", (29, 33), (1002, 2013)),
    "5x5 cut above": ("5x5 vendor", (41, 38), (0, 6)),
    "5x5 off the grid": ("5x5 vendor", (41, 38), (9, 13)),
    "5x5 cut right": ("5x5 vendor", (36, 40), (17, 2008)),
    "2x3 whole sensor": ("2x3", (60, 62), None),
    "2x3 off the grid": ("2x3", (17, 20), (3, 4)),
    "3x4 whole sensor": ("3x4", (90, 100), None),
    "3x4 off the grid": ("3x4", (25, 29), (4, 3)),
    "3x4 cut on all sides": ("3x4", (90, 100), (0, 0)),
}


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("case", list(OWN_CASES))
def test_every_method_keeps_each_bands_own_samples(case, method):
    which, shape, origin = OWN_CASES[case]
    sensor = sensors()[which][0]
    frame = np.random.default_rng(3).integers(0, 4096, shape).astype(np.uint16)
    cube = demosaic(frame, sensor, method, sensor_origin_px=origin)
    (rows, cols), band = layout(sensor, shape, origin or (0, 0))
    assert cube.shape == (*band.shape, sensor.n_bands)
    assert_array_equal(own(cube.values, band), frame[rows, cols])


# -- brute-force checks ------------------------------------------------------------------------


@pytest.mark.parametrize("dtype, atol", [(np.float64, 1e-12), (np.float32, 1e-5)])
@pytest.mark.parametrize("which, origin", [("4x4", (5, 7)), ("5x5 vendor", (4, 9)),
                                           ("3x4", (3, 6)), ("2x3", (1, 1))])
def test_bilinear_is_the_tent_kernel_of_brauers_and_aach(which, origin, dtype, atol):
    """Away from the edges, WB is each band's sparse samples convolved with the separable tent
    kernel ``(1 - |i|/n)(1 - |j|/m)`` of size (2n - 1) x (2m - 1)."""
    sensor = sensors()[which][0]
    n, m = sensor.mosaic_shape
    shape = (8 * n + 3, 8 * m + 1)
    frame = random_frame(shape, 5, dtype)
    (rows, cols), band = layout(sensor, shape, origin)
    kept = frame[rows, cols].astype(np.float64)
    cube = demosaic(frame, sensor, "bilinear", sensor_origin_px=origin).values
    assert cube.dtype == dtype
    inner = np.s_[n:-n, m:-m]
    for b in range(sensor.n_bands):
        expected = convolve(sparse(kept, band, b), tent(n, m), mode="constant")
        assert_allclose(cube[..., b][inner], expected[inner], rtol=0, atol=atol)


def _textured(shape, seed):
    """A frame with structure at several scales and a sharp edge, positive."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    base = 0.6 + 0.3 * np.sin(yy / 3.0 + 0.5) * np.cos(xx / 4.0) + 0.2 * (xx > shape[1] // 2)
    return base + 0.1 * rng.random(shape)


@pytest.mark.parametrize("which, origin", [("4x4", (2, 3)), ("3x4", (4, 2))])
def test_ppid_is_the_ppi_plus_each_bands_difference_interpolated(which, origin):
    """Eq. (30-34): PPI plus the tent-kernel interpolation of ``I - PPI`` at the band's
    samples, away from the edges."""
    sensor = sensors()[which][0]
    n, m = sensor.mosaic_shape
    shape = (8 * n + 1, 8 * m + 3)
    (rows, cols), band = layout(sensor, shape, origin)
    frame = _textured(shape, 4)
    kept = frame[rows, cols]
    ppi = pseudo_panchromatic(kept, n, m)
    cube = demosaic(frame, sensor, "ppid", sensor_origin_px=origin).values
    inner = np.s_[n:-n, m:-m]
    for b in range(sensor.n_bands):
        expected = ppi + convolve(sparse(kept - ppi, band, b), tent(n, m), mode="constant")
        assert_allclose(cube[..., b][inner], expected[inner], rtol=0, atol=1e-12)


def brute_ri_band(kept, ppi, band, b, n, m, radius=monno2017.RADIUS,
                  eps_fraction=monno2017.EPS_FRACTION):
    """Residual interpolation of band ``b`` with the guided filter written out (He et al.):
    on the band's sub-grid, per window ``a = cov(g, v) / (var(g) + (eps mean g)^2)``,
    ``c = mean v - a mean g``; each sample's ``a`` averaged over the windows holding it; the
    residual ``v - a g`` and ``a`` interpolated with the tent kernel; ``a PPI + residual``.
    Valid where every window is whole."""
    (y0,), (x0,) = (np.unique(np.nonzero(band == b)[k] % s) for k, s in ((0, n), (1, m)))
    v, g = kept[y0::n, x0::m], ppi[y0::n, x0::m]
    size = 2 * radius + 1

    def mean(a):
        return uniform_filter(a, size, mode="constant")

    mv, mg = mean(v), mean(g)
    a = (mean(g * v) - mg * mv) / (mean(g * g) - mg * mg + (eps_fraction * mg) ** 2)
    a_bar = mean(a)
    offset = v - a_bar * g
    grid_a, grid_o = np.zeros_like(kept), np.zeros_like(kept)
    grid_a[y0::n, x0::m], grid_o[y0::n, x0::m] = a_bar, offset
    k = tent(n, m)
    return convolve(grid_a, k, mode="constant") * ppi + convolve(grid_o, k, mode="constant")


@pytest.mark.parametrize("which, origin", [("4x4", (1, 2)), ("5x5 vendor", (3, 0)),
                                           ("3x4", (2, 5))])
def test_ri_is_a_guided_filter_against_the_ppi_plus_residuals(which, origin):
    sensor = sensors()[which][0]
    n, m = sensor.mosaic_shape
    shape = (14 * n, 14 * m + 2)
    (rows, cols), band = layout(sensor, shape, origin)
    frame = _textured(shape, 6)
    kept = frame[rows, cols]
    ppi = pseudo_panchromatic(kept, n, m)
    cube = demosaic(frame, sensor, "ri", sensor_origin_px=origin).values
    inner = np.s_[6 * n:-6 * n, 6 * m:-6 * m]
    for b in range(sensor.n_bands):
        expected = brute_ri_band(kept, ppi, band, b, n, m)
        assert_allclose(cube[..., b][inner], expected[inner], rtol=0, atol=1e-12)


@pytest.mark.parametrize("which", list(sensors()))
def test_nearest_takes_the_sample_of_the_tile_window_holding_the_pixel(which):
    """Each band's sample at or before the pixel along each axis (the next one where there is
    none before it)."""
    sensor, origin = sensors()[which]
    n, m = sensor.mosaic_shape
    shape = (5 * n + 2, 6 * m + 1)
    frame = random_frame(shape, 8)
    (rows, cols), band = layout(sensor, shape, origin)
    kept = frame[rows, cols]
    cube = demosaic(frame, sensor, "nearest", sensor_origin_px=origin).values
    y0, x0 = first_samples(band, sensor.n_bands)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    for b in range(sensor.n_bands):
        sy = y0[b] + (yy - y0[b]) // n * n
        sx = x0[b] + (xx - x0[b]) // m * m
        sy[sy < 0] += n
        sx[sx < 0] += m
        inside = (sy < shape[0]) & (sx < shape[1])
        assert_array_equal(cube[..., b][inside], kept[sy[inside], sx[inside]])


@pytest.mark.parametrize("which", list(sensors()))
def test_an_affine_scene_is_reproduced(which):
    """The same linear ramp in every band: bilinear and ppid reproduce it exactly away from
    the edges (the PPI of a ramp is the ramp); ri up to its fit's regularisation."""
    sensor, origin = sensors()[which]
    n, m = sensor.mosaic_shape
    shape = (10 * n + 3, 10 * m + 2)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    frame = 0.5 + 0.01 * yy + 0.007 * xx
    truth = frame[..., None]
    inner = np.s_[2 * n + 2:-(2 * n + 2), 2 * m + 2:-(2 * m + 2)]
    assert_allclose(pseudo_panchromatic(frame, n, m)[inner], frame[inner], rtol=1e-13)
    for method, margin, rtol in [("bilinear", 1, 1e-13), ("ppid", 3, 1e-13), ("ri", 6, 1e-3)]:
        cube = demosaic(frame, sensor, method, sensor_origin_px=origin).values
        inner = np.s_[margin * n:-margin * n, margin * m:-margin * m]
        assert_allclose(cube[inner], np.broadcast_to(truth, cube.shape)[inner], rtol=rtol,
                        err_msg=method)


# -- edges -------------------------------------------------------------------------------------


def _edge_shapes(n, m):
    return [(n, m), (n + 1, m + 2), (2 * n - 1, 2 * m + 1), (n, 7 * m + 1), (6 * n + 2, m),
            (3 * n + 2, 4 * m + 3)]


@pytest.mark.parametrize("which", list(sensors()))
def test_every_value_is_finite_at_the_edges_of_any_frame(which):
    """Frames of one tile and of sizes not a multiple of the tile: every value finite, the own
    samples kept, and a grey (constant) frame grey everywhere."""
    sensor, origin = sensors()[which]
    n, m = sensor.mosaic_shape
    for shape in _edge_shapes(n, m):
        frame = random_frame(shape, sum(shape))
        _, band = layout(sensor, shape, origin)
        for method in METHODS:
            cube = demosaic(frame, sensor, method, sensor_origin_px=origin).values
            what = f"{method} {shape}"
            assert cube.shape == (*shape, sensor.n_bands), what
            assert np.isfinite(cube).all(), what
            assert_array_equal(own(cube, band), frame, err_msg=what)
            grey = demosaic(np.full(shape, 0.37, np.float32), sensor, method,
                            sensor_origin_px=origin).values
            assert_allclose(grey, 0.37, rtol=2e-7, err_msg=what)


# -- missing values ----------------------------------------------------------------------------


def _with_holes(shape, holes):
    frame = random_frame(shape, 11)
    for hole in holes:
        frame[hole] = np.nan
    return frame


def _expected_nan(frame, band, n_bands):
    """NaN exactly at each missing pixel's own band."""
    expected = np.zeros((*frame.shape, n_bands), bool)
    y, x = np.nonzero(np.isnan(frame))
    expected[y, x, band[y, x]] = True
    return expected


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("which", ["4x4", "5x5 vendor", "3x4"])
def test_a_missing_value_stays_in_its_own_band(which, method):
    """Isolated missing pixels (at corners and edges too, two adjacent) and a block smaller
    than a tile: NaN at those pixels' own bands only, never spread, and no warning."""
    sensor, origin = sensors()[which]
    n, m = sensor.mosaic_shape
    shape = (12 * n + 1, 12 * m + 3)
    rows, cols = shape
    singles = [(0, 0), (0, 17), (rows - 1, cols - 1), (rows - 1, 0), (21, cols - 1), (30, 0),
               (11, 13), (11, 14), (5 * n, 6 * m)]
    holes = [*singles, np.s_[7 * n + 1:8 * n, 3 * m + 1:4 * m]]
    frame = _with_holes(shape, holes)
    assert np.isnan(frame).sum() == len(singles) + (n - 1) * (m - 1)
    _, band = layout(sensor, shape, origin)
    cube, warned = with_masked_warnings(demosaic, frame, sensor, method, sensor_origin_px=origin)
    got = np.isnan(cube.values)
    assert got.sum() == np.isnan(frame).sum()
    assert_array_equal(got, _expected_nan(frame, band, sensor.n_bands))
    assert not warned


def _hole(where, shape, n, m):
    rows, cols = shape
    return {"one tile inside": np.s_[4 * n + 1:5 * n + 1, 5 * m + 2:6 * m + 2],
            "3 x 3 at the first corner": np.s_[:3, :3],
            "3 x 3 at the last corner": np.s_[rows - 3:, cols - 3:]}[where]


def _hole_cases():
    cases = []
    for which, where in [("5x5 vendor", "one tile inside"), ("4x4", "one tile inside"),
                         ("4x4", "3 x 3 at the first corner"),
                         ("5x5 vendor", "3 x 3 at the last corner")]:
        for method in METHODS:
            cases.append(pytest.param(which, where, method, id=f"{which}-{where}-{method}"))
    return cases


@pytest.mark.parametrize("which, where, method", _hole_cases())
def test_a_hole_no_wider_than_a_tile_stays_in_its_own_band(which, where, method):
    sensor, origin = sensors()[which]
    n, m = sensor.mosaic_shape
    shape = (10 * n + 2, 10 * m + 1)
    frame = _with_holes(shape, [_hole(where, shape, n, m)])
    _, band = layout(sensor, shape, origin)
    cube, warned = with_masked_warnings(demosaic, frame, sensor, method, sensor_origin_px=origin)
    assert_array_equal(np.isnan(cube.values), _expected_nan(frame, band, sensor.n_bands))
    assert not warned


@pytest.mark.parametrize("method", METHODS)
def test_a_hole_too_wide_to_fill_is_warned_of(method):
    """A hole several tiles wide at a corner leaves some bands with no sample near: NaN there,
    said in a MaskedWarning."""
    sensor, origin = sensors()["4x4"]
    shape = (48, 52)
    frame = _with_holes(shape, [np.s_[:14, :14]])
    cube, warned = with_masked_warnings(demosaic, frame, sensor, method, sensor_origin_px=origin)
    assert np.isnan(cube.values).sum() > np.isnan(frame).sum()
    assert len(warned) == 1 and "missing values" in str(warned[0].message)
    # far from the hole every value is there
    assert np.isfinite(cube.values[30:, 30:]).all()


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("tile", [(4, 4), (5, 5), (3, 4)])
def test_a_pixel_reaches_no_further_than_the_declared_halo(tile, method):
    """Changing one value (or making it missing) changes the cube only within
    DEMOSAIC_REACH_TILES tiles of it: the halo a chunk needs."""
    n, m = tile
    reach = DEMOSAIC_REACH_TILES[method]
    sensor = toy(tile, _shuffled(n, m, 2))
    shape = (2 * reach * n + 4 * n + 1, 2 * reach * m + 4 * m + 3)
    frame = random_frame(shape, 12, np.float64)
    base = demosaic(frame, sensor, method, sensor_origin_px=(0, 0)).values
    for k in range(3):
        py, px = shape[0] // 2 + k, shape[1] // 2 + 2 * k
        for new in (frame[py, px] + 0.5, np.nan):
            changed_frame = frame.copy()
            changed_frame[py, px] = new
            cube = demosaic(changed_frame, sensor, method, sensor_origin_px=(0, 0)).values
            diff = ~((cube == base) | (np.isnan(cube) & np.isnan(base)))
            y, x, _ = np.nonzero(diff)
            assert np.abs(y - py).max() <= reach * n and np.abs(x - px).max() <= reach * m


# -- chunked frames ----------------------------------------------------------------------------


DASK_CASES = {"4x4": ("4x4", (120, 140), (6, 9)),
              "5x5 vendor": ("5x5 vendor", (160, 180), (1, 7))}
CHUNKS = [(37, 53), (10, 13), (64, 41), (29, 1000)]


def _dask_frame(shape):
    frame = random_frame(shape, 13)
    frame[[10, 40, 77, 100], [3, 90, 120, shape[1] - 1]] = np.nan
    frame[60:63, 30:33] = np.nan
    return frame


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("case", list(DASK_CASES))
def test_a_dask_frame_gives_the_same_cube_to_the_last_bit(case, method):
    which, shape, origin = DASK_CASES[case]
    sensor = sensors()[which][0]
    frame = _dask_frame(shape)
    expected = demosaic(frame, sensor, method, sensor_origin_px=origin)
    for chunks in CHUNKS:
        lazy = demosaic(da.from_array(frame, chunks=chunks), sensor, method,
                        sensor_origin_px=origin)
        assert isinstance(lazy.data, da.Array)
        assert lazy.data.chunks[2] == (sensor.n_bands,)
        got = lazy.compute()
        assert got.dtype == expected.dtype
        assert np.array_equal(got.values, expected.values, equal_nan=True), chunks
        assert got.name == expected.name and got.attrs == expected.attrs
        for name in expected.coords:
            assert_array_equal(got[name].values, expected[name].values)


def test_a_dask_frame_on_a_distributed_cluster_gives_the_same_cube():
    from dask.distributed import Client, LocalCluster

    which, shape, origin = DASK_CASES["5x5 vendor"]
    sensor = sensors()[which][0]
    frame = _dask_frame(shape)
    expected = {method: demosaic(frame, sensor, method, sensor_origin_px=origin).values
                for method in ("ri", "nearest")}
    with (LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                       dashboard_address=":0") as cluster, Client(cluster)):
        for method, values in expected.items():
            lazy = demosaic(da.from_array(frame, chunks=(37, 53)), sensor, method,
                            sensor_origin_px=origin)
            assert np.array_equal(lazy.values, values, equal_nan=True), method


@pytest.mark.slow
@pytest.mark.parametrize("method", METHODS)
def test_a_whole_vendor_frame_in_chunks_gives_the_same_cube(method):
    """The real 5 x 5 sensor's whole frame (cut to its filter area), chunked as a reader
    would, with missing values."""
    sensor = bundled("imec_5x5_nir")
    frame = _dask_frame(sensor.size_px)
    expected = demosaic(frame, sensor, method)
    for chunks in [(256, 512), (1088, 300)]:
        got = demosaic(da.from_array(frame, chunks=chunks), sensor, method).values
        assert np.array_equal(got, expected.values, equal_nan=True), chunks


@pytest.mark.parametrize("method", ["bilinear", "ri"])
def test_a_stream_of_frames_is_each_frame_demosaicked(method):
    sensor, origin = sensors()["3x4"]
    frames = np.stack([random_frame((31, 37), s) for s in range(3)])
    frames[1, 5, 7] = np.nan
    stream = xr.DataArray(frames, dims=("frame", "y", "x"))
    single = [demosaic(f, sensor, method, sensor_origin_px=origin) for f in frames]
    for data in (frames, da.from_array(frames, chunks=(1, 13, 17))):
        cube = demosaic(stream.copy(data=data), sensor, method, sensor_origin_px=origin)
        assert cube.dims == ("frame", "y", "x", "band")
        for k, one in enumerate(single):
            assert np.array_equal(cube.values[k], one.values, equal_nan=True)
        assert_array_equal(cube["sensor_row"].values, single[0]["sensor_row"].values)


# -- refusals ----------------------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_demosaic_array_refuses_an_unknown_method_only(method):
    frame = random_frame((8, 8), 0)
    y0, x0 = np.repeat(np.arange(4), 4), np.tile(np.arange(4), 4)
    assert demosaic_array(frame, y0, x0, 4, 4, method).shape == (8, 8, 16)
    with pytest.raises(ValueError, match="unknown method 'cubic'"):
        demosaic_array(frame, y0, x0, 4, 4, "cubic")


@pytest.mark.parametrize("frame, sensor, kwargs, match", [
    (np.zeros((3, 10)), "mosaic_4x4_vis", {"sensor_origin_px": (0, 0)},
     r"holds no whole 4 x 4 tile"),
    (np.zeros((10, 3)), "mosaic_4x4_vis", {"sensor_origin_px": (0, 0)},
     r"holds no whole 4 x 4 tile"),
    (np.zeros((7, 10)), "imec_5x5_nir", {"sensor_origin_px": (0, 0)},
     r"holds no whole 5 x 5 tile inside the filter area"),
    (np.zeros((40, 40)), "mosaic_4x4_vis", {},
     r"the frame is 40 x 40 px but the sensor .* is 1088 x 2048 px.*origin_px"),
    (np.zeros((8, 8, 16)), "mosaic_4x4_vis", {"sensor_origin_px": (0, 0)},
     r"2-D mosaic frame, got shape \(8, 8, 16\) \(a cube is already split into bands"),
    (xr.DataArray(np.zeros((8, 8, 16)), dims=("y", "x", "band")), "mosaic_4x4_vis",
     {"sensor_origin_px": (0, 0)},
     r"frame of dims \(y, x\).*got dims \('y', 'x', 'band'\) \(a cube is already split"),
    (np.zeros(16), "mosaic_4x4_vis", {"sensor_origin_px": (0, 0)}, r"2-D mosaic frame"),
    (np.zeros((8, 8)), "mosaic_4x4_vis", {"sensor_origin_px": (-1, 0)},
     r"origin_px must be a sensor row and column \(whole numbers >= 0\)"),
    (np.zeros((40, 40)), "snapscan_vnir", {"sensor_origin_px": (0, 0)},
     r"sensor 'snapscan-vnir' is not a mosaic \(layout 'snapscan'\)"),
    (np.zeros((40, 40)), "mosaic_4x4_vis", {"sensor_origin_px": (0, 0), "method": "cubic"},
     r"unknown demosaic method 'cubic'; choose one of 'nearest', 'bilinear', 'ppid', 'ri'"),
], ids=["fewer rows than a tile", "fewer columns than a tile", "no tile in the filter area",
        "not the sensor's size", "a cube", "a cube DataArray", "1-D", "a negative origin",
        "not a mosaic",
        "unknown method"])
def test_demosaic_refuses(frame, sensor, kwargs, match):
    with pytest.raises(ValueError, match=match):
        demosaic(frame, bundled(sensor), **kwargs)


# -- the cube ----------------------------------------------------------------------------------


def test_the_cube_says_what_it_is_and_where_each_pixel_is():
    sensor = TOY_3X4  # size 90 x 100, filter area rows 2-86, columns 1-93
    counts = xr.DataArray(np.random.default_rng(1).integers(0, 4000, (90, 100)).astype(np.uint16),
                          dims=("y", "x"), attrs={"exposure_ms": 3.0})
    cube = demosaic(counts, sensor)
    assert cube.dims == ("y", "x", "band") and cube.shape == (85, 93, 12)
    assert cube.dtype == np.float32 and cube.name == "radiance"
    assert cube.attrs["demosaic_method"] == "ri"  # the default
    assert cube.attrs["mosaic_area_px"] == [2, 1, 85, 93]
    assert cube.attrs["exposure_ms"] == 3.0 and cube.attrs["sensor"] == sensor.name
    assert_array_equal(cube["wavelength"].values, sensor.cwl_nm)
    assert_array_equal(cube["fwhm"].values, sensor.fwhm_nm)
    assert cube["sensor_row"].dims == ("y", "band") and cube["sensor_col"].dims == ("x", "band")
    assert_array_equal(cube["sensor_row"].values, np.repeat(np.arange(2, 87)[:, None], 12, 1))
    assert_array_equal(cube["sensor_col"].values, np.repeat(np.arange(1, 94)[:, None], 12, 1))

    flat = xr.DataArray(random_frame((30, 33), 2, np.float64), dims=("y", "x"),
                        attrs={"units": "1"})
    cube = demosaic(flat, bundled("imec_5x5_nir"), "bilinear", sensor_origin_px=(1, 2015))
    assert cube.name == "reflectance" and cube.dtype == np.float64
    assert cube.attrs["units"] == "1" and cube.attrs["demosaic_method"] == "bilinear"
    assert cube.attrs["mosaic_area_px"] == [3, 2015, 28, 30]  # cut to the filter area
    assert_array_equal(cube["sensor_row"].values, np.repeat(np.arange(3, 31)[:, None], 25, 1))
    assert_array_equal(cube["sensor_col"].values,
                       np.repeat(np.arange(2015, 2045)[:, None], 25, 1))
    assert demosaic(flat, bundled("imec_5x5_nir"), "nearest", sensor_origin_px=(3, 0),
                    name="estimate").name == "estimate"


@pytest.mark.parametrize("call", [
    lambda sensor, frame, **kw: demosaic(frame, sensor, "nearest", **kw).values,
    lambda sensor, frame, **kw: mosaic_to_cube(frame, sensor, **kw).values,
    lambda sensor, frame, **kw: sensor.band_offsets_at(**kw),
], ids=["demosaic", "mosaic_to_cube", "Sensor.band_offsets_at"])
def test_origin_px_is_the_earlier_name_of_sensor_origin_px(call):
    sensor, origin = sensors()["3x4"]
    frame = np.random.default_rng(5).integers(0, 4096, (24, 32)).astype(np.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new name: no warning at all
        new = call(sensor, frame, sensor_origin_px=origin)
    with pytest.warns(FutureWarning, match=r"origin_px is the earlier name of sensor_origin_px "
                                           r"and will be removed in snapcorr 0\.3"):
        old = call(sensor, frame, origin_px=origin)
    assert_array_equal(new, old)
    with pytest.raises(TypeError, match="give sensor_origin_px once"):
        call(sensor, frame, sensor_origin_px=origin, origin_px=origin)
