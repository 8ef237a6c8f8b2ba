"""Source spectra: the sun, blackbodies (tungsten lamps), spectrum files and a cube's own;
the transmittance of the colour filter in Goossens et al. 2019 (:func:`colour_filter`) and the
published reflectances of a standard colour chart's patches (:func:`colour_checker`).

A :class:`Spectrum` is sampled at increasing wavelengths and interpolated linearly between
them; asking for it outside its range is an error, never a silent zero. The scene budget
(:mod:`snapcorr.budget`) weighs a filter's shift by such a spectrum.
"""

from __future__ import annotations

import functools
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._validation import validate_method

__all__ = [
    "COLOUR_CHECKER_PATCHES",
    "SOLAR_MODELS",
    "Spectrum",
    "blackbody",
    "colour_checker",
    "colour_filter",
    "cube_spectrum",
    "parse_source",
    "read_spectrum",
    "solar",
]

#: Tungsten lamps are modelled as blackbodies at their colour temperature (CIE illuminant A,
#: the incandescent lamp, is defined as Planck's law at 2856 K).
_C2_NM_K = 1.438776877e7  # second radiation constant, nm K


@dataclass(frozen=True)
class Spectrum:
    """A source spectrum sampled at increasing wavelengths (nm); any linear unit.

    Between samples it is interpolated linearly; outside the sampled range it is undefined, and
    asking for it raises ``ValueError``.
    """

    wavelength_nm: np.ndarray
    values: np.ndarray
    name: str = "spectrum"

    def __post_init__(self):
        w = np.asarray(self.wavelength_nm, float)
        v = np.asarray(self.values, float)
        if w.ndim != 1 or w.shape != v.shape or w.size < 2:
            raise ValueError(f"the spectrum {self.name!r} needs wavelengths and values of "
                             f"equal length (>= 2), got shapes {w.shape} and {v.shape}")
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(v))):
            raise ValueError(f"the spectrum {self.name!r} holds NaN or infinite values")
        if np.any(np.diff(w) <= 0):
            raise ValueError(f"the spectrum {self.name!r} needs strictly increasing "
                             "wavelengths (no repeats)")
        if np.any(v < 0) or not np.any(v > 0):
            raise ValueError(f"the spectrum {self.name!r} must be >= 0 and not all zero")
        object.__setattr__(self, "wavelength_nm", w)
        object.__setattr__(self, "values", v)

    @property
    def step_nm(self) -> float:
        return float(np.median(np.diff(self.wavelength_nm)))

    def peak_normalised(self) -> Spectrum:
        """The spectrum scaled to a peak of 1: its shape, all that ratios of signals need (a
        spectrum of 1e306 overflowed in their products and was said to have no signal)."""
        peak = float(np.max(self.values))
        if peak == 1.0:
            return self
        return Spectrum(self.wavelength_nm, self.values / peak, self.name)

    def __call__(self, wavelength_nm):
        lam = np.asarray(wavelength_nm, float)
        lo, hi = self.wavelength_nm[0], self.wavelength_nm[-1]
        # NaN fails every comparison: the range check below would let it through
        if lam.size and not np.all(np.isfinite(lam)):
            raise ValueError(f"the spectrum {self.name!r} is asked for at a wavelength that "
                             "is not a finite number")
        if lam.size and (lam.min() < lo - 1e-9 or lam.max() > hi + 1e-9):
            raise ValueError(f"the spectrum {self.name!r} covers {lo:g}-{hi:g} nm; "
                             f"{lam.min():.4g}-{lam.max():.4g} nm is needed")
        return np.interp(lam, self.wavelength_nm, self.values)


#: Solar spectra :func:`solar` offers, each shipped offline by a maintained package.
SOLAR_MODELS = ("kurucz", "astm-g173")


