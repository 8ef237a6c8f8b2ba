"""Where each pixel and band of a cube sits behind the lens: sensor position and chief-ray angle.

A cube pixel ``(y, x)`` of band ``b`` was exposed at sensor row ``sensor_row(y, b)`` and column
``sensor_col(x, b)`` (a mosaic keeps them per band, see :func:`~snapcorr.cube.mosaic_to_cube`;
a Snapscan cube has every band at the same position). Its distance from the optical centre on
the sensor, times the pixel pitch, gives the chief-ray angle ``tan CRA = d / x`` (Goossens et
al. 2019, Eq. 8).

Nothing is assumed that would silently move a pixel: a crop must say where it sits (its
positions, or ``sensor_origin_px``), a mosaic cube must carry its bands' positions, and an
optical centre measured on another pixel grid is carried over through millimetres or refused.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._coords import accepts_center_rc, called_from_outside, warn_x_first_return
from .._validation import check_center, check_center_rc, check_pair
from ..cube.mosaic import sensor_positions
from ..optics.chief_ray import pixel_cra_deg

__all__ = ["CubeCRA", "PlacementError", "cube_cra", "cube_cra_deg", "cube_positions",
           "optical_center", "optical_center_rc"]

#: Physical sizes (mm) closer than this fraction of a pixel count as the same image area.
_SAME_AREA_PX = 1.0


class PlacementError(ValueError):
    """Where the cube or the optical axis sits on the sensor is not known well enough."""


def _image_size(cal):
    """The calibration image's ``[width, height]``: ``image_size_px``, or ``image_shape_px``
    (rows, columns) turned about where only that is given (the two agree where both are,
    :class:`~snapcorr.optics.Lens` checks); None without either."""
    if cal.get("image_size_px") is not None:
        return cal["image_size_px"]
    shape = cal.get("image_shape_px")
    return None if shape is None else [shape[1], shape[0]]


def _full_frame(lens, sensor):
    """The full image size (rows, cols) in this sensor's pixels, and whence: the sensor's own
    ``size_px``, else the lens calibration's image converted to this pitch; None if neither."""
    if sensor.size_px is not None:
        return tuple(sensor.size_px), f"the sensor {sensor.name!r} (size_px)"
    cal = getattr(lens, "calibration", {}) or {}
    size, pitch = _image_size(cal), cal.get("pixel_pitch_um")
    if size is not None and pitch is not None:
        k = float(pitch) / sensor.require("pixel_pitch_um", "placing the cube")  # -> this
        # sensor's pixels
        w, h = (float(v) for v in size)  # recorded as [width, height]
        return (h * k, w * k), (f"the lens calibration's image ({int(w)} x {int(h)} px of "
                                f"{float(pitch):g} um)")
    return None


