"""The FWHM of a filter's whole response behind a lens, against an independent computation.

The reference here samples the vignetted pupil point by point (``tests/oracles/spectralsim.py``,
which shares no code with snapcorr), scales each ray's whole filter curve by the shift law, sums the
curves on a fine wavelength grid and reads the half-maximum crossings off it. snapcorr's
``response_fwhm`` convolves in log-wavelength with the closed-form kernel (Goossens Eq. 37).
"""

from __future__ import annotations

import numpy as np
import pytest
import spectralsim as sim
from conftest import PAPER_TRUTH
from flatsim import LensTruth

from snapcorr import Lens
from snapcorr.optics import response_fwhm

PAPER = PAPER_TRUTH
PLAIN = LensTruth(16.0, (), 0.0, 1.0, name="no vignetting")


def as_lens(truth):
    return Lens(truth.exit_pupil_mm, truth.circles, truth.magnification,
                truth.pupil_magnification)


def reference_fwhm(truth, f_number, cra_deg, cwl, fwhm, n_eff, profile):
    """Sum over pupil nodes of the filter curve scaled by each ray's factor; FWHM by search."""
    d = truth.exit_pupil_mm * np.tan(np.radians(cra_deg))
    # fewer nodes than the simulator's default: the curves are smooth over the pupil
    u, v, w = sim.pupil_samples(truth, f_number, d, theta_nodes=96, r_nodes=32)
    rho2 = (u - d) ** 2 + v * v
    s2 = rho2 / (rho2 + truth.exit_pupil_mm**2)  # sin^2 of each ray's incidence angle
    a = np.sqrt(1.0 - s2 / n_eff**2)
    lam = np.arange(cwl * a.min() - 3 * fwhm, cwl + 3 * fwhm, fwhm / 400)
    R = np.zeros_like(lam)
    for chunk in np.array_split(np.arange(a.size), max(1, a.size // 500)):
        R += (w[chunk, None] * sim.filter_profile(lam[None, :], cwl * a[chunk, None],
                                                  fwhm * a[chunk, None], profile)).sum(axis=0)
    half = R.max() / 2
    idx = np.flatnonzero(R >= half)
    i, j = idx[0], idx[-1]
    left = np.interp(half, [R[i - 1], R[i]], [lam[i - 1], lam[i]])
    right = np.interp(half, [R[j + 1], R[j]], [lam[j + 1], lam[j]])
    return right - left


QUICK = {("paper", 1.4, "gaussian"), ("plain", 2.8, "airy"), ("paper", 8.0, "airy")}
CASES = [pytest.param(lens, f, prof, marks=() if (lens, f, prof) in QUICK else pytest.mark.slow)
         for lens in ("paper", "plain") for f in (1.4, 2.8, 8.0) for prof in ("gaussian", "airy")]


@pytest.mark.parametrize(("lens", "f_number", "profile"), CASES)
def test_response_fwhm_matches_pupil_sampling(lens, f_number, profile):
    truth = {"paper": PAPER, "plain": PLAIN}[lens]
    cras = [0.0, 1.9, 10.3, 17.4, 24.0]
    cwl, fwhm, n = np.array([480.0, 700.0, 880.0]), np.array([8.0, 12.0, 15.0]), 1.75
    got = response_fwhm(cwl, fwhm, n, f_number, cras, as_lens(truth), profile=profile)
    for b in range(cwl.size):
        want = [reference_fwhm(truth, f_number, c, cwl[b], fwhm[b], n, profile) for c in cras]
        np.testing.assert_allclose(got[b], want, atol=0.02, err_msg=f"band {cwl[b]} nm")


def test_the_variance_shortcut_is_close_only_for_narrow_kernels():
    """``method="variance"`` (FWHM^2 + 8 ln 2 var) is what the module says: within 0.03 nm
    of the exact curve where the kernel is narrow (f/8 on axis), off by more than 0.5 nm at
    f/1.4 in the field, where the kernel is a wide box."""
    lens = as_lens(PAPER)
    args = ([700.0], [10.0], 1.8)
    narrow = [response_fwhm(*args, 8.0, [0.0], lens, method=m)[0, 0]
              for m in ("exact", "variance")]
    assert abs(narrow[0] - narrow[1]) < 0.03
    wide = [response_fwhm(*args, 1.4, [17.4], lens, method=m)[0, 0]
            for m in ("exact", "variance")]
    assert abs(wide[0] - wide[1]) > 0.5


def test_no_light_is_nan_and_bad_input_is_refused():
    lens = Lens(21.0, [(2.0, 16.991)], 0.06, 1.3)  # a small circle: cut off far out
    w = response_fwhm([700.0], [10.0], 1.8, 1.4, [0.0, 40.0], lens)
    assert np.isfinite(w[0, 0]) and np.isnan(w[0, 1])
    with pytest.raises(ValueError, match="profile must be one of"):
        response_fwhm([700.0], [10.0], 1.8, 2.0, [0.0], lens, profile="lorentzian")
    with pytest.raises(ValueError, match="method"):
        response_fwhm([700.0], [10.0], 1.8, 2.0, [0.0], lens, method="fast")
    with pytest.raises(ValueError, match="> 0"):
        response_fwhm([700.0], [0.0], 1.8, 2.0, [0.0], lens)


# -- the sensor names its filters' shape ------------------------------------------------------
def test_a_sensor_names_its_filter_shape_or_gives_a_measured_one(tmp_path):
    from snapcorr.cube import Sensor

    base = {"name": "s", "layout": "snapscan", "pixel_pitch_um": 5.5, "cwl_nm": [600.0, 700.0],
            "fwhm_nm": 10.0, "n_eff": 1.8}
    assert Sensor(**base).profile == "gaussian"  # the default, and not written out
    assert "profile" not in Sensor(**base).to_dict()
    airy = Sensor(**base, profile="airy")
    airy.save(tmp_path / "airy.toml")
    assert Sensor.load(tmp_path / "airy.toml").profile_shape == "airy"
    # a measured shape: a Gaussian of 10 nm tabulated, relative to the sensor file's folder
    off = np.linspace(-30.0, 30.0, 601)
    np.savetxt(tmp_path / "shape.csv", np.column_stack([off, np.exp(-4 * np.log(2) * (off / 10)
                                                                     ** 2)]),
               delimiter=",", header="offset_nm,transmission")
    (tmp_path / "measured.toml").write_text(
        '[sensor]\nname = "m"\nlayout = "snapscan"\npixel_pitch_um = 5.5\n'
        'cwl_nm = [600.0, 700.0]\nfwhm_nm = 10.0\nn_eff = 1.8\nprofile = "shape.csv"\n')
    measured = Sensor.load(tmp_path / "measured.toml")
    lens = as_lens(PAPER)
    tab = response_fwhm(measured.cwl_nm, measured.fwhm_nm, 1.8, 1.4, [0.0, 17.4], lens,
                        profile=measured.profile_shape)
    gauss = response_fwhm(measured.cwl_nm, measured.fwhm_nm, 1.8, 1.4, [0.0, 17.4], lens)
    np.testing.assert_allclose(tab, gauss, atol=0.01)
    with pytest.raises(ValueError, match="profile must be one of"):
        Sensor(**base, profile="lorentzian")
    (tmp_path / "bad.csv").write_text("500,0.1\n600,1\n700,0.1\n")
    with pytest.raises(ValueError, match="relative"):
        Sensor(**base, profile=str(tmp_path / "bad.csv"))
    with pytest.raises(FileNotFoundError, match="not found"):
        Sensor(**base, profile=str(tmp_path / "missing.csv"))


# -- fwhm_corrected in a corrected cube -------------------------------------------------------
def _corrected(chunks=None, profile="airy"):
    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor, make_cube

    sensor = Sensor("t", "snapscan", 44.0, [480.0, 700.0, 880.0], [8.0, 12.0, 15.0], 1.75,
                    profile=profile)
    cube = make_cube(np.ones((128, 160, 3), np.float32), sensor.cwl_nm)
    if chunks:
        cube = cube.chunk(chunks)
    return correct_cube(cube, sensor, 1.4, as_lens(PAPER), center_px=(80.0, 64.0)), sensor


def test_fwhm_corrected_is_the_response_of_each_pixel():
    """At pixels of the paper's three chief-ray angles (and the field's edge), against pupil
    sampling by the independent simulator: within 0.1 nm (the table adds at most 0.01)."""
    ds, sensor = _corrected()
    fw = ds["fwhm_corrected"]
    assert fw.dtype == np.float32 and fw.attrs["units"] == "nm"
    cra = ds["cra_deg"].values
    for target in (1.9, 10.3, 17.4, float(cra.max())):
        yy, xx = np.unravel_index(np.argmin(np.abs(cra - target)), cra.shape)
        for b in range(3):
            want = reference_fwhm(PAPER, 1.4, cra[yy, xx], sensor.cwl_nm[b], sensor.fwhm_nm[b],
                                  1.75, "airy")
            assert abs(float(fw.values[yy, xx, b]) - want) < 0.1, (target, b)


def test_fwhm_corrected_is_the_same_in_blocks_and_after_a_file(tmp_path):
    from snapcorr.cube import read_dataset, write_dataset

    whole, _ = _corrected(profile="gaussian")
    blocks, _ = _corrected({"y": 50, "x": 64}, profile="gaussian")
    np.testing.assert_array_equal(whole["fwhm_corrected"].values,
                                  blocks["fwhm_corrected"].values)
    write_dataset(whole, tmp_path / "c.nc")
    back = read_dataset(tmp_path / "c.nc")
    np.testing.assert_array_equal(back["fwhm_corrected"].values, whole["fwhm_corrected"].values)
    assert "fwhm_corrected" in back.coords and "gaussian filters" in back["fwhm_table"].attrs[
        "source"]


def test_a_mosaic_pixel_has_each_band_at_its_own_angle():
    from snapcorr.correct import correct_cube
    from snapcorr.cube import Sensor, mosaic_to_cube
    from snapcorr.data import sensor_path

    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    raw = np.ones((64, 96), np.float32)
    cube = mosaic_to_cube(raw, sensor, sensor_origin_px=(400, 800))
    lens = as_lens(PAPER)
    ds = correct_cube(cube, sensor, 2.0, lens, center_px=(0.0, 0.0))
    cra = ds["cra_deg"].values  # (y, x, band)
    got = ds["fwhm_corrected"].values
    for yy, xx, b in ((0, 0, 0), (7, 11, 5), (15, 23, sensor.n_bands - 1)):
        want = response_fwhm(sensor.cwl_nm[b], sensor.fwhm_nm[b], sensor.n_eff[b], 2.0,
                             [cra[yy, xx, b]], lens)[0, 0]
        assert abs(got[yy, xx, b] - want) < 0.01


def test_the_table_interpolates_within_its_tolerance():
    """The per-pixel values come from a table over CRA: against the exact curve at random
    angles, for a vignetted lens at f/1.4 (a bend at the onset) and 30 bands."""
    from snapcorr.optics import FwhmTable

    lens = as_lens(PAPER)
    cwl = np.linspace(470.0, 900.0, 30)
    table = FwhmTable.build(cwl, 10.0, 1.8, 1.4, lens, cra_max_deg=22.0, tolerance_nm=0.01)
    cra = np.random.default_rng(3).uniform(0.0, 22.0, 40)
    exact = response_fwhm(cwl, 10.0, 1.8, 1.4, cra, lens)
    assert np.max(np.abs(table(cra) - exact.T)) < 0.01
    assert table(np.zeros((2, 3))).shape == (2, 3, 30)


def test_a_fine_wavelength_tolerance_does_not_ask_the_width_table_for_it():
    """1e-4 nm is a valid wavelength tolerance; the FWHM table stops at its own floor
    (0.005 nm) instead of refusing the cube, and says which it used."""
    from snapcorr.correct import correct_cube, with_fwhm_table
    from snapcorr.cube import Sensor, make_cube

    sensor = Sensor("s", "snapscan", 300.0, np.linspace(500, 900, 6), 10.0, 1.7)
    cube = make_cube(np.ones((40, 50, 6), np.float32), sensor.cwl_nm)
    ds = with_fwhm_table(correct_cube(cube, sensor, 2.8, as_lens(PAPER), tolerance_nm=1e-4))
    assert ds.attrs["tolerance_nm"] == 1e-4
    assert "within 0.005 nm" in ds["fwhm_table"].attrs["source"]