def solar(model="kurucz", smoothing_nm=0.5, step_nm=0.1, range_nm=(300.0, 1100.0)) -> Spectrum:
    """The sun's spectrum.

    ``"kurucz"``: the Kurucz solar flux at 1 AU (``rms-solar``), as Flittner & Slater used it:
    a sliding average over ``smoothing_nm`` sampled every ``step_nm``. It is the sun alone,
    with the Fraunhofer lines but none of the Earth's oxygen and water-vapour bands.
    ``"astm-g173"``: the ASTM G173 global tilted irradiance at the ground (``pvlib``; 0.5 nm
    below 400 nm, 1 nm above, no smoothing), with the O2 and H2O bands (1.42 cm of water)
    but coarser lines.

    Parameters
    ----------
    model : {"kurucz", "astm-g173"}
        The spectrum (:data:`SOLAR_MODELS`).
    smoothing_nm : float
        Width of the sliding average, nm (``"kurucz"`` only; at most one step: none).
    step_nm : float
        Sampling step, nm (``"kurucz"`` only).
    range_nm : (float, float)
        Wavelengths kept, nm (``"astm-g173"``: its own samples within 1 nm beyond them).

    Returns
    -------
    Spectrum
        In W/m^2/nm.
    """
    validate_method(model, SOLAR_MODELS, "solar model")
    if model == "astm-g173":
        from pvlib.spectrum import get_reference_spectra

        df = get_reference_spectra(standard="ASTM G173-03")
        w = np.asarray(df.index, float)
        keep = (w >= range_nm[0] - 1) & (w <= range_nm[1] + 1)
        return Spectrum(w[keep], np.asarray(df["global"], float)[keep],
                        "sun at the ground (ASTM G173 global tilt)")
    import solar as rms_solar  # the rms-solar package
    from scipy.ndimage import uniform_filter1d

    tab = rms_solar.flux_density("Kurucz", units="W/m^2/nm", xunits="nm")
    grid = np.arange(range_nm[0], range_nm[1] + step_nm / 2, step_nm)
    values = np.interp(grid, np.asarray(tab.x, float), np.asarray(tab.y, float))
    width = max(1, round(smoothing_nm / step_nm))
    if width > 1:
        values = uniform_filter1d(values, width, mode="nearest")
    return Spectrum(grid, values, f"sun (Kurucz, {smoothing_nm:g} nm sliding average)")


#: The hottest blackbody a source may be (K): past it the spectrum over any band set is
#: Rayleigh-Jeans' already, and a larger value is a typo.
TEMPERATURE_MAX_K = 1e6


def blackbody(temperature_k, wavelength_nm=None) -> Spectrum:
    """Planck's law at ``temperature_k`` (relative spectral radiance); a tungsten lamp at its
    colour temperature."""
    t = float(temperature_k)
    if not (math.isfinite(t) and 0 < t <= TEMPERATURE_MAX_K):
        raise ValueError(f"a temperature must be finite, > 0 and at most "
                         f"{TEMPERATURE_MAX_K:g} K (the hottest stars are near 5e4 K), got "
                         f"{temperature_k!r}")
    lam = np.arange(250.0, 2500.01, 0.5) if wavelength_nm is None else np.asarray(
        wavelength_nm, float)
    with np.errstate(over="ignore"):
        v = 1.0 / (lam ** 5 * np.expm1(_C2_NM_K / (lam * t)))
    if not v.max() > 0:
        raise ValueError(f"a blackbody at {t:g} K emits nothing measurable at "
                         f"{lam[0]:g}-{lam[-1]:g} nm")
    return Spectrum(lam, v / v.max(), f"blackbody {t:g} K")


