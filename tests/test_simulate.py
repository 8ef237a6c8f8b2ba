"""Simulated flat fields: checked against the lens model, brute-force geometry and statistics."""

import math

import numpy as np
import pytest
from conftest import PAPER_LENS

from snapcorr import Lens
from snapcorr.optics.chief_ray import cra_map
from snapcorr.simulate import (
    ILLUMINATION_METHODS,
    Detector,
    LampPlaque,
    flat_frame,
    relative_illumination_map,
)

EDMUND = PAPER_LENS  # h < x
H_GE_X = Lens(21.0, [(9.0, 30.0)], 0.0, 1.0, name="h>=x")
NO_VIGNETTING = Lens(21.0, name="no vignetting")
PITCH_UM = 5.5  # 2048 pixels: an 11.3 mm wide sensor


def own_cra_deg(i, j, shape, pitch_um, x_mm, center=None):
    """Chief-ray angle of pixel (row i, column j), Goossens 2019 Eq. (8), by hand."""
    ny, nx = shape
    cx, cy = center if center is not None else ((nx - 1) / 2, (ny - 1) / 2)
    d_mm = pitch_um / 1000 * math.sqrt((j - cx) ** 2 + (i - cy) ** 2)
    return math.degrees(math.atan(d_mm / x_mm))


