"""Per-pixel corrected central wavelengths of a cube (Goossens et al. 2019, Eq. 23).

``wavelength_corrected(y, x, b) = cwl_b + mean_shift(cwl_b, n_eff_b, f, CRA(y, x, b))``.
The mean shift is proportional to the central wavelength (the shift law scales every
wavelength alike), so one curve of ``mean_shift / cwl`` over CRA per effective index serves
every band: a :class:`~snapcorr.optics.ShiftTable` built to the requested tolerance for the
exact models, Eq. (6) directly for the asymptotic one. The cube itself is not touched.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .. import __version__
from .._coords import accepts_center_rc
from .._validation import check_f_number, check_positive, validate_method
from ..cube.derived import corrected_wavelength
from ..cube.flatfield import cf_attrs
from ..cube.model import check_cube
from ..cube.sensor import Sensor
from ..optics import MODELS
from ..optics.lens import Lens
from .geometry import _largest_cra_deg
from .harmonised import HARMONISE_NODE_STEP_DEG as HARMONISE_NODE_STEP_DEG
from .harmonised import _harmonised
from .plan import CorrectionPlan, plan_correction
from .virtual import VirtualBandOptions, check_virtual_options
from .wavelengths import DEFAULT_TOLERANCE_NM, _field_max_deg, _model, relative_shift
from .widths import FWHM_TOLERANCE_NM as FWHM_TOLERANCE_NM
from .widths import _width_table, _widths_needed, _with_fwhm, _with_lazy_fwhm

__all__ = ["DEFAULT_TOLERANCE_NM", "correct_cube", "relative_shift"]


@accepts_center_rc
def correct_cube(cube, sensor, f_number, lens, *, method="auto",
                 tolerance_nm=DEFAULT_TOLERANCE_NM, center_rc=None, center_px=None,
                 sensor_origin_px=None, resample=False, harmonise=False, target_fwhm_nm=None,
                 mask=None, virtual_bands=None, virtual_matrix=None, virtual_wavelengths_nm=None,
                 virtual_fwhm_nm=None, fwhm=True):
    """Corrected central wavelength of every pixel and band; optionally the resampled cube.

    Parameters
    ----------
    cube : xarray.DataArray
        (y, x, band), numpy- or dask-backed; its bands must match the sensor's.
    sensor : Sensor
        The camera the cube was taken with (its filters).
    f_number : float
        The nominal f-number the cube was taken at.
    lens : Lens
    method : {"auto", "none", "asymptotic", "ideal", "vignetted", "harmonised"}
        The model (:data:`snapcorr.optics.MODELS`). ``"auto"``: the cheapest whose wavelength
        error stays below ``tolerance_nm`` over the cube's field
        (:func:`snapcorr.optics.choose_model`); the scene budget's choice for a spectrum is
        :func:`snapcorr.budget.recommend_model`'s. ``"harmonised"``: ``"vignetted"`` and
        ``harmonise=True``.
    tolerance_nm : float
        Largest error allowed in the corrected wavelengths (model choice and table
        interpolation), nm.
    center_rc, center_px : (row, col), optional
        Optical centre in sensor pixels, row first (``center_px=(cx, cy)``: the deprecated
        x-first form; default: from the lens calibration, converted through
        millimetres when its pixel pitch differs, else the sensor's centre, else the centre of
        the area the cube covers; :func:`~snapcorr.correct.geometry.optical_center_rc`).
    sensor_origin_px : (row, col), optional
        Sensor row and column of the cube's first pixel, for a crop that does not carry its
        positions (``sensor_row``/``sensor_col``); :func:`~snapcorr.correct.cube_positions`
        refuses a crop of unknown place and a mosaic cube without positions.
    resample : bool
        Also interpolate each pixel's spectrum onto the nominal wavelengths (``resampled``),
        NaN where that would need extrapolation.
    harmonise : bool
        Also give ``harmonised``: every pixel's spectrum on the nominal wavelengths with one
        common response per band (:mod:`snapcorr.correct.harmonise`), so the same material
        gives the same spectrum anywhere in the field. NaN where ``resampled`` would be (for
        measured responses: in the bands named in its ``not_harmonised``, and its ``note``).
    target_fwhm_nm : float, optional
        The common response's FWHM for every band (default: the widest response in the
        cube's field at each band). It must be at least that widest response: harmonising
        only widens.
    mask : xarray.DataArray, optional
        The flat-field mask (True where a value is not meaningful), kept in the output.
    virtual_bands : {"vendor", "fitted", "angle-aware"}, optional
        Also give the virtual bands (:func:`~snapcorr.correct.virtual_bands`): the vendor's
        matrix, one fitted to the measured responses, or one for each pixel's responses
        behind the lens.
    virtual_matrix : str, optional
        The vendor matrix's name, for ``virtual_bands="vendor"``.
    virtual_wavelengths_nm, virtual_fwhm_nm : array_like, optional
        Centres and widths of fitted virtual bands (default: the vendor's).
    fwhm : bool
        Give each pixel's response FWHM (``fwhm_corrected``; needs ``n_eff``) from a table
        over CRA (0.5-1.1 s for 150 bands), built when first read (values, a write, or
        :func:`~snapcorr.correct.with_fwhm_table`, which adds ``fwhm_table``) unless the
        harmonising needs it first. ``False`` leaves the widths out.

    Returns
    -------
    xarray.Dataset
        The input cube's values unchanged (under its own name); ``wavelength_scale(y, x,
        scale)`` and ``scale_index(band)``, the compact form of the corrected wavelengths
        (one factor per pixel and effective index for a Snapscan), and the coordinate
        ``wavelength_corrected(y, x, band)`` (float32, nm) rebuilt from them lazily, block by
        block (:mod:`snapcorr.cube.derived`); ``cra_deg(y, x[, band])``;
        ``fwhm_corrected(y, x, band)`` (float32, nm, lazily) unless ``fwhm=False``;
        ``resampled`` and ``harmonised`` (with ``fwhm_harmonised(band)``, the common
        response) on request; ``mask`` when given; ``virtual(y, x, virtual_band)`` and the
        matrix used, on request; provenance in attrs.
    """
    check_virtual_options(virtual_bands, virtual_matrix, virtual_wavelengths_nm,
                          virtual_fwhm_nm)
    f, cube, mask = _check_inputs(cube, sensor, f_number, lens, method, tolerance_nm,
                                  target_fwhm_nm, harmonise, mask, resample)
    cra_max = _field_max_deg(_largest_cra_deg(cube, sensor, lens, center_rc, sensor_origin_px),
                             f, lens)
    used, reason, n_eff = _model(sensor, f, cra_max, lens, method, tolerance_nm)
    want, first = _widths_needed(sensor, lens, used, fwhm, harmonise)
    widths = _width_table(sensor, lens, f, cra_max, tolerance_nm) if first else None
    harmonising = harmonise or used == "harmonised"
    plan = CorrectionPlan(f_number=f, cra_max_deg=cra_max, tolerance_nm=tolerance_nm,
                          model=used, reason=reason, n_eff=n_eff, widths=widths)
    plan = plan_correction(plan, cube, sensor, lens, center_rc, sensor_origin_px,
                           build_widths=want and widths is None and harmonising,
                           resample=resample, harmonising=harmonising)
    ds = _assembled(cube, sensor, lens, plan, mask, with_widths=fwhm)
    if want and fwhm and plan.widths is None:  # only fwhm_corrected reads it: built on first use
        ds = _with_lazy_fwhm(ds, cube, sensor, lens, f, cra_max, tolerance_nm)
    if harmonising:
        ds = _harmonised(ds, cube, plan, sensor, lens, target_fwhm_nm)
    if virtual_bands is not None:
        ds = ds.merge(_virtual(cube, sensor, lens, plan, VirtualBandOptions(
            virtual_bands, virtual_matrix, virtual_wavelengths_nm, virtual_fwhm_nm)))
    return _with_provenance(ds, sensor, lens, plan, method)


def _assembled(cube, sensor, lens, plan, mask, *, with_widths):
    """The result's variables: the cube, the compact wavelengths, the CRA, the widths (when
    ``with_widths`` and the plan has them), the mask and the resampled spectra (when given)."""
    ds = _dataset(cube, sensor, lens, plan.cra_deg, plan.scale, plan.column,
                  source=plan.scale_source, center_source=plan.center_source)
    if with_widths and plan.widths is not None:
        ds = _with_fwhm(ds, cube, lens, sensor, plan.f_number, plan.widths)
    if mask is not None:
        ds["mask"] = mask.drop_vars([c for c in mask.coords if c not in mask.dims])
        ds["mask"].attrs = {**mask.attrs, **cf_attrs("mask")}
    if plan.resampled is not None:
        ds["resampled"] = plan.resampled
    return ds


def _with_provenance(ds, sensor, lens, plan, method):
    """``ds`` with the correction's provenance in its attributes."""
    f, (row, col) = plan.f_number, plan.center_rc
    ds.attrs.update({
        "title": "per-pixel wavelength correction (Goossens et al. 2019, Eq. 23)",
        "source": f"snapcorr {__version__} correct", "Conventions": "CF-1.10",
        "lens": lens.name, "lens_vignetting_mm": [list(c) for c in lens.vignetting] or "none",
        "sensor": sensor.name, "f_number": f, "method": plan.model,
        "method_reason": plan.reason, "method_requested": method,
        "tolerance_nm": float(plan.tolerance_nm),
        "optical_center_rc": [float(row), float(col)],
        "optical_center_px": [float(col), float(row)],  # x first, for earlier readers
        "optical_center_source": plan.center_source, "cra_max_deg": plan.cra_max_deg,
        "snapcorr_version": __version__,
    })
    return ds


