"""Virtual bands: the vendor's matrix applied exactly, and the fitted and angle-aware Wiener
estimates judged on an independent forward model (tests/oracles/mosaicsim.py: pupil rays scaling the
real 5x5 sensor's measured curves, its band-pass) with spectra the prior was not fitted to
(PROSPECT-D leaves, soils and their mixtures), against the vendor's own matrix."""

import dataclasses

import mosaicsim as ms
import numpy as np
import pytest
import xarray as xr
from conftest import PAPER_LENS, PAPER_TRUTH, VENDOR_XML
from numpy.testing import assert_allclose
from vendorfiles import imec_4x4, write_newer

from snapcorr.correct import virtual_bands
from snapcorr.cube import Sensor, make_cube
from snapcorr.data import sensor_path
from snapcorr.optics.wiener import PRIOR

NOISE = 0.003  # flat-fielded band values' noise, as the issue's measurement had


@pytest.fixture(scope="module")
def nir():
    """The real 5x5 NIR sensor with an index (the file gives none) and its pitch."""
    return dataclasses.replace(Sensor.load(VENDOR_XML), n_eff=(1.8,) * 25, pixel_pitch_um=5.5)


@pytest.fixture(scope="module")
def scene():
    """Held-out spectra (the prior was fitted to colour samples) and their true virtual bands."""
    mf = ms.read_older(VENDOR_XML)
    X = np.concatenate([ms.leaves(120, 1), ms.soils_and_mixtures(120, 2)])
    return mf, X, ms.virtual_truth(mf, X)


def _cube(values, sensor, name="reflectance"):
    """Band values in the file's order (the simulator's) as a cube in the sensor's."""
    return make_cube(values[:, None, sensor.vendor_band].astype(np.float32), sensor.cwl_nm,
                     name=name)


def _bands(mf, X, f_number, cra, seed):
    R = ms.responses(mf, PAPER_TRUTH, f_number, cra, 1.8)
    rng = np.random.default_rng(seed)
    return ms.band_values(R, X) + NOISE * rng.standard_normal((X.shape[0], R.shape[0]))


def _run(values, sensor, method, f_number=None, cra=None):
    kw = {} if f_number is None else dict(f_number=f_number, lens=PAPER_LENS,
                                          cra_deg=np.full((values.shape[0], 1), float(cra)))
    ds = virtual_bands(_cube(values, sensor), sensor, method, **kw)
    return ds["virtual"].values[:, 0, :], ds["virtual_stderr"].values


def _rmse(est, truth):
    return float(np.sqrt(np.mean((est - truth) ** 2)))


def test_the_prior_is_the_maximum_likelihood_fit_to_public_reflectances():
    """The three numbers in snapcorr.optics.wiener.PRIOR, re-derived from colour-science's
    ColorChecker N Ohta, CIE 1995 and NIST CQS test samples and CIE 2017 CES (380-780 nm)."""
    colour = pytest.importorskip("colour")
    from colour.quality.cfi2017 import load_TCS_CIE2017
    from colour.quality.datasets import SDS_TCS, SDS_VS
    from scipy.optimize import minimize

    grid = np.arange(380.0, 781.0, 5.0)
    lib = [np.interp(grid, sd.wavelengths, sd.values)
           for d in (colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"], SDS_TCS["CIE 1995"],
                     SDS_VS[next(iter(SDS_VS))]) for sd in d.values()]
    ces = load_TCS_CIE2017(colour.SpectralShape(380, 780, 5))
    lib = np.array(lib + list(ces.values.T))
    assert lib.shape == (152, grid.size)
    d = np.abs(grid[:, None] - grid[None, :])

    def nll(p):  # Gaussian process with exponential covariance about a constant mean
        mean, sd, length = p[0], np.exp(p[1]), np.exp(p[2])
        L = np.linalg.cholesky(sd**2 * np.exp(-d / length) + 1e-6 * np.eye(grid.size))
        a = np.linalg.solve(L, (lib - mean).T)
        return 0.5 * np.sum(a**2) + lib.shape[0] * np.sum(np.log(np.diag(L)))

    fit = minimize(nll, [0.4, np.log(0.2), np.log(50.0)], method="Nelder-Mead",
                   options={"maxiter": 3000, "xatol": 1e-4, "fatol": 1e-3})
    assert fit.x[0] == pytest.approx(PRIOR["mean"], abs=0.005)
    assert np.exp(fit.x[1]) == pytest.approx(PRIOR["sd"], rel=0.02)
    assert np.exp(fit.x[2]) == pytest.approx(PRIOR["length_nm"], rel=0.05)


# -- the vendor's matrix, applied exactly ---------------------------------------------------------


