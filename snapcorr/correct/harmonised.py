"""``harmonised`` in a correction's result: every pixel brought to one response per band by
:mod:`snapcorr.correct.harmonise` (modelled filters; measured ones in
:mod:`snapcorr.correct.matched`)."""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from .._validation import check_positive
from .matched import _harmonised_measured
from .resample import _output_dtype, _units_of
from .widths import _kernel_variance

__all__ = ["HARMONISE_NODE_STEP_DEG"]


#: Chief-ray-angle step of the Snapscan path's weight tables, between which a pixel's weights
#: are interpolated (a band moves by at most ~0.1 nm over a step). Against the direct
#: computation the result differs by at most 3e-5 of the data's range for spectra as 12 nm
#: filters see them and 2e-4 for white noise across the bands (the worst case), tested at
#: this step in ``test_the_tabulated_path_is_the_direct_one``.
HARMONISE_NODE_STEP_DEG = 0.05


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


def _harmonised(ds, cube, plan, sensor, lens, target_fwhm_nm):
    """``ds`` with ``harmonised`` and ``fwhm_harmonised`` by the correction's ``plan``
    (:class:`~snapcorr.correct.plan.CorrectionPlan`)."""
    from .harmonise import harmonise_spectra, node_weights

    cra, scale, column, table = plan.cra_deg, plan.scale, plan.column, plan.widths
    scale_at, n_eff, f, buffer = plan.scale_at, plan.n_eff, plan.f_number, plan.buffer
    cwl = np.asarray(sensor.cwl_nm, float)

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
                                               plan.kernel_var)
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
