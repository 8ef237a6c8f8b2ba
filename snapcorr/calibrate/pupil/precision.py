"""Choosing a target for the exit-pupil fit: named target spectra and the precision they give.

:func:`pupil_precision` predicts, before any measurement, the standard error of ``x`` (and
``n_eff``) that cubes of a target would give: the Cramer-Rao bound of the model
:func:`~snapcorr.calibrate.pupil.locate.locate_pupil` fits, on synthetic annuli of the full
sensor (:func:`_synthetic_bins`). :data:`CANDIDATE_TARGETS` holds the usual targets it
compares: :func:`white_tile`, the paper's colour filter
(:func:`snapcorr.spectra.colour_filter`), :func:`rare_earth_glass` and :func:`line_lamp`;
:func:`colour_chart_precision` says the same of each patch of a standard colour chart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...optics.lens import Lens
from ...spectra import colour_filter
from .distance import MAX_REL_STDERR, _max_shift_rel, _one_blas_thread
from .index import N_EFF_BAND_STDERR, N_EFF_REL_STDERR
from .measured_target import target_model
from .solver import _pinv_solve, _prediction_derivatives, _project_off, _row_bands, _whiten
from .target import ImpreciseTargetError, check_modelled
from .target_model import PRIOR_SD, RadialBins

__all__ = ["CANDIDATE_TARGETS", "OutsideChartError", "Precision", "colour_chart_precision",
           "pupil_precision"]

# -- choosing a target ----------------------------------------------------------------------
# (the colour filter of Goossens et al. 2019 is :func:`snapcorr.spectra.colour_filter`)
def white_tile(lam):
    """A white reference tile: no spectral feature at all."""
    return np.full(np.shape(lam), 0.95)


#: Absorption bands (centre, FWHM nm, depth) of a holmium/didymium-like rare-earth glass.
RARE_EARTH_BANDS = ((446.0, 4.0, 0.5), (453.0, 3.0, 0.45), (485.0, 5.0, 0.35),
                    (536.0, 6.0, 0.55), (573.0, 8.0, 0.45), (586.0, 4.0, 0.5),
                    (640.0, 5.0, 0.4), (685.0, 6.0, 0.3), (741.0, 8.0, 0.45),
                    (803.0, 9.0, 0.5), (865.0, 7.0, 0.3))


def rare_earth_glass(lam):
    """A holmium/didymium-like glass: narrow absorption bands (:data:`RARE_EARTH_BANDS`) on
    a high continuum."""
    lam = np.asarray(lam, float)
    t = np.full(lam.shape, 0.92)
    for c, w, d in RARE_EARTH_BANDS:
        t = t * (1 - d * np.exp(-4 * math.log(2) * ((lam - c) / w) ** 2))
    return t


#: Mercury-argon lamp lines (nm) between 430 and 920 nm.
LAMP_LINES_NM = (435.8, 546.1, 577.0, 579.1, 696.5, 706.7, 738.4, 750.4, 763.5, 794.8,
                 811.5, 826.5, 842.5, 852.1, 912.3)


def line_lamp(lam):
    """Narrow emission lines (:data:`LAMP_LINES_NM`, 0.3 nm FWHM) of a mercury-argon lamp
    seen through a diffuser, on a weak continuum; the scale is arbitrary."""
    lam = np.asarray(lam, float)
    out = np.full(lam.shape, 0.01)
    for c in LAMP_LINES_NM:
        out = out + np.exp(-4 * math.log(2) * ((lam - c) / 0.3) ** 2)
    return out


#: Targets :func:`pupil_precision` compares by default.
CANDIDATE_TARGETS = {
    "white tile": white_tile,
    "colour filter (Goossens 2019)": colour_filter,
    "rare-earth glass": rare_earth_glass,
    "emission lines (Hg-Ar lamp)": line_lamp,
}


@dataclass(frozen=True)
class Precision:
    """Predicted standard errors (one standard deviation) of :func:`pupil_precision`."""

    x_stderr_mm: float
    n_eff_stderr: float | None
    spectrum_known: bool
    noise: float
    exit_pupil_mm: float = math.nan

    @property
    def informative(self) -> bool:
        """Whether the target would pin ``x`` at all (to ``MAX_REL_STDERR``)."""
        return bool(self.x_stderr_mm < MAX_REL_STDERR * self.exit_pupil_mm)


def _synthetic_bins(sensor, f_number, n_bins, size_px=None):
    """Annuli of the full sensor (centred on the axis) with their pixel counts per band."""
    rows, cols = size_px or sensor.size_px
    pitch = sensor.pixel_pitch_mm
    y = (np.arange(rows) - (rows - 1) / 2) * pitch
    x = (np.arange(cols) - (cols - 1) / 2) * pitch
    rho = (y**2)[:, None] + (x**2)[None, :]
    edges = np.linspace(0, rho.max() * (1 + 1e-12), n_bins + 1)
    idx = np.clip(np.searchsorted(edges, rho.ravel(), side="right") - 1, 0, n_bins - 1)
    n = np.bincount(idx, minlength=n_bins).astype(float)
    s1 = np.bincount(idx, rho.ravel(), minlength=n_bins)
    s2 = np.bincount(idx, rho.ravel() ** 2, minlength=n_bins)
    mean = s1 / np.maximum(n, 1)
    var = np.maximum(s2 / np.maximum(n, 1) - mean**2, 0)
    cells = 1 if sensor.layout == "snapscan" else sensor.mosaic_shape[0] * sensor.mosaic_shape[1]
    nb = sensor.n_bands
    count = np.tile(n / cells, (nb, 1))
    # an annulus no pixel falls in (a small sensor, many annuli) enters no row: NaN
    empty = np.tile(n == 0, (nb, 1))
    return RadialBins(float(f_number), mean, np.tile(mean, (nb, 1)), np.tile(var, (nb, 1)),
                      np.where(empty, np.nan, 0.0), np.where(empty, np.nan, 1.0), count)


@_one_blas_thread
def _checked_arguments(sensor, f_numbers, lens, size_px, n_bins):
    """The size, the f-numbers and the annuli of a prediction, checked before anything is
    sized by them (a size of 1e9 x 1e9 pixels asked for 7.5 GiB)."""
    from ..._validation import SENSOR_PX_MAX, check_f_number, check_integers, shown
    from ...cube.sensor import Sensor
    from .target import check_n_bins

    for name, value, kind, how in (("sensor", sensor, Sensor, "snapcorr.cube.Sensor.load"),
                                   ("lens", lens, Lens, "snapcorr.Lens.load")):
        if not isinstance(value, kind):
            raise TypeError(f"{name} must be a {kind.__name__} ({how}(NAME or PATH)), got "
                            f"{type(value).__name__} {shown(value)}")
    size = size_px if size_px is not None else sensor.size_px
    if size is None:
        raise ValueError(f"the sensor {sensor.name!r} has no size_px: give size_px")
    size = check_integers("size_px", size)
    if size.shape != (2,) or not np.all((size >= 1) & (size <= SENSOR_PX_MAX)):
        raise ValueError(f"size_px must be (rows, columns), each 1 to {SENSOR_PX_MAX}, got "
                         f"{shown(size_px if size_px is not None else sensor.size_px)}")
    values = np.atleast_1d(np.asarray(f_numbers, dtype=object)).ravel()
    if not values.size:
        raise ValueError("f_numbers must hold at least one f-number")
    return (tuple(int(v) for v in size), [check_f_number("f_numbers", v) for v in values],
            check_n_bins(n_bins))


def pupil_precision(spectrum, sensor, f_numbers, lens: Lens, *, noise=0.01, fit_n_eff=False,
                    spectrum_known=False, size_px=None, n_bins=64, profile="gaussian",
                    absolute_noise=False):
    """Predicted standard error of ``x`` (and ``n_eff``) from cubes of a target.

    The Cramer-Rao bound of the model :func:`locate_pupil` fits: the Fisher information of
    the annulus means over the full sensor, with the target's spectrum solved for (or known
    up to a scale, ``spectrum_known``) and per-pixel noise of standard deviation ``noise``
    times the brightest band's signal (the exposure set so that the brightest band is near
    full scale).

    Parameters
    ----------
    spectrum : callable
        ``S(lambda_nm)``.
    sensor : Sensor
        Needs ``size_px`` unless ``size_px`` is given.
    f_numbers : sequence of float
        The f-numbers of the cubes.
    lens : Lens
        The true lens (x, circles, magnifications).
    noise : float
    fit_n_eff : bool
        Count ``n_eff`` as unknown (one common value).
    absolute_noise : bool
        ``noise`` is in the cube's units (flat-fielded: white = 1), not a fraction of the
        brightest band.

    Returns
    -------
    Precision
        For a target without features ``x_stderr_mm`` is ``inf`` or merely huge (the bound of
        an almost singular information); ``informative`` is False either way.
    """
    size, f_numbers, n_bins = _checked_arguments(sensor, f_numbers, lens, size_px, n_bins)
    if not (math.isfinite(noise) and noise > 0):
        raise ValueError(f"noise must be > 0, got {noise!r}")
    n_design = check_modelled(sensor, "the exit pupil's precision (snapcorr pupil --predict)",
                              fit_n_eff=fit_n_eff)
    bins = [_synthetic_bins(sensor, f, n_bins, size) for f in f_numbers]
    x = float(lens.exit_pupil_mm)
    # the largest shift these f-numbers and this field give (the tables' reach: a fixed 0.15
    # made a vendor sensor's offset tables several times longer than needed)
    cone = math.radians(float(lens.cone_angle_deg(min(f_numbers))))
    reach = min(0.15, _max_shift_rel(math.sqrt(max(float(np.max(b.rho)) for b in bins)), x,
                                     np.asarray(n_design, float), cone))
    # a sensor with measured responses: each band's whole curve behind the band-pass
    truth = target_model(bins, sensor, lens, spectrum=spectrum, profile=profile,
                         n_eff_design=n_design, max_shift_rel=reach)
    y = np.asarray(truth.design(x, n_design).sum(axis=1)).ravel()
    sigma_px = noise * (1.0 if absolute_noise else float(np.max(np.abs(y))))
    for b in bins:
        b.mean[:] = 0.0
    model = target_model(bins, sensor, lens, spectrum=spectrum if spectrum_known else None,
                         profile=profile, n_eff_design=n_design, max_shift_rel=reach)
    if model.prior_sd is not None:  # the fit's prior, for the signal the target gives
        model.prior_mean = float(np.median(y))
        model.prior_sd = PRIOR_SD * float(np.max(np.abs(y)))
    count = np.empty(model.n_rows)
    for j, k, rows, ok in model.blocks:
        count[rows] = bins[j].count[k, ok]
    model.sigma = sigma_px / np.sqrt(count)
    A = model.design(x, n_design)
    s_true, _ = _pinv_solve(A, y)  # the noise-free means as the model has them
    # the fit's derivatives: the index's analytic, x's a central difference of the model
    dx, dn = _prediction_derivatives(model, x, np.asarray(n_design, float), A, s_true,
                                     central=True)
    n_rows = np.broadcast_to(np.asarray(n_design, float), model.cwl.shape)[_row_bands(model)]
    J = np.column_stack([dx] + ([dn * n_rows] if fit_n_eff else []))
    Jp = _project_off(_whiten(model, A), J)
    F = Jp.T @ Jp
    if not np.all(np.isfinite(F)) or np.linalg.cond(F) > 1e14 or F[0, 0] <= 0:
        return Precision(math.inf, math.inf if fit_n_eff else None, spectrum_known, noise, x)
    cov = np.linalg.inv(F)
    n_err = float(math.sqrt(cov[1, 1]) * np.mean(n_design)) if fit_n_eff else None
    return Precision(float(math.sqrt(cov[0, 0])), n_err, spectrum_known, noise, x)


#: A band responds where its response (through the system) is above this fraction of its
#: peak: the wavelengths a target's spectrum must be known over to predict what it can pin.
RESPONDS_FRACTION = 1e-3


def _responding_range_nm(sensor):
    """The wavelengths where any of the sensor's bands responds: its measured responses above
    :data:`RESPONDS_FRACTION` of their peaks, or modelled filters to 2.5 FWHM each side of their
    centres (a Gaussian's 3e-8 there; wider than a measured curve's cut, as a modelled profile
    may have wings)."""
    if sensor.responses is not None:
        eff = sensor.responses.effective
        on = np.any(eff > RESPONDS_FRACTION * eff.max(axis=1, keepdims=True), axis=0)
        grid = sensor.responses.wavelength_nm[on]
        if grid.size == 0:  # responses checked at load are positive somewhere: a guard only
            raise ValueError(f"the sensor {sensor.name!r} responds nowhere on its grid")
        return float(grid.min()), float(grid.max())
    cwl, fwhm = (np.asarray(v, float) for v in (sensor.cwl_nm, sensor.fwhm_nm))
    return float(np.min(cwl - 2.5 * fwhm)), float(np.max(cwl + 2.5 * fwhm))


class OutsideChartError(ValueError):
    """The sensor's bands respond where the colour chart's published spectra say nothing
    (:func:`colour_chart_precision`)."""


def _held(spectrum):
    """``spectrum`` (a :class:`~snapcorr.spectra.Spectrum`) as ``S(lambda)`` held at its end
    values outside its range, where no band responds (:func:`_beyond_the_chart`)."""
    return lambda lam: np.interp(lam, spectrum.wavelength_nm, spectrum.values)


def _corner_scale(sensor, lens, f_numbers, size, n_design):
    """The smallest ``s`` (a filter's curve at ``T0(lambda / s)``) on the field: the ray to
    the corner from the rim of the fastest f-number's pupil farthest from it, at the smallest
    design index; and the corner's CRA, degrees."""
    rows, cols = size
    r = 0.5 * math.hypot(rows - 1, cols - 1) * sensor.pixel_pitch_mm
    cra = math.atan(r / float(lens.exit_pupil_mm))
    # the ray from the pupil's rim farthest from the corner: tan(phi) = tan(cra) + tan(cone)
    phi = math.atan(math.tan(cra) + math.tan(math.radians(float(lens.cone_angle_deg(
        min(f_numbers))))))
    n = float(np.min(n_design))
    return math.sqrt(max(1 - math.sin(phi) ** 2 / n**2, 0.0)), math.degrees(cra)


def _beyond_the_chart(sensor, scale=1.0, where=""):
    """Why the colour chart's published spectra cannot judge ``sensor`` (its bands respond
    outside them), or None. ``scale``: the smallest shift factor on the field, which moves
    the responding range's blue end to ``scale`` times itself (``where`` says where)."""
    from ...spectra import colour_checker

    lo, hi = _responding_range_nm(sensor)
    lo_field = lo * scale
    grid = colour_checker(1).wavelength_nm
    w0, w1 = float(grid[0]), float(grid[-1])
    if lo_field < w0 or hi > w1:
        shifted = (f" ({lo_field:.0f} nm {where})" if lo_field < w0 <= lo else "")
        return (f"the ColorChecker's published spectra cover {w0:g}-{w1:g} nm and the sensor "
                f"{sensor.name!r} responds over {lo:.0f}-{hi:.0f} nm{shifted}: what its "
                "patches can pin there is not known (use a target whose spectrum covers the "
                "bands)")
    return None


def colour_chart_precision(sensor, f_numbers, lens: Lens, *, noise=0.01, fit_n_eff=False,
                           spectrum_known=False, size_px=None, n_bins=64,
                           absolute_noise=False, on_patch=None):
    """What each patch of a ColorChecker Classic can pin: :func:`pupil_precision` for its 24
    published reflectances (:func:`snapcorr.spectra.colour_checker`), the best first.

    A chart is a target many users have. Its patches are smooth, but a few have edges where a
    shift shows: on the imec 4 x 4 VIS responses behind the paper's lens (f/1.4 + f/8, 1 %
    noise, ``n_eff`` fitted) "red" gives ``x`` to 0.006 mm, better than a rare-earth glass's
    0.022 mm, and the grey patches nothing worth having (0.2-1.9 mm).

    Parameters
    ----------
    sensor, f_numbers, lens, noise, fit_n_eff, spectrum_known, size_px, n_bins, absolute_noise
        As for :func:`pupil_precision`.
    on_patch : callable, optional
        Called with each patch's name before its bound is computed (a progress bar).

    Returns
    -------
    list of (str, Precision)
        Every patch with its predicted errors, the smallest ``x_stderr_mm`` first.

    Raises
    ------
    OutsideChartError
        A ``ValueError``, where the sensor's bands respond outside 380-780 nm, the range of
        the published spectra (a near-infrared sensor), or reach below it shifted at the
        sensor's corner (the chief ray there and the fastest f-number's cone): what a patch
        does there is not known.
    """
    from ...spectra import COLOUR_CHECKER_PATCHES, colour_checker

    size, fs, _ = _checked_arguments(sensor, f_numbers, lens, size_px, n_bins)  # before 24
    n_design = check_modelled(sensor, "the exit pupil's precision (snapcorr pupil --predict)",
                              fit_n_eff=fit_n_eff)  # patches' work
    scale, cra = _corner_scale(sensor, lens, fs, size, n_design)
    beyond = _beyond_the_chart(sensor, scale, f"at the sensor's corner: its chief ray at "
                                              f"{cra:.1f} deg and the f/{min(fs):g} cone")
    if beyond is not None:
        raise OutsideChartError(beyond)
    spectra = [colour_checker(p) for p in COLOUR_CHECKER_PATCHES]

    out = []
    for name, sp in zip(COLOUR_CHECKER_PATCHES, spectra, strict=True):
        if on_patch is not None:
            on_patch(name)
        out.append((name, pupil_precision(_held(sp), sensor, f_numbers, lens, noise=noise,
                                          fit_n_eff=fit_n_eff, spectrum_known=spectrum_known,
                                          size_px=size_px, n_bins=n_bins,
                                          absolute_noise=absolute_noise)))
    return sorted(out, key=lambda item: item[1].x_stderr_mm)


# -- the precision of the cubes given, before the fit -----------------------------------------
#: The shift precision (nm, one standard deviation, the chief ray at the sensor's corner in
#: the longest band) a target must be able to give x and n_eff to, by default (the command
#: line's ``--tolerance-nm``): five times the lens calibration's own precision from flats
#: (~0.01 nm). On the 128 x 160 binned field of
#: ``tests/calibrate/pupil/test_locate_coverage.py`` at 1 % noise, f/1.4 + f/8, a rare-earth
#: glass gives 0.009 nm and a straight-line reflectance 0.17 nm.
DEFAULT_TOLERANCE_NM = 0.05


@dataclass(frozen=True)
class TargetPrecision:
    """What the cubes of a target can give, from the model's Fisher information at the
    search's start (:func:`target_precision`).

    ``shift_stderr_nm``: the standard error of the chief ray's shift at ``edge_mm`` from the
    axis for the longest band (``cwl_nm``), from the covariance of ``x`` and ``n_eff``.
    """

    x_mm: float
    x_stderr_mm: float
    n_eff: float
    n_eff_stderr: float | None
    shift_stderr_nm: float
    edge_mm: float
    cwl_nm: float
    n_eff_band_stderr: np.ndarray | None = None
    """With the index fitted: each band's own index's standard error, all fitted at once."""

    def summary(self) -> str:
        def rel(v, of, unit=""):
            return (f"{v:.2g}{unit} ({100 * v / of:.2g} %)" if math.isfinite(v)
                    else "(no information)")

        n = ("" if self.n_eff_stderr is None else
             f", n_eff +- {rel(self.n_eff_stderr, self.n_eff)}")
        band = self.n_eff_band_stderr
        if band is not None:
            lo, hi = (100 * float(v) / self.n_eff for v in (np.min(band), np.max(band)))
            pinned = int(np.sum(band < N_EFF_BAND_STDERR * self.n_eff))
            own = int(np.sum(band < N_EFF_REL_STDERR * self.n_eff))
            n += (f" (one per band: {lo:.2g}-{hi:.2g} %; where the data ask for it, {pinned} of "
                  f"{band.size} bands pinned to {100 * N_EFF_BAND_STDERR:g} %"
                  + (f", {own - pinned} more known to {100 * N_EFF_REL_STDERR:g} %"
                     if own > pinned else "")
                  + (f"; the {band.size - own} above {100 * N_EFF_REL_STDERR:g} %: one for "
                     "the sensor)" if own < band.size else ")"))
        return (f"predicted: this target can give x +- {rel(self.x_stderr_mm, self.x_mm, ' mm')}"
                f"{n}; the "
                f"shift at {self.edge_mm:.3g} mm from the axis ({self.cwl_nm:.4g} nm) to +- "
                f"{self.shift_stderr_nm:.2g} nm (Fisher information at x = {self.x_mm:.4g} mm, "
                "the noise measured in the cubes)")


def _edge_shift_nm(x, n, d, cwl):
    sin2 = d * d / (d * d + x * x)
    return cwl * (1.0 - math.sqrt(max(1.0 - sin2 / (n * n), 1e-12)))


def _edge_shift_gradient(x, n, d, cwl):
    """The derivatives of :func:`_edge_shift_nm` in ``x`` and in the index's scale (``n``
    times its derivative in ``n``)."""
    sin2 = d * d / (d * d + x * x)
    root = math.sqrt(max(1.0 - sin2 / (n * n), 1e-12))
    dsin2 = -2.0 * x * d * d / (d * d + x * x) ** 2
    return np.array([cwl * dsin2 / (2.0 * n * n * root), -cwl * sin2 / (n * n * root)])


def target_precision(problem, x, fit_k, edge_mm, cwl_nm):
    """:class:`TargetPrecision` of the cubes in ``problem`` (a ``_Problem``) at trial ``x``.

    The Jacobian of the profiled residuals in ``x`` and every band's index (variable
    projection in Kaufman's form, as the fit's steps take it: the index's derivative analytic,
    ``x``'s a central difference of the model at fixed target coefficients,
    :func:`~snapcorr.calibrate.pupil.index._per_band_jacobian`); with ``fit_k`` the index's
    common scale is the bands' columns summed, weighted by their indices. Its information
    matrix, with the noise the annuli show, inverted.
    """
    from .index import _per_band_jacobian

    nd = problem.n_design
    _, Jp = _per_band_jacobian(problem.model, x, nd, central=True)
    J = np.column_stack([Jp[:, 0], Jp[:, 1:] @ nd]) if fit_k else Jp[:, :1]
    F = J.T @ J
    n = float(np.mean(nd))
    inf = TargetPrecision(x, math.inf, n, math.inf if fit_k else None, math.inf, edge_mm,
                          cwl_nm)
    if not np.all(np.isfinite(F)) or F[0, 0] <= 0 or np.linalg.cond(F) > 1e14:
        return inf
    cov = np.linalg.inv(F)
    if np.any(np.diag(cov) <= 0):
        return inf
    g = _edge_shift_gradient(x, n, edge_mm, cwl_nm)[:J.shape[1]]
    shift_err = float(math.sqrt(max(g @ cov @ g, 0.0)))
    band = None
    if fit_k and nd.size >= 2:
        with np.errstate(all="ignore"):
            Fb = Jp.T @ Jp
            band = (np.sqrt(np.clip(np.diag(np.linalg.pinv(Fb)), 0, None))[1:]
                    if np.all(np.isfinite(Fb)) else np.full(nd.size, np.inf))
    return TargetPrecision(x, float(math.sqrt(cov[0, 0])), n,
                           float(math.sqrt(cov[1, 1]) * n) if fit_k else None, shift_err,
                           edge_mm, cwl_nm, band)


#: A fit's own error of x below this share of the one predicted before it, at a start within
#: :data:`BOUND_NEAR_REL` of the x fitted, is not believed: the model is not smooth where the
#: fit ended (three vignetting circles, 0.5 % noise: one seed of six reported 0.0059 mm,
#: where the prediction and the other five gave 0.045-0.047, and was 8 of it off).
BOUND_SHARE = 0.5
BOUND_NEAR_REL = 0.05


def errors_not_below_the_prediction(x, x_err, n_err, xn_err, pred, notes, cov=None):
    """x's, n_eff's and ``x n_eff``'s errors raised to the prediction made before the fit
    (``pred``, a :class:`TargetPrecision`) where x's falls below :data:`BOUND_SHARE` of it;
    said in ``notes``. With ``cov`` (the fit's, of x and the index's scale) also that,
    raised alike (:func:`raised_covariance`), as a fourth value."""
    if (pred is None or not math.isfinite(pred.x_stderr_mm)
            or abs(pred.x_mm - x) > BOUND_NEAR_REL * x
            or not x_err < BOUND_SHARE * pred.x_stderr_mm):
        return (x_err, n_err, xn_err) if cov is None else (x_err, n_err, xn_err, cov)
    fit_n_err = n_err
    notes.append(f"x's error from the fit ({x_err:.2g} mm) is below half of what these cubes "
                 f"can give by the prediction before it ({pred.x_stderr_mm:.2g} mm at x = "
                 f"{pred.x_mm:.4g} mm): the model is not smooth where the fit ended (a "
                 "vignetting onset at an annulus's edge), so the prediction's errors are "
                 "reported")
    if n_err is not None and pred.n_eff_stderr is not None:
        n_err = np.maximum(n_err, pred.n_eff_stderr)
    if x_err > 0:
        xn_err = xn_err * pred.x_stderr_mm / x_err
    out = (pred.x_stderr_mm, n_err, xn_err)
    if cov is None:
        return out
    return (*out, raised_covariance(cov, pred.x_stderr_mm, x_err, n_err, fit_n_err))


def raised_covariance(cov, x_err, x_fit_err, n_err, n_fit_err):
    """The fit's covariance of (x, the index's scale) with each row and column scaled as
    :func:`errors_not_below_the_prediction` raised that parameter's error (x's alone where
    the covariance is x's only), so what reads it (``calibrate_with_target``'s propagation)
    agrees with the errors reported."""
    f = [x_err / x_fit_err if x_fit_err > 0 else 1.0]
    if np.shape(cov)[0] > 1:
        f.append(float(np.mean(n_err) / np.mean(n_fit_err))
                 if n_err is not None and np.mean(n_fit_err) > 0 else 1.0)
    f += [1.0] * (np.shape(cov)[0] - len(f))
    d = np.asarray(f)
    return np.asarray(cov) * np.outer(d, d)


def edge_mm(sensor, center_rc, r_max):
    """The distance from the axis (at ``center_rc``, ``(row, col)``) the prediction speaks of:
    the sensor's farthest corner (the field the lens profile serves), or the cubes' field
    without a sensor size."""
    if sensor.size_px is None:
        return r_max
    rows, cols = sensor.size_px
    row, col = center_rc
    far = max(math.hypot(r - row, c - col) for r in (-0.5, rows - 0.5)
              for c in (-0.5, cols - 0.5))
    return max(far * sensor.pixel_pitch_mm, r_max)


def precision_check(problem, fit_k, edge_mm, cwl_nm, tolerance_nm, report, keep):
    """``before(x0)`` for the search: the precision predicted at ``x0`` (kept in ``keep``),
    reported, and a target that cannot reach ``tolerance_nm`` refused."""
    if tolerance_nm is not None and not (math.isfinite(tolerance_nm) and tolerance_nm > 0):
        raise ValueError(f"tolerance_nm must be > 0 nm, got {tolerance_nm!r}")

    def before(x0):
        pred = target_precision(problem, float(x0), fit_k, edge_mm, cwl_nm)
        keep.append(pred)
        if report is not None:
            report(pred.summary())
        if tolerance_nm is not None and not pred.shift_stderr_nm <= tolerance_nm:
            what = "x and n_eff" if fit_k else "x"
            raise ImpreciseTargetError(
                f"the target cannot pin {what} to the shift precision asked: the shift at "
                f"{edge_mm:.3g} mm from the axis ({cwl_nm:.4g} nm) to +- "
                f"{pred.shift_stderr_nm:.2g} nm at best, above the tolerance of "
                f"{tolerance_nm:g} nm (x +- {pred.x_stderr_mm:.2g} mm, predicted from the "
                "target's features and the cubes' noise): use a target with narrow features "
                "inside the bands (a rare-earth glass, a line lamp), less noise (average "
                "frames), or a looser tolerance")

    return before


def x_times_n_eff(x, n, err, cov, k, n_design, one_k):
    """The product ``x * mean(n_eff)`` and its standard error (``cov`` scaled)."""
    xn = x * float(np.mean(n))
    if one_k:
        g = np.array([k, x]) * float(np.mean(n_design))
        xn_err = float(np.sqrt(max(g @ cov @ g, 0.0)))
    else:
        xn_err = float(err[0]) * float(np.mean(n))
    return xn, xn_err
