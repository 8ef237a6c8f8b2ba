"""Measured filter responses behind a lens (snapcorr.optics.measured): each pupil ray scales
the whole measured curve, the band-pass in front does not move; checked against pupil
sampling written here, on the real 5x5 NIR calibration file's asymmetric, many-peaked
curves."""

import dataclasses

import numpy as np
import pytest
from conftest import PAPER_LENS, PAPER_TRUTH, PAPER_X_MM, VENDOR_XML
from numpy.testing import assert_allclose
from spectralsim import pupil_samples

from snapcorr.cube import Sensor, mosaic_to_cube
from snapcorr.cube.responses import FilterResponses, Peak
from snapcorr.optics import mean_shift, response_fwhm
from snapcorr.optics.measured import MeasuredTable


@pytest.fixture(scope="module")
def vendor():
    return Sensor.load(VENDOR_XML)


def test_a_measured_gaussian_moves_by_the_kernel_mean_and_widens_as_modelled():
    """Away from any band-pass edge the centre moves exactly by the kernel mean (Eq. 22),
    whatever the shape, and the width is the modelled filter's FWHM behind the lens."""
    grid = np.arange(400.0, 1000.01, 0.1)
    cwl, fwhm = np.array([500.0, 650.0, 800.0]), np.array([8.0, 10.0, 12.0])
    curves = np.exp(-4 * np.log(2) * ((grid[None] - cwl[:, None]) / fwhm[:, None]) ** 2)
    r = FilterResponses(grid, curves, np.ones(grid.size),
                        [[Peak(c, w, 1.0)] for c, w in zip(cwl, fwhm, strict=True)])
    table = MeasuredTable.build(r, 1.7, 1.4, PAPER_LENS, cra_max_deg=18.0)
    cra = np.array([0.0, 7.3, 12.9, 17.6])
    shift = np.stack([cwl[b] * (table.scale(cra, b) - 1) for b in range(3)])
    assert_allclose(shift, mean_shift(cwl[:, None], 1.7, 1.4, cra[None], PAPER_LENS),
                    atol=0.01)  # the table's tolerance
    assert_allclose(table(cra).T, response_fwhm(cwl, fwhm, 1.7, 1.4, cra, PAPER_LENS),
                    atol=0.02)


def _lobe(grid, eff, peak_nm):
    """The main lobe as defined: from the main peak up to its local maximum, then out while
    the response stays >= 5 % of that maximum."""
    i = int(np.argmin(np.abs(grid - peak_nm)))
    while i + 1 < grid.size and eff[i + 1] > eff[i]:
        i += 1
    while i > 0 and eff[i - 1] > eff[i]:
        i -= 1
    j = k = i
    while j > 0 and eff[j - 1] >= 0.05 * eff[i]:
        j -= 1
    while k + 1 < grid.size and eff[k + 1] >= 0.05 * eff[i]:
        k += 1
    return grid[j], grid[k]


def _sampled(sensor, b, f_number, cra_deg, n_eff, step=0.01):
    """Band b's centre and width by summing its measured curve over pupil rays: each ray
    at angle phi scales the whole (linearly interpolated) curve by a = sqrt(1 - sin^2 phi /
    n^2); the band-pass multiplies the sum."""
    r = sensor.responses
    grid = r.wavelength_nm
    if f_number is None:  # normal, collimated incidence
        a, w = np.ones(1), np.ones(1)
    else:
        d = PAPER_X_MM * np.tan(np.deg2rad(cra_deg))
        u, v, w = pupil_samples(PAPER_TRUTH, f_number, d, theta_nodes=64, r_nodes=32)
        t2 = ((u - d) ** 2 + v**2) / PAPER_X_MM**2
        a = np.sqrt(1 - t2 / (1 + t2) / n_eff**2)
    lo, hi = _lobe(grid, r.curves[b] * r.system, sensor.cwl_nm[b])
    lam = np.arange(0.85 * lo, hi, step)
    whole, lobe = np.zeros_like(lam), np.zeros_like(lam)
    for ak, wk in zip(a, w, strict=True):
        t = np.interp(lam / ak, grid, r.curves[b], left=0.0, right=0.0)
        whole += wk * t
        lobe += wk * t * ((lam / ak >= lo) & (lam / ak <= hi))
    system = np.interp(lam, grid, r.system)
    whole, lobe = whole * system, lobe * system
    centre = lobe.sum() / (lobe / lam).sum()  # the wavelength of the mean wavenumber
    width = step * np.count_nonzero(whole >= 0.5 * whole.max())
    return centre, width


