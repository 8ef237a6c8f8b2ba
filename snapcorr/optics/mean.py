"""``mean_shift``: the kernel-mean shift of every filter, by a named method or by ``"auto"``.

References
----------
.. [1] T. Goossens et al., Appl. Opt. 58, 1789 (2019), Eq. (6), (22)-(23), (46), App. B.
"""

from __future__ import annotations

import functools

import numpy as np

from .._names import CORRECTION_MODELS
from .._validation import check_f_number, check_positive, check_positive_array, validate_method
from . import goossens2019 as g19
from .lens import Lens
from .table import ShiftGrid, ShiftTable

__all__ = [
    "AUTO_GRID_MIN_SIZE",
    "AUTO_TABLE_MIN_SIZE",
    "CORRECTION_MODELS",
    "MEAN_SHIFT_METHODS",
    "METHODS",
    "MODELS",
    "cached_grid",
    "choose_model",
    "mean_shift",
    "select_method",
]

#: Safety factor on the fourth-order error estimate of Eq. (6) used by ``"auto"``.
ASYMPTOTIC_SAFETY = 4.0
#: ``"auto"`` builds a lookup table over CRA for an (f-number, n_eff) group with at least this
#: many elements: a table costs a few hundred exact evaluations, then ~0.1 us per element.
AUTO_TABLE_MIN_SIZE = 20_000
#: ``"auto"`` interpolates in a (f-number, CRA) grid (:class:`ShiftGrid`) when at least this many
#: elements with scattered f-numbers remain: a grid costs ~0.15 s to build (about 60 000 exact
#: evaluations), then ~0.3 us per element; built grids are cached. With several vignetting
#: circles a grid costs 2-20 s, and the threshold is 20 times higher.
AUTO_GRID_MIN_SIZE = 100_000


@functools.lru_cache(maxsize=16)
def _grid(lens, n_eff, f_lo, f_hi, cra_max, tolerance_nm, cwl_max):
    return ShiftGrid.build(n_eff, lens, f_range=(f_lo, f_hi), cra_max_deg=cra_max,
                           tolerance_nm=tolerance_nm, cwl_max_nm=cwl_max)


def cached_grid(n_eff, f_number, cra_deg, lens, *, tolerance_nm=0.001, cwl_max_nm=1000.0):
    """A :class:`ShiftGrid` covering these f-numbers and CRAs, from a small cache.

    The range is rounded outwards (f-numbers to half stops, CRA to 5 deg, wavelengths to
    100 nm) so that similar calls share a grid.

    Parameters
    ----------
    n_eff : float
        Effective refractive index (> 1).
    f_number : array_like
        The nominal f-numbers to cover (> 0).
    cra_deg : array_like
        The chief-ray angles to cover, degrees (only the largest |CRA| counts; at most 89).
    lens : Lens
        Must be hashable (the cache's key).
    tolerance_nm : float
        Largest interpolation error, nm.
    cwl_max_nm : float
        Longest central wavelength the tolerance holds for, nm.

    Returns
    -------
    ShiftGrid
    """
    f = np.asarray(f_number, float)
    f_lo = 2.0 ** (np.floor(2 * np.log2(f.min())) / 2)
    f_hi = max(2.0 ** (np.ceil(2 * np.log2(f.max())) / 2), f_lo * 2.0**0.5)
    cra_max = min(89.0, 5.0 * np.ceil(max(np.abs(np.asarray(cra_deg)).max(), 1e-9) / 5.0))
    cwl_max = 100.0 * np.ceil(cwl_max_nm / 100.0)
    return _grid(lens, float(n_eff), float(f_lo), float(f_hi), float(cra_max),
                 float(tolerance_nm), float(cwl_max))


def _geometry(f_number, cra_deg, lens):
    if not isinstance(lens, Lens):
        raise TypeError(f"lens must be a snapcorr.Lens, got {type(lens).__name__}")
    cra = np.asarray(cra_deg, dtype=float)
    if not np.all(np.isfinite(cra)) or np.any(np.abs(cra) >= 90):
        raise ValueError("cra_deg must be finite and between -90 and 90 degrees")
    x = lens.exit_pupil_mm
    R = lens.exit_pupil_radius_mm(f_number)
    tan_cra = np.tan(np.deg2rad(np.abs(cra)))
    return (x, R, x * tan_cra, *lens.vignetting_args(tan_cra))