def _virtual(cube, sensor, lens, plan, options):
    """The virtual bands (:class:`~snapcorr.correct.virtual.VirtualBandOptions`), each pixel at
    the mean chief-ray angle of its bands."""
    from .virtual import virtual_bands

    return virtual_bands(cube, sensor, options.method, f_number=plan.f_number, lens=lens,
                         cra_deg=plan.cra_deg.mean(axis=2), matrix=options.matrix,
                         wavelengths_nm=options.wavelengths_nm, fwhm_nm=options.fwhm_nm)


def _dataset(cube, sensor, lens, cra, scale, column, *, source, center_source):
    """The cube (unchanged), its CRA map and the compact corrected wavelengths."""
    name = cube.name or "radiance"
    data = cube.copy(deep=False)
    data.attrs = {**cf_attrs(name), **cube.attrs}
    per_band = cra.shape[2] > 1
    ds = xr.Dataset({
        name: data,
        "cra_deg": (("y", "x", "band") if per_band else ("y", "x"),
                    cra if per_band else cra[:, :, 0],
                    {"units": "degree", "long_name": "chief-ray angle",
                     "source": f"Goossens et al. 2019 Eq. 8: sensor position, pitch "
                               f"{sensor.pixel_pitch_um:g} um, optical centre ({center_source})"
                               f", exit pupil {lens.exit_pupil_mm:g} mm"}),
        "wavelength_scale": (("y", "x", "scale"), scale, {
            "units": "1", "long_name": "corrected / nominal central wavelength",
            "comment": "wavelength_corrected = wavelength * wavelength_scale[y, x, "
                       "scale_index[band]] (Goossens et al. 2019, Eq. 23)",
            "source": source}),
        "scale_index": ("band", column.astype(np.int32),
                        {"long_name": "index into wavelength_scale's scale dimension",
                         "units": "1"}),
    })
    ds["wavelength"].attrs = {"units": "nm", "long_name": "nominal central wavelength",
                              **ds["wavelength"].attrs}
    # in the cube's blocks when it has them, so a block of the coordinate matches one of data
    return ds.assign_coords(wavelength_corrected=corrected_wavelength(ds, chunks=cube.chunks))


