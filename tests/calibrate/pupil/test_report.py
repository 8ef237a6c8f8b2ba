"""The picture of an exit-pupil fit: the bands it shows and the chi-square curve it draws.

The fit is made on a cube from ``tests/oracles/spectralsim.py``; the chi-square the picture
draws about ``x`` is checked against the fit's own standard error (a rise of about one
reduced chi-square at one standard error), the bands against their spread worked out here.
"""

from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
import spectralsim as sim

from calibrate.pupil.test_locate import CWL, FWHM, N_EFF, PLAIN, as_lens
from snapcorr.calibrate import locate_pupil
from snapcorr.calibrate.pupil.report import _informative_bands
from snapcorr.cube import Sensor, make_cube

matplotlib.use("Agg")

# the field of test_locate's sensor in 64 x 80 pixels, every third band
SHAPE, PITCH_UM, CENTER, BANDS = (64, 80), 88.0, (41.15, 30.8), CWL[::3]


def test_the_most_informative_bands_are_those_whose_model_moves_most_against_its_noise():
    rng = np.random.default_rng(0)
    n_bands, per = 5, 6
    pred = rng.normal(size=n_bands * per)
    sigma = rng.uniform(0.5, 2.0, n_bands * per)
    blocks = [(0, k, slice(k * per, (k + 1) * per), None) for k in range(n_bands)]
    fit = SimpleNamespace(model=SimpleNamespace(cwl=np.arange(n_bands), blocks=blocks,
                                                sigma=sigma))
    score = [np.ptp(pred[s]) / np.median(sigma[s]) for _, _, s, _ in blocks]
    np.testing.assert_array_equal(_informative_bands(fit, pred, 3), np.argsort(score)[::-1][:3])


def test_the_chi_square_drawn_about_x_rises_as_the_fits_error_says():
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(3)
    clean = sim.target_cube(sim.colour_filter, cwl_nm=BANDS, fwhm_nm=FWHM, n_eff=N_EFF,
                            f_number=2.0, lens=PLAIN, shape=SHAPE, pixel_pitch_um=PITCH_UM,
                            center_px=CENTER, n_radii=96)
    cube = make_cube(clean + rng.normal(0.0, 0.01, clean.shape), BANDS)
    small = Sensor("test", "snapscan", PITCH_UM, BANDS, FWHM, N_EFF)
    fit = locate_pupil({2.0: cube}, small, lens=as_lens(PLAIN),
                       target_spectrum=sim.colour_filter, center_px=CENTER, n_bins=32)
    fig = fit.plot(bands=3)
    try:
        left, right = fig.axes
        assert len(left.containers) == 3  # one band's annuli a container
        points, parabola = right.lines[:2]
        x, c2 = points.get_xdata(), points.get_ydata()
        assert c2[x.size // 2] == pytest.approx(0.0, abs=0.05)  # the minimum at x itself
        s = fit.exit_pupil_stderr_mm
        one = np.interp([x[x.size // 2] - s, x[x.size // 2] + s], x, c2)
        scale = max(1.0, fit.chi2_red)
        np.testing.assert_allclose(one, scale, rtol=0.35)
        d = parabola.get_xdata()
        np.testing.assert_allclose(parabola.get_ydata(), ((d - fit.exit_pupil_mm) / s) ** 2 * scale,
                                   rtol=1e-9)
    finally:
        plt.close(fig)
