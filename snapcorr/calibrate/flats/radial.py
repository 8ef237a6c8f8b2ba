"""The optical centre of flat fields and their radial profiles about it.

scikit-image traces the iso-illumination contours and fits circles to them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._coords import called_from_outside, warn_x_first_return

__all__ = ["RadialProfile", "estimate_center", "estimate_center_rc", "radial_profile"]


def estimate_center(images, valids=None, *, levels=12):
    """The optical centre x first, ``(cx, cy)``: the earlier form of
    :func:`estimate_center_rc`, which gives it row first; removed in snapcorr 0.3.

    Parameters
    ----------
    images, valids, levels
        As for :func:`estimate_center_rc`.

    Returns
    -------
    center : (float, float) or None
        ``(cx, cy)``, x first.
    spread : float
        As for :func:`estimate_center_rc`.
    """
    if called_from_outside(2):
        warn_x_first_return("estimate_center", "estimate_center_rc", stacklevel=3)
    center, spread = estimate_center_rc(images, valids, levels=levels)
    return (None if center is None else (center[1], center[0])), spread


def estimate_center_rc(images, valids=None, *, levels=12):
    """Optical centre ``(row, col)`` in pixels from iso-illumination contours.

    Around the optical axis vignetting is radially symmetric, so every iso-illumination
    contour is a circle about the axis. Each image is smoothed (OpenCV Gaussian blur), contours
    are traced at several levels (scikit-image ``find_contours``) and circles fitted to them
    robustly (``CircleModel`` inside ``ransac``); the centre is the median of the circles'
    centres, weighted by the arc each contour covers. Images are best given as ratios to a
    reference flat, which cancels non-uniform sources.

    Parameters
    ----------
    images : sequence of array_like
        2-D images (y, x).
    valids : sequence of array_like of bool, optional
        A mask per image, True where the pixel is usable (default: every pixel).
    levels : int
        Contour levels per image, evenly spaced between its 3rd and 97th percentiles.

    Returns
    -------
    center : (float, float) or None
        None when no image holds a usable contour (a flat without fall-off).
    spread : float
        Median absolute deviation of the circle centres, pixels.
    """
    import cv2
    from skimage.measure import CircleModel, find_contours, ransac

    centers, weights = [], []
    for k, img in enumerate(images):
        img = np.asarray(img, dtype=np.float32)
        valid = np.ones(img.shape, bool) if valids is None else np.asarray(valids[k], bool)
        sigma = max(1.0, min(img.shape) / 100.0)
        w = cv2.GaussianBlur(valid.astype(np.float32), (0, 0), sigma)
        s = cv2.GaussianBlur(np.where(valid, img, 0).astype(np.float32), (0, 0), sigma)
        with np.errstate(invalid="ignore", divide="ignore"):
            smooth = np.where(w > 0.5, s / w, np.nan)
        good = smooth[np.isfinite(smooth)]
        if good.size < 100:
            continue
        lo, hi = np.percentile(good, [3, 97])
        if not hi > lo * 1.02:
            continue
        for level in np.linspace(lo, hi, levels + 2)[1:-1]:
            for contour in find_contours(smooth, level):
                if len(contour) < 20:
                    continue
                # fitted as (col, row) points, the order of the results every calibration
                # was checked with (rounding in CircleModel's solve depends on it)
                pts = contour[:, ::-1]
                try:
                    model, inliers = ransac(pts, CircleModel, min_samples=3,
                                            residual_threshold=2.0, max_trials=50, rng=0)
                except (ValueError, np.linalg.LinAlgError):
                    continue
                if model is None or inliers is None or inliers.sum() < 20:
                    continue
                (cc, rc), r = model.center, model.radius
                ang = np.sort(np.arctan2(pts[inliers, 1] - rc, pts[inliers, 0] - cc))
                span = 2 * np.pi - np.diff(np.append(ang, ang[0] + 2 * np.pi)).max()
                if span < np.pi / 3 or not np.isfinite(r) or r > 20 * max(img.shape):
                    continue
                centers.append((rc, cc))
                weights.append(span * inliers.sum())
    if not centers:
        return None, np.inf
    c = np.asarray(centers)
    w = np.asarray(weights)
    center = tuple(float(_weighted_median(c[:, i], w)) for i in range(2))
    spread = float(np.median(np.hypot(c[:, 1] - center[1], c[:, 0] - center[0])))
    return center, spread


def _weighted_median(values, weights):
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return values[order][np.searchsorted(cum, 0.5 * cum[-1])]


@dataclass(frozen=True)
class RadialProfile:
    """A flat field (or ratio of two) averaged in rings of equal chief-ray angle.

    Attributes
    ----------
    cra_deg : ndarray
        Mean chief-ray angle of the pixels in each bin.
    value, stderr : ndarray
        Bin mean and its standard error (from the scatter of the pixels in the bin).
    count : ndarray
        Pixels in each bin (bins with fewer than 4 pixels are dropped).
    """

    cra_deg: np.ndarray
    value: np.ndarray
    stderr: np.ndarray
    count: np.ndarray


def radial_profile(image, valid, cra_deg, *, bin_deg=0.1, denominator=None):
    """Average ``image`` (or ``image / denominator``) in CRA bins of width ``bin_deg``.

    With a ``denominator`` the value is the ratio of the bin sums (so a source that varies
    around the ring cancels exactly, as it multiplies both images alike) and the uncertainty
    comes from the scatter of the pixel-by-pixel ratio.

    Parameters
    ----------
    image : ndarray
        2-D image (y, x).
    valid : array_like of bool
        Same shape; True where a pixel is used (with a denominator, also only where it is > 0).
    cra_deg : array_like
        Chief-ray angle of every pixel, degrees (>= 0), same shape.
    bin_deg : float
        Bin width, degrees; bins start at 0.
    denominator : ndarray, optional
        Image of the same shape to divide by (a reference flat).

    Returns
    -------
    RadialProfile
        Only the bins with at least 4 valid pixels.
    """
    valid = np.asarray(valid, bool)
    if denominator is not None:
        valid = valid & (denominator > 0)
    idx = (np.asarray(cra_deg) * (1.0 / bin_deg)).astype(np.int32).ravel()
    w = valid.ravel().astype(np.float64)
    n = np.bincount(idx, w)
    keep = n >= 4
    nn = np.maximum(n, 1)
    theta = np.bincount(idx, w * np.asarray(cra_deg).ravel()) / nn
    a = np.where(valid, image, 0.0).ravel()
    if denominator is None:
        mean = np.bincount(idx, a) / nn
        q = a
    else:
        b = np.where(valid, denominator, 0.0).ravel()
        mean = np.bincount(idx, a) / np.where(keep, np.bincount(idx, b), 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            q = np.where(w > 0, a / np.where(w > 0, b, 1.0), 0.0)
    m1 = np.bincount(idx, q) / nn
    var = np.maximum(np.bincount(idx, q * q) / nn - m1 * m1, 0.0)
    stderr = np.sqrt(var * n / np.maximum(n - 1, 1) / nn)
    return RadialProfile(theta[keep], mean[keep], stderr[keep], n[keep].astype(np.int64))
