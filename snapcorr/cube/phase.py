"""Where a frame sits on the mosaic's tile grid, read from a white reference.

A snapshot-mosaic frame's band layout follows its first pixel's sensor position modulo the
tile (:meth:`~snapcorr.cube.Sensor.band_offsets_at`). A crop or region of interest stated one
row off puts every band in its neighbour's place, and nothing in the frame itself says so. The
white reference does: under any smooth lamp, each band's mean over a white target is the
integral of its measured response (every peak, the band-pass included) times the lamp, and the
measured responses differ between bands by far more than a smooth lamp can make up for (a
4x4 VIS sensor's band gains span 0.25-1.0). The tile's pattern of means is a fingerprint of
the tile; of the tile's possible phases, only the true one is matched by a smooth lamp.

The lamp is not known: it is fitted, as a Legendre polynomial of degree :data:`LAMP_DEGREE`
over the responses' span, at every candidate phase, and the phases are ranked by the relative
RMS misfit of the means. A phase is found where the runner-up fits at least
:data:`RATIO_MIN` times worse and the best fits within :data:`MISFIT_MAX`; otherwise the white
cannot tell, and the answer says so rather than guess. Checked in the tests on an independent
simulation through real measured responses (imec 4x4 VIS), every phase of the tile, under a
tungsten lamp (2856 K), daylight (D65) and white LEDs (CIE LED-B1..B5), with the camera's
responses off the file's by 5 % in gain and 2 nm in wavelength: right every time, with a
runner-up 3.6-190x worse; the phases that went wrong in that study (a sodium lamp, an RGB
LED) had ratios of at most 1.2 and are refused.

Only a sensor with measured responses (a vendor calibration file) carries a fingerprint: the
Gaussian bands of a sensor TOML say nothing of each band's gain.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import xarray as xr

from .._validation import called_from_outside, renamed_keywords, warn_renamed
from .mosaic import _filter_part, _origin, frame_saturation
from .sensor import Sensor

__all__ = ["FLIP_ADVICE", "FLIP_CHECK_MISFIT", "LAMP_DEGREE", "MISFIT_MAX", "RATIO_MIN",
           "MosaicPhase", "check_mosaic_phase", "flip_shown", "mosaic_phase"]

#: Degree of the Legendre polynomial that stands for the unknown lamp (times the white
#: target) over the responses' span: a tungsten lamp, daylight and a phosphor white LED are
#: matched to within 0.1-2 % through a 4x4 VIS sensor's responses, while a wrong phase misfits
#: by 4-30 %.
LAMP_DEGREE = 4
#: A phase is found where the next best phase misfits at least this many times more.
RATIO_MIN = 1.5
#: ... and where the best phase misfits (relative RMS of the bands' means) by at most this.
MISFIT_MAX = 0.10
#: The responses' span: where their sum through the band-pass is above this share of its peak.
SPAN_FRACTION = 0.01


@dataclass(frozen=True)
class MosaicPhase:
    """What a white reference says of a frame's place on the tile grid.

    Attributes
    ----------
    misfit : ndarray, shape (tile rows, tile cols)
        Relative RMS misfit of the white's band means, for the frame's first pixel at each
        tile position (row, column inside the tile, counted from the tile grid's origin
        :attr:`~snapcorr.cube.Sensor.tile_origin_px`).
    phase_px : (int, int) or None
        The tile position of the frame's first pixel that the white shows; None where it
        cannot tell (:attr:`reason` says why).
    stated_px : (int, int) or None
        The tile position the stated origin (or a whole-sensor frame) gives it, if any.
    tile_origin_px : (int, int)
        Sensor row and column where the tile grid starts.
    reason : str
        Empty where a phase is found; else why not.
    """

    misfit: np.ndarray
    phase_px: tuple | None
    stated_px: tuple | None
    tile_origin_px: tuple
    reason: str = ""

    @property
    def ranked_px(self):
        """Tile positions from the best fitting to the worst."""
        order = np.argsort(self.misfit, axis=None, kind="stable")
        return [tuple(int(v) for v in np.unravel_index(i, self.misfit.shape)) for i in order]

    @property
    def ratio(self) -> float:
        """The runner-up's misfit over the best one's (inf for a one-pixel tile)."""
        m = np.sort(self.misfit, axis=None)
        if m.size < 2:
            return float("inf")
        return float(m[1] / m[0]) if m[0] > 0 else (float("inf") if m[1] > 0 else 1.0)

    @property
    def agrees(self) -> bool | None:
        """Whether the stated origin's phase is the white's (None: nothing stated, or the
        white cannot tell)."""
        if self.stated_px is None or self.phase_px is None:
            return None
        return tuple(self.stated_px) == tuple(self.phase_px)

    def sensor_origin_px(self, near=(0, 0)):
        """The sensor row and column nearest ``near`` at which a frame's first pixel has the
        phase the white shows, or None where it cannot tell.

        Parameters
        ----------
        near : (int, int)
            A stated or approximate origin.
        """
        if self.phase_px is None:
            return None
        tile = np.array(self.misfit.shape)
        want = (np.array(self.tile_origin_px) + np.array(self.phase_px)) % tile
        near = np.asarray(near, dtype=np.int64)
        step = (want - near) % tile
        step = np.where(step >= (tile + 1) // 2, step - tile, step)  # a tie goes down
        out = near + step
        out = np.where(out < 0, out + tile, out)
        return tuple(int(v) for v in out)

    def origin_px(self, near=(0, 0)):
        """The earlier name of :meth:`sensor_origin_px`."""
        if called_from_outside(2):
            warn_renamed("MosaicPhase.origin_px", "MosaicPhase.sensor_origin_px")
        return self.sensor_origin_px(near)

    def describe(self) -> str:
        """One paragraph: the phase found (or why none), with the misfits that decide it."""
        tr, tc = self.misfit.shape
        if not np.isfinite(self.misfit).any():
            return f"the white cannot tell the mosaic's phase: {self.reason}"
        best, second = self.ranked_px[:2] if self.misfit.size > 1 else (self.ranked_px[0],) * 2
        fits = (f"a smooth lamp through the measured responses misfits the white's band means "
                f"by {100 * self.misfit[best]:.2g} % at tile position (row {best[0]}, col "
                f"{best[1]}) and {100 * self.misfit[second]:.2g} % at the next best (row "
                f"{second[0]}, col {second[1]})")
        if self.phase_px is None:
            return f"the white cannot tell the mosaic's phase: {self.reason}; {fits}"
        r0, c0 = self.tile_origin_px
        where = (f"the frame's first pixel sits at row {self.phase_px[0]}, col "
                 f"{self.phase_px[1]} of the {tr} x {tc} tile (a sensor origin ROW,COL with "
                 f"(ROW - {r0}) mod {tr} = {self.phase_px[0]} and (COL - {c0}) mod {tc} = "
                 f"{self.phase_px[1]})")
        return f"{where}; {fits}"


def _as_array(frame):
    """A white or dark frame (or several, averaged) as float64 numpy."""
    if isinstance(frame, (list, tuple)):
        frames = [_as_array(f) for f in frame]
        if len({f.shape for f in frames}) != 1:
            raise ValueError("the frames averaged for the phase differ in shape")
        return np.mean(frames, axis=0)
    data = frame.data if isinstance(frame, xr.DataArray) else frame
    return np.asarray(data, dtype=np.float64)


def _fingerprints(sensor: Sensor, degree):
    """Each band's response integrated against the lamp's Legendre basis: (bands, degree+1)."""
    resp = sensor.responses
    grid, eff = resp.wavelength_nm, resp.effective
    total = eff.sum(axis=0)
    span = grid[total > SPAN_FRACTION * total.max()]
    lo, hi = float(span[0]), float(span[-1])
    t = np.clip(2 * (grid - lo) / max(hi - lo, 1e-9) - 1, -1, 1)
    basis = np.polynomial.legendre.legvander(t, degree)  # (n, degree+1)
    step = np.diff(grid) / 2
    weights = np.concatenate([step, [0.0]]) + np.concatenate([[0.0], step])  # trapezoid rule
    return eff @ (basis * weights[:, None])


def _tile_means(values, tile):
    """Median over whole tiles of each position's value over its tile's level.

    ``values`` is (rows, cols) starting at a reference pixel; each tile-sized window from it is
    divided by its own level (a lamp's and the lens's fall-off cancel). A pixel not usable
    (not finite, <= 0) is left out: its window's level is then taken from the others against
    a first estimate of the pattern. Returns (tr, tc) and the number of windows used.
    """
    tr, tc = tile
    ny, nx = values.shape[0] // tr, values.shape[1] // tc
    win = values[:ny * tr, :nx * tc].reshape(ny, tr, nx, tc).transpose(0, 2, 1, 3)
    win = win.reshape(ny * nx, tr, tc)
    win = np.where(np.isfinite(win) & (win > 0), win, np.nan)
    good = np.isfinite(win)
    win = win[good.sum(axis=(1, 2)) >= max(1, tr * tc // 2)]  # at least half the tile
    if win.shape[0] == 0:
        return None, 0
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a position with no usable value
        first = np.nanmedian(win / np.nanmean(win, axis=(1, 2), keepdims=True), axis=0)
        known = np.isfinite(win) & np.isfinite(first)
        level = (np.where(known, win, 0).sum(axis=(1, 2), keepdims=True)
                 / np.where(known, first, 0).sum(axis=(1, 2), keepdims=True))
        return np.nanmedian(win / level, axis=0), int(win.shape[0])


def _misfits(means, sensor, degree):
    """Relative RMS misfit of ``means`` (tile positions relative to the reference pixel) for
    the reference pixel at every tile position."""
    tr, tc = sensor.mosaic_shape
    band_at = np.full((tr, tc), -1)
    off = np.asarray(sensor.band_offset)
    band_at[off[:, 0], off[:, 1]] = np.arange(sensor.n_bands)
    prints = _fingerprints(sensor, degree)
    qr, qc = np.meshgrid(np.arange(tr), np.arange(tc), indexing="ij")
    out = np.empty((tr, tc))
    for pr in range(tr):
        for pc in range(tc):
            bands = band_at[(qr + pr) % tr, (qc + pc) % tc].ravel()
            keep = (bands >= 0) & np.isfinite(means.ravel())
            design = prints[bands[keep]] / means.ravel()[keep, None]
            coef, *_ = np.linalg.lstsq(design, np.ones(int(keep.sum())), rcond=None)
            out[pr, pc] = np.sqrt(np.mean((design @ coef - 1) ** 2))
    return out


def _frame_means(white, dark, sensor, sensor_origin_px, saturation):
    """The white's tile means relative to the frame's first usable pixel, that pixel's offset
    in the frame, and the stated phase of the frame's first pixel (or None)."""
    w = _as_array(white)
    if w.ndim != 2:
        raise ValueError(f"a white frame is 2-D, got shape {w.shape}")
    if saturation is not None:
        w = np.where(w >= np.float64(saturation), np.nan, w)
    if dark is not None:
        d = _as_array(dark)
        if d.shape != w.shape:
            raise ValueError(f"the dark ({d.shape[0]} x {d.shape[1]}) and the white "
                             f"({w.shape[0]} x {w.shape[1]}) differ in size")
        w = w - d
    whole = sensor.size_px is not None and tuple(w.shape) == tuple(sensor.size_px)
    stated, k = None, (0, 0)
    if sensor_origin_px is not None or whole:
        r0, c0 = _origin(w.shape, sensor, sensor_origin_px)
        (lo_r, lo_c), (hi_r, hi_c) = _filter_part(w.shape, sensor, r0, c0)
        k = (lo_r - r0, lo_c - c0)
        w = w[k[0]:hi_r - r0, k[1]:hi_c - c0]
        stated = tuple(int(v) for v in (np.array([r0, c0]) - sensor.tile_origin_px)
                       % np.array(sensor.mosaic_shape))
    means, n = _tile_means(w, sensor.mosaic_shape)
    return means, n, k, stated


