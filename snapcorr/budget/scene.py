"""The scene budget: each correction model's residual signal error for a scene's spectrum.

References
----------
.. [1] D. E. Flittner, P. N. Slater (1991); D. N. Mishev, K. P. Bakalova; T. Goossens et al.,
   Appl. Opt. 58, 1789 (2019), Eq. 13 (the kernel's response). See :mod:`snapcorr.budget`.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from .._coords import accepts_center_rc
from .._validation import check_f_number, check_positive, validate_method
from ..optics import CORRECTION_MODELS, Lens, mean_shift
from ..optics.response import kernel_bins
from .report import Budget
from .signal import (
    SIGNAL_PROFILES,
    _dense_on_a_lattice,
    _FilterMoments,
    _lattice,
    _signals_on_grid,
)

__all__ = ["profile_of", "scene_budget"]

#: Gauss-Hermite nodes of the harmonising Gaussian in the budget.
_HERMITE_NODES = 12


def scene_budget(source, sensor, f_number, lens: Lens, *, cra_max_deg,
                 profile=None, n_cra=33, models=CORRECTION_MODELS, tolerance_pct=0.5,
                 kernel_step_nm=0.05, shift_step_nm=0.02):
    """The residual of each correction model for every band of ``sensor`` over CRA
    0..``cra_max_deg`` behind ``lens`` at ``f_number``, for the ``source`` spectrum.

    Each band's filter is ``profile`` (``"multi_lorentzian"``, Flittner & Slater's; ``"pi"``,
    Mishev & Bakalova's rectangle) of the sensor's FWHM, moved and smeared by the kernel (the
    widening and dimming Mishev & Bakalova add for a tilted filter is :func:`band_signal`'s).
    The pixel's signal is the full kernel response (Goossens Eq. 13,
    :func:`~snapcorr.optics.response.kernel_bins`); each model's
    residual is that signal over the signal of the filter placed at the model's mean shift,
    minus 1.

    Parameters
    ----------
    source : snapcorr.spectra.Spectrum
        The scene's spectrum (:func:`snapcorr.spectra.parse_source`).
    sensor : Sensor
        Every band's central wavelength, FWHM and effective index.
    f_number : float
        Nominal f-number.
    lens : Lens
    cra_max_deg : float
        The field's largest chief-ray angle, degrees (below the lens's cut-off).
    profile : {"gaussian", "multi_lorentzian", "pi"}, optional
        The filters' shape (default: the sensor's own, which must be one of these).
    n_cra : int
        Chief-ray angles tabulated, 0..``cra_max_deg``.
    models : sequence of str
        Models to evaluate, of :data:`snapcorr.optics.CORRECTION_MODELS` (``"none"`` always is).
    tolerance_pct : float
        Radiometric tolerance, percent, kept for :meth:`Budget.recommend`.
    kernel_step_nm, shift_step_nm : float
        Bin width of the kernel and step of the shift grid, nm.

    Returns
    -------
    Budget
    """
    source = source.peak_normalised()  # ratios only: the scale goes, and any overflow
    profile = profile_of(sensor, profile)
    for m in models:
        validate_method(m, CORRECTION_MODELS, "model")
    # in order of cost, for recommend(); "none" always (the reference of radius_mm and plot)
    models, left_out = _models_for(lens, tuple(
        m for m in CORRECTION_MODELS if m in models or m == "none"))
    tolerance_pct = check_positive("tolerance_pct", tolerance_pct)
    if int(n_cra) < 2:
        raise ValueError(f"n_cra must be >= 2 (the axis and the field's edge), got {n_cra!r}")
    f = check_f_number("f_number", f_number)
    cra_max = float(cra_max_deg)
    cutoff = float(lens.cutoff_cra_deg(f))
    if not (math.isfinite(cra_max) and 0 <= cra_max < cutoff):
        raise ValueError(f"cra_max_deg must lie in [0, {cutoff:.2f}) deg (the lens's full "
                         f"cut-off at f/{f:g}), got {cra_max_deg!r}")
    cwl = np.asarray(sensor.cwl_nm, float)
    fwhm = np.asarray(sensor.fwhm_nm, float)
    n_eff = np.asarray(sensor.n_eff, float)
    cra = np.linspace(0.0, cra_max, int(n_cra))
    ref = float(cwl.max())
    # The kernel in wavelength scales exactly with the filter's centre (Eq. 3): its bins are
    # built once per (n_eff, CRA) at the largest centre and scaled to each band; likewise
    # each model's mean shift (one curve over CRA per n_eff).
    bins, per_model = {}, {}
    for n in np.unique(n_eff):
        bins[n] = [kernel_bins(ref, n, f, c, lens, step_nm=kernel_step_nm) for c in cra]
        per_model[n] = {m: (np.zeros(cra.size) if m == "none" else np.asarray(
            mean_shift(ref, n, f, cra, lens, method="vignetted" if m == "harmonised" else m),
            float)) for m in models}
    lat = _lattice(source) or _dense_on_a_lattice(source)
    d = shift_step_nm if lat is None else lat[1] / math.ceil(lat[1] / shift_step_nm - 1e-9)
    widening = (_widening(cwl, fwhm, n_eff, f, cra, lens, profile) if "harmonised" in models
                else None)
    residual = np.empty((len(models), cwl.size, cra.size))
    shifts = np.empty_like(residual)
    for b in range(cwl.size):
        scale = cwl[b] / ref
        kernel = [(mu * scale, w) for mu, w in bins[n_eff[b]]]
        means = [per_model[n_eff[b]][m] * scale for m in models]
        residual[:, b] = _band_residuals(
            source, SIGNAL_PROFILES[profile](cwl[b], fwhm[b], n_eff[b]), kernel, means, models,
            None if widening is None else (widening[0][b], widening[1][b]), d, lat)
        shifts[:, b] = means
    radius = lens.exit_pupil_mm * np.tan(np.deg2rad(cra))
    ds = xr.Dataset(
        {"residual": (("model", "band", "cra"), residual,
                      {"units": "1", "long_name": "signal error left by the model"}),
         "mean_shift": (("model", "band", "cra"), shifts, {"units": "nm"}),
         "radius_mm": ("cra", radius, {"units": "mm", "long_name": "image radius"}),
         "radius_px": ("cra", radius / sensor.pixel_pitch_mm, {"units": "px"})},
        coords={"model": list(models), "cra": ("cra", cra, {"units": "deg"}),
                "wavelength": ("band", cwl, {"units": "nm"})},
        attrs={"source": source.name, "lens": lens.name, "f_number": f,
               "sensor": sensor.name, "profile": profile, "kernel_step_nm": kernel_step_nm,
               **({"models_left_out": left_out} if left_out else {})},
    )
    return Budget(ds, tolerance_pct=tolerance_pct)


def _models_for(lens, models):
    """The models a budget of ``lens`` evaluates, and what it leaves out and why: Eq. (6) is
    derived for the paper's pupil, so another pupil's budget goes without it."""
    if lens.pupil_radiance == "paper" or "asymptotic" not in models:
        return models, ""
    return (tuple(m for m in models if m != "asymptotic"),
            f"asymptotic (Eq. 6 holds for the paper's pupil, not the {lens.pupil_radiance} "
            "one)")


def profile_of(sensor, profile=None):
    """The filters' shape a budget models: ``profile`` (a name of
    :data:`~snapcorr.budget.SIGNAL_PROFILES`) when given, else the sensor's own, refused when
    the budget does not model it."""
    if profile is None:
        if sensor.profile not in SIGNAL_PROFILES:
            raise ValueError(f"the sensor {sensor.name!r} has {sensor.profile} filters, which "
                             f"the budget does not model; name one it does with profile=: "
                             f"{', '.join(SIGNAL_PROFILES)}")
        profile = sensor.profile
    validate_method(profile, SIGNAL_PROFILES, "profile")
    return profile


def _widening(cwl, fwhm, n_eff, f, cra, lens, profile):
    """Each pixel's harmonising Gaussian: its variance (band, CRA), nm^2, the kernel variance
    it lacks against the pixel of the largest in the field (as ``correct_cube`` widens); and
    where that pixel is."""
    from ..optics.bandwidth import kernel_log_variance

    kv = np.empty((cwl.size, np.size(cra)))
    for n in np.unique(n_eff):
        kv[n_eff == n] = kernel_log_variance(n, f, cra, lens)[None, :]
    kv *= np.asarray(cwl, float)[:, None] ** 2
    kv = np.where(np.isnan(kv), -np.inf, kv)
    var = np.clip(np.max(kv, axis=1, keepdims=True) - kv, 0, None)
    return np.where(np.isfinite(kv), var, np.nan), np.argmax(kv, axis=1)


def _band_residuals(source, prof, kernel, means, models, widening, d, lattice):
    """One band's residual (model, CRA): the pixel's kernel response over the filter placed
    at each model's mean shift, minus 1; for ``"harmonised"``, the pixel's response widened
    by its Gaussian (``widening``: variance over CRA, and the widest pixel) over the widest
    pixel's. Every shift asked for is taken from one pass over the source on a grid of step
    ``d`` nm (0 among them), interpolated: exactly 1 for a flat source."""
    gh_x, gh_w = np.polynomial.hermite_e.hermegauss(_HERMITE_NODES)
    gh_w = gh_w / gh_w.sum()
    mus = [mu for mu, _ in kernel]
    spread = []
    if widening is not None:  # the kernel's points, recentred and spread by the nodes
        sig = np.sqrt(widening[0])
        m_h = means[models.index("harmonised")]
        spread = [((mu - m_h[i])[:, None] + sig[i] * gh_x[None, :]).ravel()
                  for i, mu in enumerate(mus)]
    try:
        r = _relative_signals(source, prof, mus + means + spread, d, lattice)
    except ValueError:
        if not spread:
            raise
        # the widened band reaches past the source's end: no harmonised figure here
        spread = []
        r = _relative_signals(source, prof, mus + means, d, lattice)
    pos, pixel = 0, np.empty(len(kernel))
    for i, (_, w) in enumerate(kernel):
        pixel[i] = np.sum(w * r[pos:pos + w.size]) / np.sum(w)  # exactly 1 where every r is
        pos += w.size
    out = np.empty((len(models), len(kernel)))
    for k in range(len(models)):
        out[k] = pixel / r[pos:pos + len(kernel)] - 1.0
        pos += len(kernel)
    if widening is not None and not spread:
        out[models.index("harmonised")] = np.nan
    elif widening is not None:
        # the pixel's response recentred on the nominal wavelength and widened, against the
        # common response (the widest pixel's, recentred); normalised by the same sums of
        # ones: exactly 1 where every r is 1
        h = np.empty(len(kernel))
        for i, (_, w) in enumerate(kernel):
            rk = r[pos:pos + w.size * gh_x.size].reshape(w.size, gh_x.size)
            h[i] = np.sum(w * (rk @ gh_w)) / np.sum(w * (np.ones_like(rk) @ gh_w))
            pos += w.size * gh_x.size
        out[models.index("harmonised")] = h / h[widening[1]] - 1.0
    return out


def _relative_signals(source, prof, shift_lists, d, lattice):
    """``P(cwl + s) / P(cwl)`` at every shift ``s`` of ``shift_lists`` (concatenated)."""
    allshift = np.concatenate(shift_lists)
    j0 = int(np.floor(allshift.min() / d)) - 1
    j1 = int(np.ceil(allshift.max() / d)) + 1
    p = _signals_on_grid(source, prof, _FilterMoments.of(prof), j0, j1, d, lattice=lattice)
    p0 = p[-j0]  # the shift 0
    if not p0 > 0:
        raise ValueError(f"the source {source.name!r} has no signal in the band at "
                         f"{prof.cwl_nm:g} nm")
    return np.interp(allshift, np.arange(j0, j1 + 1) * d, p / p0)


@accepts_center_rc
def recommend_model(cube, sensor, f_number, lens, source, *, tolerance_pct=0.5,
                    center_rc=None, center_px=None, sensor_origin_px=None):
    """The cheapest model whose signal error for ``source`` stays below ``tolerance_pct`` over
    the field of ``cube``: the scene budget's answer for
    :func:`~snapcorr.correct.correct_cube`'s ``method``.

    Parameters
    ----------
    cube : xarray.DataArray
        The cube to correct: its pixels set the field (the largest chief-ray angle), and
        ``source="cube"`` takes its mean spectrum.
    sensor : Sensor
    f_number : float
    lens : Lens
    source : snapcorr.spectra.Spectrum or str
        The scene's spectrum, or text for :func:`snapcorr.spectra.parse_source`
        (``"solar"``, ``"tungsten:2856"``, ``"cube"``, a file).
    tolerance_pct : float
        Radiometric tolerance, percent of the signal.
    center_rc, center_px, sensor_origin_px : optional
        As for :func:`~snapcorr.correct.correct_cube` (``center_px`` deprecated).

    Returns
    -------
    model : str
        One of :data:`snapcorr.optics.CORRECTION_MODELS`.
    reason : str
    attrs : dict
        Provenance to record in the correction's attrs (``ds.attrs.update(attrs)``): the
        source, the tolerance, each model's worst error, and the request and reason.

    Examples
    --------
    >>> model, reason, attrs = recommend_model(cube, sensor, 1.4, lens, "solar")  # doctest: +SKIP
    >>> ds = correct_cube(cube, sensor, 1.4, lens, method=model)  # doctest: +SKIP
    >>> ds.attrs.update(attrs)  # doctest: +SKIP
    """
    from ..correct.geometry import cube_cra
    from ..spectra import parse_source

    sensor.check_cube(cube)
    spectrum = source if hasattr(source, "wavelength_nm") else parse_source(source, cube)
    cra = cube_cra(cube, sensor, lens, center_rc=center_rc,
                   sensor_origin_px=sensor_origin_px).cra_deg
    budget = scene_budget(spectrum, sensor, f_number, lens, cra_max_deg=float(cra.max()),
                          tolerance_pct=tolerance_pct)
    model, reason = budget.recommend()
    attrs = {"budget_source": spectrum.name, "tolerance_pct": float(tolerance_pct),
             "budget_worst_pct": [budget.worst_pct(m) for m in budget.models],
             "budget_models": list(budget.models), "method_requested": "auto",
             "method_reason": reason}
    return model, reason, attrs
