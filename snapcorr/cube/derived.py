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

import threading

import numpy as np
import xarray as xr

__all__ = ["DERIVED", "LazyTable", "corrected_fwhm", "corrected_wavelength", "lazy_fwhm",
           "rebuildable", "restore", "with_fwhm_table"]

WAVELENGTH_ATTRS = {
    "units": "nm",
    "long_name": "corrected central wavelength",
    "derived_from": "wavelength * wavelength_scale[y, x, scale_index[band]]",
}


class _Blocks:
    """An array in memory as dask reads it: each block a view, when computed.
    ``dask.array.from_array`` copies any array that has a ``copy`` method, and hashes it for
    a name (copying it again when it is not contiguous, as a transposed view is): 0.1-0.2 s
    at 2048^2 for a coordinate nobody may read. This has no ``copy``, and the graph is named
    at random. So the lazy coordinates read the Dataset's arrays as they are when computed:
    a value changed in place in ``wavelength_scale`` (or the chief-ray angles) changes them
    too, as a coordinate derived from it should, in every Dataset sharing the array."""

    def __init__(self, array):
        self._array = array
        self.shape, self.ndim, self.dtype = array.shape, array.ndim, array.dtype

    def __getitem__(self, key):
        return self._array[key]


def _blocks_of(array, chunks):
    """A dask array over ``array`` (numpy) without copying or hashing it."""
    import dask.array as da

    array = np.asarray(array)
    return da.from_array(_Blocks(array), chunks=chunks, asarray=False, name=False,
                         meta=np.empty((0,) * array.ndim, array.dtype))

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
        _blocks_of(scale, (ychunks, xchunks, -1))
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
    table = _table_arrays(ds)
    return _fwhm_from(ds["cra_deg"], lambda: table, table[1].shape[0], chunks)


def lazy_fwhm(cra, table, n_bands, *, chunks=None):
    """``fwhm_corrected(y, x, band)`` over a table not built yet: ``table()`` builds it (a
    :class:`LazyTable` of a Dataset holding ``fwhm_table`` and ``fwhm_cra_deg``) when the
    first block is computed. The result's encoding carries ``table`` under
    :data:`LAZY_TABLE`, where :func:`with_fwhm_table` and the writers find it.

    Parameters
    ----------
    cra : xarray.DataArray
        ``cra_deg(y, x)`` or ``cra_deg(y, x, band)``.
    table : LazyTable
    n_bands : int
    chunks : tuple of tuples, optional
        As for :func:`corrected_fwhm`.
    """
    out = _fwhm_from(cra, lambda: _table_arrays(table()), int(n_bands), chunks)
    out.encoding[LAZY_TABLE] = table
    return out


def _table_arrays(ds):
    """``(nodes, table)`` of a Dataset with ``fwhm_table`` and ``fwhm_cra_deg``, float64."""
    return (np.asarray(ds["fwhm_cra_deg"].values, float),
            np.asarray(ds["fwhm_table"].transpose("band", "fwhm_cra").values, float))


def _fwhm_from(cra, arrays, nb, chunks):
    """The lazy interpolation of ``arrays()`` (``(nodes, table)``, asked for in each block)
    at ``cra``."""
    import dask.array as da

    per_band = "band" in cra.dims
    cra = cra.transpose("y", "x", *(("band",) if per_band else ())).data
    ny, nx = cra.shape[:2]
    if chunks is None:
        rows = max(1, (16 * 2**20) // max(1, nx * nb * 4))
        chunks = (tuple(min(rows, ny - r) for r in range(0, ny, rows)) or (0,), (nx,), (nb,))
    ychunks, xchunks, bchunks = chunks
    cc = (ychunks, xchunks) + ((bchunks,) if per_band else ())
    c = cra.rechunk(cc) if isinstance(cra, da.Array) else _blocks_of(cra, cc)

    def block(a, lo, n):
        nodes, table = arrays()
        return _fwhm_block(np.asarray(a, float), nodes, table[lo:lo + n])

    parts, lo = [], 0
    for k, n in enumerate(bchunks):
        if per_band:
            piece = c.blocks[:, :, k] if len(bchunks) > 1 else c
        else:
            piece = c
        parts.append(piece.map_blocks(block, lo, n, chunks=(ychunks, xchunks, (n,)),
                                      dtype=np.float32, meta=np.empty((0, 0, 0), np.float32),
                                      **({} if per_band else {"new_axis": 2})))
        lo += n
    data = da.concatenate(parts, axis=2) if len(parts) > 1 else parts[0]
    return xr.DataArray(data, dims=("y", "x", "band"), attrs=dict(FWHM_ATTRS))


#: The encoding key under which a lazy ``fwhm_corrected`` carries its :class:`LazyTable`.
LAZY_TABLE = "snapcorr_fwhm_table"


class LazyTable:
    """A value built by ``build()`` on its first use, once (thread-safe), then kept.

    The FWHM table behind a lazy ``fwhm_corrected``: a correction that never reads the
    widths never pays for them. Copies (``copy``, ``deepcopy``, as xarray makes of an
    encoding) are the same object; a pickled one carries the value if it was built.
    """

    def __init__(self, build):
        self._build = build
        self._value = None
        self._lock = threading.Lock()

    @property
    def built(self):
        """Whether the value has been built."""
        return self._value is not None

    def __call__(self):
        if self._value is None:
            with self._lock:
                if self._value is None:
                    self._value = self._build()
        return self._value

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self

    def __getstate__(self):
        return {"_build": self._build, "_value": self._value}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def __repr__(self):
        return f"<LazyTable {'built' if self.built else 'not built yet'}>"


def with_fwhm_table(ds):
    """``ds`` with its ``fwhm_table(band, fwhm_cra)`` and ``fwhm_cra_deg``, building the table
    if ``fwhm_corrected`` holds it lazily (as :func:`snapcorr.correct.correct_cube` leaves it
    when nothing else needs the widths). A Dataset without either is returned unchanged.
    """
    if "fwhm_table" in ds.variables or "fwhm_corrected" not in ds.variables:
        return ds
    table = ds["fwhm_corrected"].encoding.get(LAZY_TABLE)
    if table is None:
        return ds
    t = table()
    if "wavelength" in ds.variables:  # by the bands' own wavelengths: selections follow
        where = {float(w): i for i, w in enumerate(t["wavelength"].values)}
        pick = [where.get(float(w)) for w in np.atleast_1d(ds["wavelength"].values)]
        if None in pick:
            raise ValueError("the FWHM table was built for other bands than this Dataset "
                             "holds; call with_fwhm_table before changing its wavelengths")
        t = t.isel(band=pick)
    out = ds.assign_coords(fwhm_cra_deg=t["fwhm_cra_deg"])
    out["fwhm_table"] = t["fwhm_table"].drop_vars("wavelength", errors="ignore")
    return out


#: Name -> function rebuilding it from a Dataset read back from a file.
DERIVED = {"wavelength_corrected": corrected_wavelength, "fwhm_corrected": corrected_fwhm}

#: Name -> the variables :data:`DERIVED` rebuilds it from.
NEEDS = {"wavelength_corrected": ("wavelength", "wavelength_scale", "scale_index"),
         "fwhm_corrected": ("cra_deg", "fwhm_table", "fwhm_cra_deg")}


def rebuildable(ds, name):
    """Whether ``ds`` holds all that :data:`DERIVED` needs to rebuild ``name``."""
    return name in DERIVED and all(v in ds.variables for v in NEEDS[name])


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
