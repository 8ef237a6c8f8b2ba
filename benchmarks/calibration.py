"""Lens calibration: accuracy against flat-field noise, and the time for full-size flats.

Simulated integrating-sphere flats of the paper's lens (x = 21 mm, P = 7.4236 mm,
h = 16.991 mm, m = 0.06, m_P = 1.3) at f/1.4, 2, 2.8, 4 and 8, optical axis off the image
centre. For each noise level and seed, P and h are estimated by the three estimators that
``calibrate_lens`` runs on the same flats: the paper's (Eq. 26 over the discontinuities of the
ratio profiles), Eq. 26 over onsets from the area model fitted to each profile, and the joint
fit of the area model to every ratio image. The chart (``calibration_noise.png``) and its
data (``calibration_noise.csv``) are written next to this file.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from snapcorr import Lens
from snapcorr.calibrate import calibrate_lens
from snapcorr.simulate import Detector, flat_frame

from . import pyplot, write_csv

PAPER = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
F_NUMBERS = (1.4, 2.0, 2.8, 4.0, 8.0)
HERE = Path(__file__).parent
ESTIMATORS = ("onset-ratio", "onset-model", "joint")


def _flats(shape, pitch_um, electrons, seed):
    rng = np.random.default_rng(seed)
    center = (shape[0] * 0.46, shape[1] * 0.55)  # (row, col)
    camera = Detector(signal_electrons=electrons)
    return {f: flat_frame(shape, pitch_um, f, PAPER, center_rc=center, detector=camera, rng=rng)
            for f in F_NUMBERS}


def _calibrate(flats, pitch_um):
    return calibrate_lens(flats, exit_pupil_mm=21.0, pixel_pitch_um=pitch_um,
                          magnification=0.06, pupil_magnification=1.3)


def _estimates(res):
    out = {}
    for det in ("ratio", "model"):
        of = res.onset_fits.get(det)
        out[f"onset-{det}"] = (np.nan, np.nan) if of is None else (of.P_mm, of.h_mm)
    one = res.fits.get("one")
    out["joint"] = ((one.params["P_mm"], one.params["h_mm"]) if one is not None and one.success
                    else (np.nan, np.nan))
    return out


def noise_sweep(*, quick=False, echo=print, write=True):
    """Error in P and h (percent) against per-pixel noise at the optical centre."""
    if quick:
        shape, pitch, noises, seeds = (256, 256), 44.0, (0.01,), (0,)
    else:
        shape, pitch, noises, seeds = (512, 512), 22.0, (0.005, 0.01, 0.02, 0.05, 0.1, 0.2,
                                                         0.3), (0, 1, 2)
    rows = []
    echo(f"calibration against noise: {shape[1]} x {shape[0]} flats of {pitch:g} um "
         f"(the angles of a 2048 x 2048, 5.5 um sensor), {len(seeds)} seed(s)")
    echo(f"{'noise':>6} {'seed':>4}  " + "  ".join(f"{e:>22}" for e in ESTIMATORS))
    for noise in noises:
        electrons = 1.0 / noise**2
        for seed in seeds:
            res = _calibrate(_flats(shape, pitch, electrons, seed), pitch)
            est = _estimates(res)
            cells = []
            for e in ESTIMATORS:
                P, h = est[e]
                dP, dh = 100 * (P / 7.4236 - 1), 100 * (h / 16.991 - 1)
                rows.append({"noise": noise, "seed": seed, "estimator": e, "P_mm": P,
                             "h_mm": h, "P_error_pct": dP, "h_error_pct": dh,
                             "chosen": res.method == e})
                cells.append(f"P {dP:+7.2f}% h {dh:+7.2f}%")
            echo(f"{100 * noise:>5.1f}% {seed:>4}  " + "  ".join(f"{c:>22}" for c in cells))
    if write:
        _write(rows)
    return rows


def _write(rows):
    plt = pyplot()
    write_csv(HERE / "calibration_noise.csv", rows)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    for ax, key, name in ((axes[0], "P_error_pct", "P"), (axes[1], "h_error_pct", "h")):
        for k, e in enumerate(ESTIMATORS):
            sel = [r for r in rows if r["estimator"] == e]
            noise = np.array([r["noise"] for r in sel]) * 100
            err = np.abs([r[key] for r in sel])
            jitter = noise * (1 + 0.04 * (k - 1))
            ax.plot(jitter, err, "o", ms=4, alpha=0.6, color=f"C{k}")
            levels = sorted(set(noise))
            med = [np.nanmedian(err[noise == lv]) for lv in levels]
            ax.plot(levels, med, "-", color=f"C{k}", label=e)
        ax.axhline(1.0, color="k", lw=0.6, ls=":")
        ax.set(xscale="log", yscale="log", xlabel="noise per pixel at the centre (%)",
               ylabel=f"|error in {name}| (%)", title=f"{name}: points = seeds, line = median")
        ax.legend(fontsize=8)
    fig.suptitle("Calibration of the paper's 16 mm lens from simulated sphere flats "
                 "(f/1.4-f/8); dotted: the 1 % requirement")
    fig.savefig(HERE / "calibration_noise.png", dpi=110)
    plt.close(fig)


def full_size_time(*, quick=False, echo=print):
    """Seconds to calibrate five flats of a 2048 x 2048 sensor (1024 x 1024 in quick mode)."""
    n = 1024 if quick else 2048
    pitch = 5.5 * 2048 / n
    flats = _flats((n, n), pitch, 1e4, 0)
    t0 = time.perf_counter()
    res = _calibrate(flats, pitch)
    seconds = time.perf_counter() - t0
    P, h = res.lens.vignetting[0][0], res.lens.vignetting[0][1]
    echo(f"calibrating five {n} x {n} flats (1 % noise): {seconds:.1f} s on this machine; "
         f"P {100 * (P / 7.4236 - 1):+.3f} %, h {100 * (h / 16.991 - 1):+.3f} % "
         f"({res.method}, {res.model} circle)")
    return seconds, res


SUBSETS = ((1.4, 8.0), (1.4, 2.8, 8.0), (1.4, 2.0, 4.0, 8.0), F_NUMBERS)


def fnumber_sweep(*, quick=False, echo=print, write=True):
    """Error in P and h (percent) against the number of f-numbers used, 2 % noise."""
    shape, pitch = ((256, 256), 44.0) if quick else ((512, 512), 22.0)
    seeds = (0,) if quick else (0, 1, 2)
    subsets = SUBSETS[-1:] if quick else SUBSETS
    rows = []
    echo(f"calibration against the number of f-numbers (2 % noise, {len(seeds)} seed(s)):")
    for fs in subsets:
        for seed in seeds:
            flats = _flats(shape, pitch, 1.0 / 0.02**2, seed)
            res = _calibrate({f: flats[f] for f in fs}, pitch)
            est = _estimates(res)
            cells = []
            for e in ESTIMATORS:
                P, h = est[e]
                dP, dh = 100 * (P / 7.4236 - 1), 100 * (h / 16.991 - 1)
                rows.append({"f_numbers": " ".join(f"{f:g}" for f in fs), "n": len(fs),
                             "seed": seed, "estimator": e, "P_error_pct": dP,
                             "h_error_pct": dh})
                cells.append(f"{e}: P {dP:+.2f}% h {dh:+.2f}%")
            echo(f"  f/{', f/'.join(f'{f:g}' for f in fs):<28} seed {seed}: "
                 + "; ".join(cells))
    if write:
        _write_fnumbers(rows)
    return rows


def _write_fnumbers(rows):
    plt = pyplot()
    write_csv(HERE / "calibration_fnumbers.csv", rows)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    for ax, key, name in ((axes[0], "P_error_pct", "P"), (axes[1], "h_error_pct", "h")):
        for k, e in enumerate(ESTIMATORS):
            sel = [r for r in rows if r["estimator"] == e and np.isfinite(r[key])]
            n = np.array([r["n"] for r in sel], float)
            err = np.abs([r[key] for r in sel])
            ax.plot(n + 0.06 * (k - 1), err, "o", color=f"C{k}", alpha=0.7, label=e)
        ax.axhline(1.0, color="k", lw=0.6, ls=":")
        ax.set(yscale="log", xlabel="number of f-numbers (the highest is the reference)",
               ylabel=f"|error in {name}| (%)", xticks=[2, 3, 4, 5],
               title=f"{name}; missing points: no estimate (too few onsets)")
        ax.legend(fontsize=8)
    fig.suptitle("Calibration of the paper's 16 mm lens against the number of f-numbers "
                 "(2 % noise, 3 seeds)")
    fig.savefig(HERE / "calibration_fnumbers.png", dpi=110)
    plt.close(fig)