# band 2 sits on the band-pass's blue edge, band 3 has a leak as strong as its peak inside
# its lobe, band 21 a shoulder at 70 % of its peak; band 9 is a plain one
@pytest.mark.parametrize("f_number, cra_list", [(1.4, (0.0, 17.1)), (4.0, (9.3,))])
def test_measured_centres_and_widths_against_pupil_sampling(vendor, f_number, cra_list):
    table = MeasuredTable.build(vendor.responses, 1.8, f_number, PAPER_LENS, cra_max_deg=18.0)
    for b in (2, 3, 9, 21):
        c0, w0 = _sampled(vendor, b, None, 0.0, 1.8)
        assert table.normal_fwhm_nm[b] == pytest.approx(w0, abs=0.02 + 0.005 * w0)
        for cra in cra_list:
            c, w = _sampled(vendor, b, f_number, cra, 1.8)
            shift = vendor.cwl_nm[b] * (c / c0 - 1)
            ours = vendor.cwl_nm[b] * (table.scale(cra, b) - 1)
            assert ours == pytest.approx(shift, abs=0.01), (b, cra)
            assert table(np.array(cra))[b] == pytest.approx(w, abs=0.02 + 0.01 * w), (b, cra)


def test_near_a_band_pass_edge_a_band_moves_less_than_the_kernel_mean(vendor):
    """Band 2 (608 nm) sits on the band-pass's blue edge (606 nm): what reaches the pixel
    cannot go bluer, so its centre moves far less than a free filter's would."""
    table = MeasuredTable.build(vendor.responses, 1.8, 2.0, PAPER_LENS, cra_max_deg=18.0)
    e, p = (vendor.vendor_band.index(i) for i in (2, 9))  # the file's bands 2 and 9
    free = mean_shift(vendor.cwl_nm[e], 1.8, 2.0, 15.0, PAPER_LENS)
    edge = vendor.cwl_nm[e] * (table.scale(15.0, e) - 1)
    plain = vendor.cwl_nm[p] * (table.scale(15.0, p) - 1)
    assert abs(edge) < 0.3 * abs(free)
    assert plain == pytest.approx(mean_shift(vendor.cwl_nm[p], 1.8, 2.0, 15.0, PAPER_LENS),
                                  abs=0.1)


def test_correct_cube_uses_each_bands_measured_curve_at_its_own_place(vendor):
    from snapcorr.correct import correct_cube

    sensor = dataclasses.replace(vendor, n_eff=(1.8,) * 25, pixel_pitch_um=5.5)
    frame = np.random.default_rng(0).uniform(0.2, 0.8, (20, 20)).astype(np.float32)
    cube = mosaic_to_cube(frame, sensor, sensor_origin_px=(40, 60))  # a corner: CRA about 16 deg
    ds = correct_cube(cube, sensor, 2.0, PAPER_LENS, method="vignetted")
    assert "measured main lobe" in ds["wavelength_scale"].attrs["source"]
    for b in (2, 21):
        cra = float(ds["cra_deg"].values[1, 2, b])
        c0, _ = _sampled(sensor, b, None, 0.0, 1.8)
        c, w = _sampled(sensor, b, 2.0, cra, 1.8)
        assert float(ds["wavelength_corrected"].values[1, 2, b]) == pytest.approx(
            sensor.cwl_nm[b] * c / c0, abs=0.011)
        assert float(ds["fwhm_corrected"].values[1, 2, b]) == pytest.approx(w, abs=0.02 + 0.01 * w)


