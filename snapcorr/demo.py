"""``snapcorr demo``: the main job on the lens and experiment of Goossens et al. 2019.

1. The optics on the bundled Edmund Optics 16 mm profile: the kernel-mean shift of 700 nm
   filters over the field at f/1.4-f/8 by the three models (Eq. 6, exact ideal aperture,
   vignetted aperture) and the relative illumination (``mean_shift.png``, ``.csv``; the
   paper's Fig. 12, extended).
2. The paper's experiment, simulated end to end (:mod:`snapcorr.paper_experiment`): flat
   fields -> lens calibration -> a Snapscan-like cube of a colour filter on a white tile ->
   flat-fielding -> correction by both models, with the paper's metrics
   (``calibration.png``, ``lens.toml``, ``spectra.png``, ``maps.png``).

Everything is summarised in ``summary.txt``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import __version__
from ._io import atomic_write, save_png
from .data import lens_path
from .optics import METHODS, Lens, mean_shift
from .optics import MODELS as LADDER

__all__ = ["run_demo"]

F_NUMBERS = (1.4, 2.0, 2.8, 4.0, 8.0)
PAPER_CRAS = (1.9, 10.3, 17.4)
CWL_NM, N_EFF = 700.0, 1.7
MODELS = tuple(m for m in LADDER if m in METHODS)  # the ladder's mean-shift rungs


#: Written into a demo's folder: a later run may replace what is in such a folder.
MARKER = ".snapcorr-demo"


def check_out_dir(out_dir, *, overwrite=False):
    """The demo's output folder, refused if it holds files the demo did not make.

    A folder that does not exist yet, is empty, or holds a previous demo's output (the
    :data:`MARKER` file) is fine; any other folder only with ``overwrite=True``, since the demo
    writes files with common names (``lens.toml``, ``summary.txt``) into it.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out} is not a folder; choose another --out")
    if out.is_dir() and any(out.iterdir()) and not (out / MARKER).exists() and not overwrite:
        names = sorted(p.name for p in out.iterdir())
        raise FileExistsError(
            f"{out} holds files snapcorr demo did not make ({', '.join(names[:4])}"
            f"{', ...' if len(names) > 4 else ''}); choose an empty or new folder with --out, "
            "or pass --overwrite to write over files of the same names")
    return out