def _vignetted(cwl_nm, n_eff, f_number, cra_deg, lens):
    x, R, d, P, dv = _geometry(f_number, cra_deg, lens)
    g19._check_validity(x, R, d, P, dv)
    return g19.mean_shift_contour(cwl_nm, n_eff, x, R, d, P, dv, pupil=lens.pupil_radiance)


def _ideal(cwl_nm, n_eff, f_number, cra_deg, lens):
    x, R, d, _, _ = _geometry(f_number, cra_deg, lens)
    g19._check_validity(x, R, d)
    return g19.mean_shift_contour(cwl_nm, n_eff, x, R, d, pupil=lens.pupil_radiance)


def _paper_pupil_only(lens, what):
    """Refuse a formula derived for the paper's pupil for another one."""
    if lens.pupil_radiance != "paper":
        raise ValueError(f"{what} is derived for the paper's pupil (Eq. 28, uniform per area), "
                         f"not the {lens.pupil_radiance} one: use method 'vignetted', 'ideal' "
                         "or 'auto'")


def _riemann(cwl_nm, n_eff, f_number, cra_deg, lens, step_nm=g19.RIEMANN_STEP_NM):
    _paper_pupil_only(lens, "the paper's Riemann sum of its kernel (Eq. 37)")
    x, R, d, P, dv = _geometry(f_number, cra_deg, lens)
    g19._check_validity(x, R, d, P, dv)
    return g19.mean_shift_riemann(cwl_nm, n_eff, x, R, d, P, dv, step_nm=step_nm)


def _asymptotic(cwl_nm, n_eff, f_number, cra_deg, lens):
    _paper_pupil_only(lens, "Eq. (6)")
    _geometry(f_number, cra_deg, lens)
    cone = np.deg2rad(lens.cone_angle_deg(f_number))
    return g19.mean_shift_asymptotic(cwl_nm, n_eff, cone, np.deg2rad(np.abs(cra_deg)))


def _groups(n, f, min_count=1):
    """Indices of the elements sharing each (n_eff, f-number) pair, for the pairs with at
    least ``min_count`` elements (1-D keys sort fast)."""
    same_n = np.all(n == n.flat[0])
    if same_n and np.all(f == f.flat[0]):  # the usual cube: skip the sort
        return [np.arange(f.size)] if f.size >= min_count else []
    key = f if same_n else f + 1j * n
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    big = np.flatnonzero(counts >= min_count)
    if big.size > 64:  # many groups: one sort beats a mask per group
        order = np.argsort(inverse, kind="stable")
        parts = np.split(order, np.cumsum(counts)[:-1])
        return [parts[i] for i in big]
    return [np.flatnonzero(inverse == i) for i in big]


def _table(cwl_nm, n_eff, f_number, cra_deg, lens, tolerance_nm=0.001):
    cwl, n, f, cra = (a.ravel() for a in np.broadcast_arrays(
        *(np.asarray(a, float) for a in (cwl_nm, n_eff, f_number, cra_deg))))
    out = np.empty(cwl.shape)  # inputs were checked by mean_shift
    for sel in _groups(n, f):
        c = np.abs(cra[sel])
        table = ShiftTable.build(
            n[sel[0]], f[sel[0]], lens, cra_max_deg=float(c.max()),
            tolerance_nm=tolerance_nm, cwl_max_nm=float(np.abs(cwl[sel]).max()),
        )
        out[sel] = table(cwl[sel], c)
    return out.reshape(np.broadcast_shapes(*(np.shape(a) for a in
                                             (cwl_nm, n_eff, f_number, cra_deg))))


def _grid_method(cwl_nm, n_eff, f_number, cra_deg, lens, tolerance_nm=0.001):
    cwl, n, f, cra = np.broadcast_arrays(*(np.asarray(a, float) for a in
                                           (cwl_nm, n_eff, f_number, cra_deg)))
    out = np.empty(cwl.shape)  # inputs were checked by mean_shift
    flat_n, flat_out = n.ravel(), out.reshape(-1)
    for n_i in np.unique(flat_n):
        sel = flat_n == n_i
        grid = cached_grid(n_i, f.ravel()[sel], cra.ravel()[sel], lens,
                           tolerance_nm=tolerance_nm,
                           cwl_max_nm=float(np.abs(cwl.ravel()[sel]).max()))
        flat_out[sel] = grid(cwl.ravel()[sel], f.ravel()[sel], cra.ravel()[sel])
    return out


