"""The stages of a lens calibration: a mosaic's tile of gains told from a sensor's own pattern."""

import numpy as np


def test_a_tile_of_gains_is_told_from_a_sensors_own_fixed_pattern():
    """A smooth fall-off with 1 % pixel gains (PRNU), 1 % even/odd column gains and shot noise
    is no mosaic; the same light through a 5 x 5 tile of gains 0.3-1.0 is, with its period
    (not 10 x 10, where it shows as much)."""
    from snapcorr.calibrate.lens.stages import _tile_period

    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[:300, :400]
    light = 3000.0 * (1 - 0.4 * (((yy - 140) / 300.0) ** 2 + ((xx - 210) / 400.0) ** 2))
    own = (1 + 0.01 * rng.standard_normal(light.shape)) * np.where(xx % 2, 1.01, 1.0)
    flat = rng.poisson(light * own).astype(float)
    ok = np.ones(flat.shape, bool)
    assert _tile_period(flat, ok) is None
    tile = rng.uniform(0.3, 1.0, (5, 5))
    mosaic = rng.poisson(light * own * np.tile(tile, (60, 80))).astype(float)
    k, spread = _tile_period(mosaic, ok)
    assert k == 5 and spread > 0.1
