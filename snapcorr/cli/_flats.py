"""The flat fields of ``snapcorr calibrate``: read, each the mean of its bands, with their
saturation levels and dark; the mosaic whose raw frames they are; and what the lens profile
records of them."""

from __future__ import annotations

import sys

from ._options import _sensor


def _flat_sensor(args):
    """``--sensor`` without --target-cube: the mosaic whose raw frames the flats are (its band
    gains are divided out), or a sensor of another layout (a Snapscan camera) that gives the
    pixel pitch and bounds a crop at ``--sensor-origin-px``."""
    if args.sensor is None:
        return None
    return _sensor(args.sensor)


def _mosaic_of(sensor):
    """The sensor whose band gains are divided out of the flats: a mosaic's, else None."""
    return sensor if sensor is not None and sensor.layout == "mosaic" else None


def _check_crop(args, sensor, flats):
    """Flats of a sensor without a tile pattern: a crop at ``--sensor-origin-px`` must lie on
    the sensor, and flats smaller than a sensor of known size need the origin (their optical
    centre is recorded in their own pixels)."""
    if sensor is None or sensor.layout == "mosaic" or sensor.size_px is None:
        return
    (f, path), rows, cols = min(args.flat), *next(iter(flats.values())).shape
    pitch = float(sensor.pixel_pitch_um or 0)
    if abs(args.pixel_pitch_um - pitch) > 1e-9 * max(pitch, 1.0):  # binned: placed by mm
        if args.sensor_origin_px is not None:
            raise ValueError(f"--sensor-origin-px is in the sensor's {pitch:g} um pixels and "
                             f"the flats' are {args.pixel_pitch_um:g} um (--pixel-pitch-um): "
                             "a crop's origin needs the sensor's own pixels")
        return
    r0, c0 = args.sensor_origin_px or (0, 0)
    size = tuple(int(v) for v in sensor.size_px)
    if r0 + rows > size[0] or c0 + cols > size[1]:
        where = (f"at sensor row {r0}, column {c0} " if args.sensor_origin_px else "")
        raise ValueError(f"--flat {f:g}={path}: {rows} x {cols} px {where}reaches beyond the "
                         f"sensor {args.sensor} ({size[0]} x {size[1]} px): check "
                         "--sensor-origin-px and --sensor")
    if args.sensor_origin_px is None and (rows, cols) != size:
        raise ValueError(f"--flat {f:g}={path} is {rows} x {cols} px, a crop of the sensor "
                         f"{args.sensor} ({size[0]} x {size[1]} px): give --sensor-origin-px "
                         "ROW,COL (the crop's first pixel on the sensor), so the profile places "
                         "the optical centre on the sensor")


def _band_gains_said(res, cal, args):
    """Say which band gains were divided out, and record the sensor file."""
    if not res.mosaic:
        return
    cal["band_gains"] = {**cal["band_gains"], "sensor_file": str(args.sensor)}
    spread = [f"f/{f:g} {g.min():.2f}-{g.max():.2f}"
              for f, g in sorted(res.mosaic["band_gains"].items())]
    print(f"divided out the band gains of {res.mosaic['sensor'].name} (relative to their mean: "
          + ", ".join(spread) + ")", file=sys.stderr)


def _pitch_option(args, sensor):
    """``--pixel-pitch-um``, else the ``--sensor``'s pitch; refused where neither gives one."""
    if args.pixel_pitch_um is not None:
        return
    pitch = getattr(sensor, "pixel_pitch_um", None)
    if not pitch or not pitch > 0:
        raise ValueError("give the flats' pixel pitch: --pixel-pitch-um UM"
                         + ("" if sensor is None else f" (the sensor {args.sensor} gives none)"))
    args.pixel_pitch_um = float(pitch)
    print(f"pixel pitch: {pitch:g} um, the sensor's ({args.sensor})", file=sys.stderr)


def _read_flats(args, sensor=None):
    """Every flat (mean of its bands), the saturation levels and the dark. Raw flats of a
    mosaic ``sensor`` that gives its bit depth saturate at its largest code by default."""
    from ..calibrate import read_flat
    from ..cube.mosaic import frame_saturation

    flats, bands, sat = {}, set(), {}
    for f, path in sorted(args.flat):
        image, info = read_flat(path)
        flats[f] = image
        bands.add(info["bands"])
        sat[f] = (args.saturation if args.saturation is not None
                  else frame_saturation(sensor, [image], what=f"--flat {f:g}={path}")
                  or info["saturation"])
        print(f"read f/{f:g}: {path} ({image.shape[0]} x {image.shape[1]} px"
              + (f", mean of {info['bands']} bands" if info["bands"] > 1 else "") + ")",
              file=sys.stderr)
    dark = read_flat(args.dark)[0] if args.dark else None
    return flats, bands, sat, dark


def _check_flat_phase(args, sensor, flats, sat, dark, origin):
    """Raw flats of a mosaic with measured responses: the stated origin (or a whole-sensor
    frame) against the phase the first flat shows, before any fit, as ``flatfield`` checks its
    white (:func:`~snapcorr.cube.phase.check_mosaic_phase`)."""
    from ..cube.phase import check_mosaic_phase

    if sensor is None or sensor.layout != "mosaic" or sensor.responses is None:
        return
    f, image = min(flats.items())
    path = dict(args.flat)[f]
    check_mosaic_phase(image, sensor, origin,
                       dark=dark if dark is not None and dark.shape == image.shape else None,
                       saturation=sat[f], what=f"--flat {f:g}={path}")


def _flats_provenance(cal, args, bands):
    cal["bands"] = ("mean of the bands in each file" if max(bands) > 1
                    else "single-band flats")
    cal["dark"] = (str(args.dark) if args.dark else
                   "none given: the flats were taken as already dark-subtracted")
    return cal


def _no_dark_note(args):
    if not args.dark:
        print("note: no --dark: the flats were taken as already dark-subtracted; an offset left "
              "in them is read as light and biases P and h (it can even add a circle)")
