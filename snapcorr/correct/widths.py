"""Each band's response width behind the lens: the width tables (a FwhmTable, or a
MeasuredTable for measured filters) and ``fwhm_corrected``, built at once or on first read."""

from __future__ import annotations

import functools

import numpy as np
import xarray as xr

from .._threads import one_blas_thread
from ..cube.derived import LazyTable, corrected_fwhm, lazy_fwhm

__all__ = ["FWHM_TOLERANCE_NM"]


#: The finest interpolation tolerance of the FWHM table, nm: a wavelength tolerance below it
#: (which the shift tables meet) would ask for thousands of CRA nodes for widths nobody can
#: measure to that.
FWHM_TOLERANCE_NM = 0.005


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


def _measured_table(sensor, lens, f, cra_max, tolerance_nm):
    from ..optics.measured import MeasuredTable

    return MeasuredTable.build(sensor.responses, sensor.n_eff, f, lens, cra_max_deg=cra_max,
                               tolerance_nm=tolerance_nm,
                               fwhm_tolerance_nm=max(float(tolerance_nm), FWHM_TOLERANCE_NM))


def _width_table(sensor, lens, f, cra_max, tolerance_nm):
    """Each band's whole response (filter shape spread by the kernel, Eq. 13) tabulated over
    CRA once: a FwhmTable, or for measured filters a MeasuredTable (centres too)."""
    with one_blas_thread():
        return _unlimited_width_table(sensor, lens, f, cra_max, tolerance_nm)


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


def _kernel_variance(nodes, n_eff, cwl, f, lens):
    """``(n_bands, n_nodes)``: each band's kernel variance at ``nodes`` (CRA), nm^2."""
    from ..optics.bandwidth import kernel_log_variance

    n_eff = np.broadcast_to(np.asarray(n_eff, float), cwl.shape)
    out = np.empty((cwl.size, np.size(nodes)))
    for value in np.unique(n_eff):
        bands = n_eff == value
        out[bands] = kernel_log_variance(value, f, np.asarray(nodes, float), lens)[None, :]
    return out * cwl[:, None] ** 2


def _span(values):
    v = np.asarray(values, float)
    return f"{v.min():g}" if np.ptp(v) == 0 else f"{v.min():g}-{v.max():g}"