def _cube_means(cube, dark, sensor):
    """A tile cube's (``mosaic_to_cube``) band means placed at their offsets from its first
    kept pixel, and the stated phase of that pixel."""
    lo_r, lo_c = (int(v) for v in cube.attrs["mosaic_area_px"][:2])
    values = _as_array(cube.transpose("y", "x", "band"))
    if dark is not None:
        dark = _as_array(dark.transpose("y", "x", "band") if isinstance(dark, xr.DataArray)
                         else dark)
        if dark.shape != values.shape:
            raise ValueError("the dark and the white cube differ in size")
        values = values - dark
    values = values.reshape(-1, values.shape[-1])
    good = np.all(np.isfinite(values) & (values > 0), axis=1)
    if not good.any():
        return None, 0, (0, 0), None
    rel = values[good] / values[good].mean(axis=1, keepdims=True)
    means = np.full(sensor.mosaic_shape, np.nan)
    off = sensor.band_offsets_at((lo_r, lo_c))
    means[off[:, 0], off[:, 1]] = np.median(rel, axis=0)
    stated = tuple(int(v) for v in (np.array([lo_r, lo_c]) - sensor.tile_origin_px)
                   % np.array(sensor.mosaic_shape))
    return means, int(good.sum()), (0, 0), stated


@renamed_keywords(origin_px="sensor_origin_px")
def mosaic_phase(white, sensor, *, dark=None, sensor_origin_px=None, saturation=None,
                 degree=LAMP_DEGREE):
    """Find a mosaic frame's place on the tile grid from a white reference.

    Parameters
    ----------
    white : array_like or xarray.DataArray or sequence of them
        The white reference: a raw 2-D frame (numpy, dask or a DataArray ``(y, x)``; several
        are averaged), or a tile cube that :func:`~snapcorr.cube.mosaic_to_cube` made (its
        ``mosaic_area_px`` and band order say where it was taken).
    sensor : Sensor
        A mosaic sensor with measured responses (a vendor calibration file).
    dark : array_like or sequence, optional
        Dark frame(s), subtracted from a 2-D white.
    sensor_origin_px : (int, int), optional
        The stated sensor row and column of the frame's first pixel, compared with what the
        white shows (a whole-sensor frame needs none).
    saturation : float, optional
        Digital number at or above which a white pixel is saturated (left out). Default: the
        sensor's largest code (its bit depth), else the white's type's largest code
        (:func:`~snapcorr.cube.mosaic.frame_saturation`); none for a white holding values
        above the sensor's largest code (scaled frames: no level is known, every pixel is
        used, and the phase, a ratio of the tiles' means, needs none; ``flatfield`` refuses
        such a white).
    degree : int
        Degree of the polynomial fitted as the unknown lamp.

    Returns
    -------
    MosaicPhase

    Raises
    ------
    ValueError
        Not a mosaic sensor, no measured responses, or no whole tile of usable values.
    """
    if not isinstance(sensor, Sensor) or sensor.layout != "mosaic":
        raise ValueError("the mosaic's phase needs a mosaic sensor")
    if sensor.responses is None:
        raise ValueError(f"the mosaic's phase is read through the bands' measured responses, "
                         f"which the sensor {sensor.name!r} does not give (a vendor "
                         "calibration file does)")
    if isinstance(white, xr.DataArray) and white.ndim == 3:
        if "mosaic_area_px" not in white.attrs:
            raise ValueError("a white cube must be a tile cube from mosaic_to_cube (its "
                             "mosaic_area_px says where it was taken); give the raw frame")
        sensor.check_cube(white, "the white")
        means, n, k, stated = _cube_means(white, dark, sensor)
    else:
        if saturation is None:  # the sensor's largest code, or the white's type's
            try:
                saturation = frame_saturation(sensor, [white])
            except ValueError:  # a white in other units than the bit depth: its saturation
                saturation = None  # is not known, and the phase needs none (flatfield refuses)
        means, n, k, stated = _frame_means(white, dark, sensor, sensor_origin_px, saturation)
    if means is None:
        raise ValueError("the white holds no whole tile of usable values (finite, above the "
                         "dark, not saturated)")
    if np.isfinite(means).sum() < degree + 3:
        return MosaicPhase(np.full(sensor.mosaic_shape, np.inf), None, stated,
                           tuple(sensor.tile_origin_px),
                           f"{int(np.isfinite(means).sum())} usable band means are too few to "
                           f"tell against a lamp of {degree + 1} unknowns")
    at_k = _misfits(means, sensor, degree)
    # at_k is indexed by the tile position of the pixel k from the frame's first one
    misfit = np.roll(at_k, shift=(-k[0], -k[1]), axis=(0, 1))
    return _decide(misfit, stated, sensor, n)


