"""Cramér-Rao bound on the vignetting circles calibrated from integrating-sphere flat fields.

The smallest covariance any unbiased estimator of the circles' ``(P_i, h_i)`` can reach from
flats made as :func:`flatsim.make_flats` makes them: Gaussian noise of ``noise`` times the
local signal in every pixel, with unknown nuisances

* a gain per pixel (pixel response non-uniformity, the source's non-uniformity,
  ``cos^4(CRA)``: whatever is common to every flat of that pixel), profiled out;
* an exposure scale per flat, except the last one (the gains absorb a common scale);
* the optical centre ``(cx, cy)``.

Like :mod:`flatsim` it shares no code with ``snapcorr`` (it must not import it).

On a log scale a measurement is ``ln I_k = ln s_k + ln G_p + ln A_k(t_p; P, h) + const``
with standard deviation ``noise``, ``A_k`` the relative illumination of flat ``k``
(:func:`flatsim.relative_illumination`) and ``t_p = tan(CRA)`` of pixel ``p``, which moves
with the centre. A flat's pixel counts only where ``A_k > lit_min``. With ``d_k`` the
derivatives of ``ln A_k + ln s_k`` with respect to the parameters and ``w_k`` the weights
(``1 / noise^2`` where lit, 0 elsewhere), each pixel adds, once its ``ln G`` is profiled out,

    ``sum_k w_k d_k d_k^T - (sum_k w_k d_k)(sum_k w_k d_k)^T / sum_k w_k``

to the Fisher matrix. Anything common to every flat of a pixel cancels there, so
``cos^4(CRA)`` and the source carry no information. The derivatives of ``ln A_k`` with
respect to the circles and to ``t`` are central finite differences on a 1-D grid of ``t``,
interpolated to the pixels.
"""

from __future__ import annotations

import numpy as np
from flatsim import LensTruth, mean_shift_nm, relative_illumination

__all__ = ["bound", "fisher", "parameter_names", "shift_bound_nm"]

_GRID = 2049
_CHUNK = 1 << 16
_REL_STEP = 1e-6
_T_STEP = 1e-7


def parameter_names(truth, f_numbers):
    """Names of the parameters in the order of :func:`fisher`.

    Parameters
    ----------
    truth : flatsim.LensTruth
        The lens.
    f_numbers : sequence of float
        The flats' f-numbers.

    Returns
    -------
    list of str
        ``P1, h1, P2, h2, ...``, then ``cx, cy``, then ``ln_e(f/N)`` for every f-number but
        the last (the reference exposure).
    """
    names = []
    for i in range(len(truth.circles)):
        names += [f"P{i + 1}", f"h{i + 1}"]
    names += ["cx", "cy"]
    names += [f"ln_e(f/{float(f):g})" for f in list(f_numbers)[:-1]]
    return names


def _circle_values(truth):
    return [float(v) for circle in truth.circles for v in circle]


def _perturbed(truth, q, delta):
    """The lens with the ``q``-th circle value (P1, h1, P2, ...) moved by ``delta``."""
    values = _circle_values(truth)
    values[q] += delta
    circles = tuple(zip(values[0::2], values[1::2], strict=True))
    return LensTruth(truth.exit_pupil_mm, circles, truth.magnification,
                     truth.pupil_magnification)


def _step(truth, q):
    """Finite-difference step of the ``q``-th circle value, mm."""
    return _REL_STEP * max(abs(_circle_values(truth)[q]), 0.01 * truth.exit_pupil_mm)


