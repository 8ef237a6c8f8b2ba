"""A stream of raw mosaic frames through the whole pipeline, lazily: flat-field each frame
pixel by pixel, demosaic it, and correct it.

Every step is a dask graph over whole frames (the demosaicking kernel's halo comes from
:func:`dask.array.overlap.overlap` where a frame is split into blocks), so a stream larger than
memory is written frame by frame, to a ``.zarr`` store for instance, whatever scheduler runs
it (threads, processes or :mod:`dask.distributed`): the values are the same as frame by frame
in memory. The geometry (each pixel's chief-ray angle and corrected wavelengths) is the same
for every frame of a stream and is computed once.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import xarray as xr

from ._coords import accepts_center_rc
from .cube import demosaic, flatfield
from .cube.io import COMPUTED_WITH
from .cube.mosaic import frame_saturation
from .cube.phase import check_mosaic_phase

__all__ = ["process_stream"]


@accepts_center_rc
def process_stream(frames, dark, white, sensor, *, demosaic_method="ri", lens=None,
                   f_number=None, origin_px=None, saturation=None, dtype="float32",
                   resample=False, method="auto", tolerance_nm=None, center_px=None,
                   virtual_bands=None, virtual_matrix=None, virtual_wavelengths_nm=None,
                   virtual_fwhm_nm=None):
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
    origin_px : (int, int), optional
        Sensor row and column of the frames' first pixel; refused where the first white
        shows another phase of the mosaic (:func:`~snapcorr.cube.phase.check_mosaic_phase`).
    saturation : float, optional
        Default: the sensor's largest code (its ``bit_depth``), where it gives one
        (:func:`~snapcorr.cube.mosaic.frame_saturation`).
    dtype : {"float32", "float64"}
    resample : bool
        Also every frame's spectra on the nominal wavelengths (``resampled``).
    method, tolerance_nm, center_rc, center_px
        The correction's model, tolerance and optical centre
        (:func:`~snapcorr.correct.correct_cube`; harmonised spectra are not offered for
        streams).
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
    if not isinstance(frames, xr.DataArray) or tuple(frames.dims) != ("frame", "y", "x"):
        dims = tuple(frames.dims) if isinstance(frames, xr.DataArray) else type(frames).__name__
        raise ValueError(f"a stream is a DataArray of dims (frame, y, x), got {dims}")
    if (lens is None) != (f_number is None):
        raise ValueError("correcting a stream needs both a lens and an f-number")
    if lens is None and (method != "auto" or tolerance_nm is not None or center_px is not None):
        raise ValueError("method, tolerance_nm and the optical centre choose the correction: "
                         "give a lens and an f-number too (the demosaicking method is "
                         "demosaic_method)")
    if 0 in frames.shape:
        raise ValueError(f"the stream holds no frame (shape {frames.shape})")
    whites, darks = (v if isinstance(v, (list, tuple)) else [v] for v in (white, dark))
    saturation = frame_saturation(sensor, whites, saturation)
    check_mosaic_phase(whites[0], sensor, origin_px, dark=darks[0] if darks else None,
                       saturation=saturation)
    ff = flatfield(frames, dark, white, saturation=saturation, dtype=dtype)
    ds = demosaic(ff, sensor, demosaic_method, origin_px=origin_px)
    # which file each frame came from, and by what order (a folder of frames)
    ds.attrs.update({k: frames.attrs[k] for k in ("frame_files", "frame_order")
                     if k in frames.attrs})
    if lens is None:
        if resample or virtual_bands is not None:
            raise ValueError("resampling a stream, or its virtual bands, need a lens and an "
                             "f-number")
        return ds
    from .correct import correct_cube

    cube = ds["reflectance"]
    if method in ("harmonised",):
        raise ValueError("a stream's correction gives corrected wavelengths (and resampled "
                         "spectra); harmonised spectra are made cube by cube with "
                         "correct_cube")
    options = {"method": method, "center_px": center_px, "virtual_bands": virtual_bands,
               "virtual_matrix": virtual_matrix, "virtual_wavelengths_nm": virtual_wavelengths_nm,
               "virtual_fwhm_nm": virtual_fwhm_nm}
    if tolerance_nm is not None:
        options["tolerance_nm"] = tolerance_nm
    # the first frame computed once (held in memory while the geometry is found): the
    # virtual bands' error bars read several patches of it
    first = cube.isel(frame=0)
    geometry = correct_cube(first.persist() if first.chunks is not None else first, sensor,
                            f_number, lens, **options)
    per_frame = ["reflectance"] + (["virtual"] if virtual_bands is not None else [])
    out = ds.merge(geometry.drop_vars(per_frame), compat="override")
    out.attrs = {**ds.attrs, "flatfield_method": ds.attrs.get("method"), **geometry.attrs}
    if resample:
        out["resampled"] = _resampled_frames(cube, geometry, sensor)
    if virtual_bands is not None:
        # written in the cube's pass: each frame demosaicked once for both
        out["virtual"] = _virtual_frames(cube, geometry).assign_attrs({COMPUTED_WITH: cube.name})
    return out


def _resampled_frames(cube, geometry, sensor):
    """Every frame's spectra on the nominal wavelengths, frame by frame (each a cube of its
    own), written in the cube's pass (each frame demosaicked once)."""
    from .correct.core import _resampled

    scale, column = geometry["wavelength_scale"].values, geometry["scale_index"].values
    out = xr.concat([_resampled(cube.isel(frame=i), scale, column, sensor.cwl_nm)
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
