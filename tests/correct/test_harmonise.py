"""Spectra that are the same anywhere in the field (``correct_cube(harmonise=True)``).

The cubes are made by ``tests/oracles/spectralsim.py``, which shares no code with snapcorr: it
samples the vignetted pupil point by point and scales each ray's whole filter curve by the shift
law.
The pixels are those at the three chief-ray angles of Goossens et al. (1.9, 10.3, 17.4 deg).
"""

from __future__ import annotations

import numpy as np
import pytest
import spectralsim as sim
from conftest import PAPER_TRUTH
from flatsim import LensTruth

from snapcorr import Lens
from snapcorr.correct import correct_cube
from snapcorr.correct.harmonise import harmonise_spectra
from snapcorr.cube import Sensor, make_cube

PAPER = PAPER_TRUTH
PLAIN = LensTruth(21.0, (), 0.06, 1.3, name="no vignetting")
CWL = np.arange(470.0, 901.0, 5.0)  # 87 bands of 12 nm every 5 nm
SHAPE, PITCH, CENTER = (6, 160), 44.0, (2.0, 3.0)  # CRA 0-18.3 deg along a row


def as_lens(truth):
    return Lens(truth.exit_pupil_mm, truth.circles, truth.magnification,
                truth.pupil_magnification, name=truth.name)


def spread_at_paper_angles(ds, values):
    """The largest difference, over bands, between the spectra of the pixels nearest CRA 1.9,
    10.3 and 17.4 deg."""
    cra = ds["cra_deg"].values
    pix = [np.unravel_index(np.argmin(np.abs(cra - c)), cra.shape) for c in (1.9, 10.3, 17.4)]
    spectra = np.array([values[p] for p in pix])
    keep = np.all(np.isfinite(spectra), axis=0)
    return float(np.max(np.ptp(spectra[:, keep], axis=0)))


#: A didymium (Nd/Pr) glass: Lorentzian absorption lines (centre nm, FWHM nm, optical depth),
#: synthetic, placed where neodymium and praseodymium absorb (strongest at 577-586, 733-751
#: and 794-806.5 nm).
ND_LINES = [(441, 6, 0.15), (482, 5, 0.35), (512, 5, 0.25), (521, 4, 0.4), (527, 5, 0.45),
            (573, 4, 0.5), (577, 3, 0.8), (582, 4, 1.2), (586, 4, 0.9), (627, 5, 0.12),
            (680, 4, 0.15), (733, 3, 0.5), (740, 3, 0.9), (746, 4, 0.8), (751, 4, 0.5),
            (794, 3, 0.6), (799, 3, 1.0), (804, 3, 1.3), (806.5, 2.5, 0.9),
            (866, 4, 0.3), (873, 3, 0.45), (880, 3, 0.35)]


def didymium_glass(lam):
    lam = np.asarray(lam, float)
    tau = np.zeros(lam.shape)
    for c, w, a in ND_LINES:
        tau += a / (1 + ((lam - c) / (w / 2)) ** 2)
    return 0.91 * np.exp(-tau)


def _spreads(target, profile, truth, f_number, seed):
    clean = sim.target_cube(target, cwl_nm=CWL, fwhm_nm=12.0, n_eff=1.8, f_number=f_number,
                            lens=truth, shape=SHAPE, pixel_pitch_um=PITCH, center_px=CENTER,
                            profile=profile)
    noisy = clean + np.random.default_rng(seed).normal(0, 0.002 * clean.max(), clean.shape)
    sensor = Sensor("t", "snapscan", PITCH, CWL, 12.0, 1.8, profile=profile)
    ds = correct_cube(make_cube(noisy.astype(np.float32), CWL), sensor, f_number,
                      as_lens(truth), center_px=CENTER, resample=True, harmonise=True)
    return (ds, spread_at_paper_angles(ds, ds["resampled"].values),
            spread_at_paper_angles(ds, ds["harmonised"].values))


@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.slow),
                                  pytest.param(2, marks=pytest.mark.slow)])
@pytest.mark.parametrize(("target", "profile"), [("didymium", "gaussian"),
                                                  ("rare_earth_glass", "airy")])
def test_sharp_red_absorption_at_f1_4_is_harmonised_over_seeds(target, profile, seed):
    """Glass with sharp absorption near 800 nm behind the paper's lens at f/1.4, where the
    responses are far from Gaussian: harmonising must at least halve the resampled spread
    for every seed. Widening by FWHMs in quadrature reached only 0.56-0.87 here (it gave the
    pixels near the axis twice the variance they lack); by the kernels' variances, 0.2-0.4."""
    fn = didymium_glass if target == "didymium" else sim.rare_earth_glass
    _, resampled, harmonised = _spreads(fn, profile, PAPER, 1.4, seed)
    assert harmonised <= 0.5 * resampled, (harmonised, resampled)


CASES = [("rare_earth_glass", "gaussian", "paper", 1.4),
         ("colour_filter", "gaussian", "paper", 1.4),
         ("emission_lines", "gaussian", "plain", 1.4),
         ("rare_earth_glass", "gaussian", "plain", 2.8),
         pytest.param("rare_earth_glass", "airy", "paper", 1.4, marks=pytest.mark.slow)]