def _decide(misfit, stated, sensor, n):
    """The phase of the smallest misfit, where it stands out and fits."""
    ph = MosaicPhase(misfit, None, stated, tuple(sensor.tile_origin_px))
    best = ph.ranked_px[0]
    reason = ""
    if misfit[best] > MISFIT_MAX:
        reason = (f"no phase fits within {100 * MISFIT_MAX:g} % (is it a white under a smooth "
                  "lamp, of this sensor?)")
    elif ph.ratio < RATIO_MIN:
        reason = (f"two phases fit nearly equally (the next best within {RATIO_MIN:g}x of the "
                  "best): a lamp with narrow lines, or too few tiles")
    return MosaicPhase(misfit, None if reason else best, stated, ph.tile_origin_px,
                       reason + (f" ({n} tiles)" if reason else ""))


#: A white whose best phase misfits by more than this (a smooth lamp through the right
#: phase: 0.1-2 %) is tried flipped too (:func:`flip_shown`).
FLIP_CHECK_MISFIT = 0.02

#: How a camera may flip its frames (a mirror or flip setting): the tile means' axes reversed.
_FLIPS = {"mirrored left-right": (slice(None), slice(None, None, -1)),
          "upside down": (slice(None, None, -1), slice(None)),
          "turned half round (mirrored both ways)": (slice(None, None, -1),
                                                     slice(None, None, -1))}


