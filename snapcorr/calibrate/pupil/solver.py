"""The linear least squares inside the exit-pupil fit (:mod:`~snapcorr.calibrate.pupil.locate`).

For a trial exit pupil distance ``x`` (and index), the binned cubes are linear in the target's
spectral coefficients: :class:`_Problem` solves for them by weighted least squares (with the
unknown target's prior) and returns the whitened residuals, the coefficients profiled out
(variable projection). :func:`~snapcorr.calibrate.pupil.locate.locate_pupil`, its precision bound
(:func:`~snapcorr.calibrate.pupil.locate.pupil_precision`) and the fit's picture
(:mod:`~snapcorr.calibrate.pupil.report`) share it; it depends on neither of them.
"""

from __future__ import annotations

import numpy as np

#: A design filled above this fraction, and of at most DENSE_MAX entries, is solved as a dense
#: matrix (the sparse product of such a matrix with itself took most of a whole-sensor fit
#: with measured responses, whose curves reach most of the target's hats).
DENSE_FILL = 0.02
DENSE_MAX = 25_000_000


def _dense_if_filled(A):
    """``A`` as a dense array when it is filled above DENSE_FILL (and small enough)."""
    size = A.shape[0] * A.shape[1]
    if hasattr(A, "toarray") and DENSE_FILL * size < A.nnz and size <= DENSE_MAX:
        return A.toarray()
    return A


def _gram(A):
    """``A^T A`` as a dense array."""
    N = A.T @ A
    return N.toarray() if hasattr(N, "toarray") else np.asarray(N)


def _pinv_solve(Aw, rhs):
    """Minimum-norm least squares ``Aw z = rhs`` (``rhs`` 1-D or 2-D) through the scaled
    normal equations; also the rank used. A well-conditioned system (the unknown target
    with its prior) is solved by Cholesky, anything else by eigenvalues."""
    from scipy import linalg

    Aw = _dense_if_filled(Aw)
    N = _gram(Aw)
    b = Aw.T @ rhs
    d = np.sqrt(np.clip(np.diag(N), 1e-300, None))
    Ns = N / d[:, None] / d[None, :]
    try:
        c = linalg.cho_factor(Ns, check_finite=False)
        if np.min(np.abs(np.diag(c[0]))) ** 2 > 1e-10:
            z = linalg.cho_solve(c, b / (d if b.ndim == 1 else d[:, None]), check_finite=False)
            return (z / d if b.ndim == 1 else z / d[:, None]), N.shape[0]
    except linalg.LinAlgError:
        pass
    w, V = np.linalg.eigh(Ns)
    keep = w > 1e-12 * w.max()
    bd = b / (d if b.ndim == 1 else d[:, None])
    z = V[:, keep] @ ((V[:, keep].T @ bd) / (w[keep] if b.ndim == 1 else w[keep][:, None]))
    return (z / d if b.ndim == 1 else z / d[:, None]), int(keep.sum())


def _whiten(model, A):
    """The whitened design, with the target's prior as extra rows when it is unknown."""
    from scipy import sparse

    Aw = sparse.diags_array(1.0 / model.sigma) @ A
    if model.prior_sd is None:
        return Aw
    eye = sparse.identity(A.shape[1], format="csr") / model.prior_sd
    return sparse.vstack([Aw, eye], format="csr")


def _whitened_y(model):
    yw = model.y / model.sigma
    if model.prior_sd is None:
        return yw
    return np.concatenate([yw, np.full(model.n_columns, model.prior_mean / model.prior_sd)])


def _solve(model, A, *, rank=False):
    """Weighted least squares for the linear coefficients: ``s``, whitened residuals (the
    prior's rows last), and with ``rank`` the number of parameters the data spend on them
    (the trace of the hat matrix: the rank without a prior, less with one; else None)."""
    Aw = _whiten(model, A)
    yw = _whitened_y(model)
    s, used = _pinv_solve(Aw, yw)
    if not rank:
        return s, yw - Aw @ s, None
    rank = used
    if model.prior_sd is not None:  # the prior is isotropic: lambda / (lambda + 1 / sd^2)
        Ad = _dense_if_filled(Aw[:model.n_rows])
        lam = np.clip(np.linalg.eigvalsh(_gram(Ad)), 0.0, None)
        rank = float(np.sum(lam / (lam + model.prior_sd**-2)))
    return s, yw - Aw @ s, rank


