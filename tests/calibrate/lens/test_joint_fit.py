"""The joint fit's model of a block near the pupil's full cut-off, against pupil sampling.

Where a vignetting circle sweeps across a small (slow) exit pupil, the light falls from all
to nothing within a few degrees, like a power 3/2 at both ends. A block of 8 x 8 pixels there
spans half of the remaining light, and a flat's outlier mask drops pixels unevenly inside it.
The fit compares block means of the valid pixels with its model, so the model must be that
mean, not the value at the block's centre: evaluated at the centre it was 1 % off next to the
cut-off (17 standard errors at 0.5 % noise per pixel), which biased P and h by 0.05 % and
raised the reduced chi-square to 1.3.

The truth here is written in the test: every pixel's light is the area common to the exit
pupil (radius R, on the axis) and the circle (radius P, centre h tan CRA), sampled on a fine
grid of vertical chords across the pupil (each chord's overlap is the shorter of the two
half-chords, twice), then averaged over each block's valid pixels.
"""

from __future__ import annotations

import numpy as np
import pytest

from snapcorr.calibrate.lens.joint_fit import BlockData, _block_model, block_centroids

X, P, H = 21.0, 7.0, 28.0  # h > x: the circle sweeps across the pupil as the CRA grows
F = 11.0
R = X / (2 * F)
PITCH_MM = 7.1e-3
BLOCK = 8
CENTER = (3.5, 2.5)  # optical centre near one corner: the field reaches the full cut-off


def sampled_fraction(tan, n=20000):
    """Fraction of the pupil left by the circle, by ``n`` vertical chords across the pupil."""
    u = -R + (np.arange(n) + 0.5) * (2 * R / n)  # chord positions, midpoints
    out = np.empty(tan.size)
    half_pupil = np.sqrt(np.clip(R * R - u * u, 0, None))
    for i, c in enumerate(np.ravel(tan) * H):
        half_circle = np.sqrt(np.clip(P * P - (u - c) ** 2, 0, None))
        out[i] = np.sum(2 * np.minimum(half_pupil, half_circle)) * (2 * R / n)
    return out.reshape(np.shape(tan)) / (np.pi * R * R)


@pytest.fixture(scope="module")
def scene():
    # a strip of blocks along the diagonal that crosses the cut-off
    t_on, t_cut = (P - R) / H, (P + R) / H
    rho_px = np.array([t_on, t_cut]) * X / PITCH_MM
    lo, hi = int(rho_px[0] / np.sqrt(2)) // BLOCK, int(rho_px[1] / np.sqrt(2)) // BLOCK + 2
    ny = nx = (hi + 1) * BLOCK
    yy, xx = np.mgrid[:ny, :nx].astype(float)
    tan = np.hypot(xx - CENTER[0], yy - CENTER[1]) * PITCH_MM / X
    # only the blocks on the diagonal strip are needed: sample there
    near = np.abs((xx // BLOCK) - (yy // BLOCK)) <= 1
    frac = np.zeros((ny, nx))
    frac[near] = sampled_fraction(tan[near])
    # an outlier mask that drops pixels unevenly: where the light is low, one in ten (more
    # than a flat's outlier mask drops next to a cut-off: up to 13 % in the last 0.1 deg)
    rng = np.random.default_rng(3)
    valid = near & ~((frac < 0.3) & (rng.random(frac.shape) < 0.10))
    return frac, valid, lo, hi


def block_truth(frac, valid):
    ny, nx = frac.shape
    s = (frac * valid).reshape(ny // BLOCK, BLOCK, nx // BLOCK, BLOCK).sum(axis=(1, 3))
    n = valid.reshape(ny // BLOCK, BLOCK, nx // BLOCK, BLOCK).sum(axis=(1, 3))
    with np.errstate(invalid="ignore"):
        return s / n, n


def model_of(valid, use_centroids=True, block_px=BLOCK):
    ny, nx = valid.shape
    by, bx = np.mgrid[: ny // BLOCK, : nx // BLOCK]
    c = (BLOCK - 1) / 2.0
    xpix, ypix = (bx * BLOCK + c).ravel(), (by * BLOCK + c).ravel()
    (dx, dy, sx, sy), = block_centroids([valid], BLOCK)
    data = BlockData(q=np.zeros((1, xpix.size)), sigma=np.ones((1, xpix.size)), xpix=xpix,
                     ypix=ypix, R_mm=np.array([R]), R_ref_mm=None, pitch_mm=PITCH_MM, x_mm=X,
                     gains=True, block_px=block_px,
                     **({"xoff": dx.ravel()[None], "yoff": dy.ravel()[None],
                         "xsd": sx.ravel()[None], "ysd": sy.ravel()[None]}
                        if use_centroids else {}))
    return _block_model(data, "one", [P, H, *CENTER[::-1]], CENTER[::-1])[0].reshape(by.shape)


def test_the_chord_sampling_is_right_where_the_answer_is_known():
    # fully lit inside the onset, dark past the cut-off, half at the symmetric point
    t_on, t_cut = (P - R) / H, (P + R) / H
    got = sampled_fraction(np.array([0.5 * t_on, 1.01 * t_cut]))
    assert got[0] == pytest.approx(1.0, abs=1e-6) and got[1] == 0.0
    # the circle's edge through the pupil's centre: a lens-shaped overlap, analytic
    t_mid = np.sqrt(P * P) / H  # circle centre at distance P: its edge passes the axis
    d = P
    lens = (R * R * np.arccos((d * d + R * R - P * P) / (2 * d * R))
            + P * P * np.arccos((d * d + P * P - R * R) / (2 * d * P))
            - 0.5 * np.sqrt((-d + R + P) * (d + R - P) * (d - R + P) * (d + R + P)))
    assert sampled_fraction(np.array([t_mid]))[0] == pytest.approx(lens / (np.pi * R * R),
                                                                    rel=1e-6)


def test_block_model_is_the_mean_of_the_valid_pixels_near_full_cut_off(scene):
    frac, valid, lo, hi = scene
    want, n = block_truth(frac, valid)
    got = model_of(valid)
    diag = np.zeros(want.shape, bool)
    k = np.arange(lo, min(hi, *want.shape))
    diag[k, k] = True
    sel = diag & (n >= BLOCK * BLOCK // 2) & (want > 0.02) & (want < 0.6)
    assert sel.sum() >= 8  # blocks in the steep part next to the cut-off
    rel = np.abs(got[sel] / want[sel] - 1)
    assert rel.max() < 5e-4, rel.max()
    # the same at the block centres, as the fit once did: far off (this test can fail)
    centre = model_of(valid, use_centroids=False, block_px=1)
    assert np.max(np.abs(centre[sel] / want[sel] - 1)) > 5e-3