#: Named methods of :func:`mean_shift`, name -> function (``"auto"``: None, the dispatcher
#: :func:`select_method` picks). Each takes ``(cwl_nm, n_eff, f_number, cra_deg, lens)``.
MEAN_SHIFT_METHODS = {
    "vignetted": _vignetted,
    "ideal": _ideal,
    "asymptotic": _asymptotic,
    "riemann": _riemann,
    "table": _table,
    "grid": _grid_method,
    "auto": None,
}
#: The earlier name of :data:`MEAN_SHIFT_METHODS`.
METHODS = MEAN_SHIFT_METHODS


def select_method(n_eff, f_number, cra_deg, lens, *, cwl_nm=1000.0, tolerance_nm=0.001):
    """The method ``"auto"`` uses for each element, as an array of names.

    The rule, cheapest first (the exact rungs of :data:`CORRECTION_MODELS`):

    1. ``"asymptotic"`` (Eq. 6) where the pixel is not vignetted (below the onset of Eq. 46,
       or a lens without vignetting circles) and ``ASYMPTOTIC_SAFETY`` times the fourth-order
       error estimate (:func:`~snapcorr.optics.goossens2019.asymptotic_error_estimate_nm`) is
       below the tolerance (the paper's pupil only: Eq. 6 is derived for it);
    2. ``"ideal"`` (exact, one full circle) where the pixel is not vignetted;
    3. ``"vignetted"`` (exact, the chain of arcs bounding the vignetted pupil) elsewhere.

    Before the onset the vignetted and the ideal kernels are identical, so step 2 loses nothing.

    Parameters
    ----------
    n_eff : array_like
        Effective refractive index of each filter.
    f_number : array_like
        Nominal f-number.
    cra_deg : array_like
        Chief-ray angle, degrees.
    lens : Lens
    cwl_nm : array_like
        Central wavelength, nm (the error of Eq. 6 scales with it).
    tolerance_nm : float
        Largest error allowed, nm.

    Returns
    -------
    ndarray of str
        ``"asymptotic"``, ``"ideal"`` or ``"vignetted"`` for each element (the arguments
        broadcast).
    """
    cra = np.abs(np.asarray(cra_deg, float))
    not_vign = ~lens.is_vignetted(f_number, cra)
    tan_cone = 1.0 / (2.0 * lens.working_f_number(f_number))
    err = g19.asymptotic_error_estimate_nm(cwl_nm, n_eff, tan_cone, np.tan(np.deg2rad(cra)))
    paper = lens.pupil_radiance == "paper"
    asym = not_vign & (ASYMPTOTIC_SAFETY * np.abs(err) <= tolerance_nm) & paper
    return np.where(asym, "asymptotic", np.where(not_vign, "ideal", "vignetted"))


#: The correction models, cheapest first: the ladder :func:`choose_model` and the scene budget
#: (:func:`snapcorr.budget.scene_budget`) climb, and the ``method`` of
#: :func:`snapcorr.correct.correct_cube`. ``"none"`` keeps the nominal wavelengths;
#: ``"asymptotic"`` is Eq. (6); ``"ideal"`` the exact kernel mean of the full pupil;
#: ``"vignetted"`` the exact mean of the vignetted pupil (Eq. 22); ``"harmonised"`` that mean
#: and one common response per band (:mod:`snapcorr.correct.harmonise`), for scenes where the
#: widening of the response matters too. The tuple lives in :mod:`snapcorr._names` (the
#: command line offers it without loading the physics); ``MODELS`` is its earlier name here.
MODELS = CORRECTION_MODELS