def sample_pixels(shape, n=40, seed=3):
    ny, nx = shape
    rng = np.random.default_rng(seed)
    picks = [(0, 0), (0, nx - 1), (ny - 1, 0), (ny - 1, nx - 1), (ny // 2, nx // 2)]
    picks += list(zip(rng.integers(0, ny, n).tolist(), rng.integers(0, nx, n).tolist(),
                      strict=True))
    return picks


# -- the lens model --------------------------------------------------------------------------
@pytest.mark.parametrize("lens", [EDMUND, H_GE_X], ids=lambda lens: lens.name)
@pytest.mark.parametrize("f_number", [1.4, 2.8, 8.0])
def test_noise_free_flat_is_optical_vignetting_times_cos4(lens, f_number):
    shape = (544, 1024)
    pitch = 2 * PITCH_UM  # the field of a 1088 x 2048 sensor
    flat = flat_frame(shape, pitch, f_number, lens, noise=False,
                      detector=Detector(signal_electrons=1.0), dtype=np.float64)
    assert flat.dtype == np.float64
    for i, j in sample_pixels(shape):
        cra = own_cra_deg(i, j, shape, pitch, lens.exit_pupil_mm)
        expected = lens.relative_illumination(f_number, cra) * math.cos(math.radians(cra)) ** 4
        assert flat[i, j] == pytest.approx(expected, abs=1e-6), (i, j, cra)
    # the corner is strongly vignetted at f/1.4, so the comparison above is not trivial
    if f_number == 1.4:
        assert flat[0, 0] < 0.6


def test_signal_electrons_is_the_mean_at_the_optical_center():
    flat = flat_frame((101, 101), PITCH_UM, 2.0, EDMUND,
                      detector=Detector(signal_electrons=2500.0), noise=False, dtype=np.float64)
    assert flat[50, 50] == 2500.0
    assert flat.max() == 2500.0


def test_natural_vignetting_can_be_switched_off():
    shape = (9, 11)
    a = relative_illumination_map(shape, 400.0, 2.0, H_GE_X, method="exact")
    b = relative_illumination_map(shape, 400.0, 2.0, H_GE_X, method="exact",
                                  natural_vignetting=False)
    cos4 = np.cos(np.deg2rad(cra_map(shape, 400.0, 21.0))) ** 4
    np.testing.assert_allclose(a, b * cos4, rtol=1e-12, atol=1e-15)
    assert np.all(cos4[0] < 0.99)


def three_disc_grid_count(R, P, dv, rho, dp, n=800):
    """Fraction of the pupil disc (radius R, centre 0) that also lies in the disc (P, dv) and
    the disc (rho, dp), by counting the points of an n x n midpoint grid over the pupil."""
    step = 2 * R / n
    c = (np.arange(n) + 0.5) * step - R
    X, Y = np.meshgrid(c, c, indexing="ij")
    inside = X**2 + Y**2 <= R * R
    if P is not None:
        inside &= (X - dv) ** 2 + Y**2 <= P * P
    inside &= (X - dp) ** 2 + Y**2 <= rho * rho
    return inside.sum() * step * step / (math.pi * R * R)


@pytest.mark.parametrize(
    ("lens", "f_number", "acceptance_deg"),
    [(EDMUND, 1.4, 12.0), (EDMUND, 2.8, 6.0), (EDMUND, 2.8, 20.0), (H_GE_X, 1.4, 15.0),
     (H_GE_X, 4.0, 3.5), (H_GE_X, 2.0, 16.0), (NO_VIGNETTING, 2.0, 10.0)],
    ids=["edmund-f1.4", "edmund-f2.8", "edmund-f2.8-wide", "h>=x-f1.4", "h>=x-f4",
         "h>=x-f2-wide", "no-vignetting"],
)
def test_pixel_vignetting_area_against_a_grid_count(lens, f_number, acceptance_deg):
    # Pixel j of a one-row image with its optical centre on pixel 0 is 0.7 j mm off axis.
    n, pitch_mm = 13, 0.7
    v = relative_illumination_map((1, n), pitch_mm * 1000, f_number, lens, center_px=(0, 0),
                                  natural_vignetting=False, pixel_acceptance_deg=acceptance_deg)
    v_lens_only = relative_illumination_map((1, n), pitch_mm * 1000, f_number, lens,
                                            center_px=(0, 0), natural_vignetting=False)
    x = lens.exit_pupil_mm
    R = float(lens.exit_pupil_radius_mm(f_number))
    rho = x * math.tan(math.radians(acceptance_deg))
    P, h = lens.vignetting[0] if lens.vignetting else (None, None)
    for j in range(n):
        t = pitch_mm * j / x
        expected = three_disc_grid_count(R, P, None if P is None else h * t, rho, x * t)
        # midpoint counting on an 800^2 grid: the ~3000 boundary cells are each half in on
        # average, so the count's error is ~ sqrt(3000) cells ~ 1e-4 of the pupil area
        assert v[0, j] == pytest.approx(expected, abs=5e-4), j
    # the acceptance cone really cuts the light somewhere in the field
    assert np.max(v_lens_only - v) > 0.05


@pytest.mark.parametrize("lens", [EDMUND, H_GE_X, NO_VIGNETTING,
                                  Lens(21.0, [(6.0, -5.0)], name="h<0"),
                                  Lens(21.0, [(7.5, 21.0)], name="h=x")],
                         ids=lambda lens: lens.name)
def test_radial_interpolation_is_within_1e_6_of_the_exact_per_pixel_value(lens):
    shape = (90, 120)
    worst = 0.0
    for f_number in (1.4, 4.0, 11.0):
        R = float(lens.exit_pupil_radius_mm(f_number))
        # include an acceptance circle just wider than the pupil: nearly tangent discs
        near = math.degrees(math.atan(R * (1 + 1e-3) / lens.exit_pupil_mm))
        for acceptance in (None, 8.0, near):
            kw = dict(center_px=(31.3, -8.6), pixel_acceptance_deg=acceptance)
            # 100 um pixels reach CRA ~ 35 deg, past the cut-off of every lens here
            fast = relative_illumination_map(shape, 100.0, f_number, lens, **kw)
            exact = relative_illumination_map(shape, 100.0, f_number, lens, method="exact", **kw)
            worst = max(worst, float(np.max(np.abs(fast - exact))))
    assert worst < 1e-6


@pytest.mark.parametrize("method", ILLUMINATION_METHODS)
def test_every_method_gives_finite_values_in_0_1(method):
    v = relative_illumination_map((20, 30), 300.0, 1.4, EDMUND, method=method,
                                  pixel_acceptance_deg=20.0)
    assert v.shape == (20, 30) and v.dtype == np.float64
    assert np.all(np.isfinite(v)) and np.all((v >= 0) & (v <= 1))


# -- off-centre optical axis -----------------------------------------------------------------
@pytest.mark.parametrize(
    ("center", "brightest"),
    [((300.0, 100.0), (100, 300)), ((300.4, 100.6), (101, 300)), ((-50.0, 20.0), (20, 0)),
     ((600.0, 300.0), (255, 511))],
)
def test_brightest_pixel_is_at_the_optical_center(center, brightest):
    flat = flat_frame((256, 512), PITCH_UM, 1.4, EDMUND, center_px=center, noise=False,
                      dtype=np.float64)
    assert np.unravel_index(np.argmax(flat), flat.shape) == brightest


# -- noise -----------------------------------------------------------------------------------
@pytest.mark.parametrize("signal", [400.0, 1e4, 1e5])
def test_shot_noise_is_poisson(signal):
    frame = flat_frame((512, 512), PITCH_UM, 2.8, NO_VIGNETTING, natural_vignetting=False,
                       detector=Detector(signal_electrons=signal), rng=11, dtype=np.float64)
    assert frame.mean() == pytest.approx(signal, rel=1e-3)
    assert frame.std() / frame.mean() == pytest.approx(1 / math.sqrt(signal), rel=0.02)


def test_shot_noise_at_the_center_of_a_vignetted_flat():
    frame = flat_frame((1024, 1024), PITCH_UM, 2.0, EDMUND, rng=2)
    center = frame[448:576, 448:576].astype(np.float64)  # within 0.5 mm: V > 0.99
    assert center.std() / 1e4 == pytest.approx(0.01, rel=0.03)


def test_read_noise_adds_in_quadrature_then_gain_and_dark():
    signal, read, gain, dark = 1e4, 100.0, 2.0, 50.0
    frame = flat_frame((512, 512), PITCH_UM, 2.8, NO_VIGNETTING, natural_vignetting=False,
                       detector=Detector(signal_electrons=signal, read_noise_electrons=read,
                                         gain_electrons_per_dn=gain, dark_dn=dark),
                       rng=5, dtype=np.float64)
    assert frame.mean() == pytest.approx(signal / gain + dark, rel=1e-3)
    assert frame.std() == pytest.approx(math.sqrt(signal + read**2) / gain, rel=0.02)


def test_same_seed_same_frame_different_seeds_differ():
    kw = dict(detector=Detector(read_noise_electrons=5.0))
    a = flat_frame((64, 80), PITCH_UM, 2.0, EDMUND, rng=42, **kw)
    b = flat_frame((64, 80), PITCH_UM, 2.0, EDMUND, rng=42, **kw)
    c = flat_frame((64, 80), PITCH_UM, 2.0, EDMUND, rng=43, **kw)
    d = flat_frame((64, 80), PITCH_UM, 2.0, EDMUND, rng=np.random.default_rng(42), **kw)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, d)
    assert np.mean(a != c) > 0.9


def test_noise_free_frame_is_the_expectation_and_draws_nothing():
    gen = np.random.default_rng(0)
    state = gen.bit_generator.state
    a = flat_frame((32, 48), PITCH_UM, 2.0, EDMUND, noise=False, rng=gen,
                   detector=Detector(dark_dn=10.0, gain_electrons_per_dn=4.0))
    assert gen.bit_generator.state == state
    v = relative_illumination_map((32, 48), PITCH_UM, 2.0, EDMUND)
    np.testing.assert_allclose(a, (1e4 * v / 4.0 + 10.0).astype(np.float32), rtol=0)
    assert a.dtype == np.float32


def test_integer_dtype_rounds_and_clips():
    kw = dict(natural_vignetting=False, noise=False)
    rounded = flat_frame((4, 5), PITCH_UM, 2.8, NO_VIGNETTING,
                         detector=Detector(signal_electrons=100.4), dtype=np.uint8, **kw)
    assert rounded.dtype == np.uint8 and np.all(rounded == 100)
    up = flat_frame((4, 5), PITCH_UM, 2.8, NO_VIGNETTING,
                    detector=Detector(signal_electrons=100.6), dtype=np.int32, **kw)
    assert np.all(up == 101)
    high = flat_frame((4, 5), PITCH_UM, 2.8, NO_VIGNETTING,
                      detector=Detector(signal_electrons=300.0), dtype=np.uint8, **kw)
    assert np.all(high == 255)
    low = flat_frame((4, 5), PITCH_UM, 2.8, NO_VIGNETTING,
                     detector=Detector(signal_electrons=1.0, dark_dn=-40000.0), dtype=np.int16,
                     **kw)
    assert np.all(low == -32768)
    # read noise on a faint signal goes negative: an unsigned frame is clipped at 0
    faint = flat_frame((64, 64), PITCH_UM, 2.8, NO_VIGNETTING, detector=Detector(
        signal_electrons=4.0, read_noise_electrons=20.0), dtype=np.uint16, rng=1)
    assert faint.dtype == np.uint16 and faint.min() == 0 and np.mean(faint == 0) > 0.3
    huge = flat_frame((2, 2), PITCH_UM, 2.8, NO_VIGNETTING,
                      detector=Detector(signal_electrons=1e19), noise=False, dtype=np.int64,
                      natural_vignetting=False)
    assert np.all(huge == np.iinfo(np.int64).max - 1023)  # the largest float below 2**63


def test_saturation_clips():
    frame = flat_frame((128, 128), PITCH_UM, 2.8, NO_VIGNETTING, natural_vignetting=False,
                       detector=Detector(saturation_dn=9900.0), rng=3)
    assert frame.max() == 9900.0
    assert np.mean(frame == 9900.0) == pytest.approx(0.84, abs=0.03)  # P(N >= 9900), N ~ 1e4
    free = flat_frame((64, 96), 100.0, 1.4, EDMUND, noise=False, dtype=np.float64)
    clipped = flat_frame((64, 96), 100.0, 1.4, EDMUND, noise=False, dtype=np.float64,
                         detector=Detector(saturation_dn=7000.0))
    np.testing.assert_array_equal(clipped, np.minimum(free, 7000.0))
    assert np.any(free > 7000.0) and np.any(free < 7000.0)


# -- lamp and plaque -------------------------------------------------------------------------
def hand_irradiance(X, Y, D):
    """Hanssen 2017, E(x, y, z) slide, inverse square, up to E_cal (d_cal + 0.2175)^2."""
    r = math.sqrt(X**2 + (D + 0.3175) ** 2)
    d_eff2 = (r - 0.1) ** 2 + Y**2
    return (D / math.sqrt(X**2 + Y**2 + D**2)) / d_eff2


def x_only_ray(tan_x, L, view_deg):
    """Plaque point hit by the ray tilted by arctan(tan_x) in the plane of incidence: the
    triangle (camera, plaque centre, point) with the law of sines."""
    beta, v = math.atan(tan_x), math.radians(view_deg)
    return L * math.sin(beta) / math.cos(v - beta)


def test_lamp_plaque_axis_pixel_is_one():
    assert LampPlaque().relative_signal(0.0, 0.0) == 1.0
    odd = LampPlaque(60.0, 80.0, 30.0, brdf={(0, 1): 0.8, (1, 0): 0.3, "t": 1.0})
    assert odd.relative_signal(0.0, 0.0) == pytest.approx(1.0, abs=1e-15)
    assert odd.brdf_ratio(0.0, 0.0) != pytest.approx(1.0)  # 30 deg is not 0/45: g(axis) != 1


def test_irradiance_is_inverse_square_and_e_cal_at_the_calibration_distance():
    assert LampPlaque().irradiance_ratio(0.0, 0.0) == pytest.approx(1.0, abs=1e-14)
    farther = LampPlaque(lamp_distance_cm=60.0).irradiance_ratio(0.0, 0.0)
    assert farther == pytest.approx((50.2175 / 60.2175) ** 2, rel=1e-14)


@pytest.mark.parametrize(("D", "L", "view"), [(50.0, 50.0, 45.0), (60.0, 80.0, 35.0)])
@pytest.mark.parametrize("tan_x", [-0.25, -0.1, 0.15, 0.3])
def test_lamp_plaque_in_plane_rays_by_hand(D, L, view, tan_x):
    source = LampPlaque(lamp_distance_cm=D, camera_distance_cm=L, view_angle_deg=view)
    X = x_only_ray(tan_x, L, view)
    x_cm, y_cm = source.plaque_point(tan_x, 0.0)
    assert (x_cm, y_cm) == (pytest.approx(X, rel=1e-12), 0.0)
    expected = hand_irradiance(X, 0.0, D) / hand_irradiance(0.0, 0.0, D)
    assert source.relative_signal(tan_x, 0.0) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize(("D", "L", "view"), [(50.0, 50.0, 45.0), (60.0, 80.0, 35.0)])
@pytest.mark.parametrize("tan_y", [-0.3, 0.1, 0.2])
def test_lamp_plaque_vertical_rays_by_hand(D, L, view, tan_y):
    # the ray tilted out of the plane of incidence hits the plaque straight above the lamp
    source = LampPlaque(lamp_distance_cm=D, camera_distance_cm=L, view_angle_deg=view)
    Y = L * tan_y
    x_cm, y_cm = source.plaque_point(0.0, tan_y)
    assert x_cm == pytest.approx(0.0, abs=1e-12) and y_cm == pytest.approx(Y, rel=1e-12)
    expected = hand_irradiance(0.0, Y, D) / hand_irradiance(0.0, 0.0, D)
    assert source.relative_signal(0.0, tan_y) == pytest.approx(expected, rel=1e-12)


COEFFS = {(1, 0): 0.3, (0, 1): -0.2, (2, 0): 0.5, (1, 1): 0.25, (0, 2): 0.6, (2, 2): -0.4,
          "t": 0.7}


def hand_g(l_i, l_s, t_s):
    return 1 + sum(c * l_i ** k[0] * l_s ** k[1] for k, c in COEFFS.items() if k != "t") + (
        COEFFS["t"] * t_s**2)


@pytest.mark.parametrize("tan_x", [-0.2, 0.1, 0.25])
def test_brdf_polynomial_in_the_plane_of_incidence(tan_x):
    D, L, view = 50.0, 50.0, 45.0
    lamb = LampPlaque(D, L, view)
    rough = LampPlaque(D, L, view, brdf=COEFFS)
    X = x_only_ray(tan_x, L, view)
    sin_i = abs(X) / math.hypot(X, D)
    # camera at x = L sin(view) on the +x side: light travelling to +x moves towards it
    # (phi_r = 0, l_i = +sin(theta_i)), light travelling to -x away from it (phi_r = 180 deg)
    l_i = sin_i if X > 0 else -sin_i
    theta_s = math.atan2(L * math.sin(math.radians(view)) - X, L * math.cos(math.radians(view)))
    l_s = math.sin(theta_s) - math.sin(math.radians(45))
    g = hand_g(l_i, l_s, 0.0)  # g(axis) = 1 at 0/45
    ratio = rough.relative_signal(tan_x, 0.0) / lamb.relative_signal(tan_x, 0.0)
    assert ratio == pytest.approx(g, rel=1e-12)
    assert abs(g - 1) > 0.01


@pytest.mark.parametrize("tan_y", [-0.2, 0.15])
def test_brdf_polynomial_out_of_plane(tan_y):
    D, L, view = 50.0, 50.0, 45.0
    Y = L * tan_y
    xc = L * math.sin(math.radians(view))  # camera's x; the plaque point is (0, Y)
    sin_i = abs(Y) / math.hypot(Y, D)
    phi_i = math.atan2(Y, 0.0)  # azimuth of the light's travel along the plaque
    phi_s = math.atan2(-Y, xc)  # azimuth of the scatter direction towards the camera
    phi_r = phi_s - phi_i
    dist = math.sqrt(xc**2 + Y**2 + (L * math.cos(math.radians(view))) ** 2)
    l_s = math.hypot(xc, Y) / dist - math.sin(math.radians(45))
    g = hand_g(sin_i * math.cos(phi_r), l_s, sin_i * math.sin(phi_r))
    rough = LampPlaque(D, L, view, brdf=COEFFS)
    ratio = rough.relative_signal(0.0, tan_y) / LampPlaque(D, L, view).relative_signal(0.0, tan_y)
    assert ratio == pytest.approx(g, rel=1e-12)


def test_brdf_ratio_normalised_by_the_axis_when_not_at_0_45():
    coeffs = {(0, 1): 0.5}
    source = LampPlaque(view_angle_deg=30.0, brdf=coeffs)
    l_s_axis = math.sin(math.radians(30)) - math.sin(math.radians(45))
    assert source.brdf_ratio(0.0, 0.0) == pytest.approx(1 + 0.5 * l_s_axis, rel=1e-14)
    lamb = LampPlaque(view_angle_deg=30.0)
    x_cm, _ = source.plaque_point(0.2, 0.0)
    theta_s = math.atan2(50 * math.sin(math.radians(30)) - x_cm, 50 * math.cos(math.radians(30)))
    g = (1 + 0.5 * (math.sin(theta_s) - math.sin(math.radians(45)))) / (1 + 0.5 * l_s_axis)
    ratio = source.relative_signal(0.2, 0.0) / lamb.relative_signal(0.2, 0.0)
    assert ratio == pytest.approx(g, rel=1e-12)


def test_lamp_plaque_flat_is_asymmetric_and_varies_by_several_percent():
    # a 2048 x 2048, 5.5 um sensor (11.3 mm) sampled every 8th pixel
    source = LampPlaque()
    shape, pitch = (256, 256), 8 * PITCH_UM
    flat = relative_illumination_map(shape, pitch, 2.8, NO_VIGNETTING, natural_vignetting=False,
                                     source=source)
    left, right = flat[128, 0], flat[128, 255]
    top, bottom = flat[0, 128], flat[255, 128]
    assert abs(right / left - 1) > 0.05  # the side nearer the camera is brighter
    assert right > left
    assert top == pytest.approx(bottom, rel=1e-12)  # mirror symmetry in y
    assert abs(top / right - 1) > 0.01  # not radially symmetric
    assert flat.max() / flat.min() - 1 > 0.05
    # flat_frame multiplies the lens terms by the source, pixel by pitch
    lens_only = flat_frame(shape, pitch, 2.0, EDMUND, noise=False, dtype=np.float64)
    with_source = flat_frame(shape, pitch, 2.0, EDMUND, noise=False, dtype=np.float64,
                             source=source)
    i, j = 40, 201
    tx = (j - 127.5) * pitch / 1000 / EDMUND.exit_pupil_mm
    ty = (i - 127.5) * pitch / 1000 / EDMUND.exit_pupil_mm
    assert with_source[i, j] == pytest.approx(lens_only[i, j] * source.relative_signal(tx, ty),
                                              rel=1e-12)


def test_lamp_plaque_broadcasts_and_passes_nan():
    source = LampPlaque(brdf={(1, 0): 0.2, "t": 0.3})
    tx = np.linspace(-0.2, 0.3, 6)
    ty = np.linspace(0.1, -0.25, 6)
    flat = source.relative_signal(tx, ty)
    assert flat.shape == (6,)
    np.testing.assert_array_equal(source.relative_signal(tx.reshape(2, 3), ty.reshape(2, 3)),
                                  flat.reshape(2, 3))
    assert source.relative_signal(float(tx[4]), float(ty[4])) == flat[4]
    out = source.relative_signal(np.array([np.nan, 0.1]), np.array([0.0, np.nan]))
    assert np.all(np.isnan(out))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [(dict(view_angle_deg=0.0), "view_angle_deg"), (dict(view_angle_deg=90.0), "view_angle_deg"),
     (dict(lamp_distance_cm=-1.0), "lamp_distance_cm"),
     (dict(camera_distance_cm=0.0), "camera_distance_cm"),
     (dict(brdf={(0, 0): 1.0}), "unknown brdf key"), (dict(brdf={(3, 1): 1.0}), "unknown brdf"),
     (dict(brdf={"s": 1.0}), "unknown brdf key")],
)
def test_lamp_plaque_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LampPlaque(**kwargs)


