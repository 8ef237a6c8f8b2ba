"""The picture of an exit-pupil fit: the target's signal over the field, and chi-square in x.

It reads the fit it is given (:class:`~snapcorr.calibrate.pupil.locate.PupilFit`) and re-solves
the model through :mod:`~snapcorr.calibrate.pupil.solver`; it never imports
:mod:`~snapcorr.calibrate.pupil.locate`, which reaches it through ``PupilFit.plot``.
"""

from __future__ import annotations

import numpy as np

from .solver import _Problem

__all__ = ["plot_pupil_fit"]


def _informative_bands(fit, pred, how_many):
    """Bands whose model changes most over the field, in units of their noise."""
    score = np.zeros(fit.model.cwl.size)
    for _, k, rows, _ in fit.model.blocks:
        if rows.stop - rows.start < 2:
            continue
        p = pred[rows]
        score[k] = max(score[k], float(np.ptp(p) / np.median(fit.model.sigma[rows])))
    return np.argsort(score)[::-1][:how_many]


def plot_pupil_fit(fit, *, bands=4):
    """Left: annulus means of the most informative bands against the distance from the axis,
    one marker per f-number, with the fitted model. Right: chi-square against ``x`` about the
    fit, with the parabola its standard error implies."""
    import matplotlib.pyplot as plt

    model = fit.model
    pred = np.asarray(model.design(fit.exit_pupil_mm, fit.n_eff) @ fit.coefficients).ravel()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    markers = "os^vD<>"
    for c, k in zip(colours, _informative_bands(fit, pred, bands), strict=False):
        for j, kk, rows, ok in model.blocks:
            if kk != k or rows.stop == rows.start:
                continue
            d = np.sqrt(model.bins[j].rho[ok])
            label = f"{model.cwl[k]:g} nm" if j == 0 else None
            ax.errorbar(d, model.y[rows], yerr=model.sigma[rows], fmt=markers[j % 7], ms=3,
                        color=c, alpha=0.6, label=label)
            ax.plot(d, pred[rows], "-", color=c, lw=1)
    for j, b in enumerate(model.bins):
        ax.plot([], [], markers[j % 7], color="0.4", ms=4, label=f"f/{b.f_number:g}")
    ax.set_xlabel("distance from the optical axis (mm)")
    ax.set_ylabel("flat-fielded signal (annulus mean)")
    ax.set_title("the target over the field; lines: the fitted model")
    ax.legend(fontsize=8, ncol=2)

    x, sx = fit.exit_pupil_mm, fit.exit_pupil_stderr_mm
    # with the index held at its fit, chi-square in x follows the conditional error
    scale = max(1.0, fit.chi2_red)
    s_cond = float(1.0 / np.sqrt(np.linalg.inv(fit.covariance)[0, 0] / scale)) \
        if fit.covariance.shape[0] > 1 else sx
    problem = _Problem(model, fit.n_eff)
    grid = x + s_cond * np.linspace(-3, 3, 9)
    grid = grid[grid > 0]
    c2 = np.array([problem.chi2(g) for g in grid])
    held = " and n_eff held" if fit.covariance.shape[0] > 1 else ""
    bx.plot(grid, c2 - c2.min(), "o", label=f"chi-square (target re-fitted{held} at each x)")
    fine = np.linspace(grid.min(), grid.max(), 200)
    bx.plot(fine, ((fine - x) / s_cond) ** 2 * scale, "-",
            label=f"x = {x:.4g} +- {sx:.2g} mm" + (f" ({s_cond:.2g} with n_eff held)"
                                                   if held else ""))
    bx.set_xlabel("exit pupil distance x (mm)")
    bx.set_ylabel("chi-square above its minimum")
    bx.set_title(f"reduced chi-square {fit.chi2_red:.3g}; n_eff {fit.n_eff_fitted}")
    bx.legend(fontsize=8)
    fig.tight_layout()
    return fig
