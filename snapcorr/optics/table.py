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

__all__ = ["ShiftTable"]

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
    def build(cls, n_eff, f_number, lens: Lens, *, cra_max_deg, tolerance_nm=0.001,
              cwl_max_nm=1000.0, nodes=None):
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
        grid = [np.linspace(a, b, max(3, int(np.ceil((b - a) / _INITIAL_STEP_DEG)) + 1))
                for a, b in itertools.pairwise(breaks)]
        cra = np.unique(np.concatenate(grid))

        def exact(c):
            tan_c = np.tan(np.deg2rad(c))
            d = x * tan_c
            if lens.has_vignetting:
                P, h = lens.vignetting_radius_mm, lens.vignetting_distance_mm
                return g19.mean_shift_contour(1.0, n_eff, x, R, d, P, h * tan_c, nodes=nodes)
            return g19.mean_shift_contour(1.0, n_eff, x, R, d, nodes=nodes)

        g19._check_validity(x, R, x * np.tan(np.deg2rad(cra_max)),
                            lens.vignetting_radius_mm,
                            (lens.vignetting_distance_mm or 0.0) * np.tan(np.deg2rad(cra_max)))
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
