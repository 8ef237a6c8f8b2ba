"""The exit-pupil fit's linear least squares, against ``numpy.linalg`` on random designs.

The weighted solution (with and without the unknown target's prior) against
``numpy.linalg.lstsq`` on the whitened system written out in full; the minimum-norm solution
of a rank-deficient design against ``numpy.linalg.pinv``; the parameters the data spend
against the trace of the hat matrix; the projection against ``I - A A^+``.
"""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import sparse

from snapcorr import Lens
from snapcorr.calibrate.pupil.solver import (
    _pinv_solve,
    _prediction_derivatives,
    _project_off,
    _solve,
)
from snapcorr.optics.shift import check_n_eff


def _design(seed, rows=60, cols=8, density=0.4):
    rng = np.random.default_rng(seed)
    A = sparse.random_array((rows, cols), density=density, rng=rng, format="csr")
    y = rng.normal(size=rows)
    sigma = rng.uniform(0.5, 2.0, rows)
    return A, y, sigma


def _model(y, sigma, cols, prior_sd=None, prior_mean=0.0):
    return SimpleNamespace(y=y, sigma=sigma, prior_sd=prior_sd, prior_mean=prior_mean,
                           n_rows=y.size, n_columns=cols)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_weighted_least_squares_is_lstsq_on_the_whitened_system(seed):
    A, y, sigma = _design(seed)
    s, r, _ = _solve(_model(y, sigma, A.shape[1]), A)
    Aw = A.toarray() / sigma[:, None]
    want, *_ = np.linalg.lstsq(Aw, y / sigma, rcond=None)
    np.testing.assert_allclose(s, want, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(r, y / sigma - Aw @ want, rtol=1e-8, atol=1e-10)


def test_the_prior_is_rows_of_the_system_and_the_rank_the_hat_matrix_trace():
    A, y, sigma = _design(3, rows=30, cols=12)
    sd, mean = 0.8, 0.3
    s, r, rank = _solve(_model(y, sigma, 12, prior_sd=sd, prior_mean=mean), A, rank=True)
    Aw = A.toarray() / sigma[:, None]
    big = np.vstack([Aw, np.eye(12) / sd])
    rhs = np.concatenate([y / sigma, np.full(12, mean / sd)])
    want, *_ = np.linalg.lstsq(big, rhs, rcond=None)
    np.testing.assert_allclose(s, want, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(r, rhs - big @ want, rtol=1e-8, atol=1e-10)
    hat = Aw @ np.linalg.inv(Aw.T @ Aw + np.eye(12) / sd**2) @ Aw.T
    assert rank == pytest.approx(np.trace(hat), rel=1e-8)
    assert 0 < rank < 12


def test_a_rank_deficient_design_gets_a_least_squares_solution_and_its_rank():
    """Of the many solutions, the one of least norm in the columns scaled to unit length (the
    normal equations are solved scaled): ``D^-1 pinv(A D^-1) b``, ``D`` the column norms."""
    rng = np.random.default_rng(6)
    B = rng.normal(size=(40, 4))
    A = np.column_stack([B, B[:, 0] + B[:, 1], 2 * B[:, 2]])  # rank 4 of 6 columns
    d = np.linalg.norm(A, axis=0)
    b = rng.normal(size=40)
    z, used = _pinv_solve(sparse.csr_array(A), b)
    assert used == np.linalg.matrix_rank(A) == 4
    best, *_ = np.linalg.lstsq(A, b, rcond=None)
    np.testing.assert_allclose(A @ z, A @ best, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(z, np.linalg.pinv(A / d) @ b / d, rtol=1e-6, atol=1e-9)
    rhs = rng.normal(size=(40, 3))  # several right-hand sides at once
    Z, _ = _pinv_solve(sparse.csr_array(A), rhs)
    np.testing.assert_allclose(Z, np.linalg.pinv(A / d) @ rhs / d[:, None], rtol=1e-6,
                               atol=1e-9)


def test_the_projection_removes_what_the_columns_explain():
    A, _, _ = _design(7)
    J = np.random.default_rng(8).normal(size=(A.shape[0] - 5, 2))  # the prior's rows missing
    got = _project_off(A, J)
    dense = A.toarray()
    full = np.vstack([J, np.zeros((5, 2))])
    want = full - dense @ np.linalg.pinv(dense) @ full
    np.testing.assert_allclose(got, want, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(dense.T @ got, 0.0, atol=1e-9)


class _BoundedModel:
    """A model whose design at ``x`` builds the lens there and checks the index as the real
    ones do (refusing a lens or an index out of bounds), with rows known in closed form:
    ``log(x) n_b``, ``sqrt(x) n_b^2``, ``1 / x`` for each band ``b``."""

    analytic_dn = False

    def __init__(self):
        self.sigma = np.ones(6)
        self.n_rows = 6
        self.blocks = [(0, k, slice(3 * k, 3 * k + 3), None) for k in range(2)]

    def design(self, x, n):
        Lens(x)
        n = check_n_eff(n)
        rows = [[f] for k in range(2)
                for f in (np.log(x) * n[k], np.sqrt(x) * n[k] ** 2, 1.0 / x)]
        return sparse.csr_array(np.array(rows))


@pytest.mark.parametrize("central", [False, True])
@pytest.mark.parametrize("x", [1e-3, 21.0, 1e6])
def test_the_derivatives_step_inward_at_the_bounds_of_x_and_n_eff(x, central):
    """A lens at x = 1e6 mm (or 1e-3 mm) and an index next to 5 are a lens's and a filter's:
    the differences stay inside the bounds (a central step's 1000010 mm was refused) and give
    the closed-form derivatives."""
    model = _BoundedModel()
    n = np.array([4.9999, 1.7])
    s = np.array([1.0])
    A = model.design(x, n)
    dx, dn = _prediction_derivatives(model, x, n, A, s, central=central)
    want_dx = np.concatenate([[n[k] / x, n[k] ** 2 / (2 * np.sqrt(x)), -1 / x**2]
                              for k in range(2)])
    np.testing.assert_allclose(dx, want_dx, rtol=1e-4 if not central else 1e-8,
                               atol=1e-12 * np.max(np.abs(want_dx)))
    want_dn = np.concatenate([[np.log(x), 2 * np.sqrt(x) * n[k], 0.0] for k in range(2)])
    np.testing.assert_allclose(dn, want_dn, rtol=1e-3, atol=1e-9 * np.max(np.abs(want_dn)))