def read_spectrum(path) -> Spectrum:
    """A spectrum from a text file (two columns, wavelength in nm and value; ``#`` comments;
    comma, semicolon, tab or space separated; header lines before the numbers are skipped) or
    an ``.npy`` array of shape (n, 2) or (2, n)."""
    from .files.reading import check_input, check_table_size

    try:
        p = check_input(path, what="spectrum")
    except FileNotFoundError:
        raise ValueError(f"no spectrum file {str(path)!r}") from None
    check_table_size(p, "spectrum")
    if p.suffix == ".npy":
        try:
            a = np.load(p)  # never pickles: an object array is refused
        except (ValueError, EOFError, OSError) as err:
            raise ValueError(f"{p}: not a NumPy array of numbers ({err}); a spectrum is two "
                             "columns, wavelength nm and value") from None
    else:
        try:
            text = p.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{p}: not a text file; a spectrum is two columns of numbers "
                             "(wavelength nm, value), one row per line") from None
        rows = []
        for k, line in enumerate(text.splitlines(), 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            fields = [f for f in re.split(r"[,;\s]+", line) if f]
            try:
                rows.append([float(f) for f in fields])
            except ValueError:
                if rows:  # text after the data began
                    raise ValueError(f"{p}, line {k}: not numbers: {line[:60]!r}") from None
                continue  # a header line
        if not rows or any(len(r) != len(rows[0]) for r in rows):
            raise ValueError(f"{p}: need two columns of numbers (wavelength nm, value), one "
                             "row per line")
        a = np.array(rows)
    try:
        a = np.asarray(a, float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{p}: need two columns of numbers (wavelength nm, value)") from None
    if a.ndim == 2 and a.shape[0] == 2 and a.shape[1] != 2:
        a = a.T
    if a.ndim == 2 and a.shape[1] == 2 and a.shape[0] < 2:
        held = "no row" if a.shape[0] == 0 else "one row"
        raise ValueError(f"{p}: {held} of (wavelength nm, value); a spectrum needs at least two "
                         "rows, one per wavelength")
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"{p}: need two columns (wavelength nm, value), got shape {a.shape}")
    order = np.argsort(a[:, 0])
    from ._validation import check_wavelengths_nm

    try:  # a file in micrometres is said so, not left to fail as a spectrum too short
        sp = Spectrum(a[order, 0], a[order, 1], p.name)
        check_wavelengths_nm("its wavelengths", sp.wavelength_nm)
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None
    return sp


def cube_spectrum(cube, y=None, x=None) -> Spectrum:
    """The spectrum of one pixel of a cube (``y``, ``x``), or its mean over all pixels.

    A cube samples the scene at its bands only: between band centres the spectrum is linear,
    so structure narrower than the band spacing is not seen; beyond the first and last band it
    is held at their values (200 nm either side), for the filters' tails.

    Parameters
    ----------
    cube : xarray.DataArray
        Dims ``(y, x, band)`` with a ``wavelength(band)`` coordinate, nm.
    y, x : int, optional
        The pixel (indices); both or neither. Neither: the mean over all pixels (NaN skipped).

    Returns
    -------
    Spectrum
        Bands in increasing wavelength; bands whose value is not finite are left out and
        negative values are clipped to 0.

    Raises
    ------
    ValueError
        No finite value in the spectrum.
    """
    da = cube if y is None else cube.isel(y=y, x=x)
    if y is None:
        da = da.mean(("y", "x"), skipna=True)
    v = np.asarray(da.values, float)
    w = np.asarray(cube["wavelength"].values, float)
    order = np.argsort(w)
    ok = np.isfinite(v[order])
    where = "mean" if y is None else f"pixel ({y}, {x})"
    w, v = w[order][ok], np.clip(v[order][ok], 0.0, None)
    if w.size == 0:
        raise ValueError(f"the cube's {where} spectrum has no finite value")
    w = np.concatenate([[w[0] - 200.0], w, [w[-1] + 200.0]])
    v = np.concatenate([[v[0]], v, [v[-1]]])
    return Spectrum(w, v, f"cube {where}")


def parse_source(text, cube=None) -> Spectrum:
    """``"solar"`` (or ``"solar:astm-g173"``, see :func:`solar`), ``"tungsten:TEMPERATURE_K"``
    (or ``"blackbody:..."``), ``"cube"`` (the mean spectrum of ``cube``), ``"cube:Y,X"`` (one
    of its pixels) or the path of a spectrum file."""
    t = str(text).strip()
    kind, _, arg = t.partition(":")
    if kind == "solar":
        return solar(arg or "kurucz")
    if kind in ("tungsten", "blackbody") and arg:
        try:
            temperature = float(arg)
        except ValueError:
            raise ValueError(f"{kind}: needs a temperature in K, e.g. {kind}:2856, "
                             f"got {arg!r}") from None
        return blackbody(temperature)
    if kind == "cube":
        if cube is None:
            raise ValueError(f"source {t!r} needs a cube")
        if not arg:
            return cube_spectrum(cube)
        try:
            y, x = (int(v) for v in arg.split(","))
        except ValueError:
            raise ValueError(f"cube:Y,X needs two pixel indices, got {arg!r}") from None
        if not (0 <= y < cube.sizes["y"] and 0 <= x < cube.sizes["x"]):
            raise ValueError(f"pixel ({y}, {x}) is outside the {cube.sizes['y']} x "
                             f"{cube.sizes['x']} cube")
        return cube_spectrum(cube, y, x)
    if Path(t).suffix or "/" in t or "\\" in t or os.path.lexists(t):
        return read_spectrum(t)  # a path: what is (or is not) there is said by the reader
    raise ValueError(f"unknown source {t!r}: use solar, solar:astm-g173, "
                     "tungsten:TEMPERATURE_K, cube, cube:Y,X or the path of a two-column "
                     "spectrum file")


def colour_filter(wavelength_nm):
    """A red glass-like long-pass filter with a notch: features that a shift moves.

    The colour filter of the experiment in Goossens et al. 2019 as simulated by
    :mod:`snapcorr.paper_experiment` (a long-pass edge at 640 nm, a notch at 760 nm), and one
    of the targets :data:`snapcorr.calibrate.CANDIDATE_TARGETS` offers for the exit pupil.

    Parameters
    ----------
    wavelength_nm : array_like
        Wavelengths, nm.

    Returns
    -------
    ndarray
        The transmittance (0.04-0.94), of the shape of ``wavelength_nm``.
    """
    lam = np.asarray(wavelength_nm, float)
    edge = 1.0 / (1.0 + np.exp(-(lam - 640.0) / 9.0))
    notch = 1.0 - 0.45 * np.exp(-0.5 * ((lam - 760.0) / 12.0) ** 2)
    return 0.04 + 0.9 * edge * notch


#: The 24 patches of the X-Rite (Macbeth) ColorChecker Classic, in the chart's reading order
#: (:func:`colour_checker`).
COLOUR_CHECKER_PATCHES = (
    "dark skin", "light skin", "blue sky", "foliage", "blue flower", "bluish green", "orange",
    "purplish blue", "moderate red", "purple", "yellow green", "orange yellow", "blue", "green",
    "red", "yellow", "magenta", "cyan", "white 9.5 (.05 D)", "neutral 8 (.23 D)",
    "neutral 6.5 (.44 D)", "neutral 5 (.70 D)", "neutral 3.5 (1.05 D)", "black 2 (1.5 D)")


@functools.cache
def _colour_checker_table():
    from ._bundled import calibration_dir

    path = calibration_dir() / "targets" / "colour_checker_ohta.csv"
    lines = [ln for ln in path.read_text(encoding="utf-8").splitlines()
             if ln.strip() and not ln.startswith("#")]
    names = tuple(lines[0].split(",")[1:])
    if names != COLOUR_CHECKER_PATCHES:
        raise ValueError(f"{path} does not hold the chart's 24 patches in reading order")
    table = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    table.setflags(write=False)
    return table


def colour_checker(patch) -> Spectrum:
    """The published spectral reflectance of one patch of the X-Rite (Macbeth) ColorChecker
    Classic: N. Ohta's measurement [1]_, 380-780 nm at 5 nm (``calibration/targets/``).

    A chart's own patches differ from these by a few per cent, and the published values end at
    780 nm. The exit-pupil fit solves for the target's spectrum and does not need them:
    :func:`snapcorr.calibrate.colour_chart_precision` uses them to predict how well each patch
    can pin ``x`` and ``n_eff`` on a sensor whose bands lie within their range.

    Parameters
    ----------
    patch : str or int
        A name of :data:`COLOUR_CHECKER_PATCHES` (any case), or the patch's number 1-24 in
        reading order (1 dark skin, 15 red, 24 black).

    Returns
    -------
    Spectrum
        Named ``"ColorChecker <patch>"``; asking for it outside 380-780 nm is an error.

    References
    ----------
    .. [1] N. Ohta, "The basis of color reproduction engineering", Corona-sha (1997); the
       values as colour-science 0.4.7 ships them (``SDS_COLOURCHECKERS["ColorChecker N
       Ohta"]``, BSD-3-Clause).

    Examples
    --------
    >>> red = colour_checker("red")
    >>> float(red(700.0)) > 5 * float(red(450.0))
    True
    >>> colour_checker(15).name
    'ColorChecker red'
    """
    if isinstance(patch, (bool, np.bool_)) or not isinstance(patch, (str, int, np.integer)):
        raise ValueError(f"patch must be a patch's name or number 1-24, got {patch!r}")
    if isinstance(patch, str):
        names = [n.lower() for n in COLOUR_CHECKER_PATCHES]
        if patch.strip().lower() not in names:
            raise ValueError(f"no ColorChecker patch named {patch!r}; the patches: "
                             + ", ".join(COLOUR_CHECKER_PATCHES))
        i = names.index(patch.strip().lower())
    else:
        if not 1 <= int(patch) <= len(COLOUR_CHECKER_PATCHES):
            raise ValueError(f"the ColorChecker's patches are numbered 1-24, got {patch!r}")
        i = int(patch) - 1
    table = _colour_checker_table()
    return Spectrum(table[:, 0], table[:, 1 + i], name=f"ColorChecker {COLOUR_CHECKER_PATCHES[i]}")
