"""Reading and writing cubes, frames and results, through the libraries that own each format.

=============  =================================================  ===========================
extension      format                                             library
=============  =================================================  ===========================
``.hdr``       ENVI header + data (``.raw``, ``.img``, ...);      Spectral Python
               BSQ, BIL or BIP; ``wavelength`` and ``fwhm`` in
               the header's ``wavelength units``
``.tif(f)``    TIFF: one page with a channel per band, or one     OpenImageIO
               single-channel page per band; metadata in the
               image description (JSON)
``.exr``       OpenEXR in the spectral layout of Fichet et al.    OpenImageIO
               2021 (``S0.<nm>nm`` emissive, ``T.<nm>nm``
               reflective channels, ``spectralLayoutVersion``)
``.nc``        netCDF 4                                           xarray (h5netcdf)
``.zarr``      Zarr (a folder), consolidated metadata, chunked    xarray (zarr)
               for larger-than-memory work
``.npy``       array; snapcorr writes a JSON sidecar              numpy
               (``cube.npy.json``) with wavelengths, fwhm, name,
               attrs and sensor positions; a bare ``.npy`` needs
               ``wavelength_nm``
=============  =================================================  ===========================

Reading
    :func:`read_cube` (a ``(y, x, band)`` cube), :func:`read_frame` (a raw 2-D frame) and
    :func:`read_dataset` (a whole result written by :func:`write_dataset`) share one reader
    per format, as does :func:`snapcorr.calibrate.read_flat`. A path is examined before it is
    opened (a FIFO, socket, device, symbolic link loop, or a folder where a file is expected is
    refused, see :func:`snapcorr.files.reading.check_input`); ENVI headers are validated before use.
    Wavelengths come back in nm (``attrs["units"] = "nm"``) whatever the file's units
    (ENVI ``wavelength units``, the ``units`` attribute of a netCDF or Zarr ``wavelength``):
    nanometres, micrometres, millimetres and metres are converted, anything else refused, and
    the result must pass :func:`snapcorr._validation.check_wavelengths_nm`. With ``chunks``,
    the data are read lazily: ENVI and ``.npy`` block by block as dask computes them, netCDF
    and Zarr through xarray. ``chunks="rows"`` reads in blocks of whole rows (every x and
    band) of about :data:`BLOCK_BYTES`, as :func:`row_blocks` cuts them, decided from the
    shape once the file's header is read: the file is opened once, and each block reads only
    its rows (TIFF and OpenEXR, which OpenImageIO reads whole, are cut in memory).

Sensor positions
    ``sensor_row(y, band)`` and ``sensor_col(x, band)`` survive every format: native
    coordinates in netCDF and Zarr; elsewhere per band an offset and one step when
    ``position = offset_b + index * step`` exactly, else every value. In ENVI headers these are
    ``snapcorr sensor row offset = {...}`` with ``snapcorr sensor row step = N`` (or
    ``snapcorr sensor row = {...}``, row-major ``(y, band)``), the same for ``col``; in the
    JSON of TIFF, EXR and ``.npy`` sidecars ``{"offset": [...], "step": N}`` or
    ``{"values": [[...], ...]}``.

Attributes
    netCDF cannot store every attribute type, so :func:`write_dataset` (and :func:`write_cube`
    to ``.nc`` and ``.zarr``) writes strings, integers and floats (and 1-D numeric arrays of 2
    or more values) as themselves and everything else (booleans, None, lists, tuples, dicts,
    strings that start with ``json:``) as a string ``json:<JSON>``; :func:`read_dataset` and
    :func:`read_cube` decode them (a tuple comes back as a list). Other types are refused.
    TIFF, OpenEXR and ``.npy`` sidecars keep a cube's attributes in their JSON, ENVI headers
    in one field, ``snapcorr attrs = json:{...}``.
    Variables and coordinates whose attrs hold ``derived_from`` are not written; the file
    lists them in ``derived_variables`` and :func:`read_dataset` rebuilds them
    (:func:`snapcorr.cube.derived.restore`). Every file carries a mark of its writer (the
    attribute ``written_by = "snapcorr <version>"``, the header field ``snapcorr version``,
    ``"written_by"`` in the JSON of TIFF, EXR and sidecars).

Writing
    Writers check everything (dtype, sizes, wavelengths, attributes, the format's limits)
    before writing anything, write atomically (a hidden temporary name next to the target,
    then renamed) and never write over, into or around an input (an ENVI header and its data
    file, a ``.npy`` and its sidecar count as one). An existing target is replaced only with
    ``overwrite=True`` and only if snapcorr wrote it (its mark); a Zarr store also must hold
    nothing but Zarr metadata and arrays at its top level.

Modules
    This module holds the entry points; each format is one object of the registry
    :data:`snapcorr.files.registry.FILE_FORMATS`, in its family's module
    (:mod:`snapcorr.files.envi`, :mod:`snapcorr.files.images` for TIFF and OpenEXR,
    :mod:`snapcorr.files.npy`, :mod:`snapcorr.files.datasets` for netCDF and Zarr). What
    they share: :mod:`snapcorr.files.attrs` (attribute and sensor-position encoding),
    :mod:`snapcorr.files.storage` (what every reader shares, lazy row blocks),
    :mod:`snapcorr.files.marks` (the writer's mark) and :mod:`snapcorr.files.outputs`
    (targets, inputs and marks checked before writing).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import xarray as xr

from .._validation import check_wavelengths_nm
from ..cube.model import (
    FWHM_LONG_NAME,
    POSITION_ATTRS,
    POSITION_DIMS,
    check_cube,
    check_dtype,
    make_cube,
)
from .attrs import _decode_positions, _json_attrs, _one_line, _positions, decode_attrs
from .chunks import _IncompleteStore
from .datasets import (
    COMPRESSIONS,
    _encoded,
    _open_dataset,
    _to_dataset,
    stored_as,
)
from .marks import writer_mark
from .outputs import _check_targets, _check_writable
from .reading import check_input
from .registry import FORMATS, format_by_suffix, format_of
from .storage import _ENVI_DATA, _resolve_chunks, _Rows, _rows_per_block, _to_nm

__all__ = ["BLOCK_BYTES", "FORMATS", "read_array", "read_cube", "read_cube_and_mask",
           "read_dataset", "read_frame", "row_blocks", "write_cube", "write_dataset"]


#: Target size of the blocks a cube is streamed in (``snapcorr correct``, ``flatfield``), and
#: of the blocks ``chunks="rows"`` reads.
BLOCK_BYTES = 16 * 2**20


def row_blocks(cube, target_bytes=BLOCK_BYTES):
    """``cube`` in dask blocks of whole rows (every x and band) of about ``target_bytes``:
    memory stays bounded whatever the cube's size, and each spectrum stays in one block.
    ``read_cube(path, chunks="rows")`` reads a file directly in these blocks (of
    :data:`BLOCK_BYTES`)."""
    rows = _rows_per_block(cube.sizes["x"], cube.sizes["band"], cube.dtype, target_bytes)
    return cube.chunk({"y": rows, "x": -1, "band": -1})


def _as_chunks(chunks):
    """``chunks`` as the readers take them: ``"rows"`` becomes a
    :class:`~snapcorr.files.storage._Rows` of :data:`BLOCK_BYTES` (looked up now)."""
    if isinstance(chunks, str) and chunks == "rows":
        return _Rows(BLOCK_BYTES)
    if chunks is None or isinstance(chunks, _Rows):
        return chunks
    if not isinstance(chunks, dict):
        raise ValueError(f"chunks must be a dict of block sizes by dim ({{'y': 256}}), "
                         f"'rows' or None, got {chunks!r:.60}")
    for dim, size in chunks.items():
        whole = isinstance(size, int | np.integer) and not isinstance(size, bool)
        if not (whole and (size > 0 or size == -1)) and size not in ("auto", None):
            raise ValueError(f"chunks[{dim!r}] must be a whole number of values > 0, -1 (the "
                             f"whole dim) or 'auto', got {size!r:.60}")
    return chunks


# -- reading ---------------------------------------------------------------------------------


def read_array(path, *, what="cube", drop_alpha=False):
    """A file's values as stored, ``(y, x, band)``, before they are made a cube, the file
    checked as :func:`read_cube` checks it.

    Parameters
    ----------
    path : str or Path
        Any format :func:`read_cube` reads.
    what : str
        What the file is, in a refusal (``"flat field"``).
    drop_alpha : bool
        Leave an image's alpha channel out.

    Returns
    -------
    numpy.ndarray or xarray.Variable
        A numpy array (ENVI and ``.npy`` memory-mapped) or a netCDF or Zarr variable.
    """
    return _read_file(Path(path), what=what, drop_alpha=drop_alpha).data


def _read_file(path, *, chunks=None, what="cube", drop_alpha=False):
    """The one reader behind :func:`read_cube`, :func:`read_frame` and ``read_flat``.

    ``chunks``: None (read whole), a dict by dim, or ``"rows"`` (:func:`read_cube`); the
    file is opened once whichever is given."""
    chunks = _as_chunks(chunks)
    found_format, path, data_file = format_of(path, what)
    fmt = found_format.name
    check_input(path, directory=found_format.directory, what=what)
    try:
        found = found_format.read(path, data_file, chunks, what, drop_alpha)
    except (ValueError, TypeError, FileNotFoundError) as err:
        if str(err).startswith(str(path)) or str(err).startswith("no such file"):
            raise
        raise ValueError(f"{path}: cannot read it as {fmt}: {_one_line(err)}") from None
    except Exception as err:  # the libraries raise their own types; all mean a bad file
        raise ValueError(f"{path}: cannot read it as {fmt}: {type(err).__name__}: "
                         f"{_one_line(err)}") from None
    dtype = found.data.dtype
    if dtype.kind not in "iuf":
        try:
            check_dtype(dtype, f"{path}: a {what}")
        except TypeError as err:
            raise ValueError(str(err)) from None
    return found


def read_cube(path, *, wavelength_nm=None, chunks=None):
    """Read a cube from any supported format (see the module table).

    Parameters
    ----------
    path : str or Path
        A file (a folder for ``.zarr``); an ENVI cube by its header or its data file.
    wavelength_nm : array_like, optional
        Band wavelengths, nm, for files that carry none (a bare ``.npy``, a plain TIFF) or
        carry them in no length unit (ENVI ``wavelength units = Index``); a file's own
        wavelengths win, and a mismatch in length is an error.
    chunks : dict or "rows", optional
        Dask chunks (e.g. ``{"y": 512}``, or ``{}`` for the file's own): the cube is read
        lazily (ENVI and ``.npy`` block by block as computed). ``"rows"``: blocks of whole
        rows (every x and band) of about :data:`BLOCK_BYTES` (a value counted as
        ``max(itemsize, 4)`` bytes), decided from the shape once the header is read; the
        same blocks as ``row_blocks(read_cube(path, chunks={}))``, but the file is opened
        once, and each block reads only its own rows (a netCDF variable stored contiguously
        too). TIFF and OpenEXR are read whole by OpenImageIO, then cut.

    Returns
    -------
    xarray.DataArray
        dims ``(y, x, band)``, ``wavelength`` (and ``fwhm``) in nm, ``sensor_row`` and
        ``sensor_col`` when the file has them.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not a regular file (or folder for ``.zarr``), an unreadable or invalid file, wavelengths
        missing, in no length unit or not plausible in nm, values that are not real numbers.
    """
    return read_cube_and_mask(path, wavelength_nm=wavelength_nm, chunks=chunks)[0]


def read_cube_and_mask(path, *, wavelength_nm=None, chunks=None):
    """:func:`read_cube`'s cube and, from a netCDF or Zarr flat-field result, its
    ``mask(y, x, band)`` in the same blocks (None otherwise): the file is opened once.

    Parameters
    ----------
    path : str or Path
    wavelength_nm : array_like, optional
    chunks : dict or "rows", optional
        As for :func:`read_cube`; the mask comes in the cube's blocks.

    Returns
    -------
    cube : xarray.DataArray
    mask : xarray.DataArray or None
    """
    chunks = _as_chunks(chunks)
    f = _read_file(path, chunks=chunks, what="cube")
    try:
        cube = _to_cube(f, wavelength_nm)
    except (TypeError, ValueError, OverflowError) as err:
        if str(err).startswith(str(f.path)):
            raise
        raise type(err)(f"{f.path}: {err}") from None
    if chunks is not None and cube.chunks is None:  # read in memory (TIFF, OpenEXR)
        cube = cube.chunk(_resolve_chunks(chunks, cube.shape, cube.dtype))
    mask = f.extras.get("mask")
    if mask is not None and cube.chunks is not None:  # block for block with the cube
        mask = mask.chunk(dict(zip(mask.dims, cube.chunks, strict=True)))
    ignore = cube.attrs.get("data_ignore_value") if f.fmt == "envi" else None
    if ignore is not None:  # the header's no-data value (kept in the cube, as stored); a
        # result's copy of its raw cube's value says nothing of the values it computed
        ignored = (cube == ignore).drop_vars(list(cube.coords)).rename("mask")
        mask = ignored if mask is None else (mask | ignored)
    return cube, mask


def _cube_wavelengths(f, given, n_bands):
    if given is not None and np.size(given) != n_bands:  # the file's own would win unseen
        raise ValueError(f"{f.path} has {n_bands} bands but wavelength_nm gives "
                         f"{np.size(given)}; use the sensor it was taken with")
    wl = None
    if f.wavelength is not None:
        try:
            wl = _to_nm(f.wavelength, f.units, f"{f.path}: wavelength")
        except ValueError:
            if given is None:
                raise
            if str(f.units).strip().lower() != "index":  # ENVI's word for band numbers
                warnings.warn(f"{f.path}: its wavelength units {f.units!r} are not a length, "
                              "so its wavelengths are not read: the sensor's are used",
                              stacklevel=4)
    if wl is None:
        if given is None:
            raise ValueError(f"{f.path} carries no wavelengths; pass wavelength_nm")
        try:
            wl = np.atleast_1d(np.asarray(given, dtype=float))
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"wavelength_nm must be numbers, got {given!r:.80}") from None
    if wl.shape != (n_bands,):
        raise ValueError(f"{f.path} has {n_bands} bands but {wl.size} wavelengths")
    wl = check_wavelengths_nm("wavelengths", wl, where=str(f.path))
    fw = None
    if f.fwhm is not None:
        fw = _to_nm(f.fwhm, f.fwhm_units, f"{f.path}: fwhm")
        if fw.size == 1:
            fw = np.full(n_bands, fw[0])
        if fw.shape != (n_bands,):
            raise ValueError(f"{f.path}: {fw.size} fwhm values for {n_bands} bands")
    return wl, fw


def _to_cube(f, given):
    if f.file_ndim != 3:
        raise ValueError(f"{f.path} holds a {f.file_ndim}-D array; a cube is (y, x, band) "
                         "(read a 2-D frame with read_frame)")
    ny, nx, nb = f.data.shape
    wl, fw = _cube_wavelengths(f, given, nb)
    attrs = {k: v for k, v in f.attrs.items() if k not in ("written_by", "derived_variables")}
    wl_attrs = {"units": "nm", "long_name": "nominal wavelength"}
    if isinstance(f.data, xr.DataArray):
        cube = f.data.drop_vars([c for c in ("wavelength", "fwhm") if c in f.data.coords])
        wl_attrs = {**f.data["wavelength"].attrs, **wl_attrs} \
            if "wavelength" in f.data.coords else wl_attrs
        cube = cube.assign_coords(wavelength=("band", wl, wl_attrs))
        if fw is not None:
            cube = cube.assign_coords(
                fwhm=("band", fw, {"units": "nm", "long_name": FWHM_LONG_NAME}))
        cube.attrs = attrs
        cube.name = f.name
        return check_cube(cube)
    # a file that names nothing: whole numbers are a camera's raw counts (make_cube)
    cube = make_cube(f.data, wl, fwhm_nm=fw, attrs=attrs, name=f.name)
    sizes = {"y": ny, "x": nx, "band": nb}
    for name, spec in f.positions.items():
        dims = POSITION_DIMS[name]
        values = _decode_positions(spec, tuple(sizes[d] for d in dims), name, str(f.path))
        cube = cube.assign_coords({name: (dims, values, POSITION_ATTRS[name])})
    return check_cube(cube)


def read_frame(path, *, chunks=None):
    """Read a raw 2-D frame (a mosaic sensor's image, a flat, a dark).

    Parameters
    ----------
    path : str or Path
        A 2-D ``.npy`` (or ``(y, x, 1)``), a single-channel single-page TIFF or OpenEXR (an
        alpha channel is ignored), a single-band ENVI file, or a ``(y, x, 1)`` (or ``(y, x)``)
        variable in ``.nc`` or ``.zarr``.
    chunks : dict or "rows", optional
        Dask chunks (e.g. ``{"y": 512}``): read lazily (ENVI and ``.npy`` block by block as
        computed). ``"rows"``: blocks of whole rows of about :data:`BLOCK_BYTES`, decided
        from the shape once the header is read, the file opened once (see
        :func:`read_cube`).

    Returns
    -------
    xarray.DataArray
        dims ``("y", "x")``, named ``"frame"``; attrs ``source`` (and ``data_ignore_value``
        from an ENVI header).

    Raises
    ------
    ValueError
        A file holding more than one band (the message says how many), or any error of
        :func:`read_cube`'s readers.
    """
    chunks = _as_chunks(chunks)
    f = _read_file(path, chunks=chunks, what="frame", drop_alpha=True)
    nb = f.data.shape[2]
    if nb != 1:
        raise ValueError(f"{f.path} holds {nb} bands; a frame is one 2-D image: read it with "
                         "read_cube, or save the one band you need")
    attrs = {k: v for k, v in f.attrs.items() if k in ("source", "data_ignore_value")}
    attrs.setdefault("source", str(f.path))
    if isinstance(f.data, xr.DataArray):
        data = f.data.isel(band=0).data
    else:
        data = f.data[:, :, 0]
    frame = xr.DataArray(data, dims=("y", "x"), attrs=attrs, name="frame")
    if chunks is not None and frame.chunks is None:  # read in memory (TIFF, OpenEXR)
        chunks = _resolve_chunks(chunks, frame.shape, frame.dtype, frame.dims)
        frame = frame.chunk({k: v for k, v in chunks.items() if k in ("y", "x")})
    return frame


def read_dataset(path, *, chunks=None):
    """Open a result written by :func:`write_dataset` (``.nc`` or ``.zarr``).

    Attributes of the Dataset, its variables and coordinates come back as they were in
    memory (``json:`` strings decoded), the variables the file lists in
    ``derived_variables`` are rebuilt (:func:`snapcorr.cube.derived.restore`), and the
    writer's marks (``written_by``, ``derived_variables``) are removed from the attributes.

    Parameters
    ----------
    path : str or Path
    chunks : dict, optional
        Dask chunks (e.g. ``{}`` for the file's own): read lazily.

    Returns
    -------
    xarray.Dataset
    """
    from ..cube.derived import restore

    path = Path(path)
    found = format_by_suffix(path.suffix)
    if found is None or not found.holds_datasets:
        raise ValueError(f"results are .nc or .zarr files, got {path.suffix or '(none)'!r} "
                         f"for {path}")
    fmt = found.name
    check_input(path, directory=found.directory, what="result")
    try:
        ds = _open_dataset(path, fmt, chunks)
    except _IncompleteStore:
        raise
    except Exception as err:  # the libraries' own error types: report them plainly
        raise ValueError(f"{path}: cannot read it as {fmt}: {type(err).__name__}: "
                         f"{_one_line(err)}") from None
    ds.attrs = decode_attrs(ds.attrs)
    for var in ds.variables.values():
        var.attrs = decode_attrs(var.attrs)
    ds = restore(ds)
    for key in ("written_by", "derived_variables"):
        ds.attrs.pop(key, None)
    return ds


# -- writing ---------------------------------------------------------------------------------


def write_cube(cube, path, *, overwrite=False, inputs=(), interleave="bsq"):
    """Write a cube; the format follows the extension (see the module table).

    Everything is checked before anything is written: the cube (:func:`check_cube`: real
    values, no empty dim, wavelengths in nm without repeats), its attributes, the format's
    limits, the inputs and an existing target.

    Parameters
    ----------
    cube : xarray.DataArray
    path : str or Path
    overwrite : bool
        Replace an existing output snapcorr wrote (never one of ``inputs``, nor another file).
    inputs : sequence of paths
        Files the cube came from; writing over, into or around any of them is refused.
    interleave : {"bsq", "bil", "bip"}
        ENVI band interleave.

    Returns
    -------
    Path
        The path written (an ENVI cube: its header).
    """
    check_cube(cube)
    path = Path(path)
    if path.suffix.lower() in _ENVI_DATA:
        raise ValueError(f"an ENVI cube is written by its header's name: "
                         f"{path.with_suffix('.hdr')} (its data go to "
                         f"{path.with_suffix('.raw').name}), not {path.name}")
    found, path, _ = format_of(path)
    if found.native_byte_order:  # written whole: the values in the machine's own byte order
        values = np.asarray(cube.values)  # (zarr gives an explicit "<f4", OpenImageIO
        cube = cube.copy(data=values.astype(values.dtype.newbyteorder("=")))  # refuses it)
    _check_writable(found.name, cube, path, interleave)
    name = cube.name or "radiance"
    if found.holds_datasets:
        ds = _encoded(_to_dataset(cube))
    else:
        meta = _cube_meta(cube, name)
    _check_targets(found.name, found.targets(path), overwrite=overwrite, inputs=inputs)
    if found.holds_datasets:
        found.write(ds, path)
    else:
        found.write(cube, path, meta, interleave=interleave)
    return path


def _cube_meta(cube, name):
    meta = {"written_by": writer_mark(), "name": name, "dtype": str(cube.dtype),
            "shape": list(cube.shape),
            "attrs": _json_attrs(cube.attrs, f"cube {name!r}"),
            "wavelength_nm": [float(v) for v in cube.wavelength.values]}
    if "fwhm" in cube.coords:
        meta["fwhm_nm"] = [float(v) for v in cube.fwhm.values]
    meta.update(_positions(cube))
    return meta




def write_dataset(ds, path, *, overwrite=False, inputs=(), compression="auto",
                  store_derived=False, dtype=None, pack_range=None):
    """Write a Dataset (a corrected cube with its mask, raw data and provenance) to ``.nc`` or
    ``.zarr``, atomically.

    Every attribute of the Dataset, its variables and coordinates is written (see the module
    docstring for how netCDF and Zarr hold those they cannot store natively; other types are
    refused before anything is written); variables and coordinates whose attrs hold
    ``derived_from`` are left out and listed in ``derived_variables``, for
    :func:`read_dataset` to rebuild, unless ``store_derived``. Zarr stores get consolidated
    metadata.

    Parameters
    ----------
    ds : xarray.Dataset
        Not changed.
    path : str or Path
        ``.nc`` or ``.zarr``.
    overwrite : bool
        Replace an existing output snapcorr wrote (never one of ``inputs``, nor another file
        or folder).
    inputs : sequence of paths
        Files the data came from; writing over, into or around any of them is refused.
    compression : {"auto", "all", "none"}
        ``"auto"`` compresses where it pays: every numeric variable of a Zarr store (Blosc LZ4,
        about as fast as writing plainly); in netCDF, DEFLATE (level 1, byte shuffle) for
        integer and boolean variables (raw counts, masks: about 0.6 and under 0.05 of their
        size) and stored derived variables (smooth: about 0.25), while noisy floating-point
        cubes stay plain (about 0.75 of their size for 6 x the writing time). ``"all"`` also
        compresses those; ``"none"`` compresses nothing.
    store_derived : bool
        Write the derived variables (``wavelength_corrected``, ``fwhm_corrected``) as plain
        data variables, with their formula in ``computed_from``, for readers without snapcorr.
    dtype : {None, "float32", "float16", "uint16"}
        The type the values (the cube and the spectra computed from it) are stored as; None
        keeps each variable's own. ``"uint16"`` packs them by CF ``scale_factor`` and
        ``add_offset`` (NaN as ``_FillValue`` 65535, codes 0-65534 in ``valid_range``), which
        xarray and netCDF readers apply: ratios (units ``"1"``) over -0.5 to 3.5 by default,
        a step of 6.1e-5, at most 3.2e-5 from the value computed (half a step and float32's
        rounding); values outside the range are stored as its ends (clipped). Each packed
        variable says its packing, its error and the clipping in its ``storage`` and
        ``packing_error`` attributes. ``"float16"``
        (Zarr only; netCDF has no such type): relative error at most 4.9e-4; finite values
        beyond its range, +-65504, are stored as +-65504 (clipped, said in ``storage``),
        infinities and NaN as they are. A camera's
        numbers are never stored as either: the input's copy (``raw``) keeps its type, and
        other values in counts (or without units) are refused.
    pack_range : (float, float), optional
        ``(lo, hi)`` for ``"uint16"``: needed for values in units other than ``"1"``.

    Returns
    -------
    Path

    Warns
    -----
    PackingClipWarning
        Once per packed variable with values beyond its range (the count and the share), and
        for float16 once per variable with finite values beyond +-65504.
    """
    path = Path(path)
    found = format_by_suffix(path.suffix)
    if found is None or not found.holds_datasets:
        raise ValueError(f"results are written as .nc or .zarr, got {path.suffix or '(none)'!r}")
    if compression not in COMPRESSIONS:
        raise ValueError(f"compression must be one of {', '.join(COMPRESSIONS)}, got "
                         f"{compression!r}")
    out = stored_as(_encoded(ds, store_derived=store_derived), dtype, pack_range, found.name)
    _check_targets(found.name, found.targets(path), overwrite=overwrite, inputs=inputs)
    return found.write(out, path, compression)
