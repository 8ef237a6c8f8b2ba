"""Cleaning a small flat: its noise measured from what pixels it has, its outliers found.

A flat of 16 x 16 pixels (196 residuals) was below the 200 the noise curve needed: the
noise came out 0, every pixel's scatter was an outlier against it, and calibrate said the
flat had "0 % usable pixels (saturated, dead or non-finite)". The flats here are made in the
test: a smooth fall-off, Gaussian noise of a known sigma, one hot pixel.
"""

import numpy as np
import pytest

from snapcorr.calibrate import clean_flat, noise_model

SIGMA = 20.0


def flat(n, seed=0):
    yy, xx = np.mgrid[:n, :n]
    img = 3000.0 * (1 - 0.5 * ((yy - n / 2) ** 2 + (xx - n / 2) ** 2) / n**2)
    img = img + np.random.default_rng(seed).normal(0.0, SIGMA, img.shape)
    img[n // 2, n // 3] = 60000.0  # hot
    return img


@pytest.mark.parametrize("n", [16, 24, 32])
def test_a_small_flat_measures_its_noise_and_masks_only_its_outlier(n):
    img = flat(n)
    ok = np.ones(img.shape, bool)
    ok[n // 2, n // 3] = False  # the noise of the rest
    a, b, c = noise_model(img, ok)
    var = a + b * 3000.0 + c * 3000.0**2
    assert 0.6 * SIGMA**2 < var < 1.6 * SIGMA**2, (a, b, c)
    _, valid, _ = clean_flat(img)
    assert not valid[n // 2, n // 3]
    assert valid.mean() > 0.9


def test_a_flat_of_a_few_pixels_gives_no_noise_and_calls_nothing_an_outlier():
    img = flat(5)[:5, :5]
    img[2, 1] = 3000.0  # no hot pixel: its neighbours say nothing of the noise here
    assert noise_model(img, np.ones(img.shape, bool)) == (0.0, 0.0, 0.0)
    assert clean_flat(img)[1].all()