def flip_shown(white, sensor, *, dark=None, sensor_origin_px=None, saturation=None,
               found=None):
    """Whether a raw white fits a phase of the tile far better flipped than as it is
    (:data:`RATIO_MIN` times): a camera set to mirror or flip its frames puts every band
    where another's pattern says it is, and flat-fielding went on without a word (imec 5x5:
    no phase within 23 % as saved, against 0.04 % mirrored back), or a wrong phase was
    found and a wrong origin advised (imec 4x4: 9.7 % at another phase). Tried only where the
    best phase misfits by more than :data:`FLIP_CHECK_MISFIT`.

    Parameters
    ----------
    white, sensor, dark, sensor_origin_px, saturation
        As :func:`mosaic_phase`.
    found : MosaicPhase, optional
        :func:`mosaic_phase` of the white as it is, if already known.

    Returns
    -------
    str or None
        What the white shows (``"fits the 'imec' tile far better mirrored left-right than as
        it is (...)"``), or None.
    """
    first = white[0] if isinstance(white, (list, tuple)) else white
    if getattr(first, "ndim", 2) != 2 or sensor.responses is None:
        return None
    if found is None:
        found = mosaic_phase(white, sensor, dark=dark, sensor_origin_px=sensor_origin_px,
                             saturation=saturation)
    if not (np.isfinite(found.misfit).any() and np.min(found.misfit) > FLIP_CHECK_MISFIT):
        return None
    try:
        means, _, _, _ = _frame_means(white, dark, sensor, sensor_origin_px, saturation)
    except ValueError:
        return None
    if means is None:
        return None
    tried = [(_decide(_misfits(means[flip], sensor, LAMP_DEGREE), None, sensor, 0), how)
             for how, flip in _FLIPS.items() if means[flip].shape == means.shape]
    if not tried:
        return None
    ph, how = min(tried, key=lambda t: np.min(t[0].misfit))
    if ph.phase_px is None or not RATIO_MIN * np.min(ph.misfit) < np.min(found.misfit):
        return None
    return (f"fits the {sensor.name!r} tile far better {how} than as it is (a smooth lamp "
            f"misfits its band means by {100 * np.min(ph.misfit):.2g} % {how}, "
            f"{100 * np.min(found.misfit):.2g} % at best as it is)")


