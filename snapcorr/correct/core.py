"""Per-pixel corrected central wavelengths of a cube (Goossens et al. 2019, Eq. 23).

``wavelength_corrected(y, x, b) = cwl_b + mean_shift(cwl_b, n_eff_b, f, CRA(y, x, b))``.
The mean shift is proportional to the central wavelength (the shift law scales every
wavelength alike), so one curve of ``mean_shift / cwl`` over CRA per effective index serves
every band: a :class:`~snapcorr.optics.ShiftTable` built to the requested tolerance for the
exact models, Eq. (6) directly for the asymptotic one. The cube itself is not touched.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import threading
from concurrent import futures

import numpy as np
import xarray as xr

from .. import __version__
from .._coords import accepts_center_rc
from .._validation import check_positive, validate_method
from ..cube.derived import LazyTable, corrected_fwhm, corrected_wavelength, lazy_fwhm
from ..cube.flatfield import cf_attrs
from ..cube.model import check_cube
from ..cube.sensor import Sensor
from ..optics import MODELS, ShiftTable, choose_model, mean_shift
from ..optics.lens import Lens
from .geometry import _largest_cra_deg, cube_cra_deg

__all__ = ["correct_cube", "relative_shift"]

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


@accepts_center_rc
def correct_cube(cube, sensor, f_number, lens, *, method="auto",
                 tolerance_nm=DEFAULT_TOLERANCE_NM, center_px=None, sensor_origin_px=None,
                 resample=False, harmonise=False, target_fwhm_nm=None, mask=None,
                 virtual_bands=None, virtual_matrix=None, virtual_wavelengths_nm=None,
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
        the area the cube covers; :func:`~snapcorr.correct.optical_center`).
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
    f, cube, mask = _check_inputs(cube, sensor, f_number, lens, method, tolerance_nm,
                                  target_fwhm_nm, harmonise, mask, resample)
    cwl = np.asarray(sensor.cwl_nm, float)
    cra_max = _field_max_deg(_largest_cra_deg(cube, sensor, lens, center_px, sensor_origin_px),
                             f, lens)
    used, reason, n_eff = _model(sensor, f, cra_max, lens, method, tolerance_nm)
    want, first = _widths_needed(sensor, lens, used, fwhm, harmonise)
    widths = _width_table(sensor, lens, f, cra_max, tolerance_nm) if first else None
    harmonising = harmonise or used == "harmonised"
    cra, center, center_source, scale_at, how, scale, column, resampled, buffer, widths, kv = \
        _maps(cube, sensor, lens, f, center_px, sensor_origin_px, cra_max, used, n_eff,
              tolerance_nm, widths, want and widths is None and harmonising, resample,
              harmonising)
    ds = _assembled(cube, sensor, lens, f, cra, scale, column, how, center_source,
                    widths if fwhm else None, mask, resampled)
    if want and fwhm and widths is None:  # only fwhm_corrected reads it: built on first use
        ds = _with_lazy_fwhm(ds, cube, sensor, lens, f, cra_max, tolerance_nm)
    if harmonising:
        ds = _harmonised(ds, cube, cra, scale, column, cwl, widths, target_fwhm_nm,
                         scale_at, n_eff, sensor, f, lens, buffer, kv)
    if virtual_bands is not None:
        ds = ds.merge(_virtual(cube, sensor, f, lens, cra, virtual_bands, virtual_matrix,
                               virtual_wavelengths_nm, virtual_fwhm_nm))
    return _with_provenance(ds, sensor, lens, f, used, reason, method, tolerance_nm, center,
                            center_source, cra_max)


def _maps(cube, sensor, lens, f, center_px, sensor_origin_px, cra_max, used, n_eff,
          tolerance_nm, widths, build_widths, resample, harmonising):
    """Every pixel's CRA and scales (and ``resampled``), and the width table when
    ``build_widths``: harmonising needs it before its pass, so it is built on a second thread
    (small arrays, one core; the field's largest CRA is known without the map) while this
    one makes the maps. Then each thread, once done, makes the harmonised output's memory
    ready, a share at a time (:class:`_Pages`)."""
    # (only where the pass will run: a table for it, distinct increasing wavelengths)
    buffer = (_output_buffer(cube, sensor.cwl_nm)
              if harmonising and (build_widths or widths is not None) else None)
    pages = _Pages(buffer) if buffer is not None else None
    with _one_blas_thread() if build_widths else contextlib.nullcontext():
        later = (_in_background(_harmonising_tables, sensor, lens, f, cra_max, tolerance_nm,
                                n_eff, pages) if build_widths else None)
        try:
            cra, center, center_source = cube_cra_deg(cube, sensor, lens, center_px,
                                                      sensor_origin_px=sensor_origin_px)
            scale_at, how = _scale_function(sensor, f, lens, used, tolerance_nm, cra_max,
                                            widths)
            scale, column = _scales(cra, n_eff, scale_at,
                                    per_band=sensor.responses is not None)
            resampled = (_resampled(cube, scale, column, np.asarray(sensor.cwl_nm, float))
                         if resample else None)
            if pages is not None:
                pages.touch()
        except BaseException as err:
            if pages is not None:  # the other thread touches no more of it
                pages.cancel()
            if later is not None:  # waited for (no work left running); its error told too
                futures.wait([later])
                if (other := later.exception()) is not None:
                    err.add_note(f"(the width table failed too: {other!r})")
            raise
    widths, kv = later.result() if later is not None else (widths, None)
    return (cra, center, center_source, scale_at, how, scale, column, resampled, buffer, widths,
            kv)


def _harmonising_tables(sensor, lens, f, cra_max, tolerance_nm, n_eff, pages=None):
    """The width table, and each band's kernel variance at its angles (nm^2); then a share of
    the output's ``pages``. On a second thread, under the BLAS limit its caller set
    (:func:`_one_blas_thread`)."""
    table = _unlimited_width_table(sensor, lens, f, cra_max, tolerance_nm)
    kv = _kernel_variance(table.cra_deg, n_eff, np.asarray(sensor.cwl_nm, float), f, lens)
    if pages is not None:
        pages.touch()
    return table, kv


def _in_background(fn, *args):
    """``fn(*args)`` on a thread of its own: a :class:`concurrent.futures.Future`."""
    pool = futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="snapcorr")
    try:
        return pool.submit(fn, *args)
    finally:
        pool.shutdown(wait=False)  # the thread ends with its one job


def _output_dtype(cube):
    """Float32 for float32 and small-integer cubes, else float64."""
    return np.float32 if cube.dtype in (np.float32, np.float16, np.uint8, np.int8, np.uint16,
                                        np.int16) else np.float64


def _output_buffer(cube, cwl):
    """For an in-memory cube, the array the harmonising pass writes into (its pages not yet
    touched: :class:`_Pages`). None for a dask cube (written block by block) and for bands
    not in increasing wavelength (the pass writes them in order, then they are put back)."""
    if cube.chunks is not None or not np.all(np.diff(np.asarray(cwl, float)) > 0):
        return None
    return np.empty(cube.shape, _output_dtype(cube))


class _Pages:
    """An array's memory made ready, every page of it touched once, by whichever threads
    call :meth:`touch`, a share at a time: the kernel maps and zeroes a cube's worth of fresh
    memory (about 0.6 of a copy's time), before the pass rather than in it, by the thread
    that is free (the width table's or the maps') rather than one chosen in advance."""

    SHARE_BYTES = 64 << 20

    def __init__(self, out):
        self._flat = out.reshape(-1)
        self._step = max(1, 4096 // out.itemsize)
        self._share = max(self._step, self.SHARE_BYTES // out.itemsize)
        self._next = 0
        self._lock = threading.Lock()

    def touch(self):
        """Touch shares until none is left (numpy lets go of the GIL while it writes)."""
        while (share := self._claim()) is not None:
            self._flat[share] = 0

    def _claim(self):
        """The next share not yet claimed (a slice: one element per page), or None."""
        with self._lock:
            start = self._next
            if start >= self._flat.size:
                return None
            self._next = start + self._share
        return slice(start, min(start + self._share, self._flat.size), self._step)

    def cancel(self):
        """Leave the shares not yet begun."""
        with self._lock:
            self._next = self._flat.size


def _assembled(cube, sensor, lens, f, cra, scale, column, how, center_source, widths, mask,
               resampled):
    """The result's variables: the cube, the compact wavelengths, the CRA, the widths (when
    given), the mask and the resampled spectra (when given)."""
    ds = _dataset(cube, sensor, lens, cra, scale, column, source=how,
                  center_source=center_source)
    if widths is not None:
        ds = _with_fwhm(ds, cube, lens, sensor, f, widths)
    if mask is not None:
        ds["mask"] = mask.drop_vars([c for c in mask.coords if c not in mask.dims])
        ds["mask"].attrs = {**mask.attrs, **cf_attrs("mask")}
    if resampled is not None:
        ds["resampled"] = resampled
    return ds


def _widths_needed(sensor, lens, used, fwhm, harmonise):
    """Whether the widths' table is wanted at all (``fwhm_corrected``, the harmonising), and
    whether it is needed first (measured responses: the bands' centres the scales need).
    Without ``n_eff`` there is none."""
    if sensor.n_eff is None:
        return False, False
    want = fwhm or harmonise or used == "harmonised"
    first = sensor.responses is not None and (
        used not in ("none", "asymptotic") and not (used == "ideal" and lens.has_vignetting))
    return want, first


def _with_provenance(ds, sensor, lens, f, used, reason, method, tolerance_nm, center,
                     center_source, cra_max):
    """``ds`` with the correction's provenance in its attributes."""
    ds.attrs.update({
        "title": "per-pixel wavelength correction (Goossens et al. 2019, Eq. 23)",
        "source": f"snapcorr {__version__} correct", "Conventions": "CF-1.10",
        "lens": lens.name, "lens_vignetting_mm": [list(c) for c in lens.vignetting] or "none",
        "sensor": sensor.name, "f_number": f, "method": used, "method_reason": reason,
        "method_requested": method, "tolerance_nm": float(tolerance_nm),
        "optical_center_rc": [float(center[1]), float(center[0])],
        "optical_center_px": [float(center[0]), float(center[1])],  # x first, deprecated
        "optical_center_source": center_source, "cra_max_deg": cra_max,
        "snapcorr_version": __version__,
    })
    return ds


def _virtual(cube, sensor, f, lens, cra, method, matrix, wavelengths_nm, fwhm_nm):
    """The virtual bands, each pixel at the mean chief-ray angle of its bands."""
    from .virtual import virtual_bands

    return virtual_bands(cube, sensor, method, f_number=f, lens=lens, cra_deg=cra.mean(axis=2),
                         matrix=matrix, wavelengths_nm=wavelengths_nm, fwhm_nm=fwhm_nm)


def _model(sensor, f, cra_max, lens, method, tolerance_nm):
    """The model used and why, and the bands' effective indices (ones where unknown, which
    only the model "none" allows)."""
    cwl = np.asarray(sensor.cwl_nm, float)
    if sensor.n_eff is None and method != "none":
        sensor.require("n_eff", f"the wavelength correction (--method {method}; --method "
                                "none keeps the nominal wavelengths)")
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
        raise ValueError(f"the cube is named {cube.name!r}, a name the result gives another "
                         "variable: rename it first (cube.rename('radiance'))")
    if (resample or harmonise) and cube.sizes["band"] < 2:
        what = "resample" if resample else "harmonise"
        raise ValueError(f"{what} interpolates along each pixel's spectrum, and a one-band "
                         f"cube has none: leave out {what}=True (--{what})")
    if not isinstance(sensor, Sensor) or not isinstance(lens, Lens):
        raise TypeError(f"correct_cube(cube, sensor, f_number, lens) takes a Sensor and a Lens,"
                        f" got {type(sensor).__name__} and {type(lens).__name__}")
    validate_method(method, ("auto", *MODELS))
    f = check_positive("f_number", f_number)
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


#: The finest interpolation tolerance of the FWHM table, nm: a wavelength tolerance below it
#: (which the shift tables meet) would ask for thousands of CRA nodes for widths nobody can
#: measure to that.
FWHM_TOLERANCE_NM = 0.005


def _measured_table(sensor, lens, f, cra_max, tolerance_nm):
    from ..optics.measured import MeasuredTable

    return MeasuredTable.build(sensor.responses, sensor.n_eff, f, lens, cra_max_deg=cra_max,
                               tolerance_nm=tolerance_nm,
                               fwhm_tolerance_nm=max(float(tolerance_nm), FWHM_TOLERANCE_NM))


def _width_table(sensor, lens, f, cra_max, tolerance_nm):
    """Each band's whole response (filter shape spread by the kernel, Eq. 13) tabulated over
    CRA once: a FwhmTable, or for measured filters a MeasuredTable (centres too)."""
    with _one_blas_thread():
        return _unlimited_width_table(sensor, lens, f, cra_max, tolerance_nm)


def _one_blas_thread():
    """BLAS on one thread (:func:`snapcorr._threads.one_blas_thread`): the tables multiply
    small matrices only."""
    from .._threads import one_blas_thread

    return one_blas_thread()


def _unlimited_width_table(sensor, lens, f, cra_max, tolerance_nm):
    from ..optics.bandwidth import FwhmTable

    if sensor.responses is not None:
        return _measured_table(sensor, lens, f, cra_max, tolerance_nm)
    # the widths need no finer table than FWHM_TOLERANCE_NM even when the wavelengths do
    tol = max(float(tolerance_nm), FWHM_TOLERANCE_NM)
    return FwhmTable.build(sensor.cwl_nm, sensor.fwhm_nm, sensor.n_eff, f, lens,
                           cra_max_deg=cra_max, profile=sensor.profile_shape,
                           tolerance_nm=tol)


def _fwhm_dataset(table, lens, sensor, f):
    """The width table as stored: ``fwhm_table(band, fwhm_cra)`` over ``fwhm_cra_deg``, with
    the bands' nominal ``wavelength``."""
    if sensor.responses is not None:
        what = (f"measured responses through the system ({sensor.responses.system_name}), "
                "each ray scaling the whole curve, FWHM about the main peak,")
    else:
        what = f"{sensor.profile} filters (FWHM {_span(sensor.fwhm_nm)} nm at normal incidence)"
    return xr.Dataset(
        {"fwhm_table": (("band", "fwhm_cra"), table.fwhm_nm, {
            "units": "nm", "long_name": "FWHM of each band's whole response at fwhm_cra_deg",
            "source": f"{what} spread by the kernel of lens {lens.name} at f/{f:g} (Goossens "
                      "et al. 2019 Eq. 13, 37; each ray scales the curve); linear "
                      f"interpolation within {table.tolerance_nm:g} nm"})},
        coords={"fwhm_cra_deg": ("fwhm_cra", table.cra_deg, {
                    "units": "degree", "long_name": "chief-ray angles of fwhm_table"}),
                "wavelength": ("band", np.asarray(sensor.cwl_nm, float))})


def _built_fwhm_dataset(sensor, lens, f, cra_max, tolerance_nm):
    return _fwhm_dataset(_width_table(sensor, lens, f, cra_max, tolerance_nm), lens, sensor, f)


def _with_fwhm(ds, cube, lens, sensor, f, table):
    """``fwhm_corrected``: the width table interpolated per pixel lazily."""
    t = _fwhm_dataset(table, lens, sensor, f)
    ds = ds.assign_coords(fwhm_cra_deg=t["fwhm_cra_deg"])
    ds["fwhm_table"] = t["fwhm_table"].drop_vars("wavelength")
    return ds.assign_coords(fwhm_corrected=corrected_fwhm(ds, chunks=cube.chunks))


def _with_lazy_fwhm(ds, cube, sensor, lens, f, cra_max, tolerance_nm):
    """``fwhm_corrected`` over a width table built when it is first read (its values, a write,
    :func:`~snapcorr.cube.derived.with_fwhm_table`): a correction that never reads the
    widths never builds it (0.5-1 s for 150 bands, whatever the cube's size)."""
    table = LazyTable(functools.partial(_built_fwhm_dataset, sensor, lens, f, cra_max,
                                        tolerance_nm))
    return ds.assign_coords(fwhm_corrected=lazy_fwhm(ds["cra_deg"], table, ds.sizes["band"],
                                                     chunks=cube.chunks))


#: Chief-ray-angle step of the Snapscan path's weight tables, between which a pixel's weights
#: are interpolated (a band moves by at most ~0.1 nm over a step). Against the direct
#: computation the result differs by at most 3e-5 of the data's range for spectra as 12 nm
#: filters see them and 2e-4 for white noise across the bands (the worst case), tested at
#: this step in ``test_the_tabulated_path_is_the_direct_one``.
HARMONISE_NODE_STEP_DEG = 0.05


def _kernel_variance(nodes, n_eff, cwl, f, lens):
    """``(n_bands, n_nodes)``: each band's kernel variance at ``nodes`` (CRA), nm^2."""
    from ..optics.bandwidth import kernel_log_variance

    n_eff = np.broadcast_to(np.asarray(n_eff, float), cwl.shape)
    out = np.empty((cwl.size, np.size(nodes)))
    for value in np.unique(n_eff):
        bands = n_eff == value
        out[bands] = kernel_log_variance(value, f, np.asarray(nodes, float), lens)[None, :]
    return out * cwl[:, None] ** 2


def _reference_response(table, inside, ends, field, n_eff, cwl, f, lens, kv=None):
    """Kernel variances over the table's CRAs (band, node), nm^2, and the reference pixel's
    kernel variance and FWHM per band.

    The widening is set by the kernels' variances, not by the FWHMs: the responses are the
    filter convolved with each pixel's kernel, so their variances differ by the kernels'
    exactly, whatever the shapes, while FWHMs add in quadrature only for Gaussians (the
    kernel is box-like: at f/1.4 the quadrature rule widened the pixels near the axis by
    ~30 % too much in variance, and more for Airy filters, whose width is in the wings).
    The reference is the pixel of the largest kernel variance in the field; a wider target
    adds to it (target^2 - its FWHM^2) / (8 ln 2). ``kv``: the variances over the table's CRAs
    if already computed.
    """
    if kv is None:
        kv = _kernel_variance(table.cra_deg, n_eff, cwl, f, lens)
    kv_field = np.concatenate([_kernel_variance(ends, n_eff, cwl, f, lens), kv[:, inside]],
                              axis=1)
    ref = np.nanargmax(np.where(np.isnan(kv_field), -np.inf, kv_field), axis=1)
    rows = np.arange(cwl.size)
    return kv, kv_field[rows, ref], field[rows, ref]


def _harmonised(ds, cube, cra, scale, column, cwl, table, target_fwhm_nm, scale_at, n_eff,
                sensor, f, lens, buffer=None, kv=None):
    from .harmonise import harmonise_spectra, node_weights

    if table is None:  # no widths without n_eff
        sensor.require("n_eff", "harmonise (each pixel's bandwidth)")
    cra_lo, cra_hi = float(cra.min()), float(cra.max())
    inside = (table.cra_deg >= cra_lo) & (table.cra_deg <= cra_hi)
    ends = np.array([cra_lo, cra_hi])
    field = np.concatenate([table(ends).T, table.fwhm_nm[:, inside]], axis=1)
    target, how = _common_width(np.nanmax(field, axis=1), target_fwhm_nm, cwl)
    if sensor.responses is not None:
        return _harmonised_measured(ds, cube, cra, np.concatenate([ends, table.cra_deg[inside]]),
                                    target_fwhm_nm, target, how, n_eff, sensor, f, lens)
    kv, kv_ref, fwhm_ref = _reference_response(table, inside, ends, field, n_eff, cwl, f, lens,
                                               kv)
    extra = np.clip(target ** 2 - fwhm_ref ** 2, 0.0, None) / (8 * math.log(2))
    var_table = np.clip((extra + kv_ref)[:, None] - kv, 0.0, None)
    # the spectra are walked in increasing wavelength; bands listed otherwise are put in order
    # for the pass and back after it
    order = np.argsort(cwl, kind="stable")
    inverse = np.argsort(order, kind="stable")
    if np.any(np.diff(cwl[order]) <= 0):
        raise ValueError("two bands share a nominal wavelength: harmonising needs distinct "
                         "ones")
    in_order = np.array_equal(order, np.arange(order.size))
    cs, cols, vt = cwl[order], column[order], var_table[order]
    dtype = _output_dtype(cube)

    def ordered(data):
        data = np.asarray(data, dtype)
        return data if in_order else data[..., order]

    def restored(out):
        return out if in_order else out[..., inverse]

    def into(data):  # an in-memory cube is one block: the output readied for it
        return buffer if buffer is not None and in_order and buffer.shape == data.shape \
            else None

    snapscan = cra.shape[2] == 1 and scale.shape[2] == 1
    if snapscan:
        cra_hi = max(cra_hi, cra_lo + 1e-6)  # two distinct nodes even for one pixel
        nodes = np.linspace(cra_lo, cra_hi, max(2, math.ceil(
            (cra_hi - cra_lo) / HARMONISE_NODE_STEP_DEG) + 1))
        node_sigma = np.sqrt(np.stack([np.interp(nodes, table.cra_deg, v) for v in vt],
                                      axis=1))
        node_scale = scale_at(nodes, float(np.unique(n_eff)[0]))
        # the weights on the nodes once, not once per block of a dask cube
        weights = node_weights(cs, nodes, node_scale, node_sigma)

        def block(data, c, sc):
            return restored(harmonise_spectra(ordered(data), sc, cols, cs, cra=c[..., 0],
                                              weights=weights, out=into(data)))
    else:
        def block(data, c, sc):
            sig = np.empty(data.shape)
            for k, b in enumerate(order):  # k: place in the walk, b: the band
                cb = c[..., b if c.shape[2] > 1 else 0]
                sig[..., k] = np.sqrt(np.interp(cb, table.cra_deg, vt[k]))
            return restored(harmonise_spectra(ordered(data), sc, cols, cs, sig,
                                              out=into(data)))

    cr = xr.DataArray(cra, dims=("y", "x", "c"))
    sc = xr.DataArray(scale, dims=("y", "x", "m"))
    data = cube
    if cube.chunks is not None:
        data = cube.chunk({"band": -1})
        cr = cr.chunk({"y": data.chunks[0], "x": data.chunks[1], "c": -1})
        sc = sc.chunk({"y": data.chunks[0], "x": data.chunks[1], "m": -1})
    out = xr.apply_ufunc(block, data, cr, sc, input_core_dims=[["band"], ["c"], ["m"]],
                         output_core_dims=[["band"]], dask="parallelized",
                         output_dtypes=[dtype]).transpose("y", "x", "band")
    out.attrs = _harmonised_attrs(cube, how)
    ds["harmonised"] = out
    ds["fwhm_harmonised"] = ("band", target, {"units": "nm",
                                              "long_name": "FWHM of the common response of "
                                                           "harmonised",
                                              "source": how})
    return ds


def _common_width(widest, target_fwhm_nm, cwl):
    """The common response's FWHM per band (the widest in the field unless one is asked
    for, which must be at least that: harmonising only widens) and how it was chosen."""
    if target_fwhm_nm is None:
        return widest, "the widest response in the field at each band"
    F = check_positive("target_fwhm_nm", target_fwhm_nm)
    short = np.flatnonzero(widest > F + 1e-9)
    if short.size:
        b = short[np.argmax(widest[short])]
        raise ValueError(f"target_fwhm_nm {F:g} nm is narrower than the widest response in "
                         f"the field ({widest[b]:.3g} nm at {cwl[b]:g} nm): harmonising "
                         "only widens; ask for at least that")
    return np.full(cwl.size, F), f"{F:g} nm at every band (asked for)"


def _harmonised_measured(ds, cube, cra, angles, target_fwhm_nm, target, how, n_eff, sensor,
                         f, lens):
    """``harmonised`` for measured responses: each band's value through its common response
    (:func:`snapcorr.optics.measured.common_responses` at the pixel of the largest kernel
    variance in the field, ``angles`` its chief-ray angles), estimated from every band of the
    pixel by the Wiener matrix at its angle (:func:`~snapcorr.correct.harmonise.matched_table`);
    the bands the band-pass edge cuts are NaN (:func:`_edge_bands`)."""
    from ..optics.measured import common_responses
    from .harmonise import harmonise_matched, matched_table

    cwl = np.asarray(sensor.cwl_nm, float)
    kv = _kernel_variance(angles, n_eff, cwl, f, lens)
    ref = angles[np.nanargmax(np.where(np.isnan(kv), -np.inf, kv), axis=1)]
    with _one_blas_thread():  # small matrices: 16 x faster on one thread (measured)
        targets, width = common_responses(sensor.responses, n_eff, f, ref, lens)
        if target_fwhm_nm is not None:  # widened until each is as wide as asked
            targets, width = _widened(sensor, n_eff, f, ref, lens, target, width)
        table = matched_table(sensor.responses, targets, n_eff, f, lens,
                              cra_max_deg=max(float(angles.max()), 1e-6))
    cut, cut_note = _edge_bands(sensor, n_eff, f, lens, angles)
    mats = table.matrices.copy()
    mats[:, cut, :] = np.nan
    table = table._replace(matrices=mats)
    dtype = _output_dtype(cube)

    def block(data, c):
        return harmonise_matched(np.asarray(data, dtype), c, table)

    cr = xr.DataArray(cra, dims=("y", "x", "c"))
    data = cube
    if cube.chunks is not None:
        data = cube.chunk({"band": -1})
        cr = cr.chunk({"y": data.chunks[0], "x": data.chunks[1], "c": -1})
    out = xr.apply_ufunc(block, data, cr, input_core_dims=[["band"], ["c"]],
                         output_core_dims=[["band"]], dask="parallelized",
                         output_dtypes=[dtype]).transpose("y", "x", "band")
    seen = ("each band's measured response as the pixel of the largest kernel variance in the "
            f"field (CRA {', '.join(f'{c:.2f}' for c in np.unique(np.round(ref, 2)))} deg) "
            "sees it, moved back to its place at normal incidence")
    if target_fwhm_nm is not None:
        seen += f", widened by a Gaussian to {how}"
    out.attrs = _measured_attrs(cube, sensor, seen, table, cut_note)
    ds["harmonised"] = out
    ds["fwhm_harmonised"] = ("band", width, {
        "units": "nm", "long_name": "FWHM of the common response of harmonised",
        "source": f"the width at or above half the maximum of {seen}"})
    return ds


def _widened(sensor, n_eff, f, ref, lens, target, width):
    """The common responses widened by Gaussians until each is ``target`` wide, within 0.001
    nm (those as wide already kept): each band's variance found by regula falsi (Illinois) on
    its width, which for a measured curve does not add in quadrature (a band the edge cuts
    widens far less)."""
    from ..optics.measured import common_responses

    def miss(var):
        out, w = common_responses(sensor.responses, n_eff, f, ref, lens, extra_var_nm2=var)
        return out, w, w - target

    need = width < target
    lo, f_lo = np.zeros(target.size), width - target
    hi = np.where(need, (target**2 - width**2) / (8 * math.log(2)) + 1e-3, 0.0)
    span = np.ptp(sensor.responses.wavelength_nm)
    while True:  # a bracket: at least as wide as asked at hi
        out, w, f_hi = miss(hi)
        short = need & (f_hi < 0)
        if not short.any():
            break
        if np.any(hi[short] > span**2):  # a Gaussian wider than the whole grid
            b = np.flatnonzero(short)[0]
            raise ValueError(f"target_fwhm_nm {target[b]:g} nm: the {sensor.cwl_nm[b]:g} nm "
                             "band's response behind the band-pass cannot be made that wide")
        hi = np.where(short, 4.0 * hi, hi)
    for _ in range(60):
        done = ~need | (np.abs(f_hi) <= 1e-3)
        if np.all(done):
            return out, w
        mid = np.where(done, hi, hi - f_hi * (hi - lo) / np.where(f_hi > f_lo, f_hi - f_lo, 1))
        out, w, f_mid = miss(mid)
        over = f_mid >= 0  # [lo, mid] brackets: mid is the new hi; else lo moves up
        f_lo = np.where(over & ~done, f_lo / 2, np.where(~over, f_mid, f_lo))  # (Illinois)
        lo = np.where(~over, mid, lo)
        hi, f_hi = np.where(over, mid, hi), np.where(over, f_mid, f_hi)
    raise ValueError("the common responses could not be widened to target_fwhm_nm; this is a "
                     "bug")


def _edge_bands(sensor, n_eff, f, lens, angles):
    """The bands whose main peak, moved by the kernel mean at some angle of the field, leaves
    the band-pass (falls where the system transmits less than ``PASSBAND_FRACTION`` of its
    maximum, the pass band of :meth:`~snapcorr.cube.responses.FilterResponses.main_peaks`):
    there the edge, not the filter, shapes the band, whose response then changes shape as
    the field moves rather than only moving and widening. A mask, and what to say of it."""
    from ..cube.responses import PASSBAND_FRACTION
    from ..optics.measured import moved_peak_transmission

    cwl = np.asarray(sensor.cwl_nm, float)
    n = np.broadcast_to(np.asarray(n_eff, float), cwl.shape)
    scale = np.empty((angles.size, cwl.size))
    for value in np.unique(n):  # the kernel mean, Eq. 22, as the wavelengths' tables give it
        scale[:, n == value] = 1.0 + relative_shift(
            value, f, angles, lens, model="vignetted", tolerance_nm=DEFAULT_TOLERANCE_NM,
            cwl_max_nm=float(cwl.max()))[:, None]
    passed = moved_peak_transmission(sensor.responses, scale)
    least = np.nanmin(np.where(np.isnan(passed), np.inf, passed), axis=0)
    cut = least < PASSBAND_FRACTION
    if not cut.any():
        return cut, ("none: every band's main peak, moved by the kernel mean, stays inside the "
                     f"band-pass (where it transmits at least {PASSBAND_FRACTION:.0%} of its "
                     "maximum) over the field")
    at = angles[np.nanargmin(np.where(np.isnan(passed), np.inf, passed), axis=0)]
    named = ", ".join(f"{cwl[b]:g} nm (the band-pass passes {least[b]:.0%} of its maximum at "
                      f"its moved peak, CRA {at[b]:.1f} deg)" for b in np.flatnonzero(cut))
    return cut, (f"{named}: NaN. The band's main peak, moved by the kernel mean, leaves the "
                 f"band-pass (below {PASSBAND_FRACTION:.0%} of its maximum) in the field: the "
                 "edge, not the filter, shapes its response there, which changes shape rather "
                 "than only moving and widening across the field, and its value rests on where "
                 "the band-pass edge sits at each angle, which the sensor file gives at normal "
                 "incidence only")


def _measured_attrs(cube, sensor, common, table, cut_note):
    """The attributes of ``harmonised`` for measured responses: how it was made, the common
    response, the bands left out, the noise, and what the bands can sample."""
    cwl = np.sort(np.asarray(sensor.cwl_nm, float))
    gaps = np.diff(cwl)
    return {**_units_of(cube),
            "long_name": f"{cube.attrs.get('long_name', cube.name or 'radiance')} through one "
                         "response per band",
            "source": "each band's value through its common response, estimated from all the "
                      "pixel's bands by the Wiener matrix for their responses behind the lens "
                      "at the band's chief-ray angle (Pratt & Mancill 1976; the sensor's "
                      "measured curves, every ray scaling the whole curve, behind the band-pass; "
                      "the Markov spectrum prior of the virtual bands with its level left free, "
                      f"band noise variance {table.alpha:g}), on {table.cra_deg.size} "
                      "chief-ray-angle nodes",
            "common_response": common,
            "not_harmonised": cut_note,
            "noise_gain": f"each value's noise is up to {np.nanmax(table.noise_gain):.2f} x a "
                          "band's (the largest norm of a matrix row)",
            "limits": f"{cwl.size} bands {gaps.min():.3g}-{gaps.max():.3g} nm apart (median "
                      f"{np.median(gaps):.3g} nm): spectra come out the same across the field "
                      "where their features are wider than about twice the gap between the "
                      f"bands around them ({2 * np.median(gaps):.3g} nm at the median gap, "
                      f"{2 * gaps.max():.3g} nm at the largest); narrower ones (the absorption "
                      "lines of a rare-earth glass) fall between the bands, which cannot sample "
                      "them, and keep differences however harmonised",
            "note": "NaN in the bands named in not_harmonised, and where a band the value "
                    "draws on is NaN"}


def _harmonised_attrs(cube, how):
    name = cube.name or "radiance"
    return {**_units_of(cube),
            "long_name": f"{cube.attrs.get('long_name', name)} on the nominal wavelengths, one "
                         "response per band",
            "source": "each pixel's spectrum (straight lines between its corrected wavelengths) "
                      "averaged with a Gaussian of the variance its response lacks against the "
                      "common one (the difference of the kernels' variances), at the nominal "
                      "wavelengths",
            "common_response": "the response of the pixel of the largest kernel variance, "
                               f"spread to fwhm_harmonised: {how}",
            "note": "NaN where the nominal wavelength lies outside the pixel's corrected range "
                    "(extrapolation is not done)"}


def _span(values):
    v = np.asarray(values, float)
    return f"{v.min():g}" if np.ptp(v) == 0 else f"{v.min():g}-{v.max():g}"


def _resampled(cube, scale, column, cwl):
    from .resample import resample_to_nominal

    order = np.argsort(cwl, kind="stable")
    inverse = np.argsort(order, kind="stable")
    dtype = _output_dtype(cube)

    in_order = np.array_equal(order, np.arange(order.size))

    def block(data, sc):
        data = np.asarray(data, dtype)
        if in_order:  # the usual case: no reordering copies of the cube
            return resample_to_nominal(data, sc, column, cwl)
        out = resample_to_nominal(data[..., order], sc, column[order], cwl[order])
        return out[..., inverse]

    sc = xr.DataArray(scale, dims=("y", "x", "m"))
    if cube.chunks is not None:
        # a spectrum is resampled whole: one chunk along band (chunks stay bounded in y, x)
        cube = cube.chunk({"band": -1})
        sc = sc.chunk({"y": cube.chunks[0], "x": cube.chunks[1], "m": -1})
    out = xr.apply_ufunc(block, cube, sc, input_core_dims=[["band"], ["m"]],
                         output_core_dims=[["band"]], dask="parallelized",
                         output_dtypes=[dtype])
    out = out.transpose("y", "x", "band")
    name = cube.name or "radiance"
    attrs = {**cf_attrs(name), **cube.attrs}
    out.attrs = {**_units_of(cube),
                 "long_name": f"{attrs.get('long_name', name)} on the nominal wavelengths",
                 "source": f"{name} interpolated linearly from wavelength_corrected onto "
                           "wavelength",
                 "note": "NaN where the nominal wavelength lies outside the pixel's corrected "
                         "range (extrapolation is not done)"}
    return out


def _units_of(cube):
    """``{"units": ...}`` of a spectrum computed from ``cube``: the cube's own (or what its
    name says, :func:`~snapcorr.cube.flatfield.cf_attrs`), none when nothing says ("1" is for
    ratios only)."""
    units = {**cf_attrs(cube.name or "radiance"), **cube.attrs}.get("units")
    return {} if units is None else {"units": units}
