"""Flat fields in: reading and cleaning them, and a mosaic's band gains divided out.

The image work goes through the libraries that own it: OpenImageIO and Spectral Python read
the files, OpenCV finds hot and dead pixels (median filter) and averages blocks, scikit-image
traces iso-illumination contours and fits circles to them.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "clean_flat",
    "noise_model",
    "read_flat",
    "remove_band_gains",
]

#: Only pixels whose local mean is at least this fraction of the frame's brightest (99th
#: percentile) give the band gains: past a vignetting cut-off a ratio is noise over noise.
GAIN_LIT_FRACTION = 0.2

#: Pixels further than this many robust standard deviations from their 5 x 5 median are
#: treated as hot or dead.
OUTLIER_SIGMA = 6.0


def read_flat(path):
    """Read a flat field as a 2-D float64 image; several bands are averaged.

    Read by the cube readers (:mod:`snapcorr.files.api`): ``.npy`` (2-D, or 3-D as
    (y, x, band)), TIFF (one multi-channel page, or one single-channel page per band) and
    OpenEXR (OpenImageIO; an alpha channel is ignored), ENVI ``.hdr`` (Spectral Python),
    ``.nc`` and ``.zarr`` cubes. The path is examined first: a FIFO, device, folder or link
    loop is refused before it is opened.

    A flat field's result (a ratio to a white: a variable named or ``long_name``-d
    reflectance or transmittance, or in units of ``"1"``) is refused: its vignetting was
    divided out.

    Returns
    -------
    image : ndarray, shape (ny, nx), float64
        A pixel saturated in any band is ``inf`` in the mean.
    info : dict
        ``bands`` (how many were averaged) and ``saturation`` (the largest value the file's
        integer type holds, or None for floating-point data).
    """
    from ...cube.flatfield import ratio_kind
    from ...files.api import read_array

    data = read_array(path, what="flat field", drop_alpha=True)
    kind = ratio_kind(data, by_units=False)  # a white normalised elsewhere keeps its fall-off
    if kind is not None:  # its fall-off was divided out: a lens without vignetting
        source = data.attrs.get("source") or "a ratio to a white"
        raise ValueError(f"the flat field {path} is {kind} (a flat field's result: {source}), "
                         "not the counts of a white: the lens's fall-off is divided out of it; "
                         "give the raw white frames")
    if not isinstance(data, np.ndarray):  # a netCDF or Zarr variable
        data = np.asarray(data.values)
    sat = np.iinfo(data.dtype).max if np.issubdtype(data.dtype, np.integer) else None
    image = data.mean(axis=2, dtype=np.float64) if data.shape[2] > 1 else \
        np.asarray(data[:, :, 0], dtype=np.float64)
    if sat is not None and data.shape[2] > 1:
        # a pixel saturated in any band is saturated in the mean
        image = np.where((data >= sat).any(axis=2), np.inf, image)
    return image, {"bands": int(data.shape[2]), "saturation": sat}


#: :func:`noise_model` measures the noise from at least this many pixels' residuals (a flat of
#: 16 x 16 pixels has 196); with fewer it gives none.
MIN_NOISE_PIXELS = 20


def noise_model(image, valid, *, gain=None):
    """Noise variance as ``a + b * signal + c * signal**2`` (read, shot and gain noise: the
    photon-transfer curve), measured in the image.

    The residual of each pixel from the mean of its four neighbours (OpenCV ``filter2D``) has
    variance ``1.25 sigma^2`` for independent noise and cancels any linear gradient, so steep
    fall-offs do not leak into it. Its robust spread (median absolute deviation) in bins of
    signal gives the curve, fitted with non-negative coefficients (scipy ``nnls``): a
    straight line cannot follow noise that grows with the signal itself (fixed-pattern gain,
    frames summed with different gains), and with its intercept held at or above 0 it would
    overstate the variance everywhere.

    Parameters
    ----------
    image : array_like
        2-D image (y, x).
    valid : array_like of bool
        Same shape; True where a pixel is used.
    gain : array_like, optional
        Same shape: each pixel's gain already divided out of ``image`` (a mosaic's band
        gains, :func:`remove_band_gains`). The curve is then the raw frame's, in raw counts
        ``g * signal``: a pixel's variance in the image is ``a / g^2 + b signal / g +
        c signal^2``, and each residual's, with its neighbours' gains, is fitted in bins of
        signal within each gain.

    Returns
    -------
    a, b, c : float
    """
    import cv2

    img = np.asarray(image, np.float32)
    kernel = np.array([[0, -0.25, 0], [-0.25, 1, -0.25], [0, -0.25, 0]], np.float32)
    resid = cv2.filter2D(img, -1, kernel, borderType=cv2.BORDER_REFLECT)
    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)
    ok = cv2.erode(np.asarray(valid, np.uint8), cross, borderType=cv2.BORDER_CONSTANT,
                   borderValue=0) > 0
    if gain is not None:
        ok &= np.isfinite(gain) & (np.asarray(gain) > 0)
    signal = cv2.blur(img, (3, 3))[ok]
    r = resid[ok]
    if r.size < MIN_NOISE_PIXELS:
        return 0.0, 0.0, 0.0  # no measure of the noise: nothing is called an outlier by it
    if gain is None:
        groups = [(np.arange(r.size), 1.0, 1.0)]
    else:
        groups = _gain_groups(np.where(ok, gain, 1.0).astype(np.float64), ok)
    step = max(1, r.size // 400_000)  # a few 1e5 pixels pin the curve down
    rows, variances, weights = [], [], []
    for members, ka, kb in groups:
        members = members[::step]
        order = members[np.argsort(signal[members], kind="stable")]
        # 20 bins of equal count (a band's share of the pixels, or a small flat's: fewer, of
        # 100 or more; a flat of a few hundred pixels, one bin)
        n_bins = int(np.clip(order.size // 100, 1, 20))
        for part in np.array_split(order, n_bins):
            if part.size < min(50, order.size):
                continue
            rr = r[part]
            mad = np.median(np.abs(rr - np.median(rr)))
            level = float(np.median(signal[part]))
            rows.append((ka, kb * level, level * level))
            variances.append(float((1.4826 * mad) ** 2 / 1.25))
            weights.append(float(part.size))
    return _fit_noise_curve(np.asarray(rows), np.asarray(variances), np.asarray(weights))


def _gain_groups(gain, ok):
    """Pixels of one gain (a band), and what a residual's variance has of ``a`` and ``b``
    over 1.25 times a gain-1 pixel's: ``(1 / g^2 + sum_nbrs 1 / (16 g_n^2)) / 1.25`` and the
    same with ``1 / g``. The groups are the distinct gains (at most 64, else in 64 ranges)."""
    import cv2

    nbrs = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], np.float64) / 16.0
    ka = (1.0 / gain**2 + cv2.filter2D(1.0 / gain**2, -1, nbrs,
                                       borderType=cv2.BORDER_REFLECT)) / 1.25
    kb = (1.0 / gain + cv2.filter2D(1.0 / gain, -1, nbrs, borderType=cv2.BORDER_REFLECT)) / 1.25
    g = gain[ok]
    values, key = np.unique(np.round(g, 12), return_inverse=True)
    if values.size > 64:
        key = np.minimum((np.argsort(np.argsort(g)) * 64) // g.size, 63)
    ka, kb = ka[ok], kb[ok]
    out = []
    for k in np.unique(key):
        members = np.flatnonzero(key == k)
        out.append((members, float(np.median(ka[members])), float(np.median(kb[members]))))
    return out


def _fit_noise_curve(rows, v, n):
    """``a, b, c`` >= 0 (scipy ``nnls``) of ``v ~ a rows[:, 0] + b rows[:, 1] + c rows[:, 2]``,
    each bin weighted by its variance's precision (about sqrt(2 / n) of the variance).

    The precision is that of the curve's variance at the bin, not of the bin's own estimate
    (iteratively reweighted): a bin whose measured variance is zero (pixels cut off by
    vignetting, noise below one count) would otherwise weigh without bound and crush the
    whole curve to zero. Weights are floored at 1e-6 of the largest variance."""
    from scipy.optimize import nnls

    if v.size == 0:
        return 0.0, 0.0, 0.0
    levels = np.sqrt(rows[:, 2])
    if v.size < 2 or np.ptp(levels) == 0:  # no spread of signal to fit a curve to
        return float(np.mean(v)), 0.0, 0.0
    tiny = max(1e-6 * float(np.max(v)), 1e-300)
    scale = max(float(np.max(levels)), 1e-30)
    design = rows / np.array([1.0, scale, scale * scale])
    pred = np.maximum(v, tiny)
    pred = np.where(v > 0, pred, max(float(np.median(v[v > 0])) if (v > 0).any() else tiny,
                                     tiny))
    for _ in range(4):
        w = np.sqrt(n) / np.maximum(pred, tiny)
        coef, _ = nnls(design * w[:, None], v * w)
        pred = design @ coef
    return float(coef[0]), float(coef[1] / scale), float(coef[2] / scale**2)


def clean_flat(image, *, dark=None, saturation=None, gain=None):
    """Subtract the dark frame and mask saturated, non-finite, hot and dead pixels.

    Hot and dead pixels are those further than ``OUTLIER_SIGMA`` standard deviations of the
    local noise (:func:`noise_model` at the pixel's signal) from the 5 x 5 median of their
    neighbourhood (OpenCV ``medianBlur``) and from the quadratic surface through the other
    pixels of that window (which follows a steep, curved fall-off where the median does
    not); they are masked, not replaced, so the noise of the pixels kept is untouched. Dark
    areas (a reference cut off by vignetting, an image circle smaller than the sensor) get
    their own, smaller noise, not the image's.

    Parameters
    ----------
    image : array_like
        The flat field, 2-D (y, x), real numbers (counts).
    dark : array_like, optional
        Dark frame of the same shape, subtracted; pixels where it is not finite are masked.
    saturation : float, optional
        Raw values at or above this (before the dark is subtracted) are masked as saturated.
    gain : array_like, optional
        Each pixel's gain, already divided out of ``image`` (a mosaic's band gains,
        :func:`remove_band_gains`): a pixel of gain ``g`` collected ``g`` times the light,
        and its noise is that of the raw counts over ``g`` (:func:`noise_model`).

    Returns
    -------
    image : ndarray, float32, dark subtracted (masked pixels hold 0)
    valid : ndarray of bool
    noise_var : ndarray, float32
        Noise variance of each pixel from :func:`noise_model`, for weighting.
    """
    import cv2

    img = np.asarray(image)
    if img.dtype == bool or np.iscomplexobj(img):
        raise ValueError(f"a flat field holds real numbers, got {img.dtype} values")
    img = img.astype(np.float64)
    valid = np.isfinite(img)
    if saturation is not None:
        valid &= img < saturation
    if dark is not None:
        dark = np.asarray(dark, np.float64)
        valid &= np.isfinite(dark)
        img = img - np.where(np.isfinite(dark), dark, 0.0)
    img = np.where(valid, img, 0.0).astype(np.float32)
    med = cv2.medianBlur(img, 5)
    a, b, c = noise_model(img, valid, gain=gain)
    peak = float(np.percentile(med[valid], 99)) if valid.any() else 0.0
    floor = (1e-4 * abs(peak)) ** 2  # noise-free data: tolerate rounding and kinks
    level = np.maximum(med, 0.0)
    g = 1.0 if gain is None else np.where(valid, gain, 1.0)
    var = (a / g**2 + (b / g + c * level) * level + floor).astype(np.float32)
    # without a measure of the noise (a flat of a few pixels) no pixel is called an outlier
    outlier = np.abs(img - med) > OUTLIER_SIGMA * np.sqrt(var) if a + b + c > 0 else \
        np.zeros(img.shape, bool)
    if min(img.shape) >= 5:
        # ... and off the surface its neighbours follow: a 5 x 5 median departs from a
        # steep, curved fall-off (far from the axis), and masking there kept only the
        # pixels on one side of it
        pred, spread = _local_quadratic(img)
        outlier &= np.abs(img - pred) > OUTLIER_SIGMA * np.sqrt(var * (1.0 + spread))
    valid &= ~outlier
    # Saturated neighbours drag the median: drop a one-pixel rim around masked areas too.
    bad = (~valid).astype(np.uint8)
    valid &= cv2.dilate(bad, np.ones((3, 3), np.uint8)) == 0
    img[~valid] = 0.0
    return img, valid, var


def _quadratic_kernels(side=5):
    """Weights that predict a pixel from the other pixels of a ``side x side`` window by a
    least-squares quadratic surface, for each place of the pixel in the window."""
    yy, xx = np.mgrid[0:side, 0:side]
    out = np.zeros((side, side, side, side))
    for py in range(side):
        for px in range(side):
            x, y = (xx - px).ravel(), (yy - py).ravel()
            A = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1).astype(float)
            keep = (x != 0) | (y != 0)
            w = np.zeros(side * side)
            w[keep] = np.linalg.pinv(A[keep])[0]  # the surface's value at the pixel
            out[py, px] = w.reshape(side, side)
    return out


def _local_quadratic(img, side=5):
    """Each pixel as the quadratic surface through the other pixels of the ``side x side``
    window about it (the window kept inside the frame at its edges), and the variance of
    that prediction in units of one pixel's (the sum of the squared weights): a residual
    that follows gradients and curvature, where a median does not."""
    kern = _quadratic_kernels(side)
    h, w = img.shape
    half = side // 2
    pred = np.zeros(img.shape, np.float64)
    spread = np.zeros(img.shape, np.float64)

    def span(p, n):  # the pixels that sit at place p of their window along an axis
        if p < half:
            return p, p + 1
        if p == half:
            return half, n - half
        return n - side + p, n - side + p + 1

    for py in range(side):
        r0, r1 = span(py, h)
        for px in range(side):
            c0, c1 = span(px, w)
            k = kern[py, px]
            acc = np.zeros((r1 - r0, c1 - c0))
            for a in range(side):
                for b in range(side):
                    if k[a, b] != 0.0:
                        acc += k[a, b] * img[r0 - py + a : r1 - py + a, c0 - px + b : c1 - px + b]
            pred[r0:r1, c0:c1] = acc
            spread[r0:r1, c0:c1] = float(np.sum(k * k))
    return pred, spread


def remove_band_gains(image, sensor, *, origin_px=None, dark=None, saturation=None):
    """Divide a snapshot mosaic's band gains out of a raw flat field.

    Behind a mosaic of filters each band has its own gain (a 4 x 4 sensor's span 0.25-1.0 in
    a flat of white light): a raw flat carries the tile pattern on top of the lens's fall-off.
    The pattern is a property of the layout, not noise, so it is fitted and divided out. Each
    pixel is divided by a smooth local mean of the frame: a tile-sized box average applied
    twice, once from either side, so every band weighs the same in it (whatever the pixel's
    place in the tile) and the kernel is symmetric about the pixel (a gradient of the fall-off
    cancels; what its curvature leaves is ~1e-5 of the level). A band's gain is the median of
    that ratio over its pixels, where the frame is lit (at least ``GAIN_LIT_FRACTION`` of its
    brightest) and the kernel holds no masked pixel; the gains are scaled to a mean of 1, so
    the flat keeps its level. They are fitted from each frame: they differ a little between
    f-numbers, as the filters shift with the angle of the light.

    Where the bands sit follows the sensor's layout at the frame's origin, modulo the tile
    (:func:`snapcorr.cube.mosaic.frame_area`, :meth:`Sensor.band_offsets_at`). Pixels outside the
    sensor's filter area (``filter_area_px``) carry no filter and have no band gain: they are
    NaN in the result (not used), as is a tile position that carries no band.

    Parameters
    ----------
    image : array_like
        The raw frame, 2-D (rows, cols) counts: the whole sensor, or a crop at ``origin_px``.
    sensor : Sensor
        A ``layout = "mosaic"`` sensor.
    origin_px : (int, int), optional
        Sensor row and column of the frame's first pixel (default: the frame is the whole
        sensor, of its ``size_px``).
    dark : array_like, optional
        Dark frame of the same shape, subtracted first (the gains multiply the light only).
    saturation : float, optional
        Raw values at or above this (before the dark is subtracted) are saturated: NaN.

    Returns
    -------
    image : ndarray, float64
        Dark subtracted, each pixel divided by its band's gain; NaN where the pixel is not
        finite, saturated, outside the filter area or on a tile position without a band.
    gains : ndarray, shape (n_bands,)
        Each band's gain relative to the mean over the bands, in the sensor's band order.

    Raises
    ------
    ValueError
        Not a mosaic sensor, a frame that does not fit the sensor at ``origin_px``, or a band
        with too few lit pixels to fit its gain.
    """
    check_mosaic_sensor(sensor)
    img = np.array(image, dtype=np.float64)
    if img.ndim != 2:
        raise ValueError(f"a raw mosaic flat is 2-D, got shape {img.shape}")
    if saturation is not None:
        img[img >= saturation] = np.nan
    if dark is not None:
        img = img - np.asarray(dark, np.float64)
    labels = _band_labels(img.shape, sensor, origin_px)
    img[labels < 0] = np.nan
    gains = _fit_band_gains(img, labels, sensor)
    out = img / np.where(labels >= 0, gains[np.maximum(labels, 0)], np.nan)
    return out, gains


def check_mosaic_sensor(sensor):
    """Refuse anything but a mosaic :class:`Sensor`: only its flats carry band gains."""
    from ...cube.sensor import Sensor

    if not isinstance(sensor, Sensor):
        raise TypeError(f"sensor must be a Sensor, got {type(sensor).__name__}")
    if sensor.layout != "mosaic":
        raise ValueError(f"sensor {sensor.name!r} is not a mosaic (layout {sensor.layout!r}): "
                         "its flats carry no tile pattern of band gains to remove")


def _band_labels(shape, sensor, origin_px):
    """Each pixel's band (index into the sensor's bands), -1 where it carries no filter."""
    from ...cube.mosaic import frame_area

    (lo_r, lo_c), (rows, cols), (y0, x0) = frame_area(shape, sensor, origin_px)
    r0, c0 = (0, 0) if origin_px is None else (int(origin_px[0]), int(origin_px[1]))
    tr, tc = sensor.mosaic_shape
    labels = np.full(shape, -1, np.int32)
    kept = labels[lo_r - r0:lo_r - r0 + rows, lo_c - c0:lo_c - c0 + cols]  # a view
    for b in range(sensor.n_bands):
        kept[y0[b]::tr, x0[b]::tc] = b
    return labels


def _fit_band_gains(img, labels, sensor):
    """Each band's gain over the mean of the bands: the median of pixel / symmetric local mean
    (the tile-sized box from either side: a tent of 2 t - 1 pixels, every tile position
    weighing 1 / t in each direction)."""
    import cv2

    tr, tc = sensor.mosaic_shape
    ky = np.convolve(np.ones(tr), np.ones(tr)) / tr**2
    kx = np.convolve(np.ones(tc), np.ones(tc)) / tc**2
    ok = np.isfinite(img)
    smooth = cv2.sepFilter2D(np.where(ok, img, 0.0), cv2.CV_64F, kx, ky,
                             borderType=cv2.BORDER_CONSTANT)
    cover = cv2.sepFilter2D(ok.astype(np.float64), cv2.CV_64F, kx, ky,
                            borderType=cv2.BORDER_CONSTANT)
    whole = ok & (cover > 1.0 - 1e-9)  # the kernel holds no masked pixel, nor the border
    if not whole.any():
        raise ValueError("the frame holds no pixel whose tile-sized neighbourhood is whole: "
                         "no band gain can be fitted")
    peak = float(np.percentile(smooth[whole], 99))
    lit = whole & (smooth > GAIN_LIT_FRACTION * peak) & (smooth > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = img / smooth
    gains = np.full(sensor.n_bands, np.nan)
    for b in range(sensor.n_bands):
        r = ratio[lit & (labels == b)]
        if r.size < 20:
            raise ValueError(f"band {b} ({sensor.cwl_nm[b]:g} nm) has {r.size} lit pixels in "
                             "the flat: too few to fit its gain (20 at least)")
        gains[b] = np.median(r)
    if not np.all(np.isfinite(gains) & (gains > 0)):
        raise ValueError("a band of the flat has no signal: its gain cannot be divided out")
    return gains / gains.mean()