#: What a flipped white's refusal advises.
FLIP_ADVICE = ("the camera flips its frames (a mirror or flip setting); save them as the sensor "
               "reads out, or flip them back, dark and raw frames alike")


@renamed_keywords(origin_px="sensor_origin_px")
def check_mosaic_phase(white, sensor, sensor_origin_px=None, *, dark=None, saturation=None,
                       what="the white"):
    """Refuse a stated origin whose phase the white reference clearly contradicts.

    A sensor without measured responses, a cube that does not say where it was taken (not
    from :func:`~snapcorr.cube.mosaic_to_cube`), or a white that cannot tell pass unchecked
    (the result says so, or is None); a stated phase among the nearly equal best is accepted.

    Parameters
    ----------
    white, sensor, dark, sensor_origin_px, saturation
        As :func:`mosaic_phase`.
    what : str
        What the white is, for the message (``"--white white.npy"``).

    Returns
    -------
    MosaicPhase or None
        None where the sensor has no measured responses or the white cube no
        ``mosaic_area_px``.

    Raises
    ------
    ValueError
        The white shows another phase than the stated origin (or a whole-sensor frame) gives,
        naming the phase it shows and the nearest origin that agrees; or a crop of a sensor
        of known size comes without its origin (the phase the white shows is named).
    """
    if sensor.layout != "mosaic" or sensor.responses is None:
        return None
    first = white[0] if isinstance(white, (list, tuple)) else white
    if getattr(first, "ndim", 2) == 3 and "mosaic_area_px" not in getattr(first, "attrs", {}):
        return None
    try:
        found = mosaic_phase(white, sensor, dark=dark, sensor_origin_px=sensor_origin_px,
                             saturation=saturation)
    except ValueError as err:  # say which white, for a command's one line
        raise ValueError(f"{what}: {err}") from None
    shape = getattr(first, "shape", None)
    if (found.stated_px is None and sensor.size_px is not None and len(shape or ()) == 2
            and tuple(shape) != tuple(sensor.size_px)):
        raise ValueError(
            f"{what} is a {shape[0]} x {shape[1]} px crop of the {sensor.size_px[0]} x "
            f"{sensor.size_px[1]} px sensor: give the sensor row and column of its first pixel "
            "(sensor_origin_px=), which set its chief-ray angles; "
            + found.describe())
    flipped = flip_shown(white, sensor, dark=dark, sensor_origin_px=sensor_origin_px,
                         saturation=saturation, found=found)
    if flipped is not None:
        raise ValueError(f"{what} {flipped}: {FLIP_ADVICE}")
    if found.agrees is not False:
        return found
    stated_misfit = found.misfit[tuple(found.stated_px)]
    if stated_misfit < RATIO_MIN * found.misfit[tuple(found.phase_px)]:
        return found  # the stated phase is among the nearly equal best
    near = sensor_origin_px if sensor_origin_px is not None else (0, 0)
    shown = found.sensor_origin_px(near)
    stated = ("the whole-sensor frame's" if sensor_origin_px is None
              else f"the stated origin {near[0]},{near[1]}'s")
    raise ValueError(
        f"{what} shows the mosaic at another phase than {stated}: {found.describe()}; "
        f"an origin with the white's phase is {shown[0]},{shown[1]} (sensor_origin_px=, row "
        "first); check the origin and the sensor file")
