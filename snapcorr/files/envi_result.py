"""A correction result as ENVI files, for Spectral Python, ENVI and other tools without snapcorr.

One header and data pair per image of the result, side by side, written together:

==============================  ========================================================
``STEM.hdr``                    the input cube's values (left out with
                                ``include_input=False``)
``STEM_wavelength_corrected``   each pixel's corrected central wavelength per band, nm
``STEM_fwhm_corrected``         each pixel's response FWHM per band, nm (when computed)
``STEM_resampled``              the spectra on the nominal wavelengths
``STEM_harmonised``             the spectra with one common response per band
``STEM_virtual``                the virtual bands
``STEM_mask``                   1 where a value is not meaningful (uint8)
``STEM_cra_deg``                the chief-ray angle, deg (one band, or one per band)
``STEM_raw``                    a flat-field result's raw counts, as read (left out with
                                ``include_input=False``, like the input's values)
``STEM_filter_white_raw``       its filter white's raw counts (when one was given)
==============================  ========================================================

A header carries ``wavelength`` (and ``fwhm``) only where every pixel of a band shares one:
the resampled, harmonised and virtual cubes. The input's values sit at each pixel's own
wavelengths, so their header gives none (a reader would otherwise plot them at the nominal
ones, the error the correction removes) and names ``STEM_wavelength_corrected.hdr`` instead;
``snapcorr nominal wavelength`` lists the nominal ones (which snapcorr's readers take as
the bands', as the result's ``.nc`` holds them). Every header holds the result's
provenance (``snapcorr attrs``, JSON). Dask images are written chunk by chunk into each file's
memory map, so a result larger than memory can be written.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import xarray as xr

from .attrs import JSON_PREFIX, _json_attrs, _positions, _version
from .datasets import _narrowed, _say_clipped
from .envi import NOMINAL_KEY, _envi_position_keys, _quiet_spectral
from .outputs import _check_targets, _check_writable
from .safety import atomic_write_files

__all__ = ["write_envi_result"]

#: The result's images written, in this order, after the input's values; the suffix of each.
IMAGES = ("wavelength_corrected", "fwhm_corrected", "resampled", "harmonised", "virtual",
          "mask", "cra_deg", "raw", "filter_white_raw")
#: The camera's own numbers a flat-field result keeps: the input, like its values.
RAW_IMAGES = ("raw", "filter_white_raw")
#: Images whose bands each share one wavelength: their headers carry ``wavelength``.
_ONE_PER_BAND = {"resampled": ("wavelength", None), "harmonised": ("wavelength",
                                                                   "fwhm_harmonised"),
                 "virtual": ("virtual_wavelength", "virtual_fwhm")}


def _as_image(var):
    """``var`` as a ``(y, x, band)`` array for ENVI: a mask as uint8, a map as one band."""
    dims = [d for d in var.dims if d not in ("y", "x")]
    var = var.transpose("y", "x", *dims)
    data = var.data
    if var.dtype == bool:
        data = data.astype(np.uint8)
    if var.ndim == 2:
        data = data[:, :, None]
    return data


def _stored_type(var):
    """The float type ``var`` is stored as when its encoding asks for a narrower one than its
    own (``--dtype float32`` of float64 values, :func:`~snapcorr.files.datasets.stored_as`),
    else None."""
    to = var.encoding.get("dtype")
    if var.dtype.kind != "f" or to is None or np.dtype(to).kind != "f":
        return None
    return np.dtype(to) if np.dtype(to).itemsize < var.dtype.itemsize else None


def _narrowed_image(data, to, counts):
    """``data`` cast to the float type ``to``, the finite values it cannot hold (a cast makes
    them infinite) at its largest of their sign, counted in ``counts`` as the blocks are
    written (:func:`~snapcorr.files.datasets._narrowed`)."""
    def narrow(a):
        return _narrowed(a, to, counts).astype(to)

    if hasattr(data, "dask"):
        return data.map_blocks(narrow, dtype=to)
    return narrow(np.asarray(data))


def _write_image(path, data, header):
    """One ENVI pair (BSQ) at ``path``, filled block by block: a dask image is computed one
    chunk at a time straight into the file's memory map, never held whole."""
    from spectral.io import envi

    dtype = np.dtype(data.dtype)
    with _quiet_spectral():
        img = envi.create_image(str(path), header, shape=tuple(data.shape), dtype=dtype,
                                interleave="bsq", ext=".raw", force=True)
        out = img.open_memmap(writable=True)  # (rows, cols, bands), a view of the file
    if hasattr(data, "dask"):
        import dask.array as da

        da.store(data, out, lock=False)
    else:
        out[...] = data
    out.flush()
    del out