def cube_positions(cube, sensor, lens=None, sensor_origin_px=None):
    """Sensor rows ``(ny, nb or 1)`` and columns ``(nx, nb or 1)`` of the cube's pixels.

    From the cube's ``sensor_row`` / ``sensor_col`` coordinates; else from
    ``sensor_origin_px`` (row, column of the cube's first pixel; for a mosaic sensor, of the
    tile holding it) and the sensor's layout; else, for a Snapscan cube as large as the full
    image known from the sensor's ``size_px`` or the lens calibration, from (0, 0).

    Parameters
    ----------
    cube : xarray.DataArray
        Dimensions ``y``, ``x``, ``band``; optionally coordinates ``sensor_row(y, band)`` and
        ``sensor_col(x, band)``.
    sensor : Sensor
        Its layout, band offsets, pixel pitch and ``size_px`` (when known; positions outside
        it are refused).
    lens : Lens, optional
        Its calibration's image size gives the full image when the sensor has no ``size_px``.
    sensor_origin_px : (row, col), optional
        Sensor row and column of the cube's first pixel, whole pixels; checked against the
        cube's own positions when it has them.

    Returns
    -------
    rows : ndarray, float, shape (ny, nb) or (ny, 1)
    cols : ndarray, float, shape (nx, nb) or (nx, 1)
        Sensor pixel indices; one column when every band sits at the same position.

    Raises
    ------
    PlacementError
        A mosaic cube without positions (its bands sit at different places in each tile), a
        cube smaller than the known full image without an origin (a crop placed at the
        corner would get the wrong angles), or an origin that contradicts the cube's own
        positions.
    """
    ny, nx, nb = cube.sizes["y"], cube.sizes["x"], cube.sizes["band"]
    have = "sensor_row" in cube.coords and "sensor_col" in cube.coords
    if have:
        rows = np.asarray(cube["sensor_row"].transpose("y", "band").values, float)
        cols = np.asarray(cube["sensor_col"].transpose("x", "band").values, float)
        if sensor_origin_px is not None:
            r0, c0 = check_pair("sensor_origin_px", sensor_origin_px, "two numbers (row, col)")
            if sensor.layout == "mosaic":
                dr, dc = sensor.band_offsets_at((int(r0), int(c0)))[0]
                r0, c0 = r0 + dr, c0 + dc
            if (r0, c0) != (rows[0, 0], cols[0, 0]):
                raise PlacementError(
                    f"the cube records its first pixel at sensor row {rows[0, 0]:g}, column "
                    f"{cols[0, 0]:g}, but the origin given is ({r0:g}, {c0:g}); leave out "
                    "sensor_origin_px= or fix it")
    elif sensor_origin_px is not None:
        r0, c0 = check_pair("sensor_origin_px", sensor_origin_px, "two numbers (row, col)")
        if r0 != round(r0) or c0 != round(c0):
            raise ValueError(f"sensor_origin_px must be whole pixels, got {sensor_origin_px!r}")
        rows, cols = (a.astype(float) for a in
                      sensor_positions(sensor, ny, nx, (int(r0), int(c0))))
    elif sensor.layout == "mosaic" and nb > 1:
        raise PlacementError(
            f"the cube carries no sensor positions, and the bands of the mosaic sensor "
            f"{sensor.name!r} sit at different places in each {sensor.mosaic_shape[0]} x "
            f"{sensor.mosaic_shape[1]} tile: give the raw 2-D frame (it is split with the "
            "sensor's band offsets), a tile cube snapcorr split or wrote (it carries them), or "
            "sensor_origin_px= (row, col) if cube pixel (y, x) is the tile whose top-left sensor "
            "pixel is (ROW + y * tile rows, COL + x * tile columns)")
    else:
        frame = _full_frame(lens, sensor)
        if frame is not None:
            (fr, fc), what = frame
            if abs(fr - ny) > _SAME_AREA_PX or abs(fc - nx) > _SAME_AREA_PX:
                raise PlacementError(
                    f"the cube is {ny} x {nx} px but {what} is {fr:g} x {fc:g} px, and the "
                    "cube does not say where it sits: give sensor_origin_px= (row, col), the "
                    "sensor row and column of its first pixel")
        rows, cols = (a.astype(float) for a in sensor_positions(sensor, ny, nx, (0, 0)))
    if sensor.size_px is not None and (rows.min() < 0 or cols.min() < 0
                                       or rows.max() >= sensor.size_px[0]
                                       or cols.max() >= sensor.size_px[1]):
        raise PlacementError(
            f"the cube covers sensor rows {rows.min():g}-{rows.max():g} and columns "
            f"{cols.min():g}-{cols.max():g}, outside the {sensor.size_px[0]} x "
            f"{sensor.size_px[1]} px sensor {sensor.name!r}: check sensor_origin_px= and "
            "sensor=")
    if np.all(rows == rows[:, :1]) and np.all(cols == cols[:, :1]):
        rows, cols = rows[:, :1], cols[:, :1]  # every band at the same position
    return rows, cols


