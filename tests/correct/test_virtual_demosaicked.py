"""Virtual bands of full-resolution demosaicked frames of textured scenes, judged on an
independent simulation (tests/oracles/fieldsim.py: a textured scene of leaves and soils placed at
the sensor's centre and in its corner, every pixel's band through its own chief ray's responses,
every pupil ray scaling the real measured curves, 0.3 % noise), against the Gaussian virtual
bands of the true scene: every method at least as close as the nominal bands (the physical
band nearest each virtual band), the angle-aware bands as alike across the field as the
nominal ones, and errors over ``virtual_stderr`` with an RMS in [0.5, 2]."""

import dataclasses

import fieldsim as fs
import mosaicsim as ms
import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_LENS, PAPER_TRUTH, VENDOR_XML
from vendorfiles import imec_4x4, write_newer

from snapcorr.correct import virtual_bands
from snapcorr.cube import Sensor, demosaic, demosaicking_error
from snapcorr.cube.demosaicking import DEMOSAIC_METHODS, demosaic_array

NOISE = 0.003
F_NUMBER = 2.8
METHODS = ("vendor", "fitted", "angle-aware")
BLOCK = 16  # block means of 16 x 16 pixels


def vis_camera(directory):
    """The real imec 4x4 VIS responses behind a 460-630 nm band-pass (n_eff 1.7), in a
    vendor file written to ``directory`` whose reflectance matrix is made as a vendor makes
    one (no real 4x4 matrix is at hand): the simulator's camera and snapcorr's sensor."""
    fx = imec_4x4()
    bandpass = np.interp(fx.grid, fx.components[0][1], fx.components[0][2])
    cam = fs.Camera(fx.grid, fx.curves, bandpass, np.arange(16).reshape(4, 4), (0, 0),
                    (1088, 2048), 5.5, PAPER_TRUTH, F_NUMBER, 1.7,
                    np.sort([p[0][0] for p in fx.peaks]), np.full(16, 12.0))
    fx.matrices = [("hsi_reflectance", "reflectance", cam.virtual_nm, cam.virtual_fwhm_nm,
                    fs.vendor_like_matrix(cam))]
    path = write_newer(directory / "imec_4x4.xml", fx)
    return cam, dataclasses.replace(Sensor.load(path), n_eff=(1.7,) * 16)


def nir_camera():
    """The real 5x5 NIR vendor file (its responses, band-pass and matrix), n_eff 1.8."""
    mf = ms.read_older(VENDOR_XML)
    cam = fs.Camera(mf.grid, mf.curves, mf.bandpass, np.arange(25).reshape(5, 5), (3, 0),
                    (1088, 2048), 5.5, PAPER_TRUTH, F_NUMBER, 1.8, mf.virtual_nm,
                    np.full(mf.virtual_nm.size, mf.virtual_fwhm_nm))
    return cam, dataclasses.replace(Sensor.load(VENDOR_XML), n_eff=(1.8,) * 25,
                                    pixel_pitch_um=5.5)


@pytest.fixture(scope="module")
def vis(tmp_path_factory):
    return vis_camera(tmp_path_factory.mktemp("vis"))


@pytest.fixture(scope="module")
def nir():
    return nir_camera()