def _project_off(Aw, J):
    """``J`` minus its least-squares fit by the columns of ``Aw``: the Jacobian of the
    profiled residuals (variable projection). ``J`` may lack the prior's rows (zero)."""
    if J.shape[0] < Aw.shape[0]:
        J = np.vstack([J, np.zeros((Aw.shape[0] - J.shape[0], J.shape[1]))])
    z, _ = _pinv_solve(Aw, J)
    return J - Aw @ z


def _row_bands(model):
    """The band of every row of ``model``'s data."""
    out = np.zeros(model.n_rows, int)
    for _, k, rows, _ in model.blocks:
        out[rows] = k
    return out


def _x_derivative(model, x, n, s, f0, eps_x, central):
    """The derivative in ``x`` of ``design(x) @ s`` (``f0`` at ``x``), by differences whose
    every ``x`` is a lens's (:data:`~snapcorr._validation.LENGTH_MIN_MM` to
    :data:`~snapcorr._validation.LENGTH_MAX_MM`): at a bound the stencil steps inward, one-sided
    (second order where ``central`` asks for it), as a lens at x = 1e6 mm was refused for its
    own difference's 1000010 mm."""
    from ..._validation import LENGTH_MAX_MM, LENGTH_MIN_MM

    h = x * eps_x
    hi, lo = x * (1 + eps_x), x * (1 - eps_x)
    up, down = hi <= LENGTH_MAX_MM, lo >= LENGTH_MIN_MM

    def at(v):
        return model.design(v, n) @ s

    if central and up and down:
        return (at(hi) - at(lo)) / (2 * h)
    if central and up:  # at the lower bound: forward, second order
        return (-3 * f0 + 4 * at(hi) - at(x + 2 * h)) / (2 * h)
    if central:  # at the upper bound: backward, second order
        return (3 * f0 - 4 * at(lo) + at(x - 2 * h)) / (2 * h)
    return (at(hi) - f0) / h if up else (f0 - at(lo)) / h


def _prediction_derivatives(model, x, n, A, s, *, eps_x=1e-5, eps_n=1e-4, central=False):
    """The derivatives of the whitened prediction ``A s / sigma`` at fixed ``s``: in ``x``
    (a forward difference, or with ``central`` a central one: the kernels are new at every
    ``x`` and have no derivative of their own; one-sided inward at the bounds of a lens's
    ``x``, :func:`_x_derivative`), and every row in its own band's index (the model's
    analytic derivative, :meth:`TargetModel.design` with ``dn``, where it has one, else a
    forward difference, backward for an index whose step would reach
    :data:`~snapcorr._validation.N_EFF_MAX`; every band's rows depend on its own index only,
    so one evaluation serves every band)."""
    from ..._validation import N_EFF_MAX

    As = A @ s
    dx = _x_derivative(model, x, n, s, As, eps_x, central)
    if getattr(model, "analytic_dn", False):
        dn = model.design(x, n, dn=True) @ s
    else:
        n = np.asarray(n, float)
        step = np.where(n * (1 + eps_n) < N_EFF_MAX, eps_n, -eps_n) * n
        dn = (model.design(x, n + step) @ s - As) / step[_row_bands(model)]
    return dx / model.sigma, dn / model.sigma


class _Problem:
    """``x`` (and a common scale of ``n_eff``, or one index per band) -> whitened residuals,
    the target's coefficients profiled out."""

    def __init__(self, model, n_design, progress=None):
        self.model = model
        self.n_design = np.asarray(n_design, float)
        self.progress = progress

    def evaluate(self, x, k=1.0, *, field=True, rank=False):
        """``(r, s, rank, A)``: :meth:`residuals` and the design they came from."""
        if self.progress is not None:
            self.progress(f"model at x = {float(x):.3f} mm")
        A = self.model.design(x, self.n_design * k, field=field)
        s, r, used = _solve(self.model, A, rank=rank)
        return r, s, used, A

    def residuals(self, x, k=1.0, *, field=True, rank=False):
        return self.evaluate(x, k, field=field, rank=rank)[:3]

    def chi2(self, x, k=1.0, *, field=True):
        r, _, _ = self.residuals(x, k, field=field)
        return float(r @ r)

    def jacobian(self, x, k, A, s, fit_k):
        """The Jacobian of the profiled residuals in ``x`` (and the index scale ``k``): the
        prediction's derivatives at fixed ``s`` projected off the target's columns
        (variable projection in Kaufman's form, whose ``J^T J`` is the Fisher information of
        ``x`` and ``k`` with the target's coefficients unknown)."""
        model = self.model
        dx, dn = _prediction_derivatives(model, x, self.n_design * k, A, s)
        cols = [dx] + ([dn * self.n_design[_row_bands(model)]] if fit_k else [])
        return _project_off(_whiten(model, A), np.column_stack(cols))
