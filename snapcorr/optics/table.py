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

from .._validation import check_positive
from . import goossens2019 as g19
from .lens import Lens

__all__ = ["ShiftGrid", "ShiftTable"]

_INITIAL_STEP_DEG = 0.5
_MAX_ROUNDS = 40


#: Below this the tables would only chase the exact method's own round-off (~1e-11 nm).
MIN_TOLERANCE_NM = 1e-8


def _check_build(tolerance_nm, cwl_max_nm, cra_max_deg):
    if not (np.isfinite(tolerance_nm) and tolerance_nm >= MIN_TOLERANCE_NM):
        raise ValueError(f"tolerance_nm must be finite and >= {MIN_TOLERANCE_NM} nm, "
                         f"got {tolerance_nm!r}")
    check_positive("cwl_max_nm", cwl_max_nm)
    if not (np.isfinite(cra_max_deg) and 0 <= cra_max_deg < 90):
        raise ValueError(f"cra_max_deg must lie in [0, 90), got {cra_max_deg!r}")


def _check_cra(cra_deg):
    cra = np.abs(np.asarray(cra_deg, dtype=float))
    if not (np.all(np.isfinite(cra)) and np.all(cra < 90)):
        raise ValueError("cra_deg must be finite and between -90 and 90 degrees")
    return cra


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
        """Tabulate ``mean_shift / cwl`` from 0 to ``cra_max_deg`` to ``tolerance_nm``.

        Nodes start 0.5 deg apart with every kink (two discs touching inside each other, the
        onsets of Eq. 46 among them); intervals are halved until linear interpolation holds.

        Parameters
        ----------
        n_eff : float
            Effective refractive index (> 1).
        f_number : float
            Nominal f-number.
        lens : Lens
        cra_max_deg : float
            Largest chief-ray angle, degrees, in [0, 90) and below the lens's full cut-off at
            this f-number; the table reaches at least 1 deg (or just short of the cut-off).
        tolerance_nm : float
            Largest interpolation error for any ``cwl <= cwl_max_nm``, nm (>= 1e-8).
        cwl_max_nm : float
            Longest central wavelength the tolerance holds for, nm.
        nodes : int, optional
            Gauss-Legendre nodes per arc of the exact quadrature (default
            :data:`~snapcorr.optics.goossens2019.DEFAULT_NODES`).

        Returns
        -------
        ShiftTable

        Raises
        ------
        PupilCutOffError
            ``cra_max_deg`` at or beyond the full cut-off.
        """
        n_eff, f_number = float(n_eff), float(f_number)
        _check_build(tolerance_nm, cwl_max_nm, cra_max_deg)
        cutoff = float(lens.cutoff_cra_deg(f_number))
        if cra_max_deg >= cutoff:
            raise g19.PupilCutOffError(
                f"at f/{f_number:g} the vignetting circles cut off the whole pupil from "
                f"CRA {cutoff:.3f} deg; the table was asked to reach {cra_max_deg:.3f} deg."
            )
        cra_max = max(float(cra_max_deg), min(1.0, 0.999 * cutoff))
        x, R = lens.exit_pupil_mm, float(lens.exit_pupil_radius_mm(f_number))
        breaks = [0.0, cra_max]
        # Where two discs (the pupil and a circle, or two circles) touch inside each other the
        # boundary changes its arcs: a kink in the mean (the onsets of Eq. 46 among them).
        discs = [(R, 0.0), *lens.vignetting]
        for i, (ri, hi) in enumerate(discs):
            for rj, hj in discs[i + 1:]:
                if hi != hj:
                    kink = float(np.rad2deg(np.arctan(abs(ri - rj) / abs(hi - hj))))
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
            return g19.mean_shift_contour(1.0, n_eff, x, R, x * tan_c,
                                          *lens.vignetting_args(tan_c), nodes=nodes,
                                          pupil=lens.pupil_radiance)

        top = np.tan(np.deg2rad(cra_max))
        g19._check_validity(x, R, x * top, *lens.vignetting_args(top))
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
            raise RuntimeError("ShiftTable did not converge; loosen (raise) tolerance_nm or "
                               "report a bug")
        cra, order = np.unique(np.concatenate(nodes_c), return_index=True)
        vals = np.concatenate(nodes_v)[order]
        return cls(cra, vals, n_eff, f_number, float(tolerance_nm), float(cwl_max_nm))

    def __call__(self, cwl_nm, cra_deg):
        """Mean shift in nm for central wavelengths ``cwl_nm`` at chief-ray angles ``cra_deg``."""
        cra = _check_cra(cra_deg)
        if cra.size and cra.max() > self.cra_deg[-1]:
            raise ValueError(
                f"CRA {cra.max():.3f} deg is beyond this table ({self.cra_deg[-1]:.3f} deg); "
                "build it with a larger cra_max_deg"
            )
        return np.asarray(cwl_nm, dtype=float) * np.interp(cra, self.cra_deg, self.relative_shift)

    def __len__(self):
        return self.cra_deg.size