@pytest.mark.parametrize(("target", "profile", "lens", "f_number"), CASES)
def test_harmonised_spectra_agree_across_the_field(target, profile, lens, f_number):
    """At 0.2 % noise the largest difference between the three pixels' spectra after
    harmonising is at most half of that after resampling alone."""
    truth = {"paper": PAPER, "plain": PLAIN}[lens]
    clean = sim.target_cube(getattr(sim, target), cwl_nm=CWL, fwhm_nm=12.0, n_eff=1.8,
                            f_number=f_number, lens=truth, shape=SHAPE, pixel_pitch_um=PITCH,
                            center_px=CENTER, profile=profile)
    noisy = clean + np.random.default_rng(0).normal(0, 0.002 * clean.max(), clean.shape)
    sensor = Sensor("t", "snapscan", PITCH, CWL, 12.0, 1.8, profile=profile)
    ds = correct_cube(make_cube(noisy.astype(np.float32), CWL), sensor, f_number, as_lens(truth),
                      center_px=CENTER, resample=True, harmonise=True)
    resampled = spread_at_paper_angles(ds, ds["resampled"].values)
    harmonised = spread_at_paper_angles(ds, ds["harmonised"].values)
    assert harmonised <= 0.5 * resampled, (harmonised, resampled)
    # the common response is the widest in the field, and said so
    assert np.allclose(ds["fwhm_harmonised"].values,
                       np.nanmax(ds["fwhm_corrected"].values, axis=(0, 1)), atol=0.02)
    assert "widest" in ds["harmonised"].attrs["common_response"]
    # NaN exactly where resampling would extrapolate
    np.testing.assert_array_equal(np.isnan(ds["harmonised"].values),
                                  np.isnan(ds["resampled"].values))


def test_the_tabulated_path_is_the_direct_one():
    """A Snapscan cube takes tabulated weights; the direct computation per pixel agrees."""
    from snapcorr.correct.harmonised import HARMONISE_NODE_STEP_DEG

    rng = np.random.default_rng(1)
    ny, nx = 20, 30
    cra = rng.uniform(0.0, 18.0, (ny, nx))
    nodes = np.linspace(0.0, 18.0, round(18.0 / HARMONISE_NODE_STEP_DEG) + 1)  # the library's
    node_scale = 1.0 - 0.0005 * nodes**1.5
    node_sigma = np.sqrt(np.outer(18.0 - nodes, np.linspace(0.5, 1.5, CWL.size)) / 4.0)
    scale = np.interp(cra, nodes, node_scale)[..., None]
    sigma = np.stack([np.sqrt(np.interp(cra, nodes, node_sigma[:, k] ** 2))
                      for k in range(CWL.size)], axis=-1)
    column = np.zeros(CWL.size, int)
    # weights interpolated between nodes: on white noise across bands (the worst case) and
    # on spectra as 12 nm filters see them
    noise = rng.random((ny, nx, CWL.size))
    k = np.arange(-8, 9)
    smooth = np.apply_along_axis(lambda v: np.convolve(v, np.exp(-0.5 * (k * 5 / 5.1) ** 2) /
                                                       np.exp(-0.5 * (k * 5 / 5.1) ** 2).sum(),
                                                       "same"), 2, rng.random((ny, nx, 200)))
    smooth = smooth[:, :, 20:20 + CWL.size]
    for data, atol in ((noise, 2e-4), (smooth, 3e-5)):  # (1.8e-4, 2.1e-5)
        direct = harmonise_spectra(data, scale, column, CWL, sigma)
        table = harmonise_spectra(data, scale, column, CWL, cra=cra, nodes=nodes,
                                  node_scale=node_scale, node_sigma=node_sigma)
        np.testing.assert_array_equal(np.isnan(direct), np.isnan(table))
        np.testing.assert_allclose(table, direct, atol=atol, equal_nan=True)


def test_the_weights_start_on_a_vector_boundary_and_any_copy_gives_the_same_values():
    """The diagonals are laid out on a 64-byte boundary (no vector read straddles two cache
    lines); weights that are not (unpickled, as a dask worker receives them) are put on one
    for the pass, and the values are the same to the bit."""
    import pickle

    from snapcorr.correct import harmonise
    from snapcorr.correct.harmonise import node_weights

    rng = np.random.default_rng(6)
    nodes = np.linspace(0.0, 18.0, 40)
    w = node_weights(CWL, nodes, 1.0 - 0.0005 * nodes**1.5,
                     np.sqrt(np.outer(18.0 - nodes, np.linspace(0.5, 1.5, CWL.size)) / 4.0))
    assert w.D.ctypes.data % 64 == 0 and w.D.strides[1] % 32 == 0
    raw = np.empty(w.D.nbytes + 64, np.uint8)
    start = -raw.ctypes.data % 64 + 16  # numpy's own boundary, not a vector's
    off = raw[start:start + w.D.nbytes].view(np.float32).reshape(w.D.shape)
    off[...] = w.D
    moved = harmonise._aligned(off)
    assert moved.ctypes.data % 64 == 0 and moved is not off
    np.testing.assert_array_equal(moved, w.D)
    assert harmonise._aligned(w.D) is w.D
    data = rng.random((6, 9, CWL.size)).astype(np.float32)
    cra = rng.uniform(0.0, 18.0, (6, 9))
    scale = np.interp(cra, nodes, 1.0 - 0.0005 * nodes**1.5)[..., None]
    column = np.zeros(CWL.size, int)
    want = harmonise_spectra(data, scale, column, CWL, cra=cra, weights=w)
    for other in (w._replace(D=off), pickle.loads(pickle.dumps(w))):
        got = harmonise_spectra(data, scale, column, CWL, cra=cra, weights=other)
        np.testing.assert_array_equal(got, want)