def _log_derivatives(truth, f_number, t):
    """Relative illumination and the derivatives of its logarithm on a grid of tan(CRA).

    Parameters
    ----------
    truth : flatsim.LensTruth
        The lens.
    f_number : float
        The f-number.
    t : ndarray
        tan(CRA), 1-D.

    Returns
    -------
    a : ndarray
        ``A(t)``.
    d : ndarray, shape (2 * n_circles + 1, t.size)
        ``d ln A / d(P1, h1, P2, h2, ...)`` and, last, ``d ln A / dt`` (0 where ``A = 0``).
    """
    a = relative_illumination(truth, f_number, t)
    lit = a > 0

    def dlog(up, down, delta):
        return np.divide(up - down, 2.0 * delta * a, out=np.zeros_like(a), where=lit)

    rows = []
    for q in range(2 * len(truth.circles)):
        delta = _step(truth, q)
        rows.append(dlog(relative_illumination(_perturbed(truth, q, delta), f_number, t),
                         relative_illumination(_perturbed(truth, q, -delta), f_number, t),
                         delta))
    rows.append(dlog(relative_illumination(truth, f_number, t + _T_STEP),
                     relative_illumination(truth, f_number, t - _T_STEP), _T_STEP))
    return a, np.stack(rows)


def fisher(truth, noise, shape, pitch_um, center_px, f_numbers, *, step=1, lit_min=0.05):
    """Fisher information on the circles, the optical centre and the exposures.

    Parameters
    ----------
    truth : flatsim.LensTruth
        The true lens.
    noise : float
        Relative standard deviation of a pixel's signal (``make_flats``' ``noise``).
    shape : tuple of int
        Sensor (rows, columns).
    pitch_um : float
        Pixel pitch, µm.
    center_px : tuple of float
        Optical centre (x = column, y = row), pixels.
    f_numbers : sequence of float
        One flat per f-number.
    step : int, optional
        Use every ``step``-th row and column, each pixel standing for ``step^2`` pixels (an
        approximation of the full sensor's information).
    lit_min : float, optional
        A flat's pixel counts where its relative illumination exceeds this.

    Returns
    -------
    F : ndarray, shape (n, n)
        Fisher matrix with every pixel's gain profiled out, in the units of the parameters
        (mm, pixels, natural log of the exposure).
    names : list of str
        The parameters, as :func:`parameter_names`.
    """
    fs = [float(f) for f in f_numbers]
    n_flats = len(fs)
    n_circ = 2 * len(truth.circles)
    names = parameter_names(truth, fs)
    n_par = len(names)
    cx, cy = (float(v) for v in center_px)
    yy, xx = np.meshgrid(np.arange(0, shape[0], step, dtype=float),
                         np.arange(0, shape[1], step, dtype=float), indexing="ij")
    dx, dy = (xx - cx).ravel(), (yy - cy).ravel()
    rho = np.hypot(dx, dy)
    k = pitch_um * 1e-3 / truth.exit_pupil_mm
    t = k * rho
    # d t / d cx = -k (x - cx) / rho, the same with y
    gx = -k * np.divide(dx, rho, out=np.zeros_like(rho), where=rho > 0)
    gy = -k * np.divide(dy, rho, out=np.zeros_like(rho), where=rho > 0)
    grid = np.linspace(0.0, float(t.max()) * (1.0 + 1e-9) + 1e-12, _GRID)
    tables = [_log_derivatives(truth, f, grid) for f in fs]

    F = np.zeros((n_par, n_par))
    for start in range(0, t.size, _CHUNK):
        sl = slice(start, start + _CHUNK)
        tc = t[sl]
        D = np.zeros((n_flats, tc.size, n_par))
        W = np.zeros((n_flats, tc.size))
        for j, (a, d) in enumerate(tables):
            W[j] = np.interp(tc, grid, a) > lit_min
            for q in range(n_circ):
                D[j, :, q] = np.interp(tc, grid, d[q])
            dlna_dt = np.interp(tc, grid, d[n_circ])
            D[j, :, n_circ] = dlna_dt * gx[sl]
            D[j, :, n_circ + 1] = dlna_dt * gy[sl]
            if j < n_flats - 1:
                D[j, :, n_circ + 2 + j] = 1.0
        count = W.sum(axis=0)
        mean = np.einsum("kn,kni->ni", W, D) / np.maximum(count, 1.0)[:, None]
        X = ((D - mean[None]) * np.sqrt(W)[..., None]).reshape(-1, n_par)
        F += X.T @ X
    return F * (step * step / noise**2), names