def test_the_vendor_matrices_are_applied_exactly(tmp_path, nir):
    fx = imec_4x4()
    sensor = Sensor.load(write_newer(tmp_path / "s.xml", fx))
    rng = np.random.default_rng(1)
    values = rng.uniform(0.05, 0.9, (6, 5, 16)).astype(np.float32)
    v = list(sensor.vendor_band)  # the file's order of the bands, the simulator's
    flat = make_cube(values[..., v], sensor.cwl_nm, name="reflectance")
    ds = virtual_bands(flat, sensor, "vendor")  # flat-fielded: the reflectance matrix
    ref = np.einsum("vb,yxb->yxv", fx.matrices[0][4], values.astype(float))
    assert_allclose(ds["virtual"].values, ref, rtol=1e-6, atol=1e-6)
    assert_allclose(ds["virtual_wavelength"].values, fx.matrices[0][2])
    dn = rng.integers(0, 1023, (6, 5, 16)).astype(np.uint16)
    counts = make_cube(dn[..., v], sensor.cwl_nm, name="radiance")
    ds = virtual_bands(counts, sensor, "vendor")  # counts: the irradiance matrix
    ref = np.einsum("vb,yxb->yxv", fx.matrices[1][4], dn.astype(float))
    assert_allclose(ds["virtual"].values, ref, rtol=1e-6, atol=1e-6)
    assert "virtual_stderr" not in ds  # no prior for counts: no error bar claimed
    ds = virtual_bands(flat, sensor, "vendor", matrix="hsi_irradiance")
    assert "white" in ds["virtual"].attrs["source"]


def test_the_older_files_irradiance_matrix_takes_a_white_for_flat_fielded_values(nir):
    mf = ms.read_older(VENDOR_XML)
    values = np.random.default_rng(2).uniform(0.1, 0.8, (7, 25))
    got = virtual_bands(_cube(values, nir), nir, "vendor")["virtual"].values[:, 0, :]
    white = (mf.curves * mf.bandpass).sum(axis=1)  # each band's signal from a flat white
    A = mf.coefficients * white / (mf.coefficients @ white)[:, None]
    assert_allclose(got, values @ A.T, rtol=1e-5, atol=1e-6)
    assert_allclose(A.sum(axis=1), 1.0)  # a flat spectrum stays flat


# -- accuracy on an independent forward model ------------------------------------------------


def test_fitted_beats_the_vendor_matrix_at_normal_incidence(nir, scene):
    mf, X, truth = scene
    values = _bands(mf, X, None, None, seed=3)
    vendor, vendor_err = _run(values, nir, "vendor")
    fitted, fitted_err = _run(values, nir, "fitted")
    assert _rmse(fitted, truth) <= 0.8 * _rmse(vendor, truth)
    for est, err in ((vendor, vendor_err), (fitted, fitted_err)):  # the error bars cover
        z = np.sqrt(np.mean((est - truth) ** 2, axis=0)) / err
        assert 0.5 <= np.sqrt(np.mean(z**2)) <= 2.0


F_NUMBERS = [pytest.param(1.4, marks=pytest.mark.slow), 2.8, pytest.param(8.0,
                                                                            marks=pytest.mark.slow)]


@pytest.mark.parametrize("f_number", F_NUMBERS)
def test_angle_aware_off_axis_beats_the_vendor_matrix_on_axis(nir, scene, f_number):
    """At CRA 12 and 17 deg the angle-aware estimate's error is at most 0.85 of the vendor
    matrix's on the axis; the fitted (normal-incidence) matrix degrades off axis, and every
    method's error bar covers its error."""
    mf, X, truth = scene
    centre = _bands(mf, X, f_number, 0.0, seed=4)
    vendor_on_axis = _rmse(_run(centre, nir, "vendor", f_number, 0.0)[0], truth)
    for cra in (12.0, 17.0):
        values = _bands(mf, X, f_number, cra, seed=5)
        results = {m: _run(values, nir, m, f_number, cra)
                   for m in ("vendor", "fitted", "angle-aware")}
        err = {m: _rmse(est, truth) for m, (est, _) in results.items()}
        assert err["angle-aware"] <= 0.85 * vendor_on_axis, (cra, err, vendor_on_axis)
        assert err["angle-aware"] < err["fitted"]
        for m, (est, stderr) in results.items():
            z = np.sqrt(np.mean((est - truth) ** 2, axis=0)) / stderr
            assert 0.5 <= np.sqrt(np.mean(z**2)) <= 2.0, (m, cra)