#: The widest common response harmonising takes, nm: wider would blur every band into one.
MAX_TARGET_FWHM_NM = 1000.0


#: Variables a correction's result holds besides the input cube.
RESULT_NAMES = ("wavelength_corrected", "fwhm_corrected", "resampled", "harmonised",
                "virtual", "mask", "cra_deg", "wavelength_scale", "scale_index", "fwhm_table",
                "fwhm_harmonised")


def _check_inputs(cube, sensor, f_number, lens, method, tolerance_nm, target_fwhm_nm,
                  harmonise, mask=None, resample=False):
    """The checks every correction makes first; returns the f-number as a float, and the cube
    and mask with the bands in the sensor's order (a mosaic cube in the vendor's tile order,
    :meth:`Sensor.in_band_order`)."""
    if isinstance(sensor, Sensor):
        cube, mask = sensor.in_band_order(cube, mask)
    check_cube(cube)
    if cube.name in RESULT_NAMES:  # e.g. a resampled cube read back from its own file
        raise ValueError(f"the cube is named {cube.name!r}, a result of a correction: correct "
                         "the cube it was made from (a result's name cannot be its input's: "
                         "in Python, rename it)")
    if (resample or harmonise) and cube.sizes["band"] < 2:
        what = "resample" if resample else "harmonise"
        raise ValueError(f"{what} interpolates along each pixel's spectrum, and a one-band "
                         f"cube has none: leave out {what}=True")
    if not isinstance(sensor, Sensor) or not isinstance(lens, Lens):
        raise TypeError(f"correct_cube(cube, sensor, f_number, lens) takes a Sensor and a Lens,"
                        f" got {type(sensor).__name__} and {type(lens).__name__}")
    validate_method(method, ("auto", *MODELS))
    f = check_f_number("f_number", f_number)
    check_positive("tolerance_nm", tolerance_nm)
    if target_fwhm_nm is not None and not (harmonise or method == "harmonised"):
        raise ValueError("target_fwhm_nm sets the common response of harmonise=True")
    if target_fwhm_nm is not None and check_positive("target_fwhm_nm",
                                                     target_fwhm_nm) > MAX_TARGET_FWHM_NM:
        raise ValueError(f"target_fwhm_nm {float(target_fwhm_nm):g} nm is wider than any band "
                         f"set spans; at most {MAX_TARGET_FWHM_NM:g} nm")
    sensor.check_cube(cube)
    if mask is not None and (tuple(mask.dims) != ("y", "x", "band") or mask.shape != cube.shape):
        raise ValueError(f"the mask has shape {mask.shape}, the cube {cube.shape}")
    return f, cube, mask