_GRID_START = (17, 33)
_GRID_MAX = (257, 513)
_CUTOFF_MARGIN = 1e-5  # relative, in tan(CRA)
_GRID_CHUNK = 32_768
_FLOAT32_TOLERANCE_NM = 1e-4


def _lagrange4(u, lo, hi):
    """Base index and the 4 cubic Lagrange weights at fractional node position ``u``.

    The 4-node stencil stays inside the smooth segment ``[lo, hi]`` (node indices) holding
    ``u``, so it never straddles a kink.
    """
    base = np.clip(u.astype(np.intp) - 1, lo, hi - 3)  # u >= 0: truncation is floor
    x = u - base  # in [1, 2] inside, [0, 1] or [2, 3] next to an edge
    x1, x2, x3 = x - 1.0, x - 2.0, x - 3.0
    x12, x03 = x1 * x2, x * x3
    w = (x12 * x3 * (-1.0 / 6.0), x03 * x2 * 0.5, x03 * x1 * -0.5, x12 * x * (1.0 / 6.0))
    return base, w


def _cell_matrices(n, lo_hi):
    """Per cell along one axis: stencil base and the (4 powers x 4 nodes) matrix taking node
    values to the monomial coefficients, in the cell's local coordinate, of the cubic that
    :func:`_lagrange4` interpolates there."""
    cells = np.arange(n - 1)
    lo, hi = lo_hi(cells)
    base = np.clip(cells - 1, lo, hi - 3)
    xs = np.linspace(0.0, 1.0, 4)
    vander = np.vander(xs, 4, increasing=True)
    mats = np.empty((cells.size, 4, 4))
    for c, b in zip(cells, base, strict=True):
        _, w = _lagrange4(c + xs, np.full(4, b), np.full(4, b + 3))
        mats[c] = np.linalg.solve(vander, np.stack(w, axis=1))
    return base, mats


def _patches(vals, a_break_nodes):
    """Monomial coefficients ``c[i, j]`` of ``sum c_ij x^i y^j`` for every cell."""
    na, nx = vals.shape
    mid = (nx - 1) // 2

    def a_bounds(cells):
        seg = np.clip(np.searchsorted(a_break_nodes, cells, side="right") - 1, 0,
                      a_break_nodes.size - 2)
        return a_break_nodes[seg], a_break_nodes[seg + 1]

    def x_bounds(cells):
        upper = cells >= mid
        return np.where(upper, mid, 0), np.where(upper, nx - 1, mid)

    base_a, ma = _cell_matrices(na, a_bounds)
    base_x, mx = _cell_matrices(nx, x_bounds)
    r = np.arange(4)
    blocks = vals[(base_a[:, None] + r)[:, None, :, None], (base_x[:, None] + r)[None, :, None, :]]
    coef = np.einsum("aim,axmn,xjn->axij", ma, blocks, mx)
    # Coefficient-major: gathering one coefficient for every query reads a contiguous row.
    return np.ascontiguousarray(coef.reshape(-1, 16).T)