def _mean_shift_over_the_field(lens):
    """Part 1: the summary's lines, the CSV's rows and the figure (without pyplot, so no
    global plotting state changes) of the mean shift and relative illumination over CRA."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    cra = np.linspace(0.0, 20.0, 201)
    rows = []
    lines = [f"snapcorr {__version__} demo: {lens.name}, cwl {CWL_NM:g} nm, n_eff {N_EFF:g}",
             f"exit pupil x = {lens.exit_pupil_mm:g} mm, {lens.describe_vignetting()}, "
             f"m = {lens.magnification:g}, m_P = {lens.pupil_magnification:g}", "",
             "spread of the mean shift between CRA 1.9, 10.3 and 17.4 deg (nm):",
             f"{'f/#':>6} {'onset':>8} {'Eq. 6':>8} {'ideal':>8} {'vignetted':>10}"]
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    ax, ax2 = fig.subplots(1, 2)
    colours = colormaps["viridis"](np.linspace(0, 0.9, len(F_NUMBERS)))
    spreads = {}
    for f, colour in zip(F_NUMBERS, colours, strict=True):
        curves = {m: mean_shift(CWL_NM, N_EFF, f, cra, lens, method=m) for m in MODELS}
        rel = lens.relative_illumination(f, cra)
        for i, c in enumerate(cra):
            rows.append((f, c, *(curves[m][i] for m in MODELS), rel[i]))
        onset = float(lens.onset_cra_deg(f))
        spread = spreads[f] = {
            m: np.ptp(mean_shift(CWL_NM, N_EFF, f, PAPER_CRAS, lens, method=m)) for m in MODELS
        }
        lines.append(f"{f:>6g} {onset:>7.2f}° {spread['asymptotic']:>8.2f} "
                     f"{spread['ideal']:>8.2f} {spread['vignetted']:>10.2f}")
        ax.plot(cra, curves["vignetted"], color=colour, lw=2, label=f"f/{f:g} vignetted")
        ax.plot(cra, curves["asymptotic"], color=colour, lw=1, ls="--")
        if onset < cra[-1]:
            ax.plot(onset, mean_shift(CWL_NM, N_EFF, f, onset, lens), "o", color=colour)
        ax2.plot(cra, rel, color=colour, lw=2, label=f"f/{f:g}")
    ax.set(xlabel="chief-ray angle (deg)", ylabel="mean shift of a 700 nm filter (nm)",
           title="Kernel mean: vignetted (solid), Eq. 6 (dashed), onset (dots)")
    ax2.set(xlabel="chief-ray angle (deg)", ylabel="relative illumination A / (pi R^2)",
            title="Relative illumination of the vignetted pupil (no cos^4)")
    for a in (ax, ax2):
        a.legend(fontsize=8)
        a.grid(alpha=0.3)
    first = F_NUMBERS[0]
    s1 = spreads[first]
    lines += ["", f"Reading: without vignetting the field spreads the filters by "
              f"~{s1['ideal']:.0f}-{s1['asymptotic']:.0f} nm at any f-number; the vignetting "
              f"circle cuts the oblique rays at wide apertures, so at f/{first:g} the spread is "
              f"only {s1['vignetted']:.1f} nm (Goossens et al. measured ~2 nm). Correcting with "
              "Eq. 6 there would over-correct the field edge by the difference."]
    return lines, rows, fig


def run_demo(out_dir, *, lens: Lens | None = None, echo=print, overwrite=False):
    """Run the demo; write ``mean_shift.png``, ``mean_shift.csv`` and ``summary.txt``, and the
    simulated experiment's ``calibration.png``, ``lens.toml``, ``spectra.png`` and ``maps.png``.

    Refuses a folder holding files the demo did not make unless ``overwrite``
    (:func:`check_out_dir`).

    Parameters
    ----------
    out_dir : str or Path
        Output folder, created if missing.
    lens : Lens, optional
        The lens of part 1 (default: the bundled Edmund Optics 16 mm profile); the simulated
        experiment uses its own.
    echo : callable
        ``echo(text)`` prints progress and the summary.
    overwrite : bool
        Write into a folder holding other files.

    Returns
    -------
    dict
        Paths of the outputs: ``figure``, ``table``, ``summary``, ``spectra``,
        ``calibration``, ``maps`` and ``lens``.
    """
    out = check_out_dir(out_dir, overwrite=overwrite)
    out.mkdir(parents=True, exist_ok=True)
    (out / MARKER).write_text(f"written by snapcorr {__version__} demo\n", encoding="utf-8")
    lens = lens or Lens.load(lens_path())
    lines, rows, fig = _mean_shift_over_the_field(lens)
    figure = save_png(fig, out / "mean_shift.png", dpi=120)
    header = "f_number,cra_deg,asymptotic_nm,ideal_nm,vignetted_nm,relative_illumination"

    def write_csv(p):
        np.savetxt(p, np.array(rows), delimiter=",", header=header, comments="", fmt="%.6f")

    table = atomic_write(out / "mean_shift.csv", write_csv)
    echo("\n".join(lines))
    echo("")
    echo("The paper's experiment, simulated (about half a minute) ...")
    from .paper_experiment import run as run_experiment

    exp_lines, _ = run_experiment(out, echo=echo)
    lines += ["", "The paper's experiment, simulated end to end:", *exp_lines]
    text = "\n".join(lines) + "\n"
    summary = atomic_write(out / "summary.txt", lambda p: p.write_text(text, encoding="utf-8"))
    names = ("mean_shift.png", "mean_shift.csv", "calibration.png", "lens.toml",
             "spectra.png", "maps.png", "summary.txt")
    echo(f"wrote {', '.join(str(out / n) for n in names)}")
    return {"figure": figure, "table": table, "summary": summary,
            "spectra": out / "spectra.png", "calibration": out / "calibration.png",
            "maps": out / "maps.png", "lens": out / "lens.toml"}