def optical_center_rc(cube, sensor, lens, *, center_rc=None, positions=None):
    """The optical centre ``(row, col)`` in sensor pixels, and where it came from.

    Given explicitly; else the lens profile's ``[calibration] center_rc`` (or the x-first
    ``center_px`` of profiles written before it), converted through millimetres when the
    calibration's pixel pitch differs from the sensor's (binned pixels, another pixel grid over
    the same image area); else the centre of the sensor (``size_px``); else the centre of the
    area the cube covers.

    Parameters
    ----------
    cube : xarray.DataArray
        Used only for the last fallback (:func:`cube_positions`).
    sensor : Sensor
        Its pixel pitch (um) and ``size_px``.
    lens : Lens
        Its ``calibration`` table (``center_rc`` or ``center_px``, ``pixel_pitch_um``,
        ``image_size_px``); the calibration's centre is used only when it records its pixel
        pitch.
    center_rc : (row, col), optional
        Optical centre given explicitly, sensor pixels.
    positions : (rows, cols), optional
        The cube's sensor positions if already known (as :func:`cube_positions` returns).

    Returns
    -------
    center_rc : (float, float)
        ``(row, col)``, sensor pixels.
    source : str
        ``"given"``, ``"lens calibration"`` (possibly with the conversion noted),
        ``"sensor centre"`` or ``"image centre"``.

    Raises
    ------
    PlacementError
        The calibration's centre was measured on another pixel grid and the two image areas
        cannot be matched (no ``image_size_px`` in the profile, no ``size_px`` for the sensor, or
        different physical sizes): pass ``center_rc`` (``--center ROW,COL``).
    """
    if center_rc is not None:
        return check_center_rc(center_rc), "given"
    cal = getattr(lens, "calibration", {}) or {}
    if ("center_rc" in cal or "center_px" in cal) and cal.get("pixel_pitch_um") is not None:
        centre, source = _calibrated_center_rc(cal, sensor)
        if str(cal.get("center_source", "")).startswith("image centre"):
            source += " (the flats' image centre, assumed: they showed no fall-off)"
        return centre, source
    if sensor.size_px is not None:
        rows, cols = sensor.size_px
        return ((rows - 1) / 2.0, (cols - 1) / 2.0), "sensor centre"
    rows, cols = positions if positions is not None else cube_positions(cube, sensor, lens)
    return ((float(rows.min()) + float(rows.max())) / 2.0,
            (float(cols.min()) + float(cols.max())) / 2.0), "image centre"


def _calibrated_center_rc(cal, sensor):
    """The lens calibration's centre ``(row, col)`` in this sensor's pixels, and its source
    (:func:`optical_center_rc`)."""
    if "center_rc" in cal:  # row first; the x-first center_px beside it is for old readers
        row, col = check_center_rc(cal["center_rc"], "the lens calibration's center_rc")
    else:  # profiles written by snapcorr 0.1 hold only the x-first (cx, cy)
        col, row = check_center(cal["center_px"], "the lens calibration's center_px")
    p_cal = float(cal["pixel_pitch_um"])
    p = sensor.require("pixel_pitch_um", "carrying the lens calibration's centre over")
    if cal.get("sensor_origin_rc") is not None:
        return _crop_center_rc(cal, sensor, (row, col), p_cal, p)
    size = _image_size(cal)
    same_pitch = abs(p_cal - p) < 1e-9 * p
    if same_pitch and (size is None or sensor.size_px is None):
        return (row, col), "lens calibration"  # the same pixel grid, as far as is known
    why = None
    if size is None:
        why = "the profile does not record the calibration image's size"
    elif sensor.size_px is None:
        why = f"the sensor {sensor.name!r} has no size_px"
    else:
        w_mm, h_mm = (float(v) * p_cal * 1e-3 for v in size)  # recorded as [width, height]
        rows, cols = sensor.size_px
        if (abs(cols * p * 1e-3 - w_mm) > _SAME_AREA_PX * p * 1e-3
                or abs(rows * p * 1e-3 - h_mm) > _SAME_AREA_PX * p * 1e-3):
            why = (f"its image ({w_mm:.3f} x {h_mm:.3f} mm) and the sensor's "
                   f"({cols * p * 1e-3:.3f} x {rows * p * 1e-3:.3f} mm) differ")
    if why is not None:
        raise PlacementError(
            f"the lens profile's optical centre was measured with {p_cal:g} um pixels and "
            f"this sensor has {p:g} um, but {why}, so the centre cannot be carried over: "
            "give center_rc= (row, col) in this sensor's pixels")
    if same_pitch:
        return (row, col), "lens calibration"
    # pixel i covers [i, i + 1) pitches from the image's edge: centres sit at i + 0.5
    k = p_cal / p
    return ((row + 0.5) * k - 0.5, (col + 0.5) * k - 0.5), \
        f"lens calibration ({p_cal:g} um pixels, converted through mm)"


