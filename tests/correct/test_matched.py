"""Harmonised spectra of a mosaic sensor with measured responses (``correct_cube(harmonise=True)``).

The frames are made here by an independent forward model (it uses numpy, scipy and the pupil
quadrature of ``tests/oracles/spectralsim.py``, never snapcorr): the real imec 4x4 VIS responses of
``tests/data`` with a band-pass of 460-630 nm (``vendorfiles.imec_4x4``, written to a vendor file
of the newer variant for snapcorr to read), behind the paper's lens on the whole 1088 x 2048
sensor of 5.5 um pixels. Every ray of a pixel's vignetted exit pupil scales each band's whole
measured curve, ``T_b(lambda / a)`` with ``a = sqrt(1 - sin^2 phi / n_eff^2)`` (each ray's curve
keeps its peak shape), behind the band-pass, which does not move; a flat-fielded value of a
uniform target under equal-energy light is ``int rho R / int R`` over the pixel's response ``R``.
Spots of one tile sit at chief-ray angles of 1-16 deg, each spectrum on its own azimuth near a
diagonal; only their pixels are simulated, the rest of the frame is a flat 0.5. Reflectances:
PROSPECT-D leaves and a soil (prosail) and colour samples (colour-science), none of them a prior
the correction fits; the featured targets are a didymium-like glass and single absorptions.

The Gaussian twin has the same layout, Gaussian filters at the file's main peaks as wide as each
measured band is at normal incidence (through the band-pass), and no band-pass; it is
harmonised by the modelled path. The spread of a band is the largest difference between the
spots' values; a method's spread is the largest over the bands it gives.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import vendorfiles
import xarray as xr
from conftest import PAPER_LENS, PAPER_TRUTH
from scipy.interpolate import CubicSpline
from spectralsim import pupil_samples

from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, mosaic_to_cube, read_dataset, write_cube

SIZE, PITCH_MM, N_EFF = (1088, 2048), 5.5e-3, 1.7
CENTRE = ((SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2)
#: The spectral integrals' grid, nm: the band-pass (logistic edges of 2 nm at 460 and 630 nm)
#: is below 1e-5 of its maximum outside it.
LAM = np.arange(430.0, 670.0 + 1e-9, 0.05)
#: Spots' azimuths (deg from the sensor's rows), one per spectrum: near the diagonals, where
#: a spot at CRA 16 deg is still on the sensor (21-29 deg in every quadrant).
AZIMUTHS = (22.0, 27.0, 158.0, 153.0, 202.0, 207.0, 338.0, 333.0)
FILL = 0.5


# -- the independent forward model ---------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Truth:
    """Each band's curve and the band-pass as the file gives them (its samples, linear
    between), or Gaussian filters without a band-pass (the twin)."""

    grid: np.ndarray
    curves: np.ndarray
    bp_grid: np.ndarray | None
    bandpass: np.ndarray | None

    def transmission(self, b, lam):
        return np.interp(lam, self.grid, self.curves[b], left=0.0, right=0.0)

    def system(self, lam):
        if self.bandpass is None:
            return np.ones_like(lam)
        return np.interp(lam, self.bp_grid, self.bandpass, left=0.0, right=0.0)


def measured_truth(fx):
    (_, bp_grid, bp), = fx.components
    return Truth(fx.grid, fx.curves, bp_grid, bp)


def twin_truth(fx):
    """Gaussians at the file's main peaks, each as wide (FWHM) as the measured band through the
    band-pass at normal incidence."""
    lam = np.arange(400.0, 700.0, 0.01)
    meas = measured_truth(fx)
    peaks = np.array([p[0][0] for p in fx.peaks])
    fwhm = np.empty(peaks.size)
    for b, peak in enumerate(peaks):
        r = meas.transmission(b, lam) * meas.system(lam)
        i = int(np.searchsorted(lam, peak))
        while r[i + 1] > r[i]:
            i += 1
        while r[i - 1] > r[i]:
            i -= 1
        half = 0.5 * r[i]
        j, k = i, i
        while r[j] >= half:
            j -= 1
        while r[k] >= half:
            k += 1
        fwhm[b] = lam[k] - lam[j]
    grid = np.arange(300.0, 900.0, 0.02)
    curves = np.exp(-4 * np.log(2) * ((grid[None] - peaks[:, None]) / fwhm[:, None]) ** 2)
    return Truth(grid, curves, None, None), peaks, fwhm


def pixel_rays(f_number, d_mm, nodes=(96, 48)):
    """Each ray's scale ``a`` and its weight over the pixel's vignetted pupil."""
    u, v, w = pupil_samples(PAPER_TRUTH, f_number, d_mm, theta_nodes=nodes[0], r_nodes=nodes[1])
    t2 = ((u - d_mm) ** 2 + v**2) / PAPER_TRUTH.exit_pupil_mm**2
    return np.sqrt(1.0 - t2 / (1.0 + t2) / N_EFF**2), w


def pixel_values(truth, spectra, f_number, pixels, *, lam=LAM, shift_step_nm=0.05,
                 nodes=(96, 48)):
    """Flat-fielded values ``int rho R / int R`` of the pixels ``(band, d_mm, spectrum)``.

    With ``Q_b(a) = int rho S T_b(lambda / a) dlambda`` (and ``Q1`` with ``rho = 1``) the value is
    ``sum_k w_k Q_b(a_k) / sum_k w_k Q1_b(a_k)`` over the pixel's rays; ``Q`` is summed on
    ``lam`` at scales ``shift_step_nm`` of shift (at 700 nm) apart and interpolated by cubic
    splines in ``a``."""
    rays = {d: pixel_rays(f_number, d, nodes) for d in {p[1] for p in pixels}}
    a_min = min(float(a.min()) for a, _ in rays.values())
    a_nodes = np.linspace(a_min - 1e-4, 1.0,
                          int(np.ceil((1.0 - a_min) * 700 / shift_step_nm)) + 4)
    rho = np.stack([np.interp(lam, s[0], s[1]) for s in spectra] + [np.ones(lam.size)], axis=1)
    S = truth.system(lam)
    splines = {}
    for b in sorted({p[0] for p in pixels}):
        T = np.stack([truth.transmission(b, lam / a) for a in a_nodes]) * S
        splines[b] = CubicSpline(a_nodes, T @ rho, axis=0)  # (nodes, spectra + 1)
    out = np.empty(len(pixels))
    for i, (b, d, s) in enumerate(pixels):
        a, w = rays[d]
        q = splines[b](a)
        out[i] = (w @ q[:, s]) / (w @ q[:, -1])
    return out


def spot_origins(cra_deg, azimuth_deg):
    """The first pixel (a multiple of the tile) of the tile nearest each angle on an azimuth."""
    out = []
    for c in cra_deg:
        r_px = PAPER_TRUTH.exit_pupil_mm * np.tan(np.deg2rad(c)) / PITCH_MM
        row = CENTRE[0] + r_px * np.sin(np.deg2rad(azimuth_deg)) - 1.5
        col = CENTRE[1] + r_px * np.cos(np.deg2rad(azimuth_deg)) - 1.5
        out.append((round(row / 4) * 4, round(col / 4) * 4))
    return out


def frame(truth, band_at, spectra, f_number, cra_deg):
    """The whole sensor's raw flat-fielded frame with one tile of each spectrum at each angle
    (spectrum ``k`` on ``AZIMUTHS[k]``), ``FILL`` elsewhere; and the spots' tiles."""
    pixels, where, spots = [], [], []
    for k, az in enumerate(AZIMUTHS[:len(spectra)]):
        spots.append(spot_origins(cra_deg, az))
        for r0, c0 in spots[-1]:
            for r in range(r0, r0 + 4):
                for c in range(c0, c0 + 4):
                    d = np.hypot(r - CENTRE[0], c - CENTRE[1]) * PITCH_MM
                    pixels.append((int(band_at[r % 4, c % 4]), d, k))
                    where.append((r, c))
    raw = np.full(SIZE, FILL, np.float32)
    for (r, c), v in zip(where, pixel_values(truth, spectra, f_number, pixels), strict=True):
        raw[r, c] = v
    return raw, spots