def test_without_n_eff_the_shift_is_refused_and_the_nominal_wavelengths_kept(vendor):
    from snapcorr.correct import correct_cube

    sensor = dataclasses.replace(vendor, pixel_pitch_um=5.5)
    cube = mosaic_to_cube(np.ones((10, 10), np.float32), sensor, sensor_origin_px=(500, 1000))
    with pytest.raises(ValueError, match=r"n_eff.*snapcorr pupil --fit-n-eff"):
        correct_cube(cube, sensor, 2.0, PAPER_LENS)
    ds = correct_cube(cube, sensor, 2.0, PAPER_LENS, method="none")
    assert_allclose(ds["wavelength_corrected"].values[0, 0], sensor.cwl_nm, rtol=1e-7)
    assert "fwhm_corrected" not in ds.coords
    with pytest.raises(ValueError, match="pixel pitch"):
        correct_cube(cube, vendor, 2.0, PAPER_LENS, method="none")


def test_bands_whose_corrected_wavelengths_cross_are_resampled_in_wavelength_order():
    from snapcorr.correct.resample import resample_to_nominal

    cwl = np.array([600.0, 610.0, 612.0, 630.0])
    scale = np.array([[[1.0, 1.0, 0.98, 1.0]]])[:, :, :]  # band 2 moves below band 1
    data = np.array([[[1.0, 2.0, 3.0, 4.0]]])
    out = resample_to_nominal(data, scale, np.arange(4), cwl)
    lam = cwl * scale[0, 0]
    order = np.argsort(lam)
    assert_allclose(out[0, 0], np.interp(cwl, lam[order], data[0, 0][order]))


def test_the_bundled_mosaic_frames_are_seen_through_the_shifted_filters():
    """snapcorr.data.mosaic_frames simulates each pixel's filter behind the lens: at the
    corner the uncorrected spectrum is off the target, and the corrected wavelengths put it
    back (it was once simulated without the shift, so correcting it looked harmful)."""
    from snapcorr.correct import correct_cube
    from snapcorr.cube import flatfield
    from snapcorr.data import mosaic_frames, mosaic_target, sensor_path

    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    raw, dark, white = mosaic_frames("mosaic_4x4_vis", f_number=2.8)
    ff = flatfield(*(mosaic_to_cube(f, sensor) for f in (raw, dark, white)))
    ds = correct_cube(ff["reflectance"], sensor, 2.8, PAPER_LENS, method="vignetted")
    target = mosaic_target(sensor)
    corner = ds.isel(y=slice(0, 5), x=slice(0, 5))
    values = corner["reflectance"].values.reshape(-1, 16).mean(axis=0)
    nominal = np.sqrt(np.mean((values - target(np.asarray(sensor.cwl_nm))) ** 2))
    moved = corner["wavelength_corrected"].values.reshape(-1, 16).mean(axis=0)
    corrected = np.sqrt(np.mean((values - target(moved)) ** 2))
    assert float(corner["cra_deg"].mean()) > 15
    assert nominal > 0.04 and corrected < 0.25 * nominal


def test_eq6_is_not_used_for_measured_responses(vendor):
    from snapcorr.correct import correct_cube

    sensor = dataclasses.replace(vendor, n_eff=(1.8,) * 25, pixel_pitch_um=5.5)
    cube = mosaic_to_cube(np.ones((10, 10), np.float32), sensor, sensor_origin_px=(540, 1020))
    with pytest.raises(ValueError, match=r"'asymptotic' is Eq\. 6"):
        correct_cube(cube, sensor, 8.0, PAPER_LENS, method="asymptotic")
    # on the axis at f/8 Eq. 6 would meet the tolerance; measured responses take the table
    ds = correct_cube(cube, sensor, 8.0, PAPER_LENS, tolerance_nm=0.05)
    assert ds.attrs["method"] == "ideal"
    assert "measured responses take the ideal aperture's table" in ds.attrs["method_reason"]
