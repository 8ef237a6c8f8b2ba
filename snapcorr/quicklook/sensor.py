"""The quick look of a sensor: its bands' responses and what each correction matrix makes of
them."""

from __future__ import annotations

import numpy as np

from .drawing import _check_path, _figure, _save, _wrapped

#: The wavelength axis of :func:`plot_sensor` spans where some curve reaches this share of its
#: peak, with a margin of :data:`RESPONSE_MARGIN` of that span on each side.
RESPONSE_FLOOR = 0.02


RESPONSE_MARGIN = 0.04


def _response_span(grid, curves):
    """The wavelengths where any of ``curves`` (rows over ``grid``) reaches
    :data:`RESPONSE_FLOOR` of its own peak, widened by :data:`RESPONSE_MARGIN` and clipped to
    the grid; the whole grid when none does."""
    grid = np.asarray(grid, float)
    a = np.abs(np.atleast_2d(np.asarray(curves, float)))
    peak = np.nanmax(a, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        reached = np.any(a >= RESPONSE_FLOOR * np.where(peak > 0, peak, np.inf), axis=0)
    if not reached.any():
        return float(grid.min()), float(grid.max())
    lo, hi = float(grid[reached].min()), float(grid[reached].max())
    pad = max(RESPONSE_MARGIN * (hi - lo), 2.0)
    return max(float(grid.min()), lo - pad), min(float(grid.max()), hi + pad)


def plot_sensor(sensor, path, *, overwrite=False):
    """A picture of a sensor's filters: each band's measured response through the system (or
    its modelled curve), the system's response, and what each correction matrix makes of the
    bands (its virtual bands' responses against Gaussians of their stated widths).

    Parameters
    ----------
    sensor : Sensor
    path : str or Path
        ``.png``, written atomically.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
    """
    from matplotlib import colormaps

    path = _check_path(path, overwrite)
    r = sensor.responses
    panels = 1 + (len(sensor.matrices) if r is not None else 0)
    fig = _figure((10, 3.2 * panels))
    axes = fig.subplots(panels, 1, squeeze=False)[:, 0]
    cmap = colormaps["turbo"]
    cwl = np.asarray(sensor.cwl_nm, float)
    shade = (cwl - cwl.min()) / max(float(np.ptp(cwl)), 1e-9)
    ax = axes[0]
    if r is not None:
        grid, eff = r.wavelength_nm, r.effective
        for b in range(sensor.n_bands):
            ax.plot(grid, eff[b] / np.max(eff[b]), color=cmap(shade[b]), lw=0.8)
        ax.plot(grid, r.system / np.max(r.system), "k--", lw=1.2, label=r.system_name)
        ax.legend(loc="upper right", fontsize=8)
        ax.set_title(_wrapped(f"{sensor.name}: {sensor.n_bands} measured responses through "
                              "the system (each scaled to its peak)"), fontsize=10)
        span = _response_span(grid, np.vstack([eff, *(m.coefficients @ eff
                                                       for m in sensor.matrices)]))
    else:
        from ..optics.bandwidth import band_profile

        n = 1.7 if sensor.n_eff is None else sensor.n_eff
        grid = np.linspace(cwl.min() - 3 * max(sensor.fwhm_nm), cwl.max() + 3 * max(
            sensor.fwhm_nm), 2000)
        for b in range(sensor.n_bands):
            curve = band_profile(sensor.profile_shape, cwl[b], sensor.fwhm_nm[b],
                                 np.broadcast_to(n, cwl.shape)[b])(grid)
            ax.plot(grid, curve / np.max(curve), color=cmap(shade[b]), lw=0.8)
        ax.set_title(_wrapped(f"{sensor.name}: {sensor.n_bands} {sensor.profile} filters"),
                     fontsize=10)
        span = (float(grid.min()), float(grid.max()))
    ax.set_xlim(*span)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("relative response")
    for ax, m in zip(axes[1:], sensor.matrices, strict=False):
        virtual = m.coefficients @ r.effective
        for v in range(m.n_virtual):
            peak = np.max(np.abs(virtual[v])) or 1.0
            colour = cmap((m.wavelength_nm[v] - cwl.min()) / max(float(np.ptp(cwl)), 1e-9))
            ax.plot(r.wavelength_nm, virtual[v] / peak, color=colour, lw=0.8)
            if np.isfinite(m.fwhm_nm[v]):
                u = (r.wavelength_nm - m.wavelength_nm[v]) / m.fwhm_nm[v]
                ax.plot(r.wavelength_nm, np.exp(-4 * np.log(2) * u * u), color=colour, lw=0.6,
                        ls=":")
        ax.axhline(0.0, color="0.5", lw=0.5)
        ax.set_title(_wrapped(f"correction matrix {m.name!r} ({m.kind}): its virtual bands' "
                              "responses (solid) and Gaussians of their widths (dotted)"),
                     fontsize=10)
        ax.set_xlim(*span)
        ax.set_xlabel("wavelength (nm)")
        ax.set_ylabel("relative response")
    return _save(fig, path)