def _crop_center_rc(cal, sensor, center, p_cal, p):
    """A centre measured on flats that are a crop of this sensor, its first pixel at the
    calibration's ``sensor_origin_rc``: in the sensor's pixels, the crop's centre plus the
    origin (the same pixel grid: the pitch must agree)."""
    r0, c0 = check_center_rc(cal["sensor_origin_rc"], "the lens calibration's sensor_origin_rc")
    if abs(p_cal - p) > 1e-9 * p:
        raise PlacementError(
            f"the lens profile's optical centre was measured on a crop of {p_cal:g} um pixels "
            f"and this sensor has {p:g} um: give center_rc= (row, col) in this sensor's "
            "pixels")
    size = sensor.size_px
    if size is not None:
        w, h = _image_size(cal) or (1, 1)  # the flats' [width, height], these pixels
        if r0 + h > size[0] or c0 + w > size[1]:
            raise PlacementError(
                f"the lens profile's flats were a {h} x {w} px crop at sensor row {r0:g}, "
                f"column {c0:g} (its sensor_origin_rc), which reaches beyond the sensor "
                f"{sensor.name!r} ({size[0]} x {size[1]} px): check the profile and the sensor, "
                "or give center_rc= (row, col) in this sensor's pixels")
    return ((center[0] + r0, center[1] + c0),
            f"lens calibration (flats cropped at sensor row {r0:g}, column {c0:g})")


class CubeCRA(NamedTuple):
    """Every pixel's chief-ray angle and the optical centre it was measured from
    (:func:`cube_cra`)."""

    #: Degrees, shape ``(ny, nx, nb)``, or ``(ny, nx, 1)`` when every band shares its pixel's
    #: position (Snapscan).
    cra_deg: np.ndarray
    #: The optical centre, ``(row, col)`` sensor pixels.
    center_rc: tuple
    #: Where the centre came from (as :func:`optical_center_rc` says).
    center_source: str


def cube_cra(cube, sensor, lens, *, center_rc=None, sensor_origin_px=None):
    """Chief-ray angle of every pixel (and band, for mosaics), and the optical centre used.

    Parameters
    ----------
    cube : xarray.DataArray
    sensor : Sensor
    lens : Lens
    center_rc : (row, col), optional
        Optical centre in sensor pixels; see :func:`optical_center_rc`.
    sensor_origin_px : (row, col), optional
        Sensor position of the cube's first pixel, for cubes that do not carry their
        positions; see :func:`cube_positions`.

    Returns
    -------
    CubeCRA
        ``(cra_deg, center_rc, center_source)``: the angles in degrees, shape ``(ny, nx, nb)``
        or ``(ny, nx, 1)`` (the last axis is 1 when every band shares its pixel's position,
        Snapscan); the centre ``(row, col)``; where it came from.
    """
    pitch, rows, cols, center, source = _placed(cube, sensor, lens, center_rc,
                                                sensor_origin_px)
    # rows (ny, 1, nb) against columns (1, nx, nb)
    cra = pixel_cra_deg(rows[:, None, :], cols[None, :, :], center, pitch, lens.exit_pupil_mm)
    return CubeCRA(cra, center, source)