# -- reflectances -------------------------------------------------------------------------------

GRID = np.arange(400.0, 1001.0)


def leaf(seed):
    import prosail

    rng = np.random.default_rng(seed)
    _, r, _ = prosail.run_prospect(rng.uniform(1.2, 2.2), rng.uniform(10, 70), rng.uniform(3, 15),
                                   rng.uniform(0, 0.6), rng.uniform(0.006, 0.02),
                                   rng.uniform(0.003, 0.01), ant=rng.uniform(0, 3),
                                   prospect_version="D")
    return GRID, r[:601]


def soil():
    import prosail

    return GRID, prosail.spectral_library.get_spectra().soil.rsoil1[:601]


def colour_sample(name):
    import colour

    sd = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"][name]
    return GRID, np.interp(GRID, sd.wavelengths, sd.values)


def dip(centre_nm, fwhm_nm, depth=0.3, level=0.6):
    """One absorption (Gaussian) of ``depth`` on a flat ``level``."""
    return GRID, level - depth * np.exp(-4 * np.log(2) * ((GRID - centre_nm) / fwhm_nm) ** 2)


#: A didymium (Nd/Pr) glass: Lorentzian lines (centre nm, FWHM nm, optical depth) where
#: neodymium and praseodymium absorb (as tests/correct/test_harmonise.py).
ND_LINES = [(441, 6, 0.15), (482, 5, 0.35), (512, 5, 0.25), (521, 4, 0.4), (527, 5, 0.45),
            (573, 4, 0.5), (577, 3, 0.8), (582, 4, 1.2), (586, 4, 0.9), (627, 5, 0.12)]