def choose_model(cwl_nm, n_eff, f_number, cra_max_deg, lens, *, tolerance_nm):
    """The cheapest model whose wavelength error is below ``tolerance_nm`` on a whole field.

    ``"none"`` when no band moves by more than the tolerance at any CRA up to
    ``cra_max_deg``; otherwise the dearest of the models :func:`select_method` picks for the
    bands at the field's edge (the errors grow with the CRA). ``"harmonised"`` is never
    chosen here: a wavelength tolerance cannot ask for it; the scene budget can
    (:meth:`snapcorr.budget.Budget.recommend`).

    Parameters
    ----------
    cwl_nm, n_eff : array_like
        Every band's central wavelength (nm) and effective index.
    f_number : float
        Nominal f-number.
    cra_max_deg : float
        The field's largest chief-ray angle, degrees.
    lens : Lens
    tolerance_nm : float
        Largest wavelength error allowed, nm.

    Returns
    -------
    model, reason : str
        One of :data:`CORRECTION_MODELS`, and a sentence saying why.

    Examples
    --------
    >>> from snapcorr import Lens
    >>> lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3)
    >>> choose_model([500.0, 900.0], 1.7, 1.4, 20.0, lens, tolerance_nm=0.01)[0]
    'vignetted'
    >>> choose_model([500.0, 900.0], 1.7, 16.0, 1.0, lens, tolerance_nm=0.5)[0]
    'none'
    """
    cwl = np.asarray(cwl_nm, float)
    n = np.asarray(n_eff, float)
    f = check_f_number("f_number", f_number)
    tol = check_positive("tolerance_nm", tolerance_nm)
    cra_max = float(cra_max_deg)
    if not 0 <= cra_max < 90:
        raise ValueError(f"cra_max_deg must lie in [0, 90), got {cra_max_deg!r}")
    picks = np.atleast_1d(select_method(n, f, cra_max, lens, cwl_nm=cwl, tolerance_nm=tol))
    model = max((str(m) for m in picks), key=CORRECTION_MODELS.index)
    # the largest shift over the field: the kernel mean is monotonic in neither the CRA nor
    # the band alone near the onset, so both ends of the field and every band
    exact = "vignetted" if model == "vignetted" else "ideal"
    worst = max(float(np.max(np.abs(mean_shift(cwl, n, f, c, lens, method=exact))))
                for c in (0.0, cra_max))
    if worst <= tol:
        return "none", (f"no band moves by more than {worst:.3g} nm <= tolerance {tol:g} nm "
                        f"at f/{f:g} up to CRA {cra_max:.2f} deg")
    onset = float(np.min(lens.onset_cra_deg(f)))
    if model == "vignetted":
        return model, (f"CRAs up to {cra_max:.2f} deg pass the onset of optical vignetting "
                       f"at f/{f:g} ({onset:.2f} deg)")
    where = ("no vignetting circle" if not lens.has_vignetting else
             f"every CRA (<= {cra_max:.2f} deg) is below the onset ({onset:.2f} deg)")
    if lens.pupil_radiance != "paper":
        return model, (f"{where}; Eq. 6 holds for the paper's pupil, not this "
                       f"{lens.pupil_radiance} one")
    tan_cone = 1.0 / (2.0 * float(lens.working_f_number(f)))
    err = g19.asymptotic_error_estimate_nm(cwl, n, tan_cone, np.tan(np.deg2rad(cra_max)))
    err = float(np.max(np.abs(err))) * ASYMPTOTIC_SAFETY
    if model == "asymptotic":
        return model, f"{where}, and Eq. 6 is within {err:.2g} nm <= {tol:g} nm"
    return model, f"{where}; Eq. 6 would be off by up to {err:.2g} nm"


