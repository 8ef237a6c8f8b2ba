"""Raw mosaic frames through the whole pipeline: one list of steps, :data:`PIPELINE_STEPS`
(flat-field each frame pixel by pixel, demosaic it, correct it, its virtual bands), for one
frame (:func:`process_frame`) and for a stream of them (:func:`process_stream`); and reading
the frame or cube a step starts from (:func:`read_cube_or_frame`, :func:`read_mosaic_frame`).

Every step is a dask graph over whole frames (the demosaicking kernel's halo comes from
:func:`dask.array.overlap.overlap` where a frame is split into blocks), so a stream larger than
memory is written frame by frame, to a ``.zarr`` store for instance, whatever scheduler runs
it (threads, processes or :mod:`dask.distributed`): the values are the same as frame by frame
in memory. The geometry (each pixel's chief-ray angle and corrected wavelengths) is the same
for every frame of a stream and is computed once.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import xarray as xr

from ._coords import accepts_center_rc
from ._threads import dask_threads
from ._validation import renamed_keywords
from .correct.resample import resample_cube
from .correct.virtual import VirtualBandOptions
from .cube import demosaic, flatfield
from .cube.flatfield import check_masked
from .cube.mosaic import frame_saturation
from .cube.phase import check_mosaic_phase
from .files.api import BLOCK_BYTES
from .files.datasets import COMPUTED_WITH

__all__ = ["PIPELINE_STEPS", "process_frame", "process_stream", "read_cube_or_frame",
           "read_mosaic_frame", "tile_rows", "with_transmittance"]

#: The steps from raw mosaic frames to a corrected cube, in order, as :func:`process_frame`
#: and :func:`process_stream` take them: each step's name and its function ``step(data,
#: job)`` (filled in below, where the steps are defined); "correct" and "virtual bands" run
#: with a lens only.
PIPELINE_STEPS = {}


def process_frame(raw, dark, white, sensor, *, demosaic_method="ri", sensor_origin_px=None,
                  saturation=None, dtype="float32", filter_white=None, lens=None,
                  f_number=None, on_step=None, **correction):
    """Flat-field a raw mosaic frame pixel by pixel, demosaic it and (with a lens) correct it:
    the steps of :data:`PIPELINE_STEPS`, as :func:`process_stream` takes them for a stream.

    Parameters
    ----------
    raw : xarray.DataArray
        The frame ``(y, x)``, numpy- or dask-backed (:func:`read_mosaic_frame`).
    dark, white : xarray.DataArray or sequence of them
        Reference frames of the raw frame's size, averaged.
    sensor : Sensor
        The mosaic sensor.
    demosaic_method : str
        A name of :data:`~snapcorr.cube.DEMOSAIC_METHODS`.
    sensor_origin_px : (int, int), optional
        Sensor row and column of the frame's first pixel.
    saturation : float, optional
        Default: the sensor's largest code (:func:`~snapcorr.cube.mosaic.frame_saturation`).
    dtype : {"float32", "float64"}
    filter_white : xarray.DataArray, optional
        The white seen through the filter: its transmittance is added
        (:func:`with_transmittance`).
    lens : Lens, optional
        With ``f_number``: correct the frame (:func:`~snapcorr.correct.correct_cube`, which
        takes the keywords ``correction``: ``method``, ``resample``, ``virtual_bands``, ...).
    f_number : float, optional
    on_step : callable, optional
        ``on_step(name)`` before each step (a progress bar's).

    Returns
    -------
    xarray.Dataset
        The demosaicked flat-field result (``reflectance(y, x, band)``, ``mask``, ``raw``,
        ``n_masked``), with the correction's variables with a lens. The mask is checked
        (:func:`~snapcorr.cube.flatfield.check_masked`): a frame all masked is refused.
    """
    if (lens is None) != (f_number is None):
        raise ValueError("correcting a frame needs both a lens and an f-number")
    whites = white if isinstance(white, (list, tuple)) else [white]
    saturation = frame_saturation(sensor, whites, saturation)
    resample = correction.pop("resample", False)
    virtual = VirtualBandOptions(*(correction.pop(k, None) for k in (
        "virtual_bands", "virtual_matrix", "virtual_wavelengths_nm", "virtual_fwhm_nm")))
    job = _Job(dark=dark, white=white, sensor=sensor, demosaic_method=demosaic_method,
               sensor_origin_px=sensor_origin_px, saturation=saturation, dtype=dtype,
               lens=lens, f_number=f_number, resample=resample, correction=correction,
               virtual=virtual, check_masked=True)
    ds = _run(raw, job, on_step)
    if filter_white is not None:
        tr = _run(filter_white, dataclasses.replace(job, name="transmittance", lens=None,
                                                    check_masked=False))
        with_transmittance(ds, tr)
    return ds


def with_transmittance(ds, tr, path=None):
    """The filter's transmittance added to a flat-field result, in place.

    Parameters
    ----------
    ds : xarray.Dataset
        A flat-field result (:func:`~snapcorr.cube.flatfield`, demosaicked or not).
    tr : xarray.Dataset
        The flat-field result of the white seen through the filter, named
        ``"transmittance"``, of the same size and place.
    path : str or Path, optional
        The file it came from (``filter_white_file``).

    Returns
    -------
    xarray.Dataset
        ``ds``, with ``transmittance``, ``filter_white_raw`` and ``transmittance_mask``.
    """
    ds["transmittance"] = tr["transmittance"]
    ds["filter_white_raw"] = tr["raw"]
    ds["transmittance_mask"] = tr["mask"].assign_attrs(
        long_name="transmittance value not meaningful")
    if path is not None:
        ds.attrs["filter_white_file"] = str(path)
    return ds


def tile_rows(frame, sensor):
    """Rows per block of a 2-D mosaic frame: whole tiles, about 16 MiB
    (:data:`~snapcorr.files.api.BLOCK_BYTES`)."""
    tr = sensor.mosaic_shape[0]
    return max(tr, (BLOCK_BYTES // max(1, frame.sizes["x"] * 4)) // tr * tr)


def read_mosaic_frame(path, sensor, *, what=None, shape=None):
    """A raw 2-D mosaic frame, opened once, lazily in whole-tile row blocks (:func:`tile_rows`).

    Parameters
    ----------
    path : str or Path
    sensor : Sensor
        The mosaic sensor (its tile's height).
    what : str, optional
        How a message names the frame (``"--dark"``).
    shape : (int, int), optional
        The frame's shape; another is refused (a reference of another frame's size).

    Returns
    -------
    xarray.DataArray
        ``(y, x)``, dask-backed.
    """
    from .files.api import read_frame

    frame = read_frame(path, chunks="rows")
    size = getattr(sensor, "size_px", None)
    if size is not None and (frame.shape[0] > size[0] or frame.shape[1] > size[1]):
        raise ValueError(f"{(what + ' ') if what else ''}{path} is {frame.shape[0]} x "
                         f"{frame.shape[1]} px, larger than the sensor {sensor.name!r} "
                         f"({size[0]} x {size[1]} px): not a raw frame of it (another camera, "
                         "or another sensor file?)")
    frame = frame.chunk({"y": tile_rows(frame, sensor), "x": -1})
    if shape is not None and frame.shape != shape:
        raise ValueError(f"{what} {path} is {frame.shape[0]} x {frame.shape[1]} px but the raw "
                         f"frame {shape[0]} x {shape[1]}: a snapshot's references are frames "
                         "of the same size and place")
    return frame


def read_cube_or_frame(path, sensor=None, sensor_origin_px=None, *, with_mask=False):
    """A cube, or a raw mosaic frame split into bands, from any format, in row blocks of
    about 16 MiB whatever the file's size (ENVI and .npy memory-mapped, never copied whole).

    Parameters
    ----------
    path : str or Path
    sensor : Sensor, optional
        The bands' wavelengths; a mosaic sensor splits a raw 2-D frame into its bands
        (:func:`~snapcorr.cube.mosaic_to_cube`).
    sensor_origin_px : (int, int), optional
        Sensor row and column of the first pixel: places a crop that does not record its
        sensor positions, and must agree with those it records.
    with_mask : bool
        Also a flat-field result's ``mask`` (or None), from the same opening.

    Returns
    -------
    xarray.DataArray, or (xarray.DataArray, xarray.DataArray or None)
    """
    cube, mask = _read_cube_or_frame(path, sensor, sensor_origin_px)
    return (cube, mask) if with_mask else cube


def _read_cube_or_frame(path, sensor, origin):
    from .files.api import read_cube_and_mask

    wl = sensor.cwl_nm if sensor is not None else None
    frame_error = None
    if sensor is not None and sensor.layout == "mosaic":
        try:
            frame = read_mosaic_frame(path, sensor)
        except ValueError as err:  # not a single-band frame: read it as a cube below
            frame_error = err
        else:
            from .cube import mosaic_to_cube

            try:
                return mosaic_to_cube(frame.data, sensor, sensor_origin_px=origin,
                                      attrs={**frame.attrs, "source": str(path)}), None
            except ValueError as err:
                raise ValueError(f"{path}: {err}") from None
    try:  # opened once, read in blocks
        cube, mask = read_cube_and_mask(path, wavelength_nm=wl, chunks="rows")
    except ValueError as err:
        if frame_error is not None and "2-D" in str(err):
            raise frame_error from None
        raise
    if origin is not None:
        from .cube import sensor_positions
        from .cube.model import with_positions

        # the positions are the sensor's bands': a cube listing them in another order (by
        # falling wavelength, the vendor's tile order) takes the sensor's first
        cube, mask = sensor.in_band_order(cube, mask)
        rows, cols = sensor_positions(sensor, cube.sizes["y"], cube.sizes["x"], origin)
        if "sensor_row" not in cube.coords:
            cube = with_positions(cube, rows, cols)
        else:
            _check_origin(path, cube, rows, cols, origin)
    return cube, mask


def _check_origin(path, cube, rows, cols, origin):
    """A --sensor-origin-px must agree with the positions the file records (which are used)."""
    for coord, dim, want in (("sensor_row", "y", rows), ("sensor_col", "x", cols)):
        if coord not in cube.coords:
            continue
        have = np.asarray(cube[coord].transpose(dim, ...).values)
        have = have if have.ndim == 2 else have[:, None]
        if have.shape[0] != want.shape[0] or not np.array_equal(
                np.broadcast_to(have, want.shape) if have.shape[1] == 1 else have, want):
            raise ValueError(f"sensor_origin_px ({origin[0]}, {origin[1]}) disagrees with the "
                             f"sensor positions {path} records (its first pixel at row "
                             f"{int(np.min(cube['sensor_row']))}, col "
                             f"{int(np.min(cube['sensor_col']))}); leave it out: the "
                             "file's positions are used")


@renamed_keywords(origin_px="sensor_origin_px")
@accepts_center_rc
def process_stream(frames, dark, white, sensor, *, demosaic_method="ri", lens=None,
                   f_number=None, sensor_origin_px=None, saturation=None, dtype="float32",
                   resample=False, method="auto", tolerance_nm=None, center_rc=None,
                   center_px=None, virtual_bands=None, virtual_matrix=None,
                   virtual_wavelengths_nm=None, virtual_fwhm_nm=None):
    """Flat-field, demosaic and (with a lens) correct a stream of raw mosaic frames.

    Parameters
    ----------
    frames : xarray.DataArray
        Dims ``(frame, y, x)``, numpy- or dask-backed (:func:`~snapcorr.cube.read_frames`).
    dark, white : xarray.DataArray or sequence of them
        Reference frames ``(y, x)`` of the frames' size, averaged (:func:`~snapcorr.cube.
        flatfield`).
    sensor : Sensor
        The mosaic sensor.
    demosaic_method : str
        A name of :data:`~snapcorr.cube.DEMOSAIC_METHODS`.
    lens : Lens, optional
        With ``f_number``: add the per-pixel corrected wavelengths
        (:func:`~snapcorr.correct.correct_cube`, computed once for the stream).
    f_number : float, optional
    sensor_origin_px : (int, int), optional
        Sensor row and column of the frames' first pixel (``origin_px``: its earlier name);
        refused where the first white shows another phase of the mosaic
        (:func:`~snapcorr.cube.phase.check_mosaic_phase`).
    saturation : float, optional
        Default: the sensor's largest code (its ``bit_depth``), where it gives one
        (:func:`~snapcorr.cube.mosaic.frame_saturation`).
    dtype : {"float32", "float64"}
    resample : bool
        Also every frame's spectra on the nominal wavelengths (``resampled``).
    method, tolerance_nm, center_rc, center_px
        The correction's model, tolerance and optical centre ``(row, col)`` in sensor pixels
        (:func:`~snapcorr.correct.correct_cube`; harmonised spectra are not offered for
        streams). ``center_px=(cx, cy)``, x first, is the centre's deprecated form.
    virtual_bands, virtual_matrix, virtual_wavelengths_nm, virtual_fwhm_nm
        Also every frame's virtual bands (:func:`~snapcorr.correct.virtual_bands`, with a
        lens): the matrix (or the angle-aware table) and the band noise are chosen once, on
        the first frame, and applied to every frame.

    Returns
    -------
    xarray.Dataset
        ``reflectance(frame, y, x, band)``, ``mask`` of the same dims, the ``raw`` frames cut
        to the filter area, ``n_masked``; with a lens the correction's variables
        (``wavelength_corrected(y, x, band)``, ``cra_deg``, ...) and its provenance, and
        ``virtual(frame, y, x, virtual_band)`` when asked for. Lazy for dask frames.
    """
    from .correct.virtual import check_virtual_options

    check_virtual_options(virtual_bands, virtual_matrix, virtual_wavelengths_nm,
                          virtual_fwhm_nm)
    if not isinstance(frames, xr.DataArray) or tuple(frames.dims) != ("frame", "y", "x"):
        dims = tuple(frames.dims) if isinstance(frames, xr.DataArray) else type(frames).__name__
        raise ValueError(f"a stream is a DataArray of dims (frame, y, x), got {dims}")
    if getattr(sensor, "layout", None) != "mosaic":
        name = getattr(sensor, "name", None) or type(sensor).__name__
        raise ValueError(f"a stream is raw mosaic frames: sensor {name!r} is not a mosaic "
                         f"(layout {getattr(sensor, 'layout', None)!r})")
    if (lens is None) != (f_number is None):
        raise ValueError("correcting a stream needs both a lens and an f-number")
    if lens is None and (method != "auto" or tolerance_nm is not None or center_rc is not None):
        raise ValueError("method, tolerance_nm and the optical centre choose the correction: "
                         "give a lens and an f-number too (the demosaicking method is "
                         "demosaic_method)")
    if 0 in frames.shape:
        raise ValueError(f"the stream holds no frame (shape {frames.shape})")
    whites, darks = (v if isinstance(v, (list, tuple)) else [v] for v in (white, dark))
    saturation = frame_saturation(sensor, whites, saturation)
    check_mosaic_phase(whites[0], sensor, sensor_origin_px, dark=darks[0] if darks else None,
                       saturation=saturation)
    if lens is None and (resample or virtual_bands is not None):
        raise ValueError("resampling a stream, or its virtual bands, need a lens and an "
                         "f-number")
    if lens is not None and method in ("harmonised",):
        raise ValueError("a stream's correction gives corrected wavelengths (and resampled "
                         "spectra); harmonised spectra are made cube by cube with "
                         "correct_cube")
    job = _Job(dark=dark, white=white, sensor=sensor, demosaic_method=demosaic_method,
               sensor_origin_px=sensor_origin_px, saturation=saturation, dtype=dtype,
               lens=lens, f_number=f_number, resample=resample,
               correction=_correction_options(method, tolerance_nm, center_rc),
               virtual=VirtualBandOptions(virtual_bands, virtual_matrix,
                                          virtual_wavelengths_nm, virtual_fwhm_nm))
    return _run(frames, job)


def _run(data, job, on_step=None):
    """``data`` through every step of :data:`PIPELINE_STEPS` that ``job`` asks for."""
    with dask_threads(import_dask=True):
        for name, step in PIPELINE_STEPS.items():
            if name in ("correct", "virtual bands") and job.lens is None:
                continue
            if on_step is not None:
                on_step(name)
            data = step(data, job)
    return data


def _correction_options(method, tolerance_nm, center_rc):
    """The keywords of :func:`~snapcorr.correct.correct_cube` that choose the correction."""
    options = {"method": method, "center_rc": center_rc}
    if tolerance_nm is not None:
        options["tolerance_nm"] = tolerance_nm
    return options


@dataclasses.dataclass
class _Job:
    """What every step of a run needs: the references, the sensor and each step's options."""

    dark: object
    white: object
    sensor: object
    demosaic_method: str = "ri"
    sensor_origin_px: tuple | None = None
    saturation: float | None = None
    dtype: str = "float32"
    lens: object = None
    f_number: float | None = None
    resample: bool = False
    correction: dict = dataclasses.field(default_factory=dict)
    virtual: VirtualBandOptions = dataclasses.field(default_factory=VirtualBandOptions)
    name: str | None = None
    check_masked: bool = False
    geometry: object = None  # a stream's first frame's correction, once made


def _flat_field(raw, job):
    """Step "flat-field": each pixel against the dark and white, its mask checked for a
    single frame (:func:`~snapcorr.cube.flatfield.check_masked`)."""
    kw = {"name": job.name} if job.name is not None else {}
    ff = flatfield(raw, job.dark, job.white, saturation=job.saturation, dtype=job.dtype, **kw)
    if job.check_masked:
        check_masked(ff)
    # which file each frame came from, and by what order (a folder of frames)
    ff.attrs.update({k: raw.attrs[k] for k in ("frame_files", "frame_order")
                     if k in raw.attrs})
    return ff


def _demosaic(ff, job):
    """Step "demosaic": every band at every pixel."""
    ds = demosaic(ff, job.sensor, job.demosaic_method, sensor_origin_px=job.sensor_origin_px)
    ds.attrs.update({k: ff.attrs[k] for k in ("frame_files", "frame_order") if k in ff.attrs})
    return ds


def _correct(ds, job):
    """Step "correct": the corrected wavelengths (and the virtual bands of a single frame);
    for a stream computed once, on its first frame (held in memory while the geometry is
    found: the virtual bands' error bars read several patches of it)."""
    from .correct import correct_cube

    cube = ds["reflectance"]
    stream = "frame" in cube.dims
    first = cube.isel(frame=0) if stream else cube
    if stream and first.chunks is not None:
        first = first.persist()
    geometry = correct_cube(first, job.sensor, job.f_number, job.lens, **job.correction,
                            **job.virtual.keywords(),
                            **({} if stream else {"resample": job.resample}))
    per_frame = ["reflectance"] + (["virtual"] if stream and job.virtual.method else [])
    out = ds.merge(geometry.drop_vars(per_frame), compat="override")
    out.attrs = {**ds.attrs, "flatfield_method": ds.attrs.get("method"), **geometry.attrs}
    if stream:
        job.geometry = geometry
        if job.resample:
            out["resampled"] = _resampled_frames(cube, geometry, job.sensor)
    return out


def _virtual(ds, job):
    """Step "virtual bands": a stream's every frame by its first frame's matrix or table,
    written in the cube's pass (each frame demosaicked once); a single frame has them from
    its correction."""
    geometry = job.geometry
    if geometry is not None and job.virtual.method is not None:
        cube = ds["reflectance"]
        ds["virtual"] = _virtual_frames(cube, geometry).assign_attrs({COMPUTED_WITH: cube.name})
    return ds


PIPELINE_STEPS.update({"flat-field": _flat_field, "demosaic": _demosaic, "correct": _correct,
                       "virtual bands": _virtual})


def _resampled_frames(cube, geometry, sensor):
    """Every frame's spectra on the nominal wavelengths, frame by frame (each a cube of its
    own), written in the cube's pass (each frame demosaicked once)."""
    scale, column = geometry["wavelength_scale"].values, geometry["scale_index"].values
    out = xr.concat([resample_cube(cube.isel(frame=i), scale, column, sensor.cwl_nm)
                     for i in range(cube.sizes["frame"])], dim="frame")
    out.attrs[COMPUTED_WITH] = cube.name
    return out


def _virtual_frames(cube, geometry):
    """Every frame's virtual bands by the first frame's matrix or angle-aware table."""
    from .correct.virtual import apply_virtual

    first = geometry["virtual"]
    cra = None
    if "virtual_table" in geometry:  # each pixel at the mean angle of its bands, as correct_cube
        cra = np.asarray(geometry["cra_deg"].transpose("y", "x", ...).values)
        cra = cra.mean(axis=2) if cra.ndim == 3 else cra
    if cube.chunks is None:
        frames = [apply_virtual(cube.isel(frame=i), geometry, cra).transpose(*first.dims)
                  for i in range(cube.sizes["frame"])]
        return xr.concat(frames, dim="frame").assign_coords(first.coords).assign_attrs(
            first.attrs)
    along = {k: cube.coords[k] for k in cube.coords if "band" not in cube.coords[k].dims}
    out = xr.DataArray(_virtual_blocks(cube.transpose("frame", "y", "x", "band").data,
                                       geometry, cra),
                       dims=("frame", "y", "x", "virtual_band"), coords=along)
    return out.transpose("frame", *first.dims).assign_coords(first.coords).assign_attrs(
        first.attrs)


def _virtual_blocks(data, geometry, cra):
    """The virtual bands of a dask stream ``(frame, y, x, band)``, block by block: the matrix,
    or the table and each pixel's angle (in the arithmetic's type), made once for the stream
    and shared by every block."""
    import dask.array as da

    from .correct.virtual import apply_table

    dtype = np.float64 if data.dtype == np.float64 else np.float32
    if "virtual_matrix" in geometry:
        mat = np.asarray(geometry["virtual_matrix"].values).T.astype(dtype)

        def one(values, rows, cols):
            return np.asarray(values, dtype) @ mat
    else:
        table = SimpleNamespace(matrices=np.asarray(geometry["virtual_table"].values),
                                cra_deg=np.asarray(geometry["virtual_cra_deg"].values))
        mat = table.matrices[0].T
        angle = np.ascontiguousarray(cra, dtype)

        def one(values, rows, cols):
            return apply_table(values, angle[rows, cols], table, dtype)

    nv = mat.shape[1]
    data = data.rechunk({3: -1})

    def block(a, block_info=None):
        (y0, y1), (x0, x1) = block_info[0]["array-location"][1:3]
        res = np.empty((*a.shape[:3], nv), dtype)
        for k in range(a.shape[0]):
            res[k] = one(a[k], slice(y0, y1), slice(x0, x1))
        return res

    return da.map_blocks(block, data, chunks=(*data.chunks[:3], (nv,)), dtype=dtype)