def didymium():
    lam = np.arange(400.0, 1000.001, 0.05)
    tau = sum(a / (1 + ((lam - c) / (w / 2)) ** 2) for c, w, a in ND_LINES)
    return lam, 0.91 * np.exp(-tau)


# -- the sensors, and what correct_cube gives at the spots ----------------------------------------


@pytest.fixture(scope="module")
def sensors(tmp_path_factory):
    fx = vendorfiles.imec_4x4()
    path = vendorfiles.write_newer(tmp_path_factory.mktemp("harmonise") / "imec4x4.xml", fx)
    measured = dataclasses.replace(Sensor.load(path), n_eff=N_EFF)
    band_at = np.full(fx.tile, -1)  # the simulators' band (the file's) at each tile position
    for b, (r, c) in enumerate(measured.band_offset):
        band_at[r, c] = measured.vendor_band[b]
    twin, peaks, fwhm = twin_truth(fx)
    gaussian = Sensor("twin", "mosaic", 5.5, tuple(peaks), tuple(fwhm), N_EFF,
                      mosaic_shape=fx.tile, size_px=SIZE,
                      band_offset=measured.in_file_order(measured.band_offset))
    return SimpleNamespace(measured=measured, gaussian=gaussian, truth=measured_truth(fx),
                           twin=twin, band_at=band_at, path=path)


