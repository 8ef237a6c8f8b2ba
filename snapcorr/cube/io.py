"""Reading and writing cubes, through the libraries that own each format.

=============  =================================================  ===========================
extension      format                                             library
=============  =================================================  ===========================
``.hdr``       ENVI header + data (``.raw``, ``.img`` or none);   Spectral Python
               BSQ, BIL or BIP; ``wavelength`` and ``fwhm``
``.tif(f)``    multi-channel TIFF, wavelengths in the channel     OpenImageIO
               names and the image description
``.exr``       OpenEXR in the spectral layout of Fichet et al.    OpenImageIO
               2021 (``S0.<nm>nm`` emissive, ``T.<nm>nm``
               reflective channels, ``spectralLayoutVersion``)
``.nc``        netCDF 4                                           xarray (h5netcdf)
``.zarr``      Zarr, chunked for larger-than-memory work          xarray (zarr)
``.npy``       bare array; wavelengths must be passed             numpy
=============  =================================================  ===========================

Writers never replace an existing file (unless ``overwrite=True``) nor any input, and write
atomically: to a temporary name in the target folder, then renamed.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

from .._io import atomic_write
from .model import check_cube, make_cube

__all__ = ["BLOCK_BYTES", "FORMATS", "read_cube", "row_blocks", "write_cube", "write_dataset"]

FORMATS = {".hdr": "envi", ".tif": "tiff", ".tiff": "tiff", ".exr": "exr", ".nc": "netcdf",
           ".zarr": "zarr", ".npy": "npy"}
_ENVI_DATA = (".raw", ".img", ".dat", ".bsq", ".bil", ".bip", "")
_REFLECTIVE = ("reflectance", "transmittance")
#: dtypes an OpenEXR float channel holds exactly (float32 has a 24-bit significand).
_EXR_EXACT = tuple(np.dtype(t) for t in (np.uint8, np.int8, np.uint16, np.int16, np.float16,
                                         np.float32))
_CHANNEL = re.compile(r"^(S0|T)\.(\d+(?:,\d*)?)nm$")


#: Target size of the blocks a cube is streamed in (``snapcorr correct``, ``flatfield``).
BLOCK_BYTES = 16 * 2**20


def row_blocks(cube, target_bytes=BLOCK_BYTES):
    """``cube`` in dask blocks of whole rows (every x and band) of about ``target_bytes``:
    memory stays bounded whatever the cube's size, and each spectrum stays in one block."""
    row_bytes = cube.sizes["x"] * cube.sizes["band"] * max(cube.dtype.itemsize, 4)
    return cube.chunk({"y": max(1, target_bytes // row_bytes), "x": -1, "band": -1})


def _format(path):
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in (".raw", ".img") and path.with_suffix(".hdr").exists():
        return "envi", path.with_suffix(".hdr")
    if suffix not in FORMATS:
        known = ", ".join(sorted(FORMATS))
        raise ValueError(f"unknown cube format {path.suffix or '(none)'!r} for {path}; "
                         f"snapcorr reads and writes {known}")
    return FORMATS[suffix], path


# -- reading ---------------------------------------------------------------------------------


def read_cube(path, *, wavelength_nm=None, chunks=None):
    """Read a cube from any supported format (see the module table).

    Parameters
    ----------
    path : str or Path
    wavelength_nm : array_like, optional
        Band wavelengths for files that carry none (``.npy``, a plain TIFF); a file's own
        wavelengths win, and a mismatch in length is an error.
    chunks : dict, optional
        Dask chunks (e.g. ``{"y": 512}``): the cube is read lazily.

    Returns
    -------
    xarray.DataArray
    """
    fmt, path = _format(path)
    if not path.exists():
        raise FileNotFoundError(f"no such file: {path}")
    try:
        cube = _READERS[fmt](path, wavelength_nm, chunks)
    except Exception as err:  # the libraries raise their own types; all mean a bad file
        if isinstance(err, ValueError) and str(err).startswith(str(path)):
            raise
        raise ValueError(f"{path}: cannot read it as {fmt}: {type(err).__name__}: {err}") from None
    if chunks is not None and cube.chunks is None:
        cube = cube.chunk(chunks)
    return cube


def _wavelengths(path, found, given, n_bands):
    wl = found if found is not None else given
    if wl is None:
        raise ValueError(f"{path} carries no wavelengths; pass wavelength_nm")
    wl = np.asarray(wl, dtype=float)
    if wl.shape != (n_bands,):
        raise ValueError(f"{path} has {n_bands} bands but {wl.size} wavelengths")
    return wl


def _read_envi(path, given, chunks=None):
    from spectral.io import envi

    img = envi.open(str(path))
    meta = img.metadata
    rows, cols, bands = img.nrows, img.ncols, img.nbands
    expected = img.offset + rows * cols * bands * np.dtype(img.dtype).itemsize
    size = os.path.getsize(img.filename)
    if size != expected:
        raise ValueError(
            f"{path}: the data file {Path(img.filename).name} has {size} bytes but the header "
            f"({rows} x {cols} x {bands}, {np.dtype(img.dtype).name}) needs {expected}; it is "
            "truncated or the header does not describe it"
        )
    data = img.open_memmap(interleave="bip", writable=False)
    data = _lazy_or_loaded(data, chunks)
    units = str(meta.get("wavelength units", "nanometers")).strip().lower()
    scale = _UNITS_TO_NM.get(units)
    if scale is None:
        raise ValueError(f"{path}: wavelength units {meta['wavelength units']!r} are not a "
                         f"length ({', '.join(sorted(_UNITS_TO_NM))}); pass wavelength_nm")
    wl = meta.get("wavelength")
    wl = None if wl is None else np.asarray(wl, dtype=float) * scale
    fw = meta.get("fwhm")
    if fw is not None:
        fw = np.asarray(fw, dtype=float) * scale
        if fw.shape != (bands,):
            raise ValueError(f"{path}: header lists {fw.size} fwhm values for {bands} bands")
    attrs = {"source": str(path), "envi_interleave": meta.get("interleave", "")}
    if "data ignore value" in meta:
        attrs["data_ignore_value"] = float(meta["data ignore value"])
    return make_cube(data, _wavelengths(path, wl, given, bands), fwhm_nm=fw, attrs=attrs)


#: ENVI ``wavelength units`` spellings and their factor to nanometres.
_UNITS_TO_NM = {"nanometers": 1.0, "nanometer": 1.0, "nanometres": 1.0, "nm": 1.0,
                "micrometers": 1e3, "micrometer": 1e3, "micrometres": 1e3, "microns": 1e3,
                "micron": 1e3, "um": 1e3, "\u00b5m": 1e3, "millimeters": 1e6, "mm": 1e6}


def _lazy_or_loaded(array, chunks):
    """A dask array over a memory map when chunks are asked for, else a native-order copy."""
    if array.dtype.byteorder not in ("=", "|"):
        array = array.astype(array.dtype.newbyteorder("="))  # big-endian files
    if chunks is None:
        return np.array(array)
    import dask.array as da

    sizes = (chunks.get("y", -1), chunks.get("x", -1), chunks.get("band", -1))
    return da.from_array(array, chunks=sizes)


def _read_oiio(path, given, chunks=None):
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise ValueError(oiio.geterror() or "OpenImageIO cannot open it")
    try:
        spec = inp.spec()
        data = inp.read_image(0, 0, 0, spec.nchannels, "unknown")
        if data is None:
            raise ValueError(inp.geterror() or "no pixels")
        names = list(spec.channelnames)
        attrs = {a.name: a.value for a in spec.extra_attribs}
    finally:
        inp.close()
    data = np.asarray(data).reshape(spec.height, spec.width, spec.nchannels)
    wl, keep, name = None, list(range(len(names))), None
    parsed = [_CHANNEL.match(n) for n in names]
    if any(parsed):
        keep = [i for i, m in enumerate(parsed) if m]
        wl = np.array([float(parsed[i].group(2).replace(",", ".")) for i in keep])
        name = "reflectance" if parsed[keep[0]].group(1) == "T" else "radiance"
        order = np.argsort(wl, kind="stable")  # EXR stores channels sorted by name
        keep, wl = [keep[i] for i in order], wl[order]
    meta = {}
    desc = attrs.get("ImageDescription") or attrs.get("snapcorr")
    if isinstance(desc, str) and desc.startswith("{"):
        meta = json.loads(desc)
    fw = meta.pop("fwhm_nm", None)
    dtype = meta.pop("dtype", None)
    written = meta.pop("wavelength_nm", None)
    if written is not None and len(written) == len(keep):
        written = np.asarray(written, dtype=float)
        if wl is None:
            wl = written
        elif np.allclose(np.sort(written), wl):
            # EXR keeps channels sorted by name: put the bands back in the written order.
            order = np.argsort(np.argsort(written, kind="stable"), kind="stable")
            keep, wl = [keep[i] for i in order], wl[order]
    cube_attrs = meta.pop("attrs", {})
    data = data[..., keep]
    if dtype is not None:
        data = data.astype(dtype)
    cube = make_cube(data, _wavelengths(path, wl, given, data.shape[2]), fwhm_nm=fw,
                     attrs={"source": str(path), **cube_attrs},
                     name=meta.pop("name", name) or "radiance")
    return cube


def _read_netcdf(path, given, chunks=None):
    ds = xr.open_dataset(path, engine="h5netcdf", chunks=chunks)
    return _from_dataset(ds, path)


def _read_zarr(path, given, chunks=None):
    ds = xr.open_zarr(path, consolidated=False, chunks=chunks)
    return _from_dataset(ds, path)


def _from_dataset(ds, path):
    names = [v for v in ds.data_vars if tuple(ds[v].dims) == ("y", "x", "band")]
    if not names:
        raise ValueError(f"{path} holds no (y, x, band) variable")
    preferred = [n for n in ("radiance", "reflectance", "transmittance") if n in names]
    cube = ds[(preferred or names)[0]]
    cube.attrs = {**ds.attrs, **cube.attrs}
    return check_cube(cube)


def _read_npy(path, given, chunks=None):
    data = np.load(path, mmap_mode="r", allow_pickle=False)
    if data.ndim != 3:
        raise ValueError(f"{path} holds a {data.ndim}-D array; a cube is (y, x, band)")
    return make_cube(_lazy_or_loaded(data, chunks),
                     _wavelengths(path, None, given, data.shape[2]), attrs={"source": str(path)})


_READERS = {"envi": _read_envi, "tiff": _read_oiio, "exr": _read_oiio, "netcdf": _read_netcdf,
            "zarr": _read_zarr, "npy": _read_npy}


# -- writing ---------------------------------------------------------------------------------


def write_cube(cube, path, *, overwrite=False, inputs=(), interleave="bsq"):
    """Write a cube; the format follows the extension (see the module table).

    Parameters
    ----------
    cube : xarray.DataArray
    path : str or Path
    overwrite : bool
        Replace an existing file (never one of ``inputs``).
    inputs : sequence of paths
        Files the cube came from; writing over any of them is refused.
    interleave : {"bsq", "bil", "bip"}
        ENVI band interleave.
    """
    check_cube(cube)
    fmt, path = _format(path)
    path = Path(path)
    targets = [path, path.with_suffix(".raw")] if fmt == "envi" else [path]
    sources = {Path(src).resolve() for src in inputs}
    sources |= {p.with_suffix(e) for p in sources if p.suffix.lower() == ".hdr"
                for e in _ENVI_DATA}
    sources |= {p.with_suffix(".hdr") for p in sources}
    for target in targets:
        if target.resolve() in sources:
            raise ValueError(f"output {target} is also an input; choose another output path")
        if target.exists() and not overwrite:
            raise FileExistsError(f"{target} exists; choose another name or pass overwrite=True")
    _WRITERS[fmt](cube, path, interleave=interleave)
    return path


def _cube_meta(cube):
    attrs = {k: v for k, v in cube.attrs.items() if isinstance(v, (str, int, float, bool))}
    meta = {"name": cube.name, "dtype": str(cube.dtype), "attrs": attrs,
            "wavelength_nm": [float(v) for v in cube.wavelength.values]}
    if "fwhm" in cube.coords:
        meta["fwhm_nm"] = [float(v) for v in cube.fwhm.values]
    return meta


def _write_envi(cube, path, *, interleave):
    from spectral.io import envi

    if interleave not in ("bsq", "bil", "bip"):
        raise ValueError(f"interleave must be bsq, bil or bip, got {interleave!r}")
    meta = {"wavelength": [float(v) for v in cube.wavelength.values],
            "wavelength units": "nm", "description": f"snapcorr cube {cube.name or ''}".strip()}
    if "fwhm" in cube.coords:
        meta["fwhm"] = [float(v) for v in cube.fwhm.values]
    data = np.asarray(cube.values)
    if data.dtype == np.float16:
        raise ValueError("ENVI has no 16-bit float type; convert the cube "
                         "(cube.astype('float32')) or write .exr, .nc or .zarr")
    tmpdir = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.stem}."))
    try:
        hdr = tmpdir / path.name
        envi.save_image(str(hdr), data, dtype=data.dtype, interleave=interleave, ext=".raw",
                        metadata=meta, force=True)
        os.replace(hdr.with_suffix(".raw"), path.with_suffix(".raw"))
        os.replace(hdr, path)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)


def _channel_name(prefix, wavelength):
    return f"{prefix}.{float(wavelength)!r}nm".replace(".", ",").replace(",", ".", 1)


def _write_oiio(cube, path, *, interleave):
    import OpenImageIO as oiio

    exr = path.suffix.lower() == ".exr"
    data = np.ascontiguousarray(cube.values)
    if exr:
        if data.dtype not in _EXR_EXACT:
            raise ValueError(
                f"OpenEXR stores 16- and 32-bit floats, so a {data.dtype} cube would not come "
                "back unchanged; convert it (cube.astype('float32')) or write .nc, .zarr or .tif"
            )
        prefix = "T" if cube.name in _REFLECTIVE else "S0"
        names = [_channel_name(prefix, w) for w in cube.wavelength.values]
        store = data.astype(np.float16 if data.dtype == np.float16 else np.float32)
        typedesc = "half" if data.dtype == np.float16 else "float"
    else:
        names = [f"{float(w)!r}nm" for w in cube.wavelength.values]
        store = data
        typedesc = {np.dtype(np.uint8): "uint8", np.dtype(np.uint16): "uint16",
                    np.dtype(np.int16): "int16", np.dtype(np.float16): "half",
                    np.dtype(np.float32): "float", np.dtype(np.float64): "double"}.get(
                        data.dtype)
        if typedesc is None:
            raise ValueError(f"snapcorr writes TIFF cubes as 8/16-bit integers or 16/32/64-bit "
                             f"floats, not {data.dtype}; convert it or write .nc or .zarr")
    ny, nx, nb = store.shape
    spec = oiio.ImageSpec(nx, ny, nb, typedesc)
    spec.channelnames = tuple(names)
    spec.attribute("ImageDescription", json.dumps(_cube_meta(cube)))
    if exr:
        spec.attribute("spectralLayoutVersion", "1.0")
        if prefix == "S0":
            spec.attribute("emissiveUnits", "W.m^-2.sr^-1")
        spec.attribute("compression", "zip")
    else:
        spec.attribute("compression", "zip")
        spec.attribute("tiff:PlanarConfiguration", "contig")

    def write(tmp):
        out = oiio.ImageOutput.create(str(path))
        if out is None or not out.open(str(tmp), spec):
            raise ValueError(f"cannot write {path}: {oiio.geterror()}")
        try:
            if not out.write_image(store):
                raise ValueError(f"cannot write {path}: {out.geterror()}")
        finally:
            out.close()

    atomic_write(path, write)


def _write_netcdf(cube, path, *, interleave):
    _write_dataset(_to_dataset(cube), path, ".nc")


def _write_zarr(cube, path, *, interleave):
    _write_dataset(_to_dataset(cube), path, ".zarr")


def _to_dataset(cube):
    name = cube.name or "radiance"
    ds = cube.to_dataset(name=name)
    ds.attrs = _portable_attrs(cube.attrs)
    ds[name].attrs = {}
    return ds


def _portable_attrs(attrs):
    """Attributes netCDF and zarr can store: numbers and strings (booleans become 0/1)."""
    out = {}
    for k, v in attrs.items():
        if isinstance(v, (bool, np.bool_)):
            out[k] = int(v)
        elif isinstance(v, (str, int, float, np.number)):
            out[k] = v
    return out


def _write_npy(cube, path, *, interleave):
    atomic_write(path, lambda tmp: np.save(tmp, np.asarray(cube.values), allow_pickle=False))


_WRITERS = {"envi": _write_envi, "tiff": _write_oiio, "exr": _write_oiio,
            "netcdf": _write_netcdf, "zarr": _write_zarr, "npy": _write_npy}


def write_dataset(ds, path, *, overwrite=False, inputs=()):
    """Write a Dataset (a corrected cube with its mask, raw data and provenance) to ``.nc`` or
    ``.zarr``, atomically, refusing to replace an input or an existing file."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".nc", ".zarr"):
        raise ValueError(f"results are written as .nc or .zarr, got {path.suffix or '(none)'!r}")
    for src in inputs:
        if Path(src).resolve() == path.resolve():
            raise ValueError(f"output {path} is also an input; choose another output path")
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; choose another name or pass overwrite=True")
    ds = ds.copy()
    ds.attrs = _portable_attrs(ds.attrs)
    try:
        return _write_dataset(ds, path, suffix)
    except (OSError, ValueError):
        raise
    except Exception as err:  # the libraries' own error types: report them plainly
        raise ValueError(f"cannot write {path}: {type(err).__name__}: {err}") from None


def _write_dataset(ds, path, suffix):
    # Dask-backed variables are written one at a time: computed together, a block read once
    # for two variables (a cube and its resampled copy) stays in memory until both are done,
    # which can hold the whole cube. Apart, each streams through in bounded memory.
    lazy = [v for v in ds.data_vars if ds[v].chunks is not None]
    first = ds.drop_vars(lazy)
    if suffix == ".nc":
        def write(tmp):
            first.to_netcdf(tmp, engine="h5netcdf")
            for v in lazy:
                ds[[v]].to_netcdf(tmp, mode="a", engine="h5netcdf")

        atomic_write(path, write)
        return path
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".zarr"))
    try:
        first.to_zarr(tmp, mode="w", consolidated=False)
        for v in lazy:
            ds[[v]].to_zarr(tmp, mode="a", consolidated=False)
        if path.exists():
            shutil.rmtree(path)
        os.replace(tmp, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path
