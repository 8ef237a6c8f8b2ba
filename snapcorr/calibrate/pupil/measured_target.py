"""The target model for measured responses: each band's whole curve behind the band-pass.

A vendor calibration file gives each band's response ``T_b(lambda)`` at normal, collimated
incidence, with every peak, leak and second order, and the band-pass ``B(lambda)`` in front of
every band. Behind the lens every ray of a pixel's cone scales the whole curve,
``T_b(lambda / a_k)`` with ``a_k = sqrt(1 - sin^2 phi_k / n_eff^2)`` (Goossens et al. 2019,
Eq. 3 applied to the whole curve as in Eq. 13; Rienstra 1998), weighted by the ray's share of
the vignetted pupil (the kernel, Eq. 37); the band-pass does not move
(:mod:`snapcorr.optics.measured`, whose kernel and log-wavelength spreading this shares). A
flat-fielded band value of a target of reflectance ``S`` is then::

    y_b(d) = int S B sum_k w_k T_b(lambda / a_k) dlambda / int B sum_k w_k T_b(lambda / a_k)

(the white reference seen through the same pixel). In ``u = log lambda`` every ray is a shift
of the curve by ``-log a_k``, so each band needs, once, the table
``Q_b[j, m] = int T_b(lambda e^(j du)) B(lambda) phi_m(lambda) dlambda`` for every offset
``j`` and every column ``phi_m`` of the target (a hat function, the given spectrum, or 1 for
the white); a bin's row is then the kernel's masses reading that table, divided by the white's
column. Nothing is linearised: a leak 200 nm from the main peak moves by its own wavelength
times ``1 - a_k``, as it does.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from scipy import sparse

from .target_model import PROFILE_CUT, TargetModel

__all__ = ["MeasuredTargetModel", "target_model"]

#: The fine grid's step (at the longest wavelength) as a fraction of the narrowest band's FWHM.
GRID_STEP_FWHM = 1 / 60


class MeasuredTargetModel(TargetModel):
    """:class:`~snapcorr.calibrate.pupil.target_model.TargetModel` for measured responses.

    Parameters
    ----------
    bins : sequence of RadialBins
    cwl_nm, fwhm_nm : array_like, shape (n_bands,)
        The bands' main peaks and widths (they size the grids, the kernels' steps and the
        index models' wavelength axis).
    lens : Lens
    responses : FilterResponses
        The measured curves and the band-pass (:class:`snapcorr.cube.FilterResponses`).
    **kwargs
        As :class:`TargetModel` (``spectrum``, ``max_shift_rel``, ``basis_step_nm``,
        ``grid_step_nm``, ``circles_at_mm``); the rays always scale the curves.
    """

    #: The offset tables of the last few models (the fit builds a fine and a coarse model,
    #: and more for its held-out test, on the same grids): key -> (responses, spectrum, Q).
    _tables_cache: ClassVar[dict] = {}
    analytic_dn = True

    def __init__(self, bins, cwl_nm, fwhm_nm, lens, *, responses, **kwargs):
        self.responses = responses
        kwargs.pop("profile", None)
        kwargs.pop("transform", None)
        if kwargs.get("grid_step_nm") is None:
            # the curves are known at ~1 nm; the kernel's masses are FWHM / 30 apart
            kwargs["grid_step_nm"] = float(np.min(fwhm_nm)) * GRID_STEP_FWHM
        super().__init__(bins, cwl_nm, fwhm_nm, lens, transform="scale", **kwargs)

    def _grid(self, profile, n_design, spectrum, max_shift_rel):
        """The hats over the band-pass (where any band passes light) and the offset tables."""
        R = self.responses
        eff = R.effective
        seen = np.flatnonzero(eff.max(axis=0) >= PROFILE_CUT * eff.max())
        lo, hi = float(R.wavelength_nm[seen[0]]), float(R.wavelength_nm[seen[-1]])
        self.lam0 = math.floor(lo / self.step) * self.step - self.step
        self.n_basis = math.ceil((hi - self.lam0) / self.step) + 2
        top = self.lam0 + (self.n_basis - 1) * self.step
        self.du = math.log1p(self.h / top)  # the fine grid's step at the longest wavelength
        n_t = math.ceil(math.log(top / self.lam0) / self.du) + 1
        lam = self.lam0 * np.exp(self.du * np.arange(n_t))
        self.n_off = math.ceil(-math.log(1.0 - max_shift_rel) / self.du) + 2
        ext = self.lam0 * np.exp(self.du * np.arange(n_t + self.n_off))
        key = (id(R), id(spectrum), self.lam0, self.n_basis, self.du, self.n_off)
        hit = self._tables_cache.get(key)
        if hit is not None and hit[0] is R and hit[1] is spectrum:
            self.Q = hit[2]
            return
        if len(self._tables_cache) >= 4:
            self._tables_cache.clear()
        B = np.interp(lam, R.wavelength_nm, R.system, left=0.0, right=0.0)
        cols = self._columns(lam, spectrum) * (B * lam * self.du)[:, None]
        self.Q = []
        self._tables_cache[key] = (R, spectrum, self.Q)
        # Q[j, m] = sum_i T[i + j] cols[i, m]: the curve's shifted copies (a strided view)
        # times the columns, each hat a few fine steps wide (a sparse product)
        C = sparse.csr_array(np.where(np.abs(cols) > 0, cols, 0.0).T)
        for curve in R.curves:
            T = np.interp(ext, R.wavelength_nm, curve, left=0.0, right=0.0)
            shifted = np.lib.stride_tricks.sliding_window_view(T, n_t)[:self.n_off + 1]
            Q = (C @ np.ascontiguousarray(shifted.T)).T
            Q[np.abs(Q) < 1e-13 * np.max(np.abs(Q))] = 0.0
            self.Q.append(np.ascontiguousarray(Q))

    def _columns(self, lam, spectrum):
        """What the bands see, on the fine grid: the target's columns and the white's last."""
        if spectrum is not None:
            S = np.asarray(spectrum(lam), float)
            if not np.all(np.isfinite(S)):
                raise ValueError("the target spectrum is not finite over the bands' range")
            return np.column_stack([S, np.ones_like(lam)])
        pos = (lam - self.lam0) / self.step
        hats = np.maximum(0.0, 1.0 - np.abs(pos[:, None] - np.arange(self.n_basis)[None, :]))
        return np.column_stack([hats, np.ones_like(lam)])

    def _band_block(self, kern, k, n, *, dn=False):
        """Rows for every bin of one cube and band ``k``: the kernel's masses read band
        ``k``'s table at their offsets ``-log a / du`` (linear interpolation), summed per bin
        and divided by the white's. With ``dn`` the rows' derivative in the index ``n``
        instead (the offsets' derivative ``d(-log a)/dn = -u / (n^3 a^2)`` through the
        interpolation and the white's division)."""
        u, w, owner, nb = kern[:4]
        Q = self.Q[k]
        if u.size == 0:
            return 0, np.zeros((nb, Q.shape[1] - 1))
        a2 = np.clip(1.0 - u / (n * n), 1e-12, None)  # Eq. 3: (lambda_c / cwl)^2
        raw = -0.5 * np.log(a2) / self.du
        pos = np.clip(raw, 0.0, self.n_off - 1e-9)
        i = np.floor(pos).astype(int)
        f = pos - i
        # the masses summed per bin and table row first: every bin reads Q once
        rows = np.concatenate([owner, owner])
        cols = np.concatenate([i, i + 1])
        shape = (nb, Q.shape[0])
        W = sparse.csr_array((np.concatenate([w * (1.0 - f), w * f]), (rows, cols)),
                             shape=shape)
        out = W @ Q
        white = out[:, -1:]
        with np.errstate(invalid="ignore", divide="ignore"):
            y = np.where(white > 0, out[:, :-1] / white, 0.0)
            if not dn:
                return 0, y
            inside = (raw > 0.0) & (raw < self.n_off - 1e-9) & (a2 > 1e-12)
            dpos = np.where(inside, -u / (n**3 * a2) / self.du, 0.0) * w
            dW = sparse.csr_array((np.concatenate([-dpos, dpos]), (rows, cols)), shape=shape)
            dout = dW @ Q
            return 0, np.where(white > 0, (dout[:, :-1] - y * dout[:, -1:]) / white, 0.0)

def target_model(bins, sensor, lens, **kwargs):
    """The target model of ``sensor``'s bands: :class:`MeasuredTargetModel` where it has
    measured responses (``profile`` is then not used), else :class:`TargetModel`.

    Parameters
    ----------
    bins : sequence of RadialBins
    sensor : Sensor
    lens : Lens
    **kwargs
        As :class:`TargetModel`.
    """
    if sensor.responses is not None:
        return MeasuredTargetModel(bins, sensor.cwl_nm, sensor.fwhm_nm, lens,
                                   responses=sensor.responses, **kwargs)
    return TargetModel(bins, sensor.cwl_nm, sensor.fwhm_nm, lens, **kwargs)