def spot_spreads(sensor, raw, spots, f_number, **kw):
    """Each spectrum's spread per band (spectra x bands) of the input, ``resampled`` and
    ``harmonised``; and the result."""
    cube = mosaic_to_cube(raw, sensor)
    ds = correct_cube(cube, sensor, f_number, PAPER_LENS, center_rc=CENTRE, resample=True,
                      harmonise=True, **kw)
    out = {}
    for name, values in (("nominal", cube.values), ("resampled", ds["resampled"].values),
                         ("harmonised", ds["harmonised"].values)):
        out[name] = np.array([np.ptp([values[r // 4, c // 4] for r, c in tiles], axis=0)
                              for tiles in spots])
    return out, ds


def largest(spread, bands=None):
    """A method's spread: the largest over the bands it gives (and ``bands`` if given)."""
    s = spread if bands is None else spread[..., bands]
    return np.nanmax(s, axis=-1)


def test_the_forward_model_converges(sensors):
    """The simulator's numerics (wavelength step, scale nodes, pupil nodes) move a value by
    far less than the spreads measured here (1e-4 and up)."""
    truth = sensors.truth
    spectra = [leaf(1), dip(540.0, 10.0)]
    pixels = [(b, d, s) for b in (3, 9) for d in (0.3, 6.3) for s in (0, 1)]
    base = pixel_values(truth, spectra, 2.8, pixels)
    for fine in ({"lam": np.arange(430.0, 670.0 + 1e-9, 0.025)}, {"shift_step_nm": 0.025},
                 {"nodes": (176, 96)}):
        assert np.max(np.abs(pixel_values(truth, spectra, 2.8, pixels, **fine) - base)) < 1e-7


def test_the_common_response_is_the_reference_pixels_moved_back(sensors):
    """The response harmonised values are given through (``common_responses``), against this
    file's rays: those of the pixel at the reference angle, each scale divided by their mean."""
    from snapcorr.optics.measured import common_responses

    measured, truth = sensors.measured, sensors.truth
    cra = 14.4
    a, w = pixel_rays(2.8, PAPER_TRUTH.exit_pupil_mm * np.tan(np.deg2rad(cra)), (48, 24))
    a = a / (w @ a / w.sum())
    grid = measured.responses.wavelength_nm
    got, _ = common_responses(measured.responses, N_EFF, 2.8, cra, PAPER_LENS)
    for b in (2, 3, 9):  # the simulator numbers the bands as the file does
        i = measured.vendor_band[b]
        want = w @ np.stack([truth.transmission(i, grid / ak) for ak in a]) * truth.system(grid)
        np.testing.assert_allclose(got[b] / got[b].max(), want / want.max(), atol=5e-4)


# -- the default checks, one f-number and three spots ---------------------------------------------


@pytest.fixture(scope="module")
def f28(sensors):
    spectra = [leaf(0), dip(545.0, 10.0), dip(545.0, 60.0)]
    raw, spots = frame(sensors.truth, sensors.band_at, spectra, 2.8, (1.0, 9.0, 16.0))
    return (*spot_spreads(sensors.measured, raw, spots, 2.8), spots)


def test_a_smooth_spectrum_is_the_same_across_the_field(f28):
    """A leaf at f/2.8, spots at CRA 1, 9 and 16 deg: 0.0004 apart (0.0058 resampled). The
    bands' measured responses are matched; widening them by Gaussians left 0.0074 over seven
    spots, more than resampling, and the Gaussian twin reaches 0.0014 (the slow test)."""
    spreads, ds, spots = f28
    harmonised, resampled = largest(spreads["harmonised"][0]), largest(spreads["resampled"][0])
    assert harmonised < 0.2 * resampled, (harmonised, resampled)
    assert harmonised < 1e-3
    # a flat spectrum (the rest of the frame) stays flat
    h = ds["harmonised"].values.copy()
    for r, c in (tile for tiles in spots for tile in tiles):
        h[r // 4, c // 4] = FILL
    assert np.nanmax(np.abs(h - FILL)) < 1e-5


def test_the_band_the_band_pass_edge_cuts_is_nan_and_named(f28, sensors):
    """The 465 nm band: its main peak, moved by the kernel mean, reaches 457.8 nm in the
    corners at f/2.8, where the band-pass passes 32 % of its maximum (below half: the edge has
    passed the peak). Every other band and every pixel is given."""
    _, ds, _ = f28
    measured = sensors.measured
    cwl = np.asarray(measured.cwl_nm)
    edge = int(np.argmin(cwl))
    h = ds["harmonised"].values
    assert np.all(np.isnan(h[..., edge]))
    assert not np.any(np.isnan(np.delete(h, edge, axis=2)))
    note = ds["harmonised"].attrs["not_harmonised"]
    assert note.startswith(f"{cwl[edge]:g} nm") and "band-pass" in note
    assert note.count(" nm (") == 1  # that band only
    # the criterion is the field's: a crop near the axis keeps the band
    crop = np.full((64, 64), FILL, np.float32)
    near = correct_cube(mosaic_to_cube(crop, measured, sensor_origin_px=(512, 992)), measured, 2.8,
                        PAPER_LENS, center_rc=CENTRE, harmonise=True)
    assert near["harmonised"].attrs["not_harmonised"].startswith("none")
    assert np.allclose(near["harmonised"].values, FILL, atol=1e-5)


def test_what_sparse_bands_cannot_harmonise_is_said_and_holds(f28):
    """16 bands up to 14.8 nm apart: a 10 nm absorption falls between them and keeps its
    differences across the field; a 60 nm one, wider than twice the largest gap, comes out
    the same."""
    spreads, ds, _ = f28
    limits = ds["harmonised"].attrs["limits"]
    assert "16 bands 4.66-14.8 nm apart (median 9.91 nm)" in limits, limits
    assert "29.6 nm at the largest" in limits, limits
    narrow, wide = largest(spreads["harmonised"][1]), largest(spreads["harmonised"][2])
    assert narrow > 0.004 and wide < 0.0015 and narrow > 5 * wide, (narrow, wide)  # 0.0068, 5e-5


@pytest.fixture(scope="module")
def corner(sensors):
    """A crop in the sensor's corner at f/2.8: its cube and result."""
    data = np.random.default_rng(3).uniform(0.2, 0.8, (64, 96)).astype(np.float32)
    cube = mosaic_to_cube(data, sensors.measured, sensor_origin_px=(0, 0))
    return cube, correct_cube(cube, sensors.measured, 2.8, PAPER_LENS, center_rc=CENTRE,
                              harmonise=True)


def test_blocks_give_the_values_of_the_whole(sensors, corner):
    cube, whole = corner
    lazy = correct_cube(cube.chunk({"y": 5, "x": 7}), sensors.measured, 2.8, PAPER_LENS,
                        center_rc=CENTRE, harmonise=True)
    xr.testing.assert_identical(lazy["harmonised"].compute(), whole["harmonised"])
    assert whole["harmonised"].dtype == np.float32


def test_the_command_names_the_band_it_leaves_out(sensors, corner, tmp_path, cli):
    cube, ref = corner
    (tmp_path / "s.toml").write_text(f'[sensor]\nvendor_file = "{sensors.path}"\n'
                                     f"n_eff = {N_EFF}\n")
    PAPER_LENS.save(tmp_path / "lens.toml")
    write_cube(cube, tmp_path / "cube.nc")
    res = cli("correct", "cube.nc", "--lens", "lens.toml", "--sensor", "s.toml", "--f-number",
              "2.8", "--center", f"{CENTRE[0]},{CENTRE[1]}", "--harmonise", "--out", "out.nc",
              cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("harmonised: not"))
    assert f"{min(sensors.measured.cwl_nm):g} nm" in line and "band-pass" in line
    out = read_dataset(tmp_path / "out.nc")
    np.testing.assert_array_equal(out["harmonised"].values, ref["harmonised"].values)
    assert out["harmonised"].attrs["not_harmonised"] == ref["harmonised"].attrs["not_harmonised"]


def test_a_wider_common_response_is_as_wide_as_asked(sensors, corner):
    cube, _ = corner
    flat = cube.copy(data=np.full(cube.shape, FILL, np.float32))
    ds = correct_cube(flat, sensors.measured, 2.8, PAPER_LENS, center_rc=CENTRE,
                      harmonise=True, target_fwhm_nm=25.0)
    np.testing.assert_allclose(ds["fwhm_harmonised"].values, 25.0, atol=0.002)
    assert "asked for" in ds["harmonised"].attrs["common_response"]
    h = ds["harmonised"].values
    assert np.allclose(h[h == h], FILL, atol=1e-5)
    # (a narrower one is refused by the check modelled filters share:
    # tests/correct/test_harmonise.py)


# -- the figures: f/1.4 and f/2.8, seven spots, smooth and featured targets, the twin ------------


SMOOTH = {"leaf": lambda: leaf(0), "leaf 2": lambda: leaf(5), "soil": soil,
          "dark skin": lambda: colour_sample("dark skin"),
          "yellow green": lambda: colour_sample("yellow green"),
          "orange": lambda: colour_sample("orange")}
FEATURED = {"didymium": didymium, "dip 10 nm": lambda: dip(545.0, 10.0)}
CRAS = (1.0, 3.5, 6.0, 8.5, 11.0, 13.5, 16.0)


@pytest.mark.slow
@pytest.mark.parametrize("f_number", [1.4, 2.8])
def test_harmonised_spectra_within_a_few_times_the_gaussian_twin(sensors, f_number):
    """Over the whole field, every smooth spectrum is harmonised within 3 x what the Gaussian
    twin reaches, every spectrum never worse than by resampling; featured targets keep
    differences many times a smooth spectrum's on both sensors (the bands cannot sample
    them). ``-s`` prints the figures of benchmarks/README.md."""
    measured = sensors.measured
    names = [*SMOOTH, *FEATURED]
    spectra = [{**SMOOTH, **FEATURED}[n]() for n in names]
    rows = {}
    for label, sensor, model in (("measured", measured, sensors.truth),
                                 ("twin", sensors.gaussian, sensors.twin)):
        parts = [spot_spreads(sensor, *frame(model, sensors.band_at, spectra[k:k + len(AZIMUTHS)],
                                             f_number, CRAS), f_number)[0]
                 for k in range(0, len(spectra), len(AZIMUTHS))]
        rows[label] = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    edge = int(np.argmin(measured.cwl_nm))
    both = np.flatnonzero(np.all(np.isfinite(rows["measured"]["resampled"]), axis=0))
    both = both[both != edge]
    m, t = rows["measured"], rows["twin"]
    for i, name in enumerate(names):
        print(f"f/{f_number:g} {name}: measured nominal {largest(m['nominal'][i]):.4f} "
              f"resampled {largest(m['resampled'][i]):.4f} harmonised "
              f"{largest(m['harmonised'][i]):.4f} | twin resampled "
              f"{largest(t['resampled'][i]):.4f} harmonised {largest(t['harmonised'][i]):.4f}")
        print("   harmonised per band (by wavelength):", " ".join(
            f"{v:.4f}" for v in m["harmonised"][i][np.argsort(measured.cwl_nm)]))
        # never worse than resampling, over the bands both give
        assert largest(m["harmonised"][i], both) <= largest(m["resampled"][i], both), name
    smooth = np.arange(len(SMOOTH))
    h, th = largest(m["harmonised"]), largest(t["harmonised"])
    assert np.all(h[smooth] <= 3 * th[smooth]), (h, th)  # within 3 x the twin
    # features between the bands keep differences, here and on the twin, many times a smooth
    # spectrum's
    featured = np.arange(len(SMOOTH), len(names))
    assert np.all(h[featured] > 10 * h[smooth].max()), h
    assert np.all(th[featured] > 3 * th[smooth].max()), th