def bound(truth, noise, shape, pitch_um, center_px, f_numbers, *, step=1, lit_min=0.05,
          held=()):
    """Cramér-Rao bound on the circles' parameters, the nuisances profiled out.

    Parameters
    ----------
    truth, noise, shape, pitch_um, center_px, f_numbers, step, lit_min
        As :func:`fisher`.
    held : tuple of int
        Circle parameters (indices into ``(P1, h1, P2, h2, ...)``) known, not estimated: an
        estimator that holds them; their rows and columns are zero.

    Returns
    -------
    ndarray, shape (2 * n_circles, 2 * n_circles)
        Covariance of ``(P1, h1, P2, h2, ...)``, mm^2: the circles' block of the inverse of
        the Fisher matrix.

    Raises
    ------
    numpy.linalg.LinAlgError
        If some parameter carries no information (e.g. a circle that cuts nowhere in the
        field).
    """
    F, names = fisher(truth, noise, shape, pitch_um, center_px, f_numbers, step=step,
                      lit_min=lit_min)
    n_circ = 2 * len(truth.circles)
    free = [i for i in range(len(names)) if i not in held]
    if held:
        C = np.zeros((len(names), len(names)))
        C[np.ix_(free, free)] = _inverse(F[np.ix_(free, free)], [names[i] for i in free])
        return C[:n_circ, :n_circ]
    return _inverse(F, names)[:n_circ, :n_circ]


def _inverse(F, names):
    """The inverse of a Fisher matrix, scaled to unit diagonal first."""
    scale = np.sqrt(np.diag(F))
    if np.any(scale <= 0):
        blind = [n for n, s in zip(names, scale, strict=True) if s <= 0]
        raise np.linalg.LinAlgError(f"the flats carry no information on {blind}")
    C = np.linalg.inv(F / np.outer(scale, scale)) / np.outer(scale, scale)
    return 0.5 * (C + C.T)


def shift_bound_nm(truth, cov, f_numbers, max_cra_deg, cwl_nm=1000.0, n_eff=1.5, n=61):
    """Largest standard deviation of the mean filter shift over the field, per f-number.

    The covariance of the circles is propagated to the mean shift over the vignetted pupil
    (:func:`flatsim.mean_shift_nm`) through its gradient, by central finite differences, at
    ``n`` chief-ray angles from 0 to ``max_cra_deg`` where the light is not fully cut.

    Parameters
    ----------
    truth : flatsim.LensTruth
        The true lens.
    cov : array_like, shape (2 * n_circles, 2 * n_circles)
        Covariance of ``(P1, h1, P2, h2, ...)``, as :func:`bound`.
    f_numbers : sequence of float
        The f-numbers.
    max_cra_deg : float
        The field's largest chief-ray angle, degrees.
    cwl_nm : float, optional
        Filter central wavelength, nm.
    n_eff : float, optional
        Filter effective index.
    n : int, optional
        Number of chief-ray angles.

    Returns
    -------
    ndarray
        Per f-number, the largest standard deviation, nm (NaN if the light is cut
        everywhere).
    """
    cov = np.asarray(cov, float)
    cra = np.linspace(0.0, float(max_cra_deg), n)
    out = []
    for f in f_numbers:
        lit = relative_illumination(truth, f, np.tan(np.deg2rad(cra))) > 0
        c = cra[lit]
        if c.size == 0:
            out.append(np.nan)
            continue
        grad = np.empty((cov.shape[0], c.size))
        for q in range(cov.shape[0]):
            delta = _step(truth, q)
            up = mean_shift_nm(_perturbed(truth, q, delta), cwl_nm, n_eff, f, c)
            down = mean_shift_nm(_perturbed(truth, q, -delta), cwl_nm, n_eff, f, c)
            grad[q] = (up - down) / (2.0 * delta)
        var = np.einsum("in,ij,jn->n", grad, cov, grad)
        var = var[np.isfinite(var)]
        out.append(float(np.sqrt(max(var.max(), 0.0))) if var.size else np.nan)
    return np.array(out)