def test_numpy_dask_and_full_resolution_cubes_agree(nir):
    rng = np.random.default_rng(6)
    values = rng.uniform(0.1, 0.7, (12, 10, 25)).astype(np.float32)
    cube = make_cube(values, nir.cwl_nm, name="reflectance")
    cra = np.linspace(2.0, 16.0, 120).reshape(12, 10)
    for method in ("vendor", "fitted", "angle-aware"):
        kw = dict(f_number=2.0, lens=PAPER_LENS, cra_deg=cra, noise=NOISE)
        a = virtual_bands(cube, nir, method, **kw)
        b = virtual_bands(cube.chunk({"y": 5, "x": 4}), nir, method, **kw)
        assert b["virtual"].chunks is not None
        xr.testing.assert_allclose(a["virtual"], b["virtual"].compute(), rtol=1e-6)
        assert a["virtual"].dtype == np.float32


# -- refusals ------------------------------------------------------------------------------------


def test_what_cannot_be_done_is_refused_in_one_line(tmp_path, nir):
    toml = Sensor.load(sensor_path("mosaic_5x5_nir"))
    cube = make_cube(np.ones((2, 2, 25), np.float32), toml.cwl_nm, name="reflectance")
    with pytest.raises(ValueError, match=r"measured responses.*vendor calibration file"):
        virtual_bands(cube, toml, "fitted")
    with pytest.raises(ValueError, match="no correction matrix"):
        virtual_bands(cube, toml, "vendor")
    fx = imec_4x4()
    fx.matrices = []
    bare = Sensor.load(write_newer(tmp_path / "bare.xml", fx))
    c16 = make_cube(np.ones((2, 2, 16), np.float32), bare.cwl_nm, name="reflectance")
    with pytest.raises(ValueError, match="no correction matrix"):
        virtual_bands(c16, bare, "vendor")
    c25 = make_cube(np.ones((2, 2, 25), np.float32), nir.cwl_nm, name="reflectance")
    with pytest.raises(ValueError, match=r"no correction matrix named 'x'.*\['custom'\]"):
        virtual_bands(c25, nir, "vendor", matrix="x")
    counts = make_cube(np.ones((2, 2, 25), np.uint16), nir.cwl_nm, name="radiance")
    with pytest.raises(ValueError, match="flat-field the cube first"):
        virtual_bands(counts, nir, "fitted")
    with pytest.raises(ValueError, match="n_eff"):
        virtual_bands(c25, Sensor.load(VENDOR_XML), "angle-aware", f_number=2.0,
                      lens=PAPER_LENS, cra_deg=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="unknown virtual_bands 'magic'"):
        virtual_bands(c25, nir, "magic")


def _brute_force_table(data, cra, nodes, mats):
    """``A(cra) @ d`` pixel by pixel: the table's matrix interpolated linearly in the angle
    (clamped at the table's ends), then the product, in float64."""
    out = np.empty((*data.shape[:2], mats.shape[1]))
    for y in range(data.shape[0]):
        for x in range(data.shape[1]):
            c = min(max(float(cra[y, x]), nodes[0]), nodes[-1])
            k = min(int(np.searchsorted(nodes, c, side="right")) - 1, nodes.size - 2)
            t = (c - nodes[k]) / (nodes[k + 1] - nodes[k])
            a = (1 - t) * mats[k] + t * mats[k + 1]
            out[y, x] = np.einsum("vb,b->v", a, data[y, x].astype(float))
    return out


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_table_kernel_is_the_interpolated_matrix_product(dtype):
    from types import SimpleNamespace

    from snapcorr.correct.virtual import apply_table

    rng = np.random.default_rng(7)
    ny, nx, nb, nv = 9, 13, 16, 11
    nodes = np.array([0.0, 2.5, 6.0, 11.0, 20.0])
    table = SimpleNamespace(cra_deg=nodes, matrices=rng.normal(0, 1, (nodes.size, nv, nb)))
    data = rng.uniform(0, 1.5, (ny, nx, nb)).astype(dtype)
    cra = rng.uniform(-3, 24, (ny, nx))  # beyond both ends of the table: clamped
    cra[0, :nodes.size] = nodes  # on the nodes themselves
    cra[1, 0], cra[1, 1] = nodes[-1] - 1e-9, nodes[0] + 1e-9  # at the edge intervals
    data[2, 3, 0] = np.nan  # a NaN in the first band, one in the last, a whole pixel
    data[4, 5, -1] = np.nan
    data[6, 7, :] = np.nan
    got = apply_table(data, cra, table, dtype)
    want = _brute_force_table(data, cra.astype(dtype), nodes.astype(dtype),
                              table.matrices.astype(dtype))
    assert got.shape == (ny, nx, nv) and got.dtype == dtype
    nan = np.isnan(data).any(axis=2)
    assert np.isnan(got[nan]).all() and not np.isnan(got[~nan]).any()
    tol = 1e-4 if dtype == np.float32 else 1e-11
    assert_allclose(got[~nan], want[~nan], rtol=tol, atol=tol)