def mean_shift(cwl_nm, n_eff, f_number, cra_deg, lens, *, method="auto", tolerance_nm=0.001):
    """Mean shift of each filter's central wavelength behind ``lens`` (Goossens 2019 Eq. 22).

    The corrected central wavelength is ``cwl_nm + mean_shift(...)`` (Eq. 23).

    Parameters
    ----------
    cwl_nm : array_like
        Central wavelength at normal, collimated incidence, nm.
    n_eff : array_like
        Effective refractive index (> 1).
    f_number : array_like
        Nominal f-number; the working f-number (Eq. 27) sets the exit-pupil radius (Eq. 28).
    cra_deg : array_like
        Chief-ray angle, degrees.
    lens : Lens
        Exit pupil and vignetting circles.
    method : {"auto", "vignetted", "ideal", "asymptotic", "riemann", "table", "grid"}
        ``"vignetted"``: exact for the vignetted aperture (contour quadrature,
        :func:`~snapcorr.optics.goossens2019.mean_shift_contour`). ``"ideal"``: exact, ignoring
        the vignetting circles. ``"asymptotic"``: Eq. (6). ``"riemann"``: the paper's left
        Riemann sum with a 0.01 nm step (slow; the baseline). ``"table"``: interpolation in
        lookup tables over CRA built per (f-number, n_eff) to ``tolerance_nm``. ``"grid"``:
        interpolation in a cached (f-number, CRA) grid per n_eff (:class:`ShiftGrid`), for many
        scattered f-numbers. ``"auto"``: the cheapest method meeting ``tolerance_nm`` for each
        element (see :func:`select_method`), with tables for large groups sharing an f-number
        and n_eff and a grid for large remainders.
    tolerance_nm : float
        Accuracy asked of ``"auto"`` and ``"table"``, nm.

    Returns
    -------
    shift : ndarray
        Shift in nm, negative towards the blue; the arguments broadcast. float32 if any
        argument is float16/float32 (computed in float64), float64 otherwise.

    Raises
    ------
    ValueError
        Bad arguments (``n_eff <= 1``, f-number <= 0, non-finite values, CRA >= 90 deg), an
        unknown method, or a pupil fully cut off by vignetting (``PupilCutOffError``).

    Warns
    -----
    EffectiveIndexWarning
        Where rays beyond 40 deg reach the filter.

    Examples
    --------
    >>> from snapcorr import Lens, mean_shift
    >>> lens = Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm")
    >>> mean_shift(700.0, 1.7, 1.4, [0.0, 20.0], lens).round(3)
    array([-6.593, -8.954])
    """
    validate_method(method, MEAN_SHIFT_METHODS)
    check_positive("tolerance_nm", tolerance_nm)
    args = (cwl_nm, n_eff, f_number, cra_deg)
    # Every method checks the same things first, so none can fail later in its own way.
    check_positive_array("cwl_nm", cwl_nm, "nm")
    g19.check_n_eff(n_eff)
    _geometry(f_number, cra_deg, lens)
    # Float policy: float16/32 in -> float32 out; everything else float64.
    low = any(np.asarray(a).dtype in (np.float16, np.float32) for a in args)
    shape = np.broadcast_shapes(*(np.shape(a) for a in args))
    if 0 in shape:
        if not isinstance(lens, Lens):
            raise TypeError(f"lens must be a snapcorr.Lens, got {type(lens).__name__}")
        return np.zeros(shape, np.float32 if low else float)
    if method in ("table", "grid"):
        out = MEAN_SHIFT_METHODS[method](*args, lens, tolerance_nm)
    elif method != "auto":
        out = MEAN_SHIFT_METHODS[method](*args, lens)
    else:
        out = _auto(*args, lens, tolerance_nm)
    return np.asarray(out, dtype=np.float32) if low else out


def _auto(cwl_nm, n_eff, f_number, cra_deg, lens, tolerance_nm):
    arrays = np.broadcast_arrays(
        *(np.asarray(a, float) for a in (cwl_nm, n_eff, f_number, cra_deg))
    )
    shape = arrays[0].shape
    cwl, n, f, cra = (a.ravel() for a in arrays)  # checked by mean_shift
    out = np.empty(cwl.shape)
    todo = np.ones(cwl.shape, bool)
    # Large groups sharing (n_eff, f-number): a table over CRA is cheapest.
    if cwl.size >= AUTO_TABLE_MIN_SIZE:
        groups = _groups(n, f, AUTO_TABLE_MIN_SIZE)
        if len(groups) == 1 and groups[0].size == cwl.size:  # one f-number and n_eff
            return _table(cwl, n, f, cra, lens, tolerance_nm).reshape(shape)
        for sel in groups:
            out[sel] = _table(cwl[sel], n[sel], f[sel], cra[sel], lens, tolerance_nm)
            todo[sel] = False
    # With several circles a grid takes seconds to build (the boundary's arcs change at more
    # places than its frame pins), so it pays only for far more elements.
    grid_min = AUTO_GRID_MIN_SIZE * (1 if len(lens.vignetting) <= 1 else 20)
    if np.count_nonzero(todo) >= grid_min and lens.pupil_radiance == "paper":  # ShiftGrid's pupil
        idx = np.flatnonzero(todo)
        out[idx] = _grid_method(cwl[idx], n[idx], f[idx], cra[idx], lens, tolerance_nm)
        todo[idx] = False
    if np.any(todo):
        idx = np.flatnonzero(todo)
        choice = select_method(
            n[idx], f[idx], cra[idx], lens, cwl_nm=np.abs(cwl[idx]), tolerance_nm=tolerance_nm
        )
        for name in ("asymptotic", "ideal", "vignetted"):
            sub = idx[choice == name]
            if sub.size:
                out[sub] = MEAN_SHIFT_METHODS[name](cwl[sub], n[sub], f[sub], cra[sub], lens)
    return out.reshape(shape)
