"""Reading a command's inputs: a cube, or a raw mosaic frame split into bands, with its
sensor origin checked; a raw frame flat-fielded, then demosaicked."""

from __future__ import annotations

import sys

from ._output import RAW_COPIES, _masked_in, _quicklook, _stored_type, _write_result
from ._progress import _StageBar


def _read(path, sensor=None, origin=None):
    """A cube (or a raw mosaic frame split into bands) from any format, in row blocks."""
    from ..pipeline import read_cube_or_frame

    return read_cube_or_frame(path, sensor, origin)


def _read_with_mask(path, sensor=None, origin=None):
    """:func:`_read`'s cube and a flat-field result's ``mask`` (or None), from one opening."""
    from ..pipeline import read_cube_or_frame

    return read_cube_or_frame(path, sensor, origin, with_mask=True)


def _read_frame_rows(path, sensor):
    """A raw 2-D mosaic frame, opened once, lazily in whole-tile row blocks."""
    from ..pipeline import read_mosaic_frame

    return read_mosaic_frame(path, sensor)


def _read_frame_checked(path, sensor, what, shape=None):
    """A raw 2-D mosaic frame, lazily in whole-tile row blocks; of ``shape`` when given."""
    from ..pipeline import read_mosaic_frame

    return read_mosaic_frame(path, sensor, what=what, shape=shape)


def _default_saturation(args, sensor, whites):
    """``--saturation`` defaults to the sensor's largest code (its bit depth), else to the
    whites' integer type's. Returns what to say of it once the work is done (None where it
    was given or none applies): the level, whence, and how to change it (a camera of fewer
    bits than its files' type saturates below the type's largest code)."""
    from ..cube.mosaic import frame_saturation

    if args.saturation is not None:
        return None
    args.saturation = frame_saturation(sensor, whites, what=f"--white {args.white[0]}")
    if args.saturation is None:
        return None
    import numpy as np

    if sensor is not None and sensor.full_scale_dn is not None:
        of, change = f"{sensor.bit_depth}-bit code of the sensor", "--saturation DN"
    else:
        of = f"code of the whites' type, {np.dtype(whites[0].dtype)}"
        change = "--saturation DN, or bit_depth in a sensor TOML, for fewer bits"
    return f"saturation: {args.saturation:g} DN, the largest {of} ({change})"


def _check_phase(args, sensor):
    """The stated origin (or a whole-sensor frame) against the phase the first white frame
    shows, before any work (a white cube records where it was taken: it is not re-checked)."""
    from ..cube.phase import check_mosaic_phase

    if sensor is None or sensor.layout != "mosaic" or sensor.responses is None:
        return
    try:
        white = _read_frame_rows(args.white[0], sensor)
        dark = _read_frame_rows(args.dark[0], sensor) if args.dark else None
    except ValueError:  # a cube, not a raw frame
        return
    check_mosaic_phase(white, sensor, args.sensor_origin_px,
                       dark=dark if dark is not None and dark.shape == white.shape else None,
                       saturation=args.saturation, what=f"--white {args.white[0]}")


def _flatfield_demosaic(args, sensor, inputs):
    """``flatfield --demosaic``: the raw frame flat-fielded pixel by pixel, then demosaicked."""
    from ..pipeline import process_frame

    if sensor is None or sensor.layout != "mosaic":
        raise ValueError("--demosaic needs a mosaic --sensor (its layout places the bands)")
    raw = _read_frame_checked(args.raw, sensor, "the raw frame")
    darks = [_read_frame_checked(p, sensor, "--dark", raw.shape) for p in args.dark]
    whites = [_read_frame_checked(p, sensor, "--white", raw.shape) for p in args.white]
    said = _default_saturation(args, sensor, whites)
    fw = (_read_frame_checked(args.filter_white, sensor, "--filter-white", raw.shape)
          if args.filter_white else None)
    with _StageBar("flat-fielding (checking the mask)"):
        ds = process_frame(raw, darks, whites, sensor, demosaic_method=args.demosaic,
                           sensor_origin_px=args.sensor_origin_px, saturation=args.saturation,
                           dtype=args.dtype, filter_white=fw)
    if fw is not None:
        ds.attrs["filter_white_file"] = str(args.filter_white)
    ds.attrs.update({"raw_file": str(args.raw), "dark_files": [str(p) for p in args.dark],
                     "white_files": [str(p) for p in args.white]})
    cube = ds["reflectance"]
    with _StageBar(f"demosaicking ({args.demosaic}) and writing {args.out.name}"):
        _write_result(args, ds, inputs, RAW_COPIES, args.raw)
    n_masked, total = _masked_in(args.out), cube.size
    print(f"wrote {args.out}: reflectance of {args.raw}, demosaicked ({args.demosaic}) to "
          f"{cube.shape[0]} x {cube.shape[1]} x {cube.shape[2]} "
          f"({_stored_type(args, cube.dtype)}), sensor rows "
          f"and columns {ds.attrs['mosaic_area_px']} (first row, first column, rows, columns); "
          f"{len(darks)} dark and {len(whites)} white frame(s) averaged; {n_masked} of {total} "
          f"values masked ({100 * n_masked / total:.2f} %)")
    if said:
        print(said, file=sys.stderr)
    _quicklook(args, "plot_flatfield", ds)
    return 0


#: What a flat-field result says of how it was made, kept (as ``input_<name>``) in the
#: correction of it.
FLATFIELD_RECORD = ("raw_file", "dark_files", "white_files", "dark_frames", "white_frames",
                    "filter_white_files", "demosaic_method", "mosaic_area_px", "sensor",
                    "created", "snapcorr_version")


def _keep_flatfield_record(path, ds):
    """A correction of a flat-field result (.nc or .zarr) keeps its raw counts (lazily, as
    stored) and its record of the raw, dark and white files: the corrected values sit next to
    the camera's numbers they came from."""
    if path.suffix.lower() not in (".nc", ".zarr"):
        return
    from ..files.api import read_dataset

    src = read_dataset(path, chunks={})
    for name in RAW_COPIES:
        raw = src.variables.get(name)
        if raw is not None and name not in ds.variables and all(
                ds.sizes.get(d) == n for d, n in raw.sizes.items()):
            ds[name] = src[name].reset_coords(drop=True)
    for key in FLATFIELD_RECORD:
        if key in src.attrs:
            ds.attrs.setdefault(f"input_{key}", src.attrs[key])


def _correct_input(args, sensor):
    """The cube to correct and, from a flat-field result, its mask (the file opened once)."""
    return _read_with_mask(args.cube, sensor, args.sensor_origin_px)