@accepts_center_rc
def optical_center(cube, sensor, lens, center_px=None, *, center_rc=None, positions=None):
    """The optical centre x first, ``(cx, cy)``: the earlier form of
    :func:`optical_center_rc`, which gives it row first; removed in snapcorr 0.3.

    Parameters
    ----------
    cube, sensor, lens, positions
        As for :func:`optical_center_rc`.
    center_rc, center_px : (row, col), optional
        Optical centre given explicitly; ``center_px=(cx, cy)``, in its old place, is the
        deprecated x-first form.

    Returns
    -------
    center : (float, float)
        ``(cx, cy)``, sensor pixels, x first.
    source : str
        As for :func:`optical_center_rc`.
    """
    if called_from_outside(2):
        warn_x_first_return("optical_center", "optical_center_rc")
    (row, col), source = optical_center_rc(cube, sensor, lens, center_rc=center_rc,
                                           positions=positions)
    return (col, row), source


@accepts_center_rc
def cube_cra_deg(cube, sensor, lens, center_px=None, *, center_rc=None, sensor_origin_px=None):
    """Chief-ray angles and the optical centre x first, ``(cra, (cx, cy), source)``: the
    earlier form of :func:`cube_cra`, which gives the centre row first; removed in snapcorr 0.3.

    Parameters
    ----------
    cube, sensor, lens, sensor_origin_px
        As for :func:`cube_cra`.
    center_rc, center_px : (row, col), optional
        Optical centre in sensor pixels; ``center_px=(cx, cy)``, in its old place, is the
        deprecated x-first form.

    Returns
    -------
    cra : ndarray
        As ``cube_cra(...).cra_deg``.
    center : (float, float)
        ``(cx, cy)``, x first.
    center_source : str
    """
    if called_from_outside(2):
        warn_x_first_return("cube_cra_deg", "cube_cra")
    cra, (row, col), source = cube_cra(cube, sensor, lens, center_rc=center_rc,
                                       sensor_origin_px=sensor_origin_px)
    return cra, (col, row), source


def _placed(cube, sensor, lens, center_rc, sensor_origin_px):
    pitch = sensor.require("pixel_pitch_um", "the chief-ray angle of each pixel")
    rows, cols = cube_positions(cube, sensor, lens, sensor_origin_px)
    center, source = optical_center_rc(cube, sensor, lens, center_rc=center_rc,
                                       positions=(rows, cols))
    return pitch, rows, cols, center, source


def _largest_cra_deg(cube, sensor, lens, center_rc=None, sensor_origin_px=None):
    """``cube_cra(...).cra_deg.max()`` without the map: for each band's positions, the row
    and the column farthest from the centre (every step from the offsets to the angle is
    monotonic, element by element the same arithmetic), so a table over the field's angles
    can be started before the map is made.

    Parameters
    ----------
    cube : xarray.DataArray
    sensor : Sensor
    lens : Lens
    center_rc : (row, col), optional
        Optical centre, sensor pixels (as :func:`cube_cra` takes it).
    sensor_origin_px : (row, col), optional
        As for :func:`cube_cra`.

    Returns
    -------
    float
        Degrees.
    """
    pitch, rows, cols, (row, col), _ = _placed(cube, sensor, lens, center_rc,
                                               sensor_origin_px)
    bands = np.arange(rows.shape[1])
    far_rows = rows[np.argmax(np.abs(rows - row), axis=0), bands]
    far_cols = cols[np.argmax(np.abs(cols - col), axis=0), bands]
    return float(np.max(pixel_cra_deg(far_rows[None, None, :], far_cols[None, None, :],
                                      (row, col), pitch, lens.exit_pupil_mm)))
