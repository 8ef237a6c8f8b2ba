"""Which pixels a quick look shows the spectra of: bright, different pixels across the field
of a flat-field result, the pixels at the lowest, middle and highest chief-ray angle of a
correction, and the windows averaged around them."""

from __future__ import annotations

import math

import numpy as np

#: Pixels whose spectra :func:`plot_flatfield` draws, and the most candidates along either side
#: of the image they are chosen from.
SPECTRA_SHOWN = 5


CANDIDATES_PX = 48


#: Candidates keep this share of the image's height and width from its edges, where any
#: are left.
EDGE_SHARE = 0.04


#: Side (pixels) of the square window whose mean spectrum :func:`plot_correction` draws
#: around each chosen pixel; the image's stride when that is larger (made odd, so the window
#: is centred), clipped to the image.
SPECTRUM_WINDOW_PX = 5


#: :func:`plot_correction` calls a pixel "on axis" only when its chief-ray angle is below
#: this (degrees); the pixel of lowest angle in a crop away from the axis is "lowest CRA".
ON_AXIS_DEG = 0.5


def _pick_by_content(values, valid, n=SPECTRA_SHOWN):
    """Up to ``n`` grid pixels whose spectra are worth seeing: bright (mean value at least the
    median and half the 99th percentile of the valid pixels' and at most that percentile: not
    dark, not a hot pixel), off
    the edges (:data:`EDGE_SHARE`) where there are such, and, one after another, the
    candidate farthest from those picked, in place (over the image's diagonal) plus in
    spectral angle (over the widest angle from the first): spread across the field, with
    spectra that differ. The first is the brightest candidate."""
    values = np.asarray(values, float)
    h, w = valid.shape
    if not valid.any():
        return []
    finite = np.isfinite(values)
    mean = np.where(finite, values, 0.0).sum(axis=2) / np.maximum(finite.sum(axis=2), 1)
    rows, cols = np.nonzero(valid)
    inner = ((np.minimum(rows, h - 1 - rows) >= EDGE_SHARE * h)
             & (np.minimum(cols, w - 1 - cols) >= EDGE_SHARE * w))
    if inner.any():  # not on the very edge, where a marker is hard to see
        rows, cols = rows[inner], cols[inner]
    level = mean[rows, cols]
    median, hi = np.percentile(level, [50.0, 99.0])
    keep = (level >= max(median, 0.5 * hi)) & (level <= hi)
    rows, cols, level = rows[keep], cols[keep], level[keep]
    spectra = np.nan_to_num(values[rows, cols])
    unit = spectra / np.maximum(np.linalg.norm(spectra, axis=1, keepdims=True), 1e-30)
    diagonal = max(math.hypot(h - 1, w - 1), 1.0)
    picked = [int(np.argmax(level))]
    angle_scale = None
    place = np.full(rows.size, np.inf)
    angle = np.full(rows.size, np.inf)
    while len(picked) < min(n, rows.size):
        k = picked[-1]
        place = np.minimum(place, np.hypot(rows - rows[k], cols - cols[k]) / diagonal)
        angle = np.minimum(angle, np.arccos(np.clip(unit @ unit[k], -1.0, 1.0)))
        if angle_scale is None:  # the widest angle from the first: spectra's own spread
            angle_scale = max(float(angle.max()), 1e-6)
        score = place + angle / angle_scale
        score[picked] = -np.inf
        picked.append(int(np.argmax(score)))
    return [(int(rows[k]), int(cols[k])) for k in picked]


def _pick_by_cra(img, cra_img):
    """Up to three grid pixels by chief-ray angle (lowest, halfway, highest) and their roles:
    "on axis", "mid-field", "edge" when the lowest angle is below :data:`ON_AXIS_DEG`, else
    "lowest CRA", "middle CRA", "highest CRA"."""
    valid = np.isfinite(cra_img) & np.isfinite(np.asarray(img, float))
    if not valid.any():
        valid = np.isfinite(cra_img)
    picked, roles = [], []
    if valid.any():
        rows, cols = np.nonzero(valid)
        angles = cra_img[rows, cols]
        lo, hi = float(angles.min()), float(angles.max())
        names = (("on axis", "mid-field", "edge") if lo < ON_AXIS_DEG
                 else ("lowest CRA", "middle CRA", "highest CRA"))
        for role, k in zip(names, (int(np.argmin(angles)),
                                   int(np.argmin(np.abs(angles - 0.5 * (lo + hi)))),
                                   int(np.argmax(angles))), strict=True):
            rc = (int(rows[k]), int(cols[k]))
            if rc not in picked:
                picked.append(rc)
                roles.append(role)
    return picked, roles


def _window_half(stride):
    """Half the side of the averaging window: :data:`SPECTRUM_WINDOW_PX` or the stride."""
    return max(SPECTRUM_WINDOW_PX, stride) // 2


def _windows(ys, xs, ny, nx, half):
    """The ``(y0, y1, x0, x1)`` of a window ``2 half + 1`` pixels a side around each pixel
    ``(ys[i], xs[i])``, clipped to an image of ``ny`` by ``nx`` pixels."""
    return [(max(0, y - half), min(ny, y + half + 1), max(0, x - half), min(nx, x + half + 1))
            for y, x in zip(ys, xs, strict=True)]


def _where(box, y, x):
    """A legend's words for the window ``box`` around the pixel ``(y, x)``."""
    h, w = box[1] - box[0], box[3] - box[2]
    if h * w == 1:
        return f"(y, x) = ({y}, {x})"
    return f"mean of {h} x {w} px around (y, x) = ({y}, {x})"