def _places(cam, size):
    """The same content at the sensor's centre and in its top-right corner, at the same
    phase of the tile (whole tiles from the tile grid's origin)."""
    n = cam.band_at.shape[0]
    r0, c0 = cam.tile_origin
    rows, cols = cam.size_px
    centre = (r0 + n * ((rows // 2 - size // 2 - r0) // n),
              c0 + n * ((cols // 2 - size // 2 - c0) // n))
    return {"centre": centre, "corner": (r0, c0 + n * ((cols - c0 - size) // n) - n)}


def _estimates(cam, sensor, placed, methods=METHODS, keep_demosaicking=True):
    """Nominal bands and each method's virtual bands of the RI-demosaicked frame."""
    frame = xr.DataArray(placed.raw.astype(np.float32), dims=("y", "x"), attrs={"units": "1"})
    cube = demosaic(frame, sensor, "ri", sensor_origin_px=placed.origin, name="reflectance")
    if not keep_demosaicking:  # what a cube demosaicked elsewhere looks like
        cube.attrs.pop("demosaic_method")
    nearest = [int(np.argmin(np.abs(np.asarray(sensor.cwl_nm) - w))) for w in cam.virtual_nm]
    out = {"nominal": (cube.values[..., nearest].astype(float), None)}
    for m in methods:
        ds = virtual_bands(cube, sensor, m, f_number=F_NUMBER, lens=PAPER_LENS,
                           cra_deg=placed.cra_deg)
        out[m] = ds["virtual"].values.astype(float), ds["virtual_stderr"].values
    return out


def figures(cam, sensor, weights, spectra, shade, seed, methods=METHODS,
             keep_demosaicking=True):
    """Per place and method: RMSE of 16 x 16 block means and per pixel, z RMS; and the RMS
    difference of block means between the centre and the corner."""
    rows = {}
    blocks = {}
    for k, (where, origin) in enumerate(_places(cam, weights.shape[0]).items()):
        placed = fs.place(cam, weights, spectra, shade, origin, NOISE, seed + k)
        for m, (est, stderr) in _estimates(cam, sensor, placed, methods,
                                           keep_demosaicking).items():
            err = est - placed.virtual
            z = (np.nan if stderr is None else float(np.sqrt(np.mean(
                np.mean(err.reshape(-1, err.shape[2]) ** 2, axis=0) / stderr**2))))
            rows[where, m] = {"block": float(np.sqrt(np.mean(fs.block_means(err, BLOCK) ** 2))),
                              "pixel": float(np.sqrt(np.mean(err**2))), "z": z}
            blocks[where, m] = fs.block_means(est, BLOCK)
    alike = {m: float(np.sqrt(np.mean((blocks["centre", m] - blocks["corner", m]) ** 2)))
             for m in ("nominal", *methods)}
    return rows, alike


def _check(rows, alike, methods=METHODS):
    for where in ("centre", "corner"):
        nominal = rows[where, "nominal"]
        for m in methods:
            got = rows[where, m]
            assert got["block"] <= nominal["block"], (where, m, got, nominal)
            assert got["pixel"] <= nominal["pixel"], (where, m, got, nominal)
            assert 0.5 <= got["z"] <= 2.0, (where, m, got)
    assert alike["angle-aware"] <= alike["nominal"], alike


def test_virtual_bands_of_a_demosaicked_textured_frame_hold(vis):
    """The 4x4 VIS sensor, a 64 x 64 dead-leaves scene at the centre and in the corner; the
    vendor's matrix and the angle-aware table (the fitted matrix goes the vendor's way through
    the error bars: the slow test below has it)."""
    cam, sensor = vis
    weights = fs.dead_leaves((64, 64), 8, seed=3)
    spectra = fs.scene_spectra(8, seed=3)
    methods = ("vendor", "angle-aware")
    _check(*figures(cam, sensor, weights, spectra, np.ones((64, 64)), seed=30,
                     methods=methods), methods=methods)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("scene", ["dead leaves", "msfasim"])
@pytest.mark.parametrize("which", ["vis", "nir"])
def test_virtual_bands_of_demosaicked_frames_hold_over_scenes_and_seeds(which, scene, seed,
                                                                        request):
    """Both real sensors, 128 x 128 scenes of both kinds (ten spectra, smooth shading)."""
    cam, sensor = request.getfixturevalue(which)
    weights, spectra, shade = fs.textured_scene((128, 128), 10, seed)
    if scene == "dead leaves":
        weights = fs.dead_leaves((128, 128), 10, seed)
    _check(*figures(cam, sensor, weights, spectra, shade, seed=10 * seed + 1))


def test_the_cross_validated_demosaicking_error_bounds_the_true_one(vis):
    """The cross-validated error, scaled to the pixels' distances from their bands' samples,
    against the true one: an upper bound (a held-out sample also loses its own value from the
    pseudo-panchromatic guide), not by more than 2 x in RMS."""
    cam, sensor = vis
    weights = fs.dead_leaves((96, 96), 8, seed=5)
    placed = fs.place(cam, weights, fs.scene_spectra(8, seed=5), np.ones((96, 96)),
                      _places(cam, 96)["corner"], NOISE, seed=50)
    frame = xr.DataArray(placed.raw.astype(np.float32), dims=("y", "x"), attrs={"units": "1"})
    cube = demosaic(frame, sensor, "ri", sensor_origin_px=placed.origin, name="reflectance")
    true = np.mean((cube.values - placed.bands).reshape(-1, 16) ** 2, axis=0)
    mse, count = demosaicking_error(cube, sensor, noise_var=NOISE**2)
    assert count == 96 * 96 + 16 * 8 * 8  # each sample once, and each 3 x 3 block centre
    ratio = np.sqrt(mse / true)
    assert 0.9 <= np.median(ratio) <= 2.0 and ratio.min() >= 0.7, ratio


@pytest.mark.parametrize("method", sorted(DEMOSAIC_METHODS))
def test_fill_missing_estimates_a_missing_sample_and_nothing_else(method):
    rng = np.random.default_rng(7)
    frame = rng.uniform(0.2, 0.8, (24, 24))
    y0, x0 = np.divmod(np.arange(16), 4)
    holed = frame.copy()
    holed[9, 6] = np.nan  # band 4 * 1 + 2 = 6's sample
    plain = demosaic_array(holed, y0, x0, 4, 4, method)
    filled = demosaic_array(holed, y0, x0, 4, 4, method, fill_missing=True)
    assert np.isnan(plain[9, 6, 6]) and np.isfinite(filled[9, 6, 6])
    assert 0.2 <= filled[9, 6, 6] <= 0.8  # from the band's samples around it
    same = np.ones(plain.shape, bool)
    same[9, 6, 6] = False
    np.testing.assert_array_equal(filled[same], plain[same])


def test_a_cube_demosaicked_elsewhere_keeps_the_pixel_noise_model(vis):
    """Without ``demosaic_method`` nothing says how the cube was made: no demosaicking error
    is assumed (the bands' own noise model, as for a tile cube). A dask cube gives the same
    error bars as in memory."""
    cam, sensor = vis
    weights = fs.dead_leaves((64, 64), 8, seed=4)
    placed = fs.place(cam, weights, fs.scene_spectra(8, seed=4), np.ones((64, 64)),
                      _places(cam, 64)["centre"], NOISE, seed=40)
    frame = xr.DataArray(placed.raw.astype(np.float32), dims=("y", "x"), attrs={"units": "1"})
    cube = demosaic(frame, sensor, "ri", sensor_origin_px=placed.origin, name="reflectance")
    with_dem = virtual_bands(cube, sensor, "fitted")
    assert "demosaicking (ri)" in with_dem["virtual_stderr"].attrs["source"]
    lazy = demosaic(frame.chunk({"y": 32, "x": 32}), sensor, "ri", sensor_origin_px=placed.origin,
                    name="reflectance")  # a dask cube: its patches read, the same figures
    np.testing.assert_allclose(virtual_bands(lazy, sensor, "fitted")["virtual_stderr"].values,
                               with_dem["virtual_stderr"].values, rtol=1e-5)
    cube.attrs.pop("demosaic_method")
    without = virtual_bands(cube, sensor, "fitted")
    assert "demosaicking" not in without["virtual_stderr"].attrs["source"]
    assert np.all(with_dem["virtual_stderr"].values > without["virtual_stderr"].values)
