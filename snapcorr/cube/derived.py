"""Variables a result can recompute from a compact stored form instead of storing them whole.

A corrected wavelength is ``cwl_b * s(y, x, k_b)``: the band's nominal wavelength times a
per-pixel factor that is the same for every band sharing an effective index (a Snapscan) or
one per band (a mosaic, whose bands sit at different positions). Stored whole it would be a
second cube; stored as ``wavelength_scale(y, x, scale)`` and ``scale_index(band)`` it is a
small fraction of one. :func:`restore` rebuilds it lazily, block by block, as a coordinate.

A variable or coordinate whose attrs carry ``derived_from`` is not written by
:func:`snapcorr.cube.write_dataset`; the file lists it in its ``derived_variables`` attribute and
:func:`snapcorr.cube.read_dataset` calls :func:`restore` to bring it back.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

__all__ = ["DERIVED", "corrected_fwhm", "corrected_wavelength", "restore"]

WAVELENGTH_ATTRS = {
    "units": "nm",
    "long_name": "corrected central wavelength",
    "derived_from": "wavelength * wavelength_scale[y, x, scale_index[band]]",
}


def _block(scale, cwl, index):
    """``cwl * scale[..., index]`` (float64) rounded once to float32, in row blocks."""
    out = np.empty((*scale.shape[:2], cwl.size), np.float32)
    first = int(index[0]) if index.size else 0
    same = bool(np.all(index == first))
    for r in range(0, scale.shape[0], 64):  # row blocks keep the gathered part small
        sc = scale[r:r + 64, :, first:first + 1] if same else scale[r:r + 64][:, :, index]
        np.multiply(sc, cwl, out=out[r:r + 64], casting="unsafe")
    return out


def corrected_wavelength(ds, *, chunks=None):
    """``wavelength_corrected(y, x, band)`` of a corrected result, lazily (dask), float32.

    Parameters
    ----------
    ds : xarray.Dataset
        Holds ``wavelength(band)`` (nm), ``wavelength_scale(y, x, scale)`` and
        ``scale_index(band)``.
    chunks : tuple of tuples, optional
        ``(y_chunks, x_chunks, band_chunks)`` of the result (default: one block of about
        16 MiB of rows, every band).

    Returns
    -------
    xarray.DataArray
        Computed block by block when read; ``.values`` gives the whole array.
    """
    import dask.array as da

    cwl = np.asarray(ds["wavelength"].values, float)
    index = np.asarray(ds["scale_index"].values, np.intp)
    scale = ds["wavelength_scale"].transpose("y", "x", "scale").data
    ny, nx = scale.shape[:2]
    if chunks is None:
        rows = max(1, (16 * 2**20) // max(1, nx * cwl.size * 4))
        chunks = (tuple(min(rows, ny - r) for r in range(0, ny, rows)) or (0,), (nx,),
                  (cwl.size,))
    ychunks, xchunks, bchunks = chunks
    sc = scale.rechunk((ychunks, xchunks, -1)) if isinstance(scale, da.Array) else \
        da.from_array(np.asarray(scale), chunks=(ychunks, xchunks, -1))
    parts, lo = [], 0
    for nb in bchunks:  # one lazy piece per band chunk
        w, k = cwl[lo:lo + nb], index[lo:lo + nb]
        parts.append(sc.map_blocks(lambda s, w=w, k=k: _block(np.asarray(s), w, k),
                                   chunks=(ychunks, xchunks, (nb,)), dtype=np.float32,
                                   meta=np.empty((0, 0, 0), np.float32)))
        lo += nb
    data = da.concatenate(parts, axis=2) if len(parts) > 1 else parts[0]
    return xr.DataArray(data, dims=("y", "x", "band"), attrs=dict(WAVELENGTH_ATTRS))


FWHM_ATTRS = {
    "units": "nm",
    "long_name": "FWHM of the pixel's whole filter response",
    "derived_from": "fwhm_table[band, fwhm_cra] interpolated linearly in fwhm_cra_deg at "
                    "cra_deg[y, x(, band)]",
}


def _fwhm_block(cra, nodes, table):
    """``table[b]`` interpolated at ``cra`` ((y, x) or (y, x, nb)), float32 (y, x, nb)."""
    nb = table.shape[0]
    out = np.empty((*cra.shape[:2], nb), np.float32)
    for r in range(0, cra.shape[0], 64):
        c = cra[r:r + 64]
        i = np.clip(np.searchsorted(nodes, c, side="right") - 1, 0, nodes.size - 2)
        w = (c - nodes[i]) / (nodes[i + 1] - nodes[i])
        if c.ndim == 2:  # one angle for every band: gather whole rows of the table
            lo, hi = table[:, i], table[:, i + 1]  # (nb, rows, x)
            val = lo + (hi - lo) * w
            out[r:r + 64] = np.moveaxis(val, 0, -1)
        else:
            b = np.arange(nb)
            lo, hi = table[b, i], table[b, i + 1]
            out[r:r + 64] = lo + (hi - lo) * w
    return out


def corrected_fwhm(ds, *, chunks=None):
    """``fwhm_corrected(y, x, band)`` of a corrected result, lazily (dask), float32.

    Parameters
    ----------
    ds : xarray.Dataset
        Holds ``cra_deg(y, x)`` or ``cra_deg(y, x, band)``, ``fwhm_table(band, fwhm_cra)`` and
        its coordinate ``fwhm_cra_deg(fwhm_cra)``.
    chunks : tuple of tuples, optional
        ``(y_chunks, x_chunks, band_chunks)`` of the result (default: blocks of about 16 MiB
        of rows, every band).
    """
    import dask.array as da

    table = np.asarray(ds["fwhm_table"].transpose("band", "fwhm_cra").values, float)
    nodes = np.asarray(ds["fwhm_cra_deg"].values, float)
    cra = ds["cra_deg"]
    per_band = "band" in cra.dims
    cra = cra.transpose("y", "x", *(("band",) if per_band else ())).data
    ny, nx = cra.shape[:2]
    nb = table.shape[0]
    if chunks is None:
        rows = max(1, (16 * 2**20) // max(1, nx * nb * 4))
        chunks = (tuple(min(rows, ny - r) for r in range(0, ny, rows)) or (0,), (nx,), (nb,))
    ychunks, xchunks, bchunks = chunks
    cc = (ychunks, xchunks) + ((bchunks,) if per_band else ())
    c = cra.rechunk(cc) if isinstance(cra, da.Array) else da.from_array(np.asarray(cra),
                                                                        chunks=cc)
    parts, lo = [], 0
    for k, n in enumerate(bchunks):
        t = table[lo:lo + n]
        if per_band:
            piece = c.blocks[:, :, k] if len(bchunks) > 1 else c
        else:
            piece = c
        parts.append(piece.map_blocks(lambda a, t=t: _fwhm_block(np.asarray(a, float), nodes, t),
                                      chunks=(ychunks, xchunks, (n,)), dtype=np.float32,
                                      meta=np.empty((0, 0, 0), np.float32),
                                      **({} if per_band else {"new_axis": 2})))
        lo += n
    data = da.concatenate(parts, axis=2) if len(parts) > 1 else parts[0]
    return xr.DataArray(data, dims=("y", "x", "band"), attrs=dict(FWHM_ATTRS))


#: Name -> function rebuilding it from a Dataset read back from a file.
DERIVED = {"wavelength_corrected": corrected_wavelength, "fwhm_corrected": corrected_fwhm}


def restore(ds):
    """``ds`` with every variable named in its ``derived_variables`` attribute rebuilt (as a
    coordinate); unknown names are an error."""
    names = ds.attrs.get("derived_variables", [])
    if isinstance(names, str):
        names = [n for n in names.replace(",", " ").split() if n]
    for name in names:
        if name not in DERIVED:
            raise ValueError(f"the file lists a derived variable {name!r} that this snapcorr "
                             f"cannot rebuild (known: {sorted(DERIVED)})")
        ds = ds.assign_coords({name: DERIVED[name](ds)})
    return ds
