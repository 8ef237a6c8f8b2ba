"""Lookup table of the kernel-mean shift over chief-ray angle, for one f-number and n_eff.

A cube has one f-number and a handful of effective indices, but millions of pixels. The mean
shift divided by the central wavelength depends on the CRA alone there, so it is tabulated once
and interpolated linearly (``np.interp``). The table is refined adaptively until linear
interpolation matches the exact contour quadrature at every interval midpoint to half the
tolerance. The onset of vignetting (Eq. 46 of Goossens 2019), where the mean turns with a
``(CRA - onset)^(3/2)`` singularity, and the on-axis tangency for ``P < R`` are always nodes.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from . import goossens2019 as g19
from .lens import Lens

__all__ = ["ShiftGrid", "ShiftTable"]

_INITIAL_STEP_DEG = 0.5
_MAX_ROUNDS = 40


@dataclass(frozen=True)
class ShiftTable:
    """Mean shift per nm of central wavelength, tabulated over CRA.

    Build with :meth:`build`; call with ``(cwl_nm, cra_deg)`` to get the shift in nm.

    Attributes
    ----------
    cra_deg : ndarray
        Nodes, degrees (increasing, from 0).
    relative_shift : ndarray
        ``mean_shift / cwl`` at the nodes.
    n_eff, f_number : float
        What the table was built for.
    tolerance_nm, cwl_max_nm : float
        The interpolation error is below ``tolerance_nm`` for any ``cwl <= cwl_max_nm``
        (checked at every interval midpoint to half the tolerance).
    """

    cra_deg: np.ndarray
    relative_shift: np.ndarray
    n_eff: float
    f_number: float
    tolerance_nm: float
    cwl_max_nm: float

    @classmethod
    def build(
        cls,
        n_eff,
        f_number,
        lens: Lens,
        *,
        cra_max_deg,
        tolerance_nm=0.001,
        cwl_max_nm=1000.0,
        nodes=None,
    ):
        """Tabulate ``mean_shift / cwl`` from 0 to ``cra_max_deg`` to ``tolerance_nm``."""
        n_eff, f_number = float(n_eff), float(f_number)
        if not (np.isfinite(tolerance_nm) and tolerance_nm > 0):
            raise ValueError(f"tolerance_nm must be > 0, got {tolerance_nm!r}")
        cutoff = float(lens.cutoff_cra_deg(f_number))
        if cra_max_deg >= cutoff:
            raise g19.PupilCutOffError(
                f"at f/{f_number:g} the vignetting circle cuts off the whole pupil from "
                f"CRA {cutoff:.3f} deg; the table was asked to reach {cra_max_deg:.3f} deg."
            )
        cra_max = max(float(cra_max_deg), min(1.0, 0.999 * cutoff))
        x, R = lens.exit_pupil_mm, float(lens.exit_pupil_radius_mm(f_number))
        breaks = [0.0, cra_max]
        if lens.has_vignetting and lens.vignetting_distance_mm != 0:
            P, h = lens.vignetting_radius_mm, abs(lens.vignetting_distance_mm)
            kink = float(np.rad2deg(np.arctan(abs(P - R) / h)))
            if 0 < kink < cra_max:
                breaks.append(kink)
        breaks = np.unique(breaks)
        grid = [
            np.linspace(a, b, max(3, int(np.ceil((b - a) / _INITIAL_STEP_DEG)) + 1))
            for a, b in itertools.pairwise(breaks)
        ]
        cra = np.unique(np.concatenate(grid))

        def exact(c):
            tan_c = np.tan(np.deg2rad(c))
            d = x * tan_c
            if lens.has_vignetting:
                P, h = lens.vignetting_radius_mm, lens.vignetting_distance_mm
                return g19.mean_shift_contour(1.0, n_eff, x, R, d, P, h * tan_c, nodes=nodes)
            return g19.mean_shift_contour(1.0, n_eff, x, R, d, nodes=nodes)

        g19._check_validity(
            x,
            R,
            x * np.tan(np.deg2rad(cra_max)),
            lens.vignetting_radius_mm,
            (lens.vignetting_distance_mm or 0.0) * np.tan(np.deg2rad(cra_max)),
        )
        vals = exact(cra)
        tol_rel = 0.5 * tolerance_nm / cwl_max_nm
        nodes_c, nodes_v = [cra], [vals]
        a, b, fa, fb = cra[:-1], cra[1:], vals[:-1], vals[1:]
        for _ in range(_MAX_ROUNDS):
            if a.size == 0:
                break
            mid = 0.5 * (a + b)
            fm = exact(mid)
            bad = np.abs(0.5 * (fa + fb) - fm) > tol_rel
            # Failing intervals get their midpoint as a node; both halves are checked again.
            nodes_c.append(mid[bad])
            nodes_v.append(fm[bad])
            a, b = np.concatenate([a[bad], mid[bad]]), np.concatenate([mid[bad], b[bad]])
            fa, fb = np.concatenate([fa[bad], fm[bad]]), np.concatenate([fm[bad], fb[bad]])
        else:
            raise RuntimeError("ShiftTable did not converge; lower the tolerance or report a bug")
        cra, order = np.unique(np.concatenate(nodes_c), return_index=True)
        vals = np.concatenate(nodes_v)[order]
        return cls(cra, vals, n_eff, f_number, float(tolerance_nm), float(cwl_max_nm))

    def __call__(self, cwl_nm, cra_deg):
        """Mean shift in nm for central wavelengths ``cwl_nm`` at chief-ray angles ``cra_deg``."""
        cra = np.abs(np.asarray(cra_deg, dtype=float))
        if cra.size and cra.max() > self.cra_deg[-1]:
            raise ValueError(
                f"CRA {cra.max():.3f} deg is beyond this table ({self.cra_deg[-1]:.3f} deg); "
                "build it with a larger cra_max_deg"
            )
        return np.asarray(cwl_nm, dtype=float) * np.interp(cra, self.cra_deg, self.relative_shift)

    def __len__(self):
        return self.cra_deg.size


_GRID_START = (33, 65)
_GRID_MAX = (513, 1025)
_CUTOFF_MARGIN_DEG = 1e-3


@dataclass(frozen=True)
class ShiftGrid:
    """Mean shift per nm of central wavelength, tabulated over (f-number, CRA) for one lens.

    For arbitrary (f-number, CRA) pairs. The grid is uniform in ``a = 1 / f_W^2`` (the shift
    is nearly linear in it) and in a normalised CRA ``xi`` that pins the onset of vignetting
    (Eq. 46) to ``xi = 1`` for every f-number: ``xi = CRA / onset`` before it and
    ``xi = 1 + sqrt((CRA - onset) / (top - onset))`` after it, which turns the
    ``(CRA - onset)^(3/2)`` behaviour into a smooth cubic. ``top`` is ``cra_max`` or just short
    of the full cut-off. Bilinear interpolation is checked against the exact contour quadrature
    at every cell centre and edge midpoint; the grid is refined until they agree to half the
    tolerance, and the few cells that still do not (where ``P = R`` or where the cut-off meets
    ``cra_max``: kinks in ``a``) are answered by the exact quadrature instead.
    """

    lens: Lens
    n_eff: float
    f_range: tuple
    cra_max_deg: float
    tolerance_nm: float
    cwl_max_nm: float
    a_nodes: np.ndarray
    values: np.ndarray
    cell_ok: np.ndarray

    @staticmethod
    def _frame(lens, a, cra_max):
        """Onset ``k`` and top ``U`` (degrees) at ``a = 1/f_W^2``."""
        R = 0.5 * lens.exit_pupil_mm * np.sqrt(a)
        if lens.has_vignetting and lens.vignetting_distance_mm != 0:
            P, h = lens.vignetting_radius_mm, abs(lens.vignetting_distance_mm)
            k = np.rad2deg(np.arctan(np.abs(P - R) / h))
            cut = np.rad2deg(np.arctan((P + R) / h)) - _CUTOFF_MARGIN_DEG
        else:
            k = np.full(np.shape(a), np.inf)
            cut = np.full(np.shape(a), np.inf)
        U = np.minimum(cra_max, cut)
        return np.minimum(k, U), U

    @staticmethod
    def _to_xi(cra, k, U):
        with np.errstate(divide="ignore", invalid="ignore"):
            lo = np.where(k > 0, cra / k, 0.0)
            hi = 1.0 + np.sqrt(np.clip((cra - k) / (U - k), 0.0, None))
        return np.where(cra <= k, lo, hi)

    @staticmethod
    def _from_xi(xi, k, U):
        return np.where(xi <= 1.0, xi * k, k + (U - k) * (xi - 1.0) ** 2)

    @classmethod
    def build(cls, n_eff, lens: Lens, *, f_range=(1.2, 22.0), cra_max_deg=30.0,
              tolerance_nm=0.001, cwl_max_nm=1000.0):
        """Tabulate ``mean_shift / cwl`` for ``f_range`` and CRA 0-``cra_max_deg``."""
        f_lo, f_hi = sorted(float(v) for v in f_range)
        fw = lens.working_f_number(np.array([f_lo, f_hi]))
        a_lo, a_hi = 1.0 / fw[1] ** 2, 1.0 / fw[0] ** 2
        tol_rel = 0.5 * tolerance_nm / cwl_max_nm
        x = lens.exit_pupil_mm

        def exact(a, xi):
            k, U = cls._frame(lens, a, cra_max_deg)
            cra = cls._from_xi(xi, k, U)
            t = np.tan(np.deg2rad(cra))
            R = 0.5 * x * np.sqrt(a)
            if lens.has_vignetting:
                P, h = lens.vignetting_radius_mm, lens.vignetting_distance_mm
                return g19.mean_shift_contour(1.0, n_eff, x, R, x * t, P, h * t)
            return g19.mean_shift_contour(1.0, n_eff, x, R, x * t)

        na, nx = _GRID_START
        while True:
            a = np.linspace(a_lo, a_hi, na)
            xi = np.linspace(0.0, 2.0, nx)
            A, XI = np.meshgrid(a, xi, indexing="ij")
            vals = exact(A, XI)
            am, xm = 0.5 * (a[1:] + a[:-1]), 0.5 * (xi[1:] + xi[:-1])
            # Cell centres and edge midpoints, against bilinear / linear interpolation.
            centre = np.abs(exact(*np.meshgrid(am, xm, indexing="ij"))
                            - 0.25 * (vals[1:, 1:] + vals[:-1, 1:] + vals[1:, :-1]
                                      + vals[:-1, :-1]))
            edge_a = np.abs(exact(*np.meshgrid(am, xi, indexing="ij"))
                            - 0.5 * (vals[1:] + vals[:-1]))
            edge_x = np.abs(exact(*np.meshgrid(a, xm, indexing="ij"))
                            - 0.5 * (vals[:, 1:] + vals[:, :-1]))
            ok = ((centre <= tol_rel) & (edge_a[:, 1:] <= tol_rel) & (edge_a[:, :-1] <= tol_rel)
                  & (edge_x[1:] <= tol_rel) & (edge_x[:-1] <= tol_rel))
            if ok.mean() > 0.99 or (na, nx) == _GRID_MAX:
                break
            # Refine the direction that fails more.
            bad_a = np.mean(edge_a > tol_rel)
            bad_x = np.mean(edge_x > tol_rel)
            if bad_a >= bad_x and na < _GRID_MAX[0]:
                na = 2 * na - 1
            elif nx < _GRID_MAX[1]:
                nx = 2 * nx - 1
            else:
                na = 2 * na - 1
        return cls(lens, float(n_eff), (f_lo, f_hi), float(cra_max_deg), float(tolerance_nm),
                   float(cwl_max_nm), a, vals, ok)

    def __call__(self, cwl_nm, f_number, cra_deg):
        """Mean shift in nm; arguments broadcast."""
        cwl, f, cra = np.broadcast_arrays(*(np.asarray(v, float) for v in
                                            (cwl_nm, f_number, cra_deg)))
        cra = np.abs(cra)
        if f.size and (f.min() < self.f_range[0] or f.max() > self.f_range[1]):
            raise ValueError(f"f-numbers outside this grid's range {self.f_range}")
        a = 1.0 / self.lens.working_f_number(f) ** 2
        k, U = self._frame(self.lens, a, self.cra_max_deg)
        if cra.size and np.any(cra > U):
            raise ValueError(
                f"CRA beyond this grid (cra_max {self.cra_max_deg} deg, or past the full "
                "cut-off of the pupil for that f-number)")
        xi = self._to_xi(cra, k, U)
        na, nx = self.values.shape
        a0, a1 = self.a_nodes[0], self.a_nodes[-1]
        u = (a - a0) / (a1 - a0) * (na - 1)
        v = xi * 0.5 * (nx - 1)
        i = np.clip(u.astype(np.intp), 0, na - 2)
        j = np.clip(v.astype(np.intp), 0, nx - 2)
        du, dv = u - i, v - j
        vals = self.values
        out = ((vals[i, j] * (1 - du) + vals[i + 1, j] * du) * (1 - dv)
               + (vals[i, j + 1] * (1 - du) + vals[i + 1, j + 1] * du) * dv)
        bad = ~self.cell_ok[i, j]
        if np.any(bad):
            x = self.lens.exit_pupil_mm
            t = np.tan(np.deg2rad(cra[bad]))
            R = self.lens.exit_pupil_radius_mm(f[bad])
            P = self.lens.vignetting_radius_mm
            dvv = None if P is None else self.lens.vignetting_distance_mm * t
            out[bad] = g19.mean_shift_contour(1.0, self.n_eff, x, R, x * t, P, dvv)
        return cwl * out