def test_lamp_plaque_rejects_lines_of_sight_that_miss_the_plaque():
    with pytest.raises(ValueError, match="never reach the plaque"):
        LampPlaque().relative_signal([0.0, -1.5], 0.0)  # 56 deg off axis, away from the plaque


# -- input checks ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        (((0, 5), PITCH_UM), {}, "shape"),
        (((4.0, 5), PITCH_UM), {}, "shape"),
        (((4,), PITCH_UM), {}, "shape"),
        (((4, 5), 0.0), {}, "pixel_pitch_um"),
        (((4, 5), -5.5), {}, "pixel_pitch_um"),
        (((4, 5), PITCH_UM), dict(pixel_acceptance_deg=0.0), r"\(0, 90\)"),
        (((4, 5), PITCH_UM), dict(pixel_acceptance_deg=90.0), r"\(0, 90\)"),
        (((4, 5), PITCH_UM), dict(center_px=(1.0, np.nan)), "center_px"),
        (((4, 5), PITCH_UM), dict(center_px=3.0), "center_px"),
        (((4, 5), PITCH_UM), dict(dtype=bool), "dtype"),
    ],
)
def test_flat_frame_rejects_bad_input(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        flat_frame(*args, 2.0, EDMUND, **kwargs)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(signal_electrons=0.0), "signal_electrons"),
        (dict(read_noise_electrons=-1.0), "read_noise_electrons"),
        (dict(gain_electrons_per_dn=0.0), "gain"),
        (dict(saturation_dn=-3.0), "saturation_dn"),
        (dict(dark_dn=np.inf), "dark_dn"),
    ],
)
def test_detector_rejects_bad_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Detector(**kwargs)
    with pytest.raises(TypeError, match="Detector"):
        flat_frame((4, 5), PITCH_UM, 2.0, EDMUND, detector=kwargs)


@pytest.mark.parametrize("f_number", [0.0, -2.0, np.nan])
def test_flat_field_rejects_bad_f_number(f_number):
    with pytest.raises(ValueError, match="f_number"):
        flat_frame((4, 5), PITCH_UM, f_number, EDMUND)


def test_relative_illumination_map_rejects_unknown_method_and_source():
    with pytest.raises(ValueError, match="'radial', 'exact'"):
        relative_illumination_map((4, 5), PITCH_UM, 2.0, EDMUND, method="spline")
    with pytest.raises(TypeError, match="relative_signal"):
        relative_illumination_map((4, 5), PITCH_UM, 2.0, EDMUND, source=1.0)
