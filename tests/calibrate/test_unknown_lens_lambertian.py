"""An unknown lens in one run when its pupil is a Lambertian disc (the paper's radius, each
ray weighted by its own cos^4), with flats and target cubes made by simulators that share no
code with snapcorr: the flats by the exact row integrals of
``tests/calibrate/lens/test_calibration_lambertian.py``, the cubes by the pupil quadrature of
``tests/oracles/spectralsim.py`` (its ``"disc-cos4"`` pupil, every ray's filter
``T0(lambda / s)``).
"""

from __future__ import annotations

import numpy as np
import pytest
import spectralsim as sim
from flatsim import LensTruth

from calibrate.lens.test_calibration_lambertian import make_flats
from calibrate.pupil.test_locate import CENTER, CWL, FWHM, N_EFF, PITCH_UM, SHAPE, sensor
from snapcorr.calibrate import calibrate_with_target
from snapcorr.cube import make_cube

X, CIRCLE, M, M_P = 21.0, (7.4236, 16.991), 0.06, 1.3
DISC = LensTruth(X, (CIRCLE,), M, M_P, name="Lambertian disc", meta={"pupil": "disc-cos4"})


def _cubes(seed, noise=0.002, f_numbers=(2.0, 8.0)):
    rng = np.random.default_rng(100 + seed)
    out = {}
    for f in f_numbers:
        data = sim.target_cube(sim.colour_filter, cwl_nm=CWL, fwhm_nm=FWHM, n_eff=N_EFF,
                               f_number=f, lens=DISC, shape=SHAPE, pixel_pitch_um=PITCH_UM,
                               center_px=CENTER)
        out[f] = make_cube(data + rng.normal(0.0, noise, data.shape), CWL)
    return out


@pytest.mark.slow
def test_the_lambertian_disc_is_chosen_and_x_covers():
    """``pupil_radiance="auto"`` (the command's default with a target) fits every pupil and
    keeps the Lambertian disc; x and n_eff within their errors. The paper's pupil alone on
    the same data misfits the flats (the chief ray's cos^4)."""
    flats = make_flats(1, 0.005, shape=SHAPE, centre=(CENTER[1], CENTER[0]), pitch_um=PITCH_UM,
                       x=X, circle=CIRCLE, working=1 + M / M_P)
    got = calibrate_with_target(flats, _cubes(1), sensor(), pixel_pitch_um=PITCH_UM,
                                fit_n_eff=True, magnification=M, pupil_magnification=M_P,
                                max_circles=1, pupil_radiance="auto")
    assert got.lens.pupil_radiance == "paper-lambertian", got.summary()
    choice = got.lens.calibration["pupil_choice"]
    assert set(choice["chi2_plus_flats_bic"]) == {"paper", "lambertian", "paper-lambertian"}
    z = {n: v for n, v in zip(got.names, (got.values - np.array(
        [X, N_EFF] + [np.nan] * (len(got.names) - 2))) / got.stderr, strict=True)}
    assert abs(z["exit_pupil_mm"]) < 4 and abs(z["n_eff"]) < 4, (z, got.summary())
    assert abs(got.values[0] / X - 1) < 0.005
