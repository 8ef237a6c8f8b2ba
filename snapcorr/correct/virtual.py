"""Virtual bands of a mosaic cube: the vendor's matrix, a fitted one, or one for each pixel's
angle behind the lens.

A snapshot-mosaic sensor's bands overlap and leak (second orders, side lobes); the vendor's
correction matrix turns them into "virtual bands" with the crosstalk removed, computed for
light at normal incidence. Behind a lens each pixel's responses shift and widen with its
chief-ray angle and the f-number, so one matrix is right on the axis only.

* ``"vendor"``: the file's matrix, applied as it is. For flat-fielded values its reflectance
  matrix; where the file has only an irradiance matrix (the older format), that matrix with
  the white folded in: ``A_vb = M_vb w_b / sum_b' M_vb' w_b'``, ``w_b`` the band's signal from
  a white under equal-energy light (so a flat spectrum stays flat), which is what the vendor's
  matrix gives for ``(raw - dark) / (white - dark)`` when the white was lit so.
* ``"fitted"``: the Wiener estimate (:mod:`snapcorr.optics.wiener`) from the measured responses
  at normal incidence onto Gaussian virtual bands.
* ``"angle-aware"``: the same, recomputed for each pixel's responses behind the lens (chief-ray
  angle, f-number, vignetting circles), tabulated over the chief-ray angle and interpolated per
  pixel (:class:`~snapcorr.optics.wiener.VirtualTable`).

The result is ``virtual(y, x, virtual_band)`` with ``virtual_wavelength`` and ``virtual_fwhm``
(nm); the matrix (or the table of matrices) used is kept next to it.

**A demosaicked cube** (from :func:`~snapcorr.cube.demosaic`, which records its method)
carries demosaicking errors that differ from band to band, many times the pixel noise on a
textured scene, and every matrix passes them on. Each band's error is measured on the cube
by cross-validation at the band's own samples (:func:`~snapcorr.cube.demosaicking_error`)
and enters ``virtual_stderr`` through the matrix (``A diag(err^2) A^T``). The vendor's matrix,
which inverts the bands' overlap and so amplifies them, is applied to the bands' Wiener
estimate from their demosaicked values (``A S (S + alpha I)^-1``), its best linear estimate
on the true bands. The fitted and angle-aware estimates keep the regularisation chosen by
generalised cross-validation: they already weigh the errors down, and a regularisation that
took the demosaicking errors as independent between bands (they are correlated, through the
pseudo-panchromatic guide every band shares) smoothed the spectra far more than they need.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import NamedTuple

import numba
import numpy as np
import xarray as xr

from .._threads import one_blas_thread
from .._validation import validate_method
from ..cube import responses as _responses
from ..cube.flatfield import cf_attrs

__all__ = ["VIRTUAL_METHODS", "VirtualBandOptions", "apply_virtual", "check_virtual_options",
           "virtual_bands", "virtual_targets"]

VIRTUAL_METHODS = ("vendor", "fitted", "angle-aware")
#: Most pixels the regularisation is chosen from and the error bars averaged over.
GCV_PIXELS = 4096
#: Interpolation tolerance of the angle-aware table (reflectance units): a tenth of the
#: estimates' own error on real sensors.
VIRTUAL_TOLERANCE = 5e-4
#: Chief-ray-angle nodes spanning the field, among which pixels are grouped to choose the
#: regularisation and at which the expected errors are evaluated.
GCV_NODES = 5


class VirtualBandOptions(NamedTuple):
    """The virtual bands asked for (:func:`~snapcorr.correct.virtual_bands`): ``method``
    (None: none), the vendor ``matrix``'s name, the fitted bands' ``wavelengths_nm`` and
    ``fwhm_nm``."""

    method: str | None = None
    matrix: str | None = None
    wavelengths_nm: object = None
    fwhm_nm: object = None

    def keywords(self):
        """As :func:`~snapcorr.correct.correct_cube` takes them."""
        return {"virtual_bands": self.method, "virtual_matrix": self.matrix,
                "virtual_wavelengths_nm": self.wavelengths_nm,
                "virtual_fwhm_nm": self.fwhm_nm}



def _is_reflectance(cube):
    """Flat-fielded values (a ratio to a white) rather than counts or radiance."""
    return (cube.name in ("reflectance", "transmittance")
            or str(cube.attrs.get("units", "")).strip() == "1")


def _vendor(sensor, name, reflectance):
    """The vendor matrix to apply, and what it is."""
    if not sensor.matrices:
        raise ValueError(f"the sensor {sensor.name!r} has no correction matrix (vendor "
                         "calibration files carry them); use virtual_bands='fitted'")
    names = [m.name for m in sensor.matrices]
    if name is not None:
        if name not in names:
            raise ValueError(f"the sensor {sensor.name!r} has no correction matrix named "
                             f"{name!r}; it has {names}")
        chosen = sensor.matrices[names.index(name)]
    else:
        want = "reflectance" if reflectance else "irradiance"
        chosen = next((m for m in sensor.matrices if m.kind == want), sensor.matrices[0])
    A = np.array(chosen.coefficients)
    how = f"the vendor's matrix {chosen.name!r} ({chosen.kind})"
    if reflectance and chosen.kind == "irradiance":
        if sensor.responses is None:
            raise ValueError(f"matrix {chosen.name!r} is for irradiance; the cube is "
                             "flat-fielded and the sensor has no responses to fold a white in")
        from ..optics.wiener import trapezoid_weights

        white = sensor.responses.effective @ trapezoid_weights(sensor.responses.wavelength_nm)
        A = A * white / (A @ white)[:, None]
        how += (", its rows weighed by each band's signal from a white under equal-energy "
                "light and normalised, for flat-fielded values")
    elif not reflectance and chosen.kind == "reflectance":
        raise ValueError(f"matrix {chosen.name!r} is for flat-fielded values, and the cube "
                         "holds counts or radiance: flat-field it first (snapcorr flatfield)")
    return chosen, A, how


#: The narrowest virtual band, in steps of the responses' grid: kept with the responses
#: (:data:`snapcorr.cube.responses.MIN_FWHM_STEPS`), whose vendor files state widths too.
MIN_FWHM_STEPS = _responses.MIN_FWHM_STEPS


def virtual_targets(sensor, wavelengths_nm=None, fwhm_nm=None):
    """The virtual bands' centres and widths, checked: given, else the vendor's, else the
    bands'.

    Parameters
    ----------
    sensor : Sensor
        With measured responses.
    wavelengths_nm : array_like, optional
        The virtual bands' centres, nm: distinct, within the responses' grid.
    fwhm_nm : float or array_like, optional
        Their FWHM, nm: at least :data:`MIN_FWHM_STEPS` steps of the responses' grid.

    Returns
    -------
    wavelength_nm, fwhm_nm : ndarray
    """
    from .._validation import check_positive_array, check_wavelengths_nm

    if wavelengths_nm is not None:
        wl = check_wavelengths_nm("virtual_wavelengths_nm", np.atleast_1d(wavelengths_nm))
        if wl.ndim != 1:
            raise ValueError(f"virtual_wavelengths_nm must be a list of wavelengths, got "
                             f"shape {wl.shape}")
    elif sensor.matrices:
        wl = np.array(sensor.matrices[0].wavelength_nm)
    else:
        wl = np.sort(np.asarray(sensor.cwl_nm, float))
    if fwhm_nm is not None:
        fw = np.broadcast_to(check_positive_array("virtual_fwhm_nm", np.asarray(fwhm_nm,
                                                                                float), "nm"),
                             wl.shape).copy()
    elif (wavelengths_nm is None and sensor.matrices
          and np.all(np.isfinite(sensor.matrices[0].fwhm_nm))):
        fw = np.array(sensor.matrices[0].fwhm_nm)
    else:
        order = np.argsort(sensor.cwl_nm)
        fw = np.interp(wl, np.asarray(sensor.cwl_nm)[order], np.asarray(sensor.fwhm_nm)[order])
    if sensor.responses is not None:
        grid = sensor.responses.wavelength_nm
        if wl.size > grid.size:  # before anything is sized by the count
            raise ValueError(f"virtual_wavelengths_nm gives {wl.size:,} bands, more than the "
                             f"{grid.size:,} samples of the responses' grid ({grid[0]:g}-"
                             f"{grid[-1]:g} nm): bands closer than its step say nothing it "
                             f"does not; ask for at most {grid.size:,}")
        step = np.interp(wl, grid[1:], np.diff(grid))
        narrow = np.flatnonzero(fw < MIN_FWHM_STEPS * step)
        if narrow.size:
            b = narrow[0]
            raise ValueError(f"virtual_fwhm_nm {fw[b]:g} nm at {wl[b]:g} nm is narrower than "
                             f"the responses' grid resolves ({MIN_FWHM_STEPS:g} of its "
                             f"{step[b]:g} nm steps); ask for at least "
                             f"{MIN_FWHM_STEPS * step.max():g} nm")
        out = _responses.reaching_beyond(wl, fw, grid)
        if out.size:
            b = out[0]
            vendor = "the vendor file's correction matrix"
            if not grid[0] <= wl[b] <= grid[-1]:  # the centre itself is outside
                blame = ("virtual_wavelengths_nm must lie inside it" if wavelengths_nm
                         is not None else f"the band comes from {vendor}; give "
                         "virtual_wavelengths_nm inside the grid")
            elif fwhm_nm is not None:  # the width reaches beyond
                blame = "virtual_fwhm_nm must be narrower there"
            else:
                source = (vendor if wavelengths_nm is None and sensor.matrices
                          else "the sensor's bands")
                blame = f"its width comes from {source}; give a narrower virtual_fwhm_nm"
            raise ValueError(f"the virtual band at {wl[b]:g} nm (FWHM {fw[b]:g} nm) reaches "
                             f"beyond the responses' grid ({grid[0]:g}-{grid[-1]:g} nm) within "
                             f"{_responses.VIRTUAL_REACH_FWHM:g} FWHM: {blame}")
    return wl, fw


#: Rows of the cube read to choose the regularisation and measure the noise: evenly spread
#: over the field, whole (neighbours along a row give the noise); a few row blocks of a
#: chunked cube are read, never the whole cube.
SAMPLE_ROWS = 16


def _sample(cube, cra=None):
    """Band values of whole rows spread over the cube (up to SAMPLE_ROWS; a one-column cube's
    first GCV_PIXELS rows, taken as one row), with their chief-ray angles: ``(rows, nx,
    n_bands)`` and ``(rows, nx)`` (None without angles)."""
    ny, nx = cube.sizes["y"], cube.sizes["x"]
    if nx == 1:
        rows = np.arange(min(ny, GCV_PIXELS))
        values = np.asarray(cube.isel(y=rows).values, float).transpose(1, 0, 2)
        return values, (None if cra is None else np.asarray(cra)[rows, :1].T)
    rows = np.unique(np.linspace(0, ny - 1, min(ny, SAMPLE_ROWS)).round().astype(int))
    values = np.asarray(cube.isel(y=rows).values, float)
    return values, (None if cra is None else np.asarray(cra)[rows])


def _pixels(sample):
    """Up to GCV_PIXELS of the sampled pixels, evenly strided: ``(n, n_bands)`` and their
    angles ``(n,)`` (None without)."""
    values, angles = sample
    flat = values.reshape(-1, values.shape[-1])
    step = max(1, int(np.ceil(flat.shape[0] / GCV_PIXELS)))
    return flat[::step], (None if angles is None else angles.reshape(-1)[::step])


#: The kernel's floating-point licence: sums reassociated (so the band sums vectorise) and
#: multiply-adds fused, but NaN and infinities kept (a NaN band value gives a NaN pixel).
_FASTMATH = {"reassoc", "contract", "nsz", "arcp"}


@numba.njit(parallel=True, cache=True, fastmath=_FASTMATH)
def _apply_table(data, cra, nodes, mats, out):  # pragma: no cover - compiled
    # mats[node, virtual, band]: each virtual band a sum over the bands, contiguous, of both
    # nodes' matrices at once; the interpolation after the sums (the matrices are linear)
    ny, nx, nb = data.shape
    m, nv = nodes.size, mats.shape[1]
    zero, one = data.dtype.type(0), data.dtype.type(1)
    for y in numba.prange(ny):
        for x in range(nx):
            c = cra[y, x]
            lo, hi = 0, m - 1  # the node interval holding c (clamped at the ends)
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if nodes[mid] <= c:
                    lo = mid
                else:
                    hi = mid
            t = zero if hi == lo else min(max((c - nodes[lo]) / (nodes[hi] - nodes[lo]),
                                              zero), one)
            for v in range(nv):
                a0 = zero
                a1 = zero
                for b in range(nb):
                    d = data[y, x, b]
                    a0 += mats[lo, v, b] * d
                    a1 += mats[hi, v, b] * d
                out[y, x, v] = a0 + t * (a1 - a0)


def apply_table(data, cra_deg, table, dtype=np.float32):
    """``virtual[y, x] = A(cra[y, x]) @ data[y, x]`` with the table's matrices interpolated
    linearly in the chief-ray angle (clamped at its ends): one compiled pass.

    Parameters
    ----------
    data : ndarray, shape (ny, nx, n_bands)
    cra_deg : ndarray, shape (ny, nx)
    table : VirtualTable
    dtype : numpy dtype
        Of the result and of the arithmetic.

    Returns
    -------
    ndarray, shape (ny, nx, n_virtual)
    """
    mats = np.ascontiguousarray(table.matrices, dtype)
    out = np.empty((*data.shape[:2], mats.shape[1]), dtype)
    _apply_table(np.ascontiguousarray(data, dtype), np.ascontiguousarray(cra_deg, dtype),
                 np.ascontiguousarray(table.cra_deg, dtype), mats, out)
    return out


def _dtype(cube):
    return np.float64 if cube.dtype == np.float64 else np.float32


def _apply(cube, A=None, table=None, cra=None):
    """``virtual = A @ bands`` for every pixel, or the table's matrix at each pixel's angle,
    block by block."""
    dtype = _dtype(cube)
    nv = A.shape[0] if A is not None else table.matrices.shape[1]
    if A is not None:
        mat = A.T.astype(dtype)

        def block(data):
            return np.asarray(data, dtype) @ mat

        args, dims = [cube], [["band"]]
    else:
        def block(data, c):
            return apply_table(data, c, table, dtype)

        c = xr.DataArray(cra, dims=("y", "x"))
        if cube.chunks is not None:
            c = c.chunk({"y": cube.chunks[0], "x": cube.chunks[1]})
        args, dims = [cube, c], [["band"], []]
    data = cube.chunk({"band": -1}) if cube.chunks is not None else cube
    args[0] = data
    return xr.apply_ufunc(block, *args, input_core_dims=dims,
                          output_core_dims=[["virtual_band"]], dask="parallelized",
                          output_dtypes=[dtype],
                          dask_gufunc_kwargs={"output_sizes": {"virtual_band": nv}})


def apply_virtual(cube, ds, cra_deg=None):
    """A cube's virtual bands by the matrix (or angle-aware table) of an earlier result.

    Parameters
    ----------
    cube : xarray.DataArray
        ``(y, x, band)``, of the sensor and geometry ``ds`` was made for.
    ds : xarray.Dataset
        A result of :func:`virtual_bands` (``virtual_matrix``, or ``virtual_table`` on
        ``virtual_cra_deg``).
    cra_deg : ndarray, shape (y, x), optional
        Each pixel's chief-ray angle, for a table.

    Returns
    -------
    xarray.DataArray
        ``virtual`` with dims ``(y, x, virtual_band)``.
    """
    if "virtual_matrix" in ds:
        return _apply(cube, A=np.asarray(ds["virtual_matrix"].values))
    table = SimpleNamespace(matrices=np.asarray(ds["virtual_table"].values),
                            cra_deg=np.asarray(ds["virtual_cra_deg"].values))
    return _apply(cube, table=table, cra=cra_deg)


def check_virtual_options(method, matrix=None, wavelengths_nm=None, fwhm_nm=None):
    """Refuse options the virtual-band ``method`` does not use, before any work: given where
    they mean nothing, they were ignored without a word.

    Parameters
    ----------
    method : {None, "vendor", "fitted", "angle-aware"}
        The method asked for (None: no virtual bands, and so none of the options).
    matrix : str, optional
        The vendor matrix's name: with ``"vendor"`` only (the other methods fit their own).
    wavelengths_nm, fwhm_nm : array_like or float, optional
        The virtual bands' centres and width: with ``"fitted"`` and ``"angle-aware"`` only
        (the vendor's matrix has its own bands).

    Raises
    ------
    ValueError
        An option the method does not use, named as ``correct_cube`` takes it.
    """
    given = [n for n, v in (("virtual_matrix=", matrix),
                            ("virtual_wavelengths_nm=", wavelengths_nm),
                            ("virtual_fwhm_nm=", fwhm_nm)) if v is not None]
    if method is None and given:
        raise ValueError(f"{given[0]} goes with virtual_bands=; give the method too")
    own = [n for n in given if n != "virtual_matrix="]
    if method == "vendor" and own:
        raise ValueError(f"{own[0]} goes with virtual_bands='fitted' or 'angle-aware': the "
                         "vendor's matrix has its own bands")
    if method in ("fitted", "angle-aware") and matrix is not None:
        raise ValueError(f"virtual_matrix= goes with virtual_bands='vendor': the {method} "
                         "method fits its own matrix")


def virtual_bands(cube, sensor, method, *, f_number=None, lens=None, cra_deg=None,
                  matrix=None, wavelengths_nm=None, fwhm_nm=None, noise=None,
                  tolerance=VIRTUAL_TOLERANCE):
    """The cube's virtual bands by ``method`` (module docstring).

    Parameters
    ----------
    cube : xarray.DataArray
        ``(y, x, band)`` with the sensor's bands (tiles or full resolution); flat-fielded
        (a ratio to a white: named ``reflectance`` or with units "1") for every method, or
        counts for the vendor's irradiance matrix.
    sensor : Sensor
        With measured responses (``"fitted"``, ``"angle-aware"``) or correction matrices
        (``"vendor"``): a vendor calibration file.
    method : {"vendor", "fitted", "angle-aware"}
    f_number : float, optional
        The f-number (``"angle-aware"``).
    lens : Lens, optional
        The lens (``"angle-aware"``).
    cra_deg : ndarray, shape (y, x), optional
        Each pixel's chief-ray angle (``"angle-aware"``).
    matrix : str, optional
        The vendor matrix's name (default: the one for the cube's kind of values).
    wavelengths_nm, fwhm_nm : array_like, optional
        Centres and widths of the fitted virtual bands (default: the vendor's, else the
        bands' own).
    noise : float, optional
        The band values' noise (reflectance units); default: chosen by generalised
        cross-validation on the cube.
    tolerance : float
        Interpolation tolerance of the angle-aware table (reflectance units).

    Returns
    -------
    xarray.Dataset
        ``virtual(y, x, virtual_band)`` with coordinates ``virtual_wavelength`` and
        ``virtual_fwhm``; ``virtual_matrix(virtual_band, band)``, or for ``"angle-aware"``
        ``virtual_table(virtual_cra, virtual_band, band)`` on ``virtual_cra_deg``; and, for
        flat-fielded values, ``virtual_stderr(virtual_band)``: each virtual band's expected
        RMS error (the Wiener posterior under the prior, with the chosen band noise, or for a
        demosaicked cube each band's error with its demosaicking), the largest over the field
        when the lens is given.
    """
    method = validate_method(method, VIRTUAL_METHODS, "virtual_bands")
    check_virtual_options(method, matrix, wavelengths_nm, fwhm_nm)
    reflectance = _is_reflectance(cube)
    if method != "vendor":
        if sensor.responses is None:
            raise ValueError(f"virtual_bands={method!r} needs the bands' measured responses, "
                             f"and the sensor {sensor.name!r} has none: give the sensor of its "
                             "vendor calibration file (.xml) as sensor=")
        if not reflectance:
            raise ValueError(f"virtual_bands={method!r} estimates reflectance: flat-field "
                             "the cube first (snapcorr flatfield); the vendor's irradiance "
                             "matrix applies to counts (virtual_bands='vendor')")
    geometry = (f_number, lens, cra_deg)
    noise_model = sample = None
    if reflectance and sensor.responses is not None:  # the band noise, for every estimate
        from ..optics.wiener import markov_prior

        sample = _sample(cube, cra_deg)  # a few rows, read once
        noise_model = _fit_alpha(sample, sensor, markov_prior(sensor.responses.wavelength_nm),
                                 noise, geometry)
        noise_model = _with_demosaicking(cube, sensor, noise_model)
    if method == "vendor":
        chosen, A, how = _vendor(sensor, matrix, reflectance)
        if noise_model is not None and np.ndim(noise_model[1]) == 1:  # demosaicked
            A, how = _on_band_estimate(sensor, A, noise_model[0], how)
        wl, fw = np.array(chosen.wavelength_nm), np.array(chosen.fwhm_nm)
        ds = _dataset(cube, _apply(cube, A=A), {"virtual_matrix": A}, wl, fw, method,
                      f"{how}, from {sensor.vendor_file or sensor.name}")
        if noise_model is not None and np.all(np.isfinite(fw)):
            ds = _with_error(ds, sample, sensor, A, wl, fw, noise_model, geometry)
        return ds
    return _estimated(cube, sample, sensor, method, geometry, wavelengths_nm, fwhm_nm,
                      noise_model, tolerance)


def _field_weights(sensor, geometry):
    """The bands' averaging weights at a few chief-ray angles spanning the cube's field (at
    normal incidence when the lens is not given), and where."""
    from ..optics.measured import responses_behind_lens
    from ..optics.wiener import normalised

    grid = sensor.responses.wavelength_nm
    f_number, lens, cra = geometry
    if lens is None or f_number is None or cra is None or sensor.n_eff is None:
        return [normalised(grid, sensor.responses.effective)], "at normal incidence"
    nodes = np.linspace(float(np.nanmin(cra)), float(np.nanmax(cra)), GCV_NODES)
    R = responses_behind_lens(sensor.responses, sensor.n_eff, f_number, nodes, lens)
    return ([normalised(grid, R[k]) for k in range(nodes.size) if np.all(np.isfinite(R[k]))],
            f"over the field (CRA {nodes[0]:.1f}-{nodes[-1]:.1f} deg behind lens {lens.name} "
            f"at f/{float(f_number):g})")


def _with_error(ds, sample, sensor, A, wl, fw, noise_model, geometry, table=None):
    """``virtual_stderr``: each virtual band's expected RMS error, the largest over the
    field.

    The best linear estimate (the Wiener one for each pixel's own responses: the angle-aware
    table when the lens and n_eff are known, else the fitted matrix at normal incidence) has
    the expected error of the prior (:func:`~snapcorr.optics.wiener.expected_error`), and
    another linear estimate's error is uncorrelated with its difference from the best one, so
    ``err^2 = mean (A y - v_best)^2 + err_best^2``, the first term measured on the cube's own
    pixels: the vendor's or a normal-incidence matrix's misfit off the axis is counted, not
    assumed away.
    """
    from ..optics.wiener import (
        VirtualTable,
        expected_error,
        gaussian_targets,
        markov_prior,
        normalised,
        wiener_matrix,
    )

    grid = sensor.responses.wavelength_nm
    phi, g = markov_prior(grid), gaussian_targets(grid, wl, fw)
    alpha, noise_var, why = noise_model
    f_number, lens, cra = geometry
    values, angles = _pixels(sample)
    if table is None and all(v is not None for v in geometry) and sensor.n_eff is not None:
        with one_blas_thread():  # small matrices (module _threads)
            table = VirtualTable.build(sensor.responses, g, sensor.n_eff, f_number, lens,
                                       cra_max_deg=max(float(np.nanmax(cra)), 1e-6),
                                       alpha=alpha, prior=phi, tolerance=VIRTUAL_TOLERANCE,
                                       noise_var=noise_var)
    if table is not None:
        best = apply_table(values[:, None, :], angles[:, None], table, np.float64)[:, 0]
        best_err = np.stack([np.interp(angles, table.cra_deg, table.stderr[:, v])
                             for v in range(g.shape[0])], axis=1)
        where = (f"over the field (CRA {np.nanmin(angles):.1f}-{np.nanmax(angles):.1f} deg "
                 f"behind lens {lens.name} at f/{float(f_number):g})")
    else:
        s0 = normalised(grid, sensor.responses.effective)
        W = wiener_matrix(s0, g, phi, alpha)
        best = values @ W.T
        best_err = np.broadcast_to(expected_error(W, s0, g, phi, noise_var), best.shape)
        where, angles = "at normal incidence", np.zeros(values.shape[0])
    misfit = 0.0 if A is None else (values @ A.T - best) ** 2
    total = misfit + best_err**2
    ok = np.all(np.isfinite(total), axis=1)
    nodes = np.linspace(angles[ok].min(), angles[ok].max(), GCV_NODES) if ok.any() else [0.0]
    near = np.argmin(np.abs(angles[ok][:, None] - np.asarray(nodes)[None, :]), axis=1)
    err = np.sqrt(np.max([total[ok][near == k].mean(axis=0)
                          for k in range(len(nodes)) if np.any(near == k)], axis=0))
    ds["virtual_stderr"] = ("virtual_band", err, {
        "units": ds["virtual"].attrs["units"],
        "long_name": "expected RMS error of virtual, the largest over the field",
        "source": f"the Wiener estimate's expected error for spectra of the Markov prior "
                  f"{where}, band noise {_rms_text(noise_var)} ({why}), plus the mean square "
                  "difference of this estimate from it on the cube's pixels; on an independent "
                  "simulation (leaves and soils; a uniform target) the actual RMS errors were "
                  "0.75-1.03 of it"})
    return ds


def _rms_text(var):
    """A noise variance (one, or one per band) as its RMS, or the range of them."""
    v = np.sqrt(np.atleast_1d(np.asarray(var, float)))
    return f"{v[0]:.2g}" if np.all(v == v[0]) else f"{v.min():.2g}-{v.max():.2g}"


def _noise_var(values, sensor, phi, alpha):
    """The band values' noise variance, from neighbouring pixels: with ``H`` the Wiener
    smoother of band values (``alpha``), the residuals ``(I - H) y`` of two neighbours differ
    by ``(I - H)`` times their noise difference (the smooth part of any difference in their
    spectra is removed), so the median of ``|r_i - r_j|^2`` is that of ``2 sigma^2`` times a
    weighted chi-square of weights ``eig((I - H)^T (I - H))`` (Satterthwaite's approximation).
    ``values`` are whole rows ``(rows, nx, n_bands)`` (:func:`_sample`); neighbours along them.
    """
    from ..optics.wiener import normalised

    s = normalised(sensor.responses.wavelength_nm, sensor.responses.effective)
    gram = s @ phi @ s.T
    M = np.eye(gram.shape[0]) - np.linalg.solve(gram + alpha * np.eye(gram.shape[0]), gram).T
    r = values @ M.T
    d = np.sum((r[:, 1:] - r[:, :-1]) ** 2, axis=2).ravel()
    d = d[np.isfinite(d)]
    if d.size < 10:
        return alpha
    W = M.T @ M
    k = np.trace(W) ** 2 / np.trace(W @ W)  # effective degrees of freedom
    return float(np.median(d) / (2.0 * np.trace(W) * (1.0 - 2.0 / (9.0 * k)) ** 3))


def _fit_alpha(sample, sensor, phi, noise, geometry=(None, None, None)):
    """The regularisation and the band noise variance: both the square of ``noise`` when
    given, else the regularisation by generalised cross-validation on the cube's own values
    (which may take less than the noise where the prior misfits: it minimises the estimate's
    error) and the noise from neighbouring pixels (:func:`_noise_var`), for the error bars."""
    from ..optics.wiener import gcv_alpha

    if noise is not None:
        return float(noise) ** 2, float(noise) ** 2, f"the stated noise {float(noise):g}"
    values, angles = _pixels(sample)
    weights, _ = _field_weights(sensor, geometry)
    if len(weights) == 1:
        groups = [values]
    else:
        cra = geometry[2]
        nodes = np.linspace(float(np.nanmin(cra)), float(np.nanmax(cra)), len(weights))
        near = np.argmin(np.abs(angles[:, None] - nodes[None, :]), axis=1)
        groups = [values[near == k] for k in range(len(weights))]
    alpha, _ = gcv_alpha(weights, groups, phi)
    return alpha, _noise_var(sample[0], sensor, phi, alpha), (
        f"regularisation by generalised cross-validation on {sum(len(g) for g in groups)} of "
        "the cube's pixels, noise from neighbouring pixels")


def _with_demosaicking(cube, sensor, noise_model):
    """The band values' error in a demosaicked cube: each band's demosaicking error, measured
    on the cube by cross-validation at the band's own samples
    (:func:`~snapcorr.cube.demosaicking_error`; it holds their noise too), for the error bars.

    The matrices keep the regularisation generalised cross-validation chooses on the cube's
    own values. The demosaicking errors differ from band to band but are correlated between
    them (by about 0.5 on simulated textured frames: much of them is the pseudo-panchromatic
    guide's, shared by every band), and that correlation cannot be read from the frame (held-
    out samples at neighbouring pixels show half of it); a Wiener estimate that took them as
    independent noise smoothed the spectra far more than they need (an RMSE 3 x larger on
    the 5x5 NIR sensor). A cube not made by :func:`~snapcorr.cube.demosaic` keeps its noise
    model."""
    method = cube.attrs.get("demosaic_method")
    if method is None or sensor.layout != "mosaic" or "mosaic_area_px" not in cube.attrs:
        return noise_model
    from ..cube.demosaicking import demosaicking_error

    alpha, noise_var, why = noise_model
    dem, count = demosaicking_error(cube, sensor, noise_var=noise_var)
    band_var = np.maximum(dem, noise_var)
    return alpha, band_var, (
        f"{why}; each band's error with its demosaicking ({method}), RMS "
        f"{np.sqrt(band_var.min()):.2g}-{np.sqrt(band_var.max()):.2g}, from cross-validation "
        f"at {count} of the bands' own samples")


def _on_band_estimate(sensor, A, alpha, how):
    """The vendor's matrix for a demosaicked cube, applied to the bands' Wiener estimate from
    their demosaicked values: ``A S (S + alpha I)^-1``, ``S = s Phi s^T`` the bands' prior
    second moment (normal incidence, as the matrix's) and ``alpha`` the regularisation the
    fitted estimate takes (it is the fitted matrix with ``A`` for ``g Phi s^T S^-1``). The
    matrix is linear, so this is its best linear estimate on the bands the cube should hold;
    applied to the demosaicked values as they are, a matrix that inverts the bands' overlap
    amplifies their demosaicking errors, which differ from band to band."""
    from ..optics.wiener import markov_prior, normalised

    s0 = normalised(sensor.responses.wavelength_nm, sensor.responses.effective)
    S = s0 @ markov_prior(sensor.responses.wavelength_nm) @ s0.T
    smoother = np.linalg.solve(S + alpha * np.eye(S.shape[0]), S).T  # S (S + alpha I)^-1
    return A @ smoother, (f"{how}, applied to the bands' Wiener estimate from their "
                          f"demosaicked values (regularisation {alpha:.3g})")


def _estimated(cube, sample, sensor, method, geometry, wavelengths_nm, fwhm_nm, noise_model,
               tolerance):
    from ..optics.wiener import (
        PRIOR,
        VirtualTable,
        gaussian_targets,
        markov_prior,
        normalised,
        wiener_matrix,
    )

    grid = sensor.responses.wavelength_nm
    wl, fw = virtual_targets(sensor, wavelengths_nm, fwhm_nm)
    g = gaussian_targets(grid, wl, fw)
    phi = markov_prior(grid)
    prior = (f"Markov prior (mean {PRIOR['mean']:g}, sd {PRIOR['sd']:g}, correlation length "
             f"{PRIOR['length_nm']:g} nm)")
    f_number, lens, cra = geometry
    alpha, noise_var, why = noise_model
    if method == "fitted":
        A = wiener_matrix(normalised(grid, sensor.responses.effective), g, phi, alpha)
        ds = _dataset(cube, _apply(cube, A=A), {"virtual_matrix": A}, wl, fw, method,
                      f"Wiener estimate (Pratt & Mancill 1976) from the measured responses at "
                      f"normal incidence onto Gaussian bands; {prior}; band noise "
                      f"{_rms_text(alpha)} ({why})")
        return _with_error(ds, sample, sensor, A, wl, fw, noise_model, geometry)
    if f_number is None or lens is None or cra is None:
        raise ValueError("virtual_bands='angle-aware' needs the lens, the f-number and each "
                         "pixel's chief-ray angle (correct_cube gives them)")
    n_eff = sensor.require("n_eff", "virtual_bands='angle-aware' (each pixel's responses)")
    with one_blas_thread():  # small matrices (module _threads)
        table = VirtualTable.build(sensor.responses, g, n_eff, f_number, lens,
                                   cra_max_deg=max(float(np.nanmax(cra)), 1e-6), alpha=alpha,
                                   prior=phi, tolerance=tolerance, noise_var=noise_var)
    ds = _dataset(cube, _apply(cube, table=table, cra=cra),
                  {"virtual_table": table.matrices, "virtual_cra_deg": table.cra_deg}, wl, fw,
                  method,
                  f"Wiener estimate (Pratt & Mancill 1976) for each pixel's measured responses "
                  f"behind lens {lens.name} at f/{float(f_number):g} (each ray scaling the "
                  f"curves), tabulated at {table.cra_deg.size} chief-ray angles and "
                  f"interpolated within {tolerance:g}; {prior}; band noise {_rms_text(alpha)} "
                  f"({why})")
    return _with_error(ds, sample, sensor, None, wl, fw, noise_model, geometry, table=table)


def _dataset(cube, out, extra, wl, fw, method, source):
    name = cube.name or "radiance"
    attrs = {**cf_attrs(name), **cube.attrs}
    out.attrs = {"units": attrs.get("units", "1"),
                 "long_name": f"{attrs.get('long_name', name)} in virtual bands",
                 "source": source, "virtual_bands": method}
    out = out.drop_vars([c for c in out.coords if c not in ("y", "x")]).assign_coords(
        virtual_wavelength=("virtual_band", wl, {"units": "nm",
                                                  "long_name": "virtual band centre"}),
        virtual_fwhm=("virtual_band", fw, {"units": "nm",
                                           "long_name": "virtual band width (FWHM)"}))
    ds = xr.Dataset({"virtual": out.transpose("y", "x", "virtual_band")})
    if "virtual_matrix" in extra:
        ds["virtual_matrix"] = (("virtual_band", "band"), extra["virtual_matrix"], {
            "units": "1", "long_name": "virtual = virtual_matrix @ band values"})
    else:
        ds = ds.assign_coords(virtual_cra_deg=("virtual_cra", extra["virtual_cra_deg"], {
            "units": "degree", "long_name": "chief-ray angles of virtual_table"}))
        ds["virtual_table"] = (("virtual_cra", "virtual_band", "band"), extra["virtual_table"], {
            "units": "1", "long_name": "virtual = matrix @ band values, the matrix "
                                       "interpolated linearly in the pixel's chief-ray angle"})
    return ds
