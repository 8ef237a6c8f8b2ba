"""Virtual bands: linear estimates of ideal bands from a mosaic sensor's physical bands.

A flat-fielded band value is its response's average of the scene's reflectance,
``y_b = int s_b(lambda) rho(lambda) dlambda`` with ``s_b`` the band's response through the
system, normalised to unit area (the white reference divides it out; equal-energy light is
assumed). A virtual band is the average over a target response ``g_v`` (a Gaussian of the
wanted centre and width, unit area). The estimate ``v = A y`` with the least expected error
over a prior of spectra of second moment ``Phi`` and band noise of variance ``alpha`` is the
Wiener estimate (Pratt & Mancill 1976 [1]_; Haneishi et al. 2000 [2]_)::

    A = g Phi s^T (s Phi s^T + alpha I)^-1

**The prior** is a first-order Markov process (exponential covariance) about a constant mean,
the smooth-spectrum model of [1]_ and [2]_: ``Phi = sd^2 exp(-|l - l'| / length) + mean^2``.
Its three numbers are the maximum-likelihood fit to 152 public reflectance spectra (the
ColorChecker N Ohta, the CIE 1995 and NIST CQS test colour samples and the 99 CIE 2017 colour
evaluation samples, as colour-science ships them, 380-780 nm at 5 nm; re-derived in the
tests): mean 0.325, standard deviation 0.293, correlation length 3900 nm (a correlation of
0.99974 per nm; [2]_ used 0.999 for paintings). A Markov process is stationary, so the same
numbers stand where the library has no samples (the near infrared).

**The regularisation** ``alpha`` is chosen by generalised cross-validation (Golub, Heath &
Wahba 1979 [3]_) on the cube's own band values: it minimises
``|(I - H) y|^2 / tr(I - H)^2`` with ``H = s Phi s^T (s Phi s^T + alpha I)^-1``, which needs
neither the noise level nor training spectra of the sensor's range. On simulated leaves and
soils it lands within a factor 2 of the best ``alpha`` at noise from 0.1 % to 3 %, where the
RMSE is within 2 % of the best. Without a cube, ``alpha`` is the square of the stated noise.

Why this method: it is the standard linear estimator for the task, it is exact for the
sensor's measured responses (second orders and leaks included), and recomputing it for each
pixel's responses behind the lens (:class:`VirtualTable`) only needs those responses; on the
real 5x5 NIR sensor it leaves 0.17-0.25 of the vendor matrix's error on simulated leaves and
soils (``benchmarks/virtual_bands.py``).

References
----------
.. [1] W. K. Pratt, C. E. Mancill, "Spectral estimation techniques for the spectral
   calibration of a color image scanner", Appl. Opt. 15, 73-75 (1976).
.. [2] H. Haneishi, T. Hasegawa, A. Hosoi, Y. Yokoyama, N. Tsumura, Y. Miyake, "System design
   for accurately estimating the spectral reflectance of art paintings", Appl. Opt. 39,
   6621-6632 (2000).
.. [3] G. H. Golub, M. Heath, G. Wahba, "Generalized cross-validation as a method for choosing
   a good ridge parameter", Technometrics 21, 215-223 (1979).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from .._validation import check_positive, check_positive_array
from .bandwidth import refine_nodes
from .lens import Lens
from .measured import responses_behind_lens

__all__ = ["ALPHAS", "PRIOR", "VirtualTable", "expected_error", "gaussian_targets", "gcv_alpha",
           "markov_prior", "normalised", "trapezoid_weights", "wiener_matrix"]

#: The prior's mean, standard deviation and correlation length (nm): the maximum-likelihood
#: fit of a Markov process to 152 public reflectance spectra (module docstring).
PRIOR = {"mean": 0.325, "sd": 0.293, "length_nm": 3900.0}
#: The regularisations generalised cross-validation chooses from (band noise variance, in
#: squared reflectance: 0.03 % to 10 % noise).
ALPHAS = np.logspace(-7.0, -2.0, 26)


def trapezoid_weights(wavelength_nm):
    """Trapezoid quadrature weights of a grid, nm: ``weights @ f`` integrates ``f``."""
    w = np.zeros(wavelength_nm.size)
    d = np.diff(wavelength_nm)
    w[:-1] += 0.5 * d
    w[1:] += 0.5 * d
    return w


def normalised(wavelength_nm, responses):
    """Rows of ``responses`` as averaging weights on the grid: ``r * w / sum(r * w)`` with
    trapezoid weights ``w``, so ``weights @ spectrum`` is the response-weighted mean.

    Parameters
    ----------
    wavelength_nm : array_like, shape (n,)
    responses : array_like, shape (m, n)

    Returns
    -------
    ndarray, shape (m, n)
    """
    grid = np.asarray(wavelength_nm, float)
    r = np.asarray(responses, float) * trapezoid_weights(grid)
    total = r.sum(axis=1, keepdims=True)
    if np.any(~(total > 0)):
        raise ValueError("a response has no positive area on the grid")
    return r / total


def gaussian_targets(wavelength_nm, centre_nm, fwhm_nm):
    """Gaussian target responses as averaging weights (:func:`normalised`).

    Parameters
    ----------
    wavelength_nm : array_like, shape (n,)
    centre_nm, fwhm_nm : array_like, shape (m,)
        Each virtual band's centre and FWHM, nm.

    Returns
    -------
    ndarray, shape (m, n)
    """
    grid = np.asarray(wavelength_nm, float)
    c = check_positive_array("virtual band wavelengths", np.atleast_1d(centre_nm), "nm")
    f = check_positive_array("virtual band FWHMs", np.broadcast_to(fwhm_nm, c.shape), "nm")
    if np.any(c - 1.5 * f < grid[0]) or np.any(c + 1.5 * f > grid[-1]):
        raise ValueError(f"virtual bands must lie within the responses' grid ({grid[0]:g}-"
                         f"{grid[-1]:g} nm) by 1.5 FWHM; got {c.min():g}-{c.max():g} nm")
    u = (grid[None, :] - c[:, None]) / f[:, None]
    return normalised(grid, np.exp(-4.0 * np.log(2.0) * u * u))


def markov_prior(wavelength_nm, *, mean=PRIOR["mean"], sd=PRIOR["sd"],
                 length_nm=PRIOR["length_nm"]):
    """Second moment of the Markov spectrum prior on a grid: ``sd^2 exp(-|dl| / length) +
    mean^2`` (module docstring).

    Parameters
    ----------
    wavelength_nm : array_like, shape (n,)
    mean, sd, length_nm : float

    Returns
    -------
    ndarray, shape (n, n)
    """
    grid = np.asarray(wavelength_nm, float)
    check_positive("length_nm", length_nm)
    return sd**2 * np.exp(-np.abs(grid[:, None] - grid[None, :]) / length_nm) + mean**2


def _noise(alpha, n_bands):
    """Band noise variances as a vector: one number for every band, or one per band."""
    a = np.broadcast_to(np.asarray(alpha, float), (n_bands,))
    if not np.all(np.isfinite(a) & (a > 0)):
        raise ValueError(f"the band noise variance alpha must be > 0 and finite, got {alpha!r}")
    return a


def wiener_matrix(weights, targets, prior, alpha):
    """``A = g Phi s^T (s Phi s^T + N)^-1`` (Pratt & Mancill 1976), ``N = diag(alpha)``.

    Parameters
    ----------
    weights : ndarray, shape (n_bands, n)
        The bands' averaging weights (:func:`normalised`).
    targets : ndarray, shape (n_virtual, n)
        The virtual bands' averaging weights.
    prior : ndarray, shape (n, n)
        Second moment of the spectra (:func:`markov_prior`).
    alpha : float or array_like, shape (n_bands,)
        Band noise variance (> 0): one for every band, or each band's (pixel noise plus a
        demosaicking error, independent between bands).

    Returns
    -------
    ndarray, shape (n_virtual, n_bands)
    """
    ps = prior @ weights.T
    gram = weights @ ps + np.diag(_noise(alpha, weights.shape[0]))
    return np.linalg.solve(gram, (targets @ ps).T).T


def expected_error(matrix, weights, targets, prior, alpha):
    """Each virtual band's expected RMS error for spectra of the prior and band noise of
    variance ``alpha``: ``sqrt(diag((A s - g) Phi (A s - g)^T + A diag(alpha) A^T))``, for
    any linear estimate ``A`` (for the Wiener one with that ``alpha`` it is
    ``g Phi g^T - A s Phi g^T``).

    Parameters
    ----------
    matrix : ndarray, shape (n_virtual, n_bands)
    weights : ndarray, shape (n_bands, n)
        The bands' averaging weights where the estimate is applied.
    targets : ndarray, shape (n_virtual, n)
    prior : ndarray, shape (n, n)
    alpha : float or array_like, shape (n_bands,)

    Returns
    -------
    ndarray, shape (n_virtual,)
    """
    miss = matrix @ weights - targets
    var = (np.sum((miss @ prior) * miss, axis=1)
           + matrix**2 @ _noise(alpha, matrix.shape[1]))
    return np.sqrt(np.clip(var, 0.0, None))


def gcv_alpha(weights, values, prior, alphas=ALPHAS):
    """The regularisation minimising generalised cross-validation on band values.

    Parameters
    ----------
    weights : sequence of ndarray, each (n_bands, n)
        The bands' averaging weights for each group of values (one per chief-ray angle node;
        one array for all).
    values : sequence of ndarray, each (n_pixels, n_bands)
        Band values of each group; rows with a non-finite value are left out.
    prior : ndarray, shape (n, n)
    alphas : array_like
        Candidates.

    Returns
    -------
    alpha : float
    score : ndarray, shape (n_alphas,)
        ``mean |(I - H) y|^2 / (mean tr(I - H) / n_bands)^2`` for each candidate.
    """
    groups = []
    for s, y in zip(weights, values, strict=True):
        y = np.asarray(y, float)
        y = y[np.all(np.isfinite(y), axis=1)]
        if y.size:
            groups.append((s @ prior @ s.T, y))
    if not groups:
        raise ValueError("no pixel with finite values in every band to choose the "
                         "regularisation from")
    alphas = np.asarray(alphas, float)
    score = np.empty(alphas.size)
    for k, a in enumerate(alphas):
        resid, trace, count = 0.0, 0.0, 0
        for gram, y in groups:
            nb = gram.shape[0]
            H = np.linalg.solve(gram + a * np.eye(nb), gram).T  # symmetric: H = G (G + aI)^-1
            r = y - y @ H.T
            resid += float(np.sum(r * r))
            trace += (nb - np.trace(H)) / nb * y.shape[0]
            count += y.shape[0] * nb
        score[k] = (resid / count) / (trace / sum(y.shape[0] for _, y in groups)) ** 2
    return float(alphas[np.argmin(score)]), score


#: The prior's leading components, by the prior's bytes: its eigen-decomposition (a few
#: tenths of a second on 601 wavelengths) is the same for every table of a sensor.
_COMPONENTS = {}


def _probes(grid, responses, prior, k=8):
    """Band values of typical spectra, on which interpolation errors are judged: the prior's
    mean and its first ``k`` principal components (scaled by their standard deviations) at
    normal incidence, as values in [0, 1] would be."""
    key = (prior.shape, k, hashlib.blake2b(np.ascontiguousarray(prior).tobytes()).hexdigest())
    if key not in _COMPONENTS:
        if len(_COMPONENTS) >= 4:
            _COMPONENTS.clear()
        values, vectors = np.linalg.eigh(prior)
        _COMPONENTS[key] = vectors[:, ::-1][:, :k] * np.sqrt(np.clip(values[::-1][:k], 0.0,
                                                                      None))
    return (normalised(grid, responses.effective) @ _COMPONENTS[key]).T


@dataclass(frozen=True)
class VirtualTable:
    """Wiener matrices for each band's response behind the lens, on chief-ray-angle nodes
    fine enough that linear interpolation between them moves no virtual value of a typical
    spectrum (the prior's mean and main components) by more than ``tolerance``.

    Attributes
    ----------
    cra_deg : ndarray, shape (n_nodes,)
    matrices : ndarray, shape (n_nodes, n_virtual, n_bands)
    alpha : float or ndarray, shape (n_bands,)
    tolerance : float
    stderr : ndarray, shape (n_nodes, n_virtual)
        Each virtual band's expected error at the nodes (:func:`expected_error`).
    """

    cra_deg: np.ndarray
    matrices: np.ndarray
    alpha: float | np.ndarray
    tolerance: float
    stderr: np.ndarray = None

    @classmethod
    def build(cls, responses, targets, n_eff, f_number, lens: Lens, *, cra_max_deg, alpha,
              prior=None, tolerance=1e-3, max_nodes=257, noise_var=None):
        """Tabulate the angle-aware matrices from 0 to ``cra_max_deg``.

        Parameters
        ----------
        responses : FilterResponses
            The measured curves and the system's, at normal incidence.
        targets : ndarray, shape (n_virtual, n)
            The virtual bands' averaging weights on the responses' grid.
        n_eff : float or array_like, shape (n_bands,)
        f_number : float
        lens : Lens
        cra_max_deg : float
        alpha : float or array_like, shape (n_bands,)
            The band noise variance of the estimate (:func:`gcv_alpha`; per band with a
            demosaicking error).
        prior : ndarray, optional
            Default: :func:`markov_prior` on the responses' grid.
        tolerance : float
            Largest change of a virtual value of a typical spectrum (reflectance units) that
            interpolating between nodes may make.
        max_nodes : int
        noise_var : float or array_like, shape (n_bands,), optional
            The band noise variance of the expected errors (default: ``alpha``).

        Returns
        -------
        VirtualTable
        """
        grid = responses.wavelength_nm
        alpha = _noise(alpha, responses.effective.shape[0])
        noise_var = alpha if noise_var is None else _noise(noise_var, alpha.size)
        phi = markov_prior(grid) if prior is None else prior
        nv = targets.shape[0]
        probes = _probes(grid, responses, phi)
        found = {}

        def at(c):
            R = responses_behind_lens(responses, n_eff, f_number, c, lens)
            out = np.full((np.size(c), nv * probes.shape[0]), np.nan)
            for j, cj in enumerate(np.atleast_1d(c)):
                if np.all(np.isfinite(R[j])):
                    s = normalised(grid, R[j])
                    A = wiener_matrix(s, targets, phi, alpha)
                    found[float(cj)] = A, expected_error(A, s, targets, phi, noise_var)
                    out[j] = (A @ probes.T).ravel()
            return out.T

        # the matrices change slowly with the angle: start 1 deg apart (each interval's
        # midpoint is still checked against the tolerance)
        nodes, _ = refine_nodes(at, f_number, lens, cra_max_deg=cra_max_deg,
                                tolerance=float(tolerance), max_nodes=max_nodes,
                                what="the virtual bands' table", start_step_deg=1.0)
        missing = [float(c) for c in nodes if float(c) not in found]
        if missing:
            raise ValueError(f"no light reaches pixels at CRA {missing[0]:.2f} deg through "
                             "the lens: the virtual bands cannot be computed there")
        return cls(nodes, np.stack([found[float(c)][0] for c in nodes]),
                   float(alpha[0]) if np.all(alpha == alpha[0]) else alpha,
                   float(tolerance), np.stack([found[float(c)][1] for c in nodes]))

    def __call__(self, cra_deg):
        """The interpolated matrix at one angle."""
        c = float(cra_deg)
        i = int(np.clip(np.searchsorted(self.cra_deg, c, side="right") - 1, 0,
                        self.cra_deg.size - 2))
        t = (c - self.cra_deg[i]) / (self.cra_deg[i + 1] - self.cra_deg[i])
        return (1 - t) * self.matrices[i] + t * self.matrices[i + 1]