def _header(ds, name, var, stem, nominal, positions):
    header = {"description": f"snapcorr result {stem}: {name}",
              "snapcorr version": _version(), "snapcorr name": name,
              "snapcorr attrs": JSON_PREFIX + json.dumps(
                  _json_attrs({**ds.attrs, **var.attrs}, f"variable {name!r}"),
                  ensure_ascii=True)}
    units = var.attrs.get("units")
    if isinstance(units, str) and units:
        header["snapcorr units"] = units
    if name in _ONE_PER_BAND:
        wl_name, fwhm_name = _ONE_PER_BAND[name]
        header["wavelength"] = [float(v) for v in ds[wl_name].values]
        header["wavelength units"] = "nm"
        if fwhm_name is not None and fwhm_name in ds.variables:
            header["fwhm"] = [float(v) for v in np.atleast_1d(ds[fwhm_name].values)]
    elif "band" in var.dims:
        # each pixel has its own wavelengths: none in the header, where they would be
        # taken for every pixel's
        header[NOMINAL_KEY] = nominal
        header["band names"] = [f"nominal {w:g} nm" for w in nominal]
        header["description"] += (f"; each pixel's wavelengths are in "
                                  f"{stem}_wavelength_corrected.hdr (nm)")
    else:
        header["band names"] = [name]
    if "band" in var.dims:  # where the bands sit on the sensor (crops, mosaics)
        header.update(positions)
    return header


def write_envi_result(ds, path, *, overwrite=False, inputs=(), include_input=True,
                      input_name=None):
    """Write a correction result (:func:`snapcorr.correct.correct_cube`) as ENVI pairs.

    Parameters
    ----------
    ds : xarray.Dataset
        The result (numpy- or dask-backed; each image is computed in turn).
    path : str or Path
        ``STEM.hdr``; the other images go to ``STEM_<name>.hdr`` beside it (module table),
        each with its data in a ``.raw`` file.
    overwrite : bool
        Replace existing files snapcorr wrote (never one of ``inputs``, nor another file).
    inputs : sequence of paths
        Files the data came from; writing over any of them is refused.
    include_input : bool
        Also write the input's values as ``STEM.hdr``, and a flat-field result's raw
        counts (``raw``, ``filter_white_raw``) as ``STEM_raw.hdr``: the camera's numbers beside
        what was computed from them.
    input_name : str, optional
        The input cube's variable (default: the result's ``cube_name`` attribute).

    Returns
    -------
    list of Path
        The headers written.
    """
    path = Path(path)
    if path.suffix.lower() != ".hdr":
        raise ValueError(f"an ENVI result is named by its header, STEM.hdr; got {path.name}")
    stem = path.stem
    nominal = [float(v) for v in ds["wavelength"].values]
    images, name = [], None
    if include_input:
        name = input_name or ds.attrs.get("cube_name")
        if name not in ds.data_vars or name in set(IMAGES) - set(RAW_IMAGES):
            raise ValueError(f"the result holds no input cube {name!r} to write as {path.name}")
        images.append((name, path))
    written = [n for n in IMAGES if n in ds.variables and n != name
               and (include_input or n not in RAW_IMAGES)]
    images += [(n, path.with_name(f"{stem}_{n}.hdr")) for n in written]
    if not images:
        raise ValueError("nothing to write: the result holds no image")
    # an image of an earlier run that this one does not write would be left beside it
    stale = [path.with_name(f"{stem}_{n}.hdr") for n in IMAGES if n not in written]
    stale += [] if include_input else [path]
    stale = [p for p in stale if p.exists()]
    if stale:
        raise ValueError(f"{stale[0]} exists and this result has no such image: it would be "
                         "left beside the new files as if it belonged to them; move it away "
                         "or choose another name")
    positions = _envi_position_keys(_positions(ds))
    pairs = []
    for name, hdr in images:
        var = ds[name]
        kind = np.uint8 if var.dtype == bool else _stored_type(var) or var.dtype
        probe = xr.DataArray(np.empty((1, 1, 1), kind),
                             dims=("y", "x", "band"))
        _check_writable("envi", probe, hdr, "bsq")
        pairs.append((name, hdr, _header(ds, name, var, stem, nominal, positions)))
    targets = []
    for _, hdr, _ in pairs:  # every pair checked before anything is written
        _check_targets("envi", [hdr, hdr.with_suffix(".raw")], overwrite=overwrite,
                       inputs=inputs)
        targets += [hdr, hdr.with_suffix(".raw")]

    clipped = {}

    def write(folder):
        for name, hdr, header in pairs:
            data, to = _as_image(ds[name]), _stored_type(ds[name])
            if to is not None:
                top = float(np.finfo(to).max)
                counts = clipped.setdefault(name, (
                    [], f"{to}'s range -{top:g} to {top:g}",
                    f"keep their {ds[name].dtype} (no --dtype)"))[0]
                data = _narrowed_image(data, to, counts)
            _write_image(folder / hdr.name, data, header)

    atomic_write_files(targets, write)
    _say_clipped(clipped, path)
    return [hdr for _, hdr, _ in pairs]
