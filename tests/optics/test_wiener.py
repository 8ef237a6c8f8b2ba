"""The Wiener estimate of virtual bands against sampled spectra: the least-squares fit of the
targets on noisy band values over draws from the prior, and generalised cross-validation
(Golub, Heath & Wahba 1979) written out from its formula."""

import numpy as np
import pytest

from snapcorr.optics.wiener import (
    expected_error,
    gaussian_targets,
    gcv_alpha,
    markov_prior,
    normalised,
    trapezoid_weights,
    wiener_matrix,
)

GRID = np.arange(600.0, 801.0, 5.0)
PRIOR_SHORT = dict(mean=0.3, sd=0.25, length_nm=60.0)  # short: the bands' choice matters


def _bands():
    """Four overlapping bands with a second-order leak each, and two virtual targets."""
    c = np.array([640.0, 680.0, 720.0, 760.0])
    r = np.exp(-0.5 * ((GRID[None, :] - c[:, None]) / 14.0) ** 2)
    r += 0.1 * np.exp(-0.5 * ((GRID[None, :] - c[::-1, None]) / 8.0) ** 2)
    return normalised(GRID, r), gaussian_targets(GRID, [665.0, 735.0], [20.0, 30.0])


def _draws(n, rng, alpha, weights):
    """Spectra of the Markov prior (mean, exponential covariance) and their noisy band values."""
    p = PRIOR_SHORT
    cov = p["sd"] ** 2 * np.exp(-np.abs(GRID[:, None] - GRID[None, :]) / p["length_nm"])
    x = p["mean"] + rng.standard_normal((n, GRID.size)) @ np.linalg.cholesky(cov).T
    y = x @ weights.T + np.sqrt(alpha) * rng.standard_normal((n, weights.shape[0]))
    return x, y


def test_trapezoid_weights_integrate_like_numpy():
    grid = np.array([400.0, 401.0, 403.5, 410.0, 411.0])
    f = np.sin(grid / 7.0) + 2.0
    assert trapezoid_weights(grid) @ f == pytest.approx(np.trapezoid(f, grid), rel=1e-14)


def test_gaussian_targets_average_and_have_the_width_asked_for():
    fine = np.arange(600.0, 800.0, 0.01)
    g = gaussian_targets(fine, [700.0], [20.0])[0]
    assert g.sum() == pytest.approx(1.0, rel=1e-12)  # an average: a flat spectrum stays
    above = fine[g >= 0.5 * g.max()]
    assert above[-1] - above[0] == pytest.approx(20.0, abs=0.02)
    assert g @ fine == pytest.approx(700.0, abs=1e-6)
    with pytest.raises(ValueError, match="within the responses' grid"):
        gaussian_targets(GRID, [610.0], [20.0])


def test_the_wiener_matrix_is_the_least_squares_fit_over_the_priors_spectra():
    weights, targets = _bands()
    alpha = 1e-4  # 1 % noise
    prior = markov_prior(GRID, **PRIOR_SHORT)
    A = wiener_matrix(weights, targets, prior, alpha)
    x, y = _draws(200_000, np.random.default_rng(1976), alpha, weights)
    v = x @ targets.T
    fit = np.linalg.lstsq(y, v, rcond=None)[0].T  # no intercept: Phi is the second moment
    np.testing.assert_allclose(A, fit, atol=0.02 * np.abs(A).max())
    # and its expected error is what the draws give, and the least of any estimate
    rms = np.sqrt(np.mean((y @ A.T - v) ** 2, axis=0))
    np.testing.assert_allclose(expected_error(A, weights, targets, prior, alpha), rms, rtol=0.02)
    other = A * 1.05
    assert np.all(expected_error(other, weights, targets, prior, alpha)
                  > expected_error(A, weights, targets, prior, alpha))


def test_gcv_is_golub_heath_wahbas_function_and_finds_the_noise():
    weights, _ = _bands()
    prior = markov_prior(GRID, **PRIOR_SHORT)
    alpha_true = 1e-4
    _, y = _draws(4000, np.random.default_rng(1979), alpha_true, weights)
    alphas = np.logspace(-7, -2, 26)
    best, score = gcv_alpha([weights], [y], prior, alphas)
    G = weights @ prior @ weights.T
    nb = G.shape[0]
    for a, s in zip(alphas, score, strict=True):
        H = G @ np.linalg.inv(G + a * np.eye(nb))  # the influence matrix
        resid = y.T - H @ y.T
        V = np.sum(resid**2) / resid.size / (np.trace(np.eye(nb) - H) / nb) ** 2
        assert s == pytest.approx(V, rel=1e-9)
    assert best == alphas[np.argmin(score)]
    assert alpha_true / 4 <= best <= alpha_true * 4
    kept = y[1::2]
    y[::2, 2] = np.nan  # rows with a missing band are left out
    np.testing.assert_array_equal(gcv_alpha([weights], [y], prior, alphas)[1],
                                  gcv_alpha([weights], [kept], prior, alphas)[1])
    with pytest.raises(ValueError, match="no pixel"):
        gcv_alpha([weights], [np.full((3, nb), np.nan)], prior, alphas)


@pytest.mark.parametrize("alpha", [0.0, -1e-4, np.nan])
def test_a_bad_noise_variance_is_refused(alpha):
    weights, targets = _bands()
    with pytest.raises(ValueError, match="alpha"):
        wiener_matrix(weights, targets, markov_prior(GRID), alpha)