@dataclass(frozen=True)
class ShiftGrid:
    """Mean shift per nm of central wavelength, tabulated over (f-number, CRA) for one lens.

    For arbitrary (f-number, CRA) pairs. The grid is uniform in ``a = 1 / f_W = 2 R / x`` (the
    shift is nearly quadratic in it) and in a normalised ``xi`` along ``t = tan(CRA)`` that
    pins the onset of vignetting (Eq. 46) to ``xi = 1`` for every f-number: ``xi = t / onset``
    before it and ``t = onset + (top - onset) (xi - 1)^2`` after it, which turns the
    ``(CRA - onset)^(3/2)`` turn-on into a smooth cubic. ``top`` is ``cra_max`` or just short
    of the full cut-off. The grid is split in ``a`` at its kinks (``P = R``, and where the
    onset or the cut-off crosses ``cra_max``), and values are interpolated with tensor-product
    cubic Lagrange polynomials that never straddle a kink (error ~ h^4), stored per cell as
    monomial patches (single precision for tolerances >= 1e-4 nm). Every cell centre and edge
    midpoint is checked against the exact contour quadrature; the grid is refined until
    99.5 % of cells agree to half the tolerance, and the rest, like CRAs past ``top``, are
    answered by the exact quadrature.
    """

    lens: Lens
    n_eff: float
    f_range: tuple
    cra_max_deg: float
    tolerance_nm: float
    cwl_max_nm: float
    a_breaks: np.ndarray  # a at the segment ends (kinks in a), increasing
    a_break_nodes: np.ndarray  # their node indices
    values: np.ndarray
    cell_ok: np.ndarray
    patches: np.ndarray  # (16, cells) monomial coefficients of the cubic patch of each cell

    @staticmethod
    def _frame(lens, a, cra_max):
        """Tangents of the onset ``k`` and of the top ``U`` at ``a = 1/f_W``.

        Everything along the CRA axis works with ``t = tan(CRA)`` (the pixel's distance from
        the axis over x, Eq. 8), which saves trigonometry per query.
        """
        R = 0.5 * lens.exit_pupil_mm * a
        top = np.tan(np.deg2rad(cra_max))
        k = U = np.full(np.shape(a), top)
        # the first onset (Eq. 46) over all circles, and the first full cut-off of any pair
        for P, h in lens.vignetting:
            if h != 0:
                k = np.minimum(k, np.abs(P - R) / abs(h))
        discs = [(R, 0.0), *lens.vignetting]
        for i, (ri, hi) in enumerate(discs):
            for rj, hj in discs[i + 1:]:
                if hi != hj:
                    U = np.minimum(U, (ri + rj) / abs(hi - hj) * (1.0 - _CUTOFF_MARGIN))
        return np.minimum(k, U), U

    @staticmethod
    def _to_xi(t, k, U):
        with np.errstate(divide="ignore", invalid="ignore"):
            r = (t - k) / (U - k)
            return np.where(r > 0, 1.0 + np.sqrt(np.maximum(r, 0.0)),
                            np.where(k > 0, t / k, 0.0))

    @staticmethod
    def _from_xi(xi, k, U):
        # After the onset t - k = (U - k) (xi - 1)^2: (t - k)^(3/2) becomes a cubic in xi.
        return np.where(xi <= 1.0, xi * k, k + (U - k) * (xi - 1.0) ** 2)

    @staticmethod
    def _interp(vals, u, v, a_break_nodes):
        """Cubic interpolation of ``vals`` at fractional node positions ``(u, v)``.

        ``a_break_nodes`` are the node indices bounding the smooth segments along ``a``; along
        ``xi`` the onset node (the middle one) splits the two halves.
        """
        nx = vals.shape[1]
        seg = np.clip(np.searchsorted(a_break_nodes, u, side="right") - 1, 0,
                      a_break_nodes.size - 2)
        i, wu = _lagrange4(u, a_break_nodes[seg], a_break_nodes[seg + 1])
        mid = (nx - 1) // 2
        upper = v >= mid
        j, wv = _lagrange4(v, np.where(upper, mid, 0), np.where(upper, nx - 1, mid))
        flat = vals.ravel()
        out = 0.0
        for p in range(4):
            row = (i + p) * nx + j
            out = out + wu[p] * (wv[0] * flat[row] + wv[1] * flat[row + 1]
                                 + wv[2] * flat[row + 2] + wv[3] * flat[row + 3])
        return out

    @staticmethod
    def _kinks(lens, a_lo, a_hi, cra_max):
        """Values of ``a`` in ``(a_lo, a_hi)`` where the frame has a kink: ``P = R``, and where
        the onset or the full cut-off crosses ``cra_max``."""
        out = []
        x = lens.exit_pupil_mm
        top = np.tan(np.deg2rad(cra_max))
        moving = [(P, abs(h)) for P, h in lens.vignetting if h != 0]
        for P, h in moving:
            # R = x a / 2 equal to: P (onset at 0); P -+ h top (onset at cra_max); and
            # h top / (1 - margin) - P (cut-off at cra_max).
            out += [P, P - h * top, P + h * top, h * top / (1.0 - _CUTOFF_MARGIN) - P]
        # where two circles' onsets cross, the first onset changes circle
        for (P1, h1), (P2, h2) in itertools.combinations(moving, 2):
            for s1, s2 in itertools.product((1.0, -1.0), repeat=2):
                den = s2 * h1 - s1 * h2
                if den != 0:
                    out.append((s2 * P2 * h1 - s1 * P1 * h2) / den)
        return sorted(2 * R_k / x for R_k in out if R_k > 0 and a_lo < 2 * R_k / x < a_hi)

    def _u(self, a):
        return np.interp(a, self.a_breaks, self.a_break_nodes.astype(float))

    @classmethod
    def build(cls, n_eff, lens: Lens, *, f_range=(1.2, 22.0), cra_max_deg=30.0,
              tolerance_nm=0.001, cwl_max_nm=1000.0):
        """Tabulate ``mean_shift / cwl`` for ``f_range`` and CRA 0-``cra_max_deg``.

        Parameters
        ----------
        n_eff : float
            Effective refractive index (> 1).
        lens : Lens
        f_range : (float, float)
            Smallest and largest nominal f-number (an interval, either order).
        cra_max_deg : float
            Largest chief-ray angle of the grid, degrees, in [0, 90); larger CRAs are answered
            by the exact quadrature.
        tolerance_nm : float
            Largest interpolation error for any ``cwl <= cwl_max_nm``, nm (>= 1e-8).
        cwl_max_nm : float
            Longest central wavelength the tolerance holds for, nm.

        Returns
        -------
        ShiftGrid
        """
        _check_build(tolerance_nm, cwl_max_nm, cra_max_deg)
        if lens.pupil_radiance != "paper":  # the grid's pupil radius is the paper's, x a / 2
            raise ValueError("ShiftGrid covers the paper's pupil only, not the "
                             f"{lens.pupil_radiance} one: use a ShiftTable per f-number "
                             "(method='table', or method='auto')")
        f_lo, f_hi = sorted(float(v) for v in f_range)
        if not f_hi > f_lo:
            raise ValueError(f"f_range must span an interval, got {f_range!r}; for a single "
                             "f-number use ShiftTable")
        fw = lens.working_f_number(np.array([f_lo, f_hi]))
        a_lo, a_hi = 1.0 / fw[1], 1.0 / fw[0]
        tol_rel = 0.5 * tolerance_nm / cwl_max_nm
        x = lens.exit_pupil_mm

        def exact(a, xi):
            k, U = cls._frame(lens, a, cra_max_deg)
            t = cls._from_xi(xi, k, U)
            return g19.mean_shift_contour(1.0, n_eff, x, 0.5 * x * a, x * t,
                                          *lens.vignetting_args(t))

        breaks = np.array([a_lo, *cls._kinks(lens, a_lo, a_hi, cra_max_deg), a_hi])
        na, nx = _GRID_START
        while True:
            # Piecewise-uniform nodes in a, >= 4 per smooth segment, ~na in all.
            counts = np.maximum(4, np.round((na - 1) * np.diff(breaks) / (a_hi - a_lo)))
            counts = counts.astype(np.intp)
            bnodes = np.concatenate([[0], np.cumsum(counts)])
            a = np.concatenate([np.linspace(b0, b1, c, endpoint=False) for b0, b1, c
                                in zip(breaks[:-1], breaks[1:], counts, strict=True)] + [[a_hi]])
            xi = np.linspace(0.0, 2.0, nx)
            vals = exact(*np.meshgrid(a, xi, indexing="ij"))
            n_a = a.size
            # Cell centres and edge midpoints, in node units and in (a, xi).
            ui, vi = np.arange(n_a - 1) + 0.5, np.arange(nx - 1) + 0.5
            errs = []
            for uu, vv in ((ui, vi), (ui, np.arange(nx)), (np.arange(n_a), vi)):
                U_, V_ = np.meshgrid(uu, vv, indexing="ij")
                A_ = np.interp(U_, bnodes.astype(float), breaks)
                errs.append(np.abs(exact(A_, 2.0 * V_ / (nx - 1))
                                   - cls._interp(vals, U_, V_, bnodes)))
            center, edge_a, edge_x = errs
            ok = ((center <= tol_rel) & (edge_a[:, 1:] <= tol_rel) & (edge_a[:, :-1] <= tol_rel)
                  & (edge_x[1:] <= tol_rel) & (edge_x[:-1] <= tol_rel))
            if ok.mean() > 0.995 or (na, nx) == _GRID_MAX:
                break
            # Refine the direction that fails more.
            if np.mean(edge_a > tol_rel) >= np.mean(edge_x > tol_rel) and na < _GRID_MAX[0]:
                na = 2 * na - 1
            elif nx < _GRID_MAX[1]:
                nx = 2 * nx - 1
            else:
                na = 2 * na - 1
        patches = _patches(vals, bnodes)
        if tolerance_nm >= _FLOAT32_TOLERANCE_NM:
            # Single precision keeps the patches' rounding below 1e-8 of the largest shift
            # (< 1e-5 nm at 1000 nm), far under this tolerance, and halves the memory traffic.
            patches = patches.astype(np.float32)
        return cls(lens, float(n_eff), (f_lo, f_hi), float(cra_max_deg), float(tolerance_nm),
                   float(cwl_max_nm), breaks, bnodes, vals, ok, patches)

    def __call__(self, cwl_nm, f_number, cra_deg):
        """Mean shift in nm; arguments broadcast."""
        cwl, f, cra = np.broadcast_arrays(*(np.asarray(v, float) for v in
                                            (cwl_nm, f_number, cra_deg)))
        if f.size and (f.min() < self.f_range[0] or f.max() > self.f_range[1]):
            raise ValueError(f"f-numbers outside this grid's range {self.f_range}")
        a = 1.0 / self.lens.working_f_number(f.ravel())
        t = np.tan(np.deg2rad(_check_cra(cra.ravel())))
        out = np.empty(a.size)
        bad = np.empty(a.size, bool)
        for lo in range(0, a.size, _GRID_CHUNK):  # cache-sized pieces run faster
            sl = slice(lo, lo + _GRID_CHUNK)
            out[sl], bad[sl] = self._relative(a[sl], t[sl])
        if np.any(bad):  # failed cells and CRAs past the grid's top: the exact method, once
            lens, tb = self.lens, t[bad]
            x = lens.exit_pupil_mm
            out[bad] = g19.mean_shift_contour(1.0, self.n_eff, x, 0.5 * x * a[bad], x * tb,
                                              *lens.vignetting_args(tb))
        return (cwl.ravel() * out).reshape(cwl.shape)

    def _relative(self, a, t):
        """``mean_shift / cwl`` at ``a = 1/f_W`` and ``t = tan(CRA)`` (checked inputs), and
        where it must come from the exact method instead."""
        k, U = self._frame(self.lens, a, self.cra_max_deg)
        beyond = t > U  # past cra_max or within the margin of the cut-off: exact method
        na, nx = self.values.shape
        u = self._u(a)
        v = np.minimum(self._to_xi(t, k, U), 2.0) * (0.5 * (nx - 1))
        iu = np.minimum(u.astype(np.intp), na - 2)
        iv = np.minimum(v.astype(np.intp), nx - 2)
        cell = iu * (nx - 1) + iv
        c = np.take(self.patches, cell, axis=1)  # one gather: (16, n), rows contiguous
        x, y = (u - iu).astype(c.dtype), (v - iv).astype(c.dtype)
        out = 0.0
        for i in (12, 8, 4, 0):  # Horner in x of Horner rows in y
            row = ((c[i + 3] * y + c[i + 2]) * y + c[i + 1]) * y + c[i]
            out = out * x + row
        return out, ~np.take(self.cell_ok, cell) | beyond
