"""The corrected wavelengths' model: which one, the relative shift it gives, and each pixel's
scales (Goossens et al. 2019, Eq. 6, 23)."""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validation import validate_method
from ..optics import MODELS, ShiftTable, choose_model, mean_shift
from .widths import _measured_table

__all__ = ["DEFAULT_TOLERANCE_NM", "relative_shift"]

DEFAULT_TOLERANCE_NM = 0.01


def relative_shift(n_eff, f_number, cra_deg, lens, *, model, tolerance_nm, cwl_max_nm):
    """``mean_shift / cwl`` at ``cra_deg`` for one effective index, by ``model``.

    The shift law scales every wavelength alike, so this one curve serves every band of the
    index: ``wavelength_corrected = cwl * (1 + relative_shift)`` (Eq. 23).

    Parameters
    ----------
    n_eff : float
        Effective refractive index.
    f_number : float
        Nominal f-number.
    cra_deg : array_like
        Chief-ray angles, degrees.
    lens : Lens
    model : str
        One of :data:`snapcorr.optics.MODELS`; ``"harmonised"`` shifts as ``"vignetted"``.
    tolerance_nm : float
        Largest interpolation error of the exact models' table at ``cwl_max_nm``, nm.
    cwl_max_nm : float
        The largest central wavelength the curve will be scaled to, nm.

    Returns
    -------
    ndarray
        Same shape as ``cra_deg``; negative (towards the blue).
    """
    validate_method(model, MODELS, "model")
    cra = np.asarray(cra_deg, float)
    if model == "none":
        return np.zeros(cra.shape)
    if model == "asymptotic":
        return mean_shift(1.0, n_eff, f_number, cra, lens, method="asymptotic")
    use = lens if model in ("vignetted", "harmonised") else dataclasses.replace(lens,
                                                                               vignetting=())
    table = ShiftTable.build(n_eff, f_number, use, cra_max_deg=max(float(cra.max()), 1e-6),
                             tolerance_nm=tolerance_nm, cwl_max_nm=cwl_max_nm)
    return np.interp(cra, table.cra_deg, table.relative_shift)


def _model(sensor, f, cra_max, lens, method, tolerance_nm):
    """The model used and why, and the bands' effective indices (ones where unknown, which
    only the model "none" allows)."""
    cwl = np.asarray(sensor.cwl_nm, float)
    if sensor.n_eff is None and method != "none":
        sensor.require("n_eff", f"the wavelength correction (method {method}; method= none "
                                "keeps the nominal wavelengths)")
    n_eff = np.asarray(sensor.n_eff if sensor.n_eff is not None else np.ones(cwl.size), float)
    measured = sensor.responses is not None
    if method == "asymptotic" and measured:
        raise ValueError("method 'asymptotic' is Eq. 6, the kernel mean's small-angle formula; "
                         "a measured band's centre moves otherwise near its band-pass's edges: "
                         "use 'ideal' or 'vignetted' (or 'auto')")
    if method != "auto":
        return method, "asked for", n_eff
    used, reason = choose_model(cwl, n_eff, f, cra_max, lens, tolerance_nm=tolerance_nm)
    if used == "asymptotic" and measured:
        used, reason = "ideal", (f"{reason}; measured responses take the ideal aperture's "
                                 "table instead (Eq. 6 is the kernel mean's, which a measured "
                                 "band's centre leaves near its band-pass's edges)")
    return used, reason, n_eff


def _field_max_deg(cra_max, f, lens):
    """The cube's largest CRA, refused where the lens passes no light at all."""
    cra_max = float(cra_max)
    cutoff = float(lens.cutoff_cra_deg(f))
    if cra_max >= cutoff:
        raise ValueError(f"at f/{f:g} the lens's vignetting circle cuts off the whole pupil "
                         f"from CRA {cutoff:.2f} deg, and this cube reaches {cra_max:.2f} deg: "
                         "those pixels saw no light through the lens model; check the lens "
                         "profile, f-number and optical centre")
    return cra_max


def _scale_function(sensor, f, lens, used, tolerance_nm, cra_max, widths):
    """``scale_at(cra, key)``: corrected / nominal wavelength at chief-ray angles ``cra`` for
    an effective index (modelled filters) or a band (measured ones, ``key`` its index), and
    what it is, for the provenance."""
    cwl = np.asarray(sensor.cwl_nm, float)
    model = (f" by the {'vignetted' if used == 'harmonised' else used} model at f/{f:g}, "
             f"lens {lens.name}, tolerance {float(tolerance_nm):g} nm")
    measured = sensor.responses is not None and used not in ("none", "asymptotic")
    if not measured:
        n_eff = np.asarray(sensor.n_eff if sensor.n_eff is not None else np.ones(cwl.size))

        def scale_at(c, key):
            n = n_eff[key] if sensor.responses is not None else key
            return 1.0 + relative_shift(n, f, c, lens, model=used, tolerance_nm=tolerance_nm,
                                        cwl_max_nm=float(cwl[n_eff == n].max()))

        return scale_at, f"1 + mean shift / cwl{model}"
    table = widths
    if used == "ideal" and lens.has_vignetting:  # the table of widths is the vignetted lens's
        table = _measured_table(sensor, dataclasses.replace(lens, vignetting=()), f, cra_max,
                                tolerance_nm)

    def scale_at(c, band):
        return table.scale(c, band)

    return scale_at, ("each band's centre (mean wavenumber of its measured main lobe through "
                      f"the system) behind the lens / at normal incidence{model}")


def _scales(cra, n_eff, scale_at, *, per_band=False):
    """``wavelength_scale`` and ``scale_index``: one factor map per distinct effective index
    (Snapscan: every band at one place), else one per band (mosaic, or measured filters,
    whose every band has its own curve)."""
    groups, column = np.unique(n_eff, return_inverse=True)
    if per_band:
        scale = np.empty((*cra.shape[:2], n_eff.size))
        for b in range(n_eff.size):
            scale[:, :, b] = scale_at(cra[:, :, b if cra.shape[2] > 1 else 0], b)
        return scale, np.arange(n_eff.size)
    if cra.shape[2] > 1:
        scale = np.empty(cra.shape)
        for n in groups:
            bands = np.flatnonzero(n_eff == n)
            scale[:, :, bands] = scale_at(cra[:, :, bands], n)
        return scale, np.arange(n_eff.size)
    scale = np.empty((*cra.shape[:2], groups.size))
    for g, n in enumerate(groups):
        scale[:, :, g] = scale_at(cra[:, :, 0], n)
    return scale, column
