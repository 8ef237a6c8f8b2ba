"""The budget's result: residuals over model, band and CRA, with the choice, table and plot."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from .._validation import check_positive, validate_method

__all__ = ["Budget"]


@dataclass
class Budget:
    """The residual signal error of each correction model over band and chief-ray angle.

    ``data`` is an :class:`xarray.Dataset` with ``residual(model, band, cra)`` (fraction),
    ``mean_shift(model, band, cra)`` (nm), ``radius_mm(cra)`` and ``radius_px(cra)`` (image
    radius of each CRA) and the set-up in attrs.
    """

    data: xr.Dataset
    tolerance_pct: float = 0.5

    def __post_init__(self):
        self.tolerance_pct = check_positive("tolerance_pct", self.tolerance_pct)

    def _tol(self, tolerance_pct):
        if tolerance_pct is None:
            return self.tolerance_pct
        return check_positive("tolerance_pct", tolerance_pct)

    @property
    def models(self):
        return tuple(str(m) for m in self.data["model"].values)

    def worst_pct(self, model):
        """Largest |residual| over bands and the field, percent (infinite where the model
        could not be evaluated: ``harmonised`` where the widened band reaches past the
        source's end)."""
        res = np.abs(self.data["residual"].sel(model=model).values)
        return math.inf if np.isnan(res).any() else float(res.max()) * 100

    def recommend(self, tolerance_pct=None):
        """``(model, reason)``: the cheapest model whose residual stays below the tolerance
        everywhere on the field; the best model when none does."""
        tol = self._tol(tolerance_pct)
        worst = {m: self.worst_pct(m) for m in self.models}
        src = self.data.attrs["source"]
        for i, m in enumerate(self.models):
            if worst[m] <= tol:
                cheaper = ", ".join(f"{c} {worst[c]:.2g} %" for c in self.models[:i])
                return m, (f"for {src}: {m} leaves at most {worst[m]:.2g} % <= {tol:g} %"
                           + (f" (cheaper: {cheaper})" if cheaper else "") + self._left_out())
        best = min(worst, key=worst.get)
        return best, (f"for {src}: no model is within {tol:g} %; {best} leaves the least, "
                      f"{worst[best]:.2g} % (the kernel also changes the filter's shape, "
                      "which no shift of the wavelengths undoes)" + self._left_out())

    def _left_out(self):
        """What the budget did not evaluate, and why (a pupil Eq. 6 does not hold for)."""
        said = self.data.attrs.get("models_left_out")
        return f"; left out: {said}" if said else ""

    def radius_mm(self, tolerance_pct=None, model="none", *, relative_to="nominal"):
        """Mishev & Bakalova's radius: the image radius (mm) inside which ``model`` leaves no
        band's signal off by more than the tolerance.

        ``relative_to="nominal"`` compares each pixel with the filter at its nominal place
        (the error of the model); ``"center"`` with the pixel on the optical axis, as Mishev
        & Bakalova normalise their frames (what a flat field taken on axis would not
        remove).

        Parameters
        ----------
        tolerance_pct : float, optional
            Largest signal error allowed, percent (default: the budget's ``tolerance_pct``).
        model : str
            One of :attr:`models` (``"none"``: uncorrected).
        relative_to : {"nominal", "center"}
            What each pixel's signal is compared with, as above.

        Returns
        -------
        float
            Radius in mm, linearly interpolated between the budget's CRA samples; ``inf``
            when the tolerance holds over the whole field of the budget, 0 when it fails on
            the axis already.
        """
        validate_method(relative_to, ("nominal", "center"), "relative_to")
        tol = self._tol(tolerance_pct) / 100
        res = self.data["residual"].sel(model=model).values  # (band, cra)
        if relative_to == "center":
            res = (1.0 + res) / (1.0 + res[:, :1]) - 1.0
        err = np.abs(res).max(axis=0)
        r = self.data["radius_mm"].values
        over = np.flatnonzero(err > tol)
        if over.size == 0:
            return math.inf
        i = over[0]
        if i == 0:
            return 0.0
        # linear between the last grid point inside and the first outside
        f = (tol - err[i - 1]) / (err[i] - err[i - 1])
        return float(r[i - 1] + f * (r[i] - r[i - 1]))

    def pixel_residual(self, cra_deg, model="none"):
        """Residual (fraction) of every pixel and band: the table interpolated at each
        pixel's CRA; ``cra_deg`` of shape (y, x) or (y, x, band)."""
        cra = np.asarray(cra_deg, float)
        grid = self.data["cra"].values
        if cra.size and (cra.min() < grid[0] - 1e-9 or cra.max() > grid[-1] + 1e-9):
            raise ValueError(f"CRAs {cra.min():.3g}-{cra.max():.3g} deg leave the budget's "
                             f"{grid[0]:.3g}-{grid[-1]:.3g} deg")
        table = self.data["residual"].sel(model=model).values  # (band, cra)
        nb = table.shape[0]
        if cra.ndim == 3 and cra.shape[2] == 1:  # one position per pixel (Snapscan)
            cra = cra[:, :, 0]
        if cra.ndim == 2:
            cra = np.broadcast_to(cra[:, :, None], (*cra.shape, nb))
        if cra.ndim != 3 or cra.shape[2] != nb:
            raise ValueError(f"cra_deg must have shape (y, x), (y, x, 1) or (y, x, {nb}), "
                             f"got {cra.shape}")
        out = np.empty(cra.shape)
        for b in range(nb):
            out[:, :, b] = np.interp(cra[:, :, b], grid, table[b])
        return xr.DataArray(out, dims=("y", "x", "band"),
                            attrs={"units": "1", "long_name": f"residual after {model}"})

    def table(self):
        """A plain-text table: per band, the worst residual of each model (percent)."""
        d = self.data
        head = f"{'band':>4} {'cwl nm':>8} " + " ".join(f"{m:>11}" for m in self.models)
        lines = [head]
        res = np.abs(d["residual"]).max("cra") * 100
        for b in range(d.sizes["band"]):
            lines.append(f"{b:>4} {float(d['wavelength'][b]):>8.2f} " + " ".join(
                f"{float(res.sel(model=m)[b]):>10.3g}%" for m in self.models))
        lines.append(f"{'all':>4} {'':>8} " + " ".join(
            f"{self.worst_pct(m):>10.3g}%" for m in self.models))
        return "\n".join(lines)

    def plot(self, path=None, tolerance_pct=None, *, overwrite=False, inputs=()):
        """Worst residual against band and against image radius, for each model.

        Without ``path`` the figure is made with pyplot (shown inline in a notebook). With
        ``path`` it is written atomically as PNG without touching pyplot's state; an existing
        file is replaced only with ``overwrite``, and never one of ``inputs``.

        Parameters
        ----------
        path : str or Path, optional
            PNG file to write.
        tolerance_pct : float, optional
            Tolerance line drawn, percent (default: the budget's ``tolerance_pct``); also sets
            the radius marked for the uncorrected model (:meth:`radius_mm`).
        overwrite : bool
            Replace an existing ``path`` (else ``ValueError``).
        inputs : iterable of str or Path
            Input files ``path`` must not replace.

        Returns
        -------
        matplotlib.figure.Figure
        """
        tol = self._tol(tolerance_pct)
        path = None if path is None else Path(path)
        if path is not None and path.exists() and not overwrite:
            raise ValueError(f"{path} exists; use overwrite=True to replace it")
        if path is None:
            import matplotlib.pyplot as plt

            fig = plt.figure(figsize=(12, 4.5), layout="constrained")
        else:
            from matplotlib.figure import Figure

            fig = Figure(figsize=(12, 4.5), layout="constrained")
        a, b = fig.subplots(1, 2)
        d = self.data
        for k, m in enumerate(self.models):
            r = np.abs(d["residual"].sel(model=m)) * 100
            a.semilogy(d["wavelength"], np.maximum(r.max("cra"), 1e-6), color=f"C{k}",
                       label=m)
            b.semilogy(d["radius_mm"], np.maximum(r.max("band"), 1e-6), color=f"C{k}",
                       label=m)
        for ax in (a, b):
            ax.axhline(tol, color="k", ls=":", lw=0.8, label=f"tolerance {tol:g} %")
            ax.set_ylabel("|signal error| (%)")
            ax.grid(alpha=0.3)
        rad = self.radius_mm(tol)
        if math.isinf(rad):
            label = "uncorrected within tolerance over the whole field"
        elif rad > 0:
            label = f"uncorrected within tolerance: r < {rad:.2f} mm"
        else:
            label = "uncorrected: over the tolerance even on axis"
        b.axvline(min(rad, float(d["radius_mm"][-1])), color="C0", ls="--", lw=0.8,
                  label=label)
        a.set(xlabel="band centre (nm)", title="worst over the field")
        b.set(xlabel="image radius (mm)", title="worst over the bands")
        b.legend(fontsize=8)
        fig.suptitle(f"Signal error from the filter shift: {d.attrs['source']}, "
                     f"{d.attrs['lens']} at f/{d.attrs['f_number']:g}")
        if path is not None:
            from ..files.png import save_png

            save_png(fig, path, dpi=110, inputs=[i for i in inputs if i is not None])
        return fig
