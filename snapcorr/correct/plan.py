"""What a correction computes before its outputs: the model, every pixel's chief-ray angle and
scales, and (for the harmonising) the width table, built on a second thread meanwhile."""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable
from concurrent import futures

import numpy as np

from .._coords import called_from_outside, warn_x_first_return
from .._threads import OutputPages, in_background, one_blas_thread
from .geometry import cube_cra
from .resample import _output_dtype, resample_cube
from .wavelengths import _scale_function, _scales
from .widths import _kernel_variance, _unlimited_width_table

__all__ = ["CorrectionPlan"]  # plan_correction is correct_cube's step


@dataclasses.dataclass
class CorrectionPlan:
    """What a correction decided and computed before its outputs (:func:`plan_correction`).

    ``model`` is the model used and ``reason`` why; ``n_eff`` the bands' effective indices;
    ``cra_deg`` every pixel's chief-ray angle ``(y, x, 1 or band)``; ``center_rc`` the
    optical centre ``(row, col)`` (``center`` its earlier x-first form, removed in 0.3) and
    ``center_source`` where it came from; ``scale_at(cra, key)`` the corrected / nominal
    wavelength and ``scale_source`` what it is; ``scale`` and ``column`` the compact
    corrected wavelengths; ``resampled`` (or None); ``widths`` the width table (or None),
    ``kernel_var`` each band's kernel variance over its angles (or None); ``buffer`` the
    array the harmonising pass writes into (or None).
    """

    f_number: float
    cra_max_deg: float
    tolerance_nm: float
    model: str
    reason: str
    n_eff: np.ndarray
    cra_deg: np.ndarray | None = None
    center_rc: tuple | None = None
    center_source: str | None = None
    scale_at: Callable | None = None
    scale_source: str | None = None
    scale: np.ndarray | None = None
    column: np.ndarray | None = None
    resampled: object = None
    buffer: np.ndarray | None = None
    widths: object = None
    kernel_var: np.ndarray | None = None


    @property
    def center(self):
        """The optical centre x first, ``(cx, cy)``: the earlier form of ``center_rc``."""
        if called_from_outside(2):
            warn_x_first_return("CorrectionPlan.center", "CorrectionPlan.center_rc",
                                stacklevel=3)
        return None if self.center_rc is None else (self.center_rc[1], self.center_rc[0])


def plan_correction(plan, cube, sensor, lens, center_rc, sensor_origin_px, *, build_widths,
                    resample, harmonising):
    """``plan`` with every pixel's CRA and scales (and ``resampled``), and the width table
    when ``build_widths``.

    Parameters
    ----------
    plan : CorrectionPlan
        The model, f-number, largest CRA and tolerance decided (and a width table if built).
    cube : xarray.DataArray
    sensor : Sensor
    lens : Lens
    center_rc, sensor_origin_px
        As :func:`~snapcorr.correct.geometry.cube_cra` takes them.
    build_widths, resample, harmonising : bool
        Build the width table meanwhile; resample; ready the harmonised output.

    Returns
    -------
    CorrectionPlan

    Notes
    -----
    Harmonising needs the width table before its pass, so it is built on a second
    thread (small arrays, one core; the field's largest CRA is known without the map) while
    this one makes the maps. Then each thread, once done, makes the harmonised output's
    memory ready, a share at a time (:class:`~snapcorr._threads.OutputPages`)."""
    f, cra_max, tolerance_nm, widths = (plan.f_number, plan.cra_max_deg, plan.tolerance_nm,
                                        plan.widths)
    # (only where the pass will run: a table for it, distinct increasing wavelengths)
    buffer = (_output_buffer(cube, sensor.cwl_nm)
              if harmonising and (build_widths or widths is not None) else None)
    pages = OutputPages(buffer) if buffer is not None else None
    with one_blas_thread() if build_widths else contextlib.nullcontext():
        later = (in_background(_harmonising_tables, sensor, lens, f, cra_max, tolerance_nm,
                               plan.n_eff, pages) if build_widths else None)
        try:
            cra, center, center_source = cube_cra(cube, sensor, lens, center_rc=center_rc,
                                                  sensor_origin_px=sensor_origin_px)
            scale_at, how = _scale_function(sensor, f, lens, plan.model, tolerance_nm,
                                            cra_max, widths)
            scale, column = _scales(cra, plan.n_eff, scale_at,
                                    per_band=sensor.responses is not None)
            resampled = (resample_cube(cube, scale, column, np.asarray(sensor.cwl_nm, float))
                         if resample else None)
            if pages is not None:
                pages.touch()
        except BaseException as err:
            if pages is not None:  # the other thread touches no more of it
                pages.cancel()
            if later is not None:  # waited for (no work left running); its error told too
                futures.wait([later])
                if (other := later.exception()) is not None:
                    err.add_note(f"(the width table failed too: {other!r})")
            raise
    widths, kv = later.result() if later is not None else (widths, None)
    return dataclasses.replace(plan, cra_deg=cra, center_rc=center, center_source=center_source,
                               scale_at=scale_at, scale_source=how, scale=scale, column=column,
                               resampled=resampled, buffer=buffer, widths=widths,
                               kernel_var=kv)


def _harmonising_tables(sensor, lens, f, cra_max, tolerance_nm, n_eff, pages=None):
    """The width table, and each band's kernel variance at its angles (nm^2); then a share of
    the output's ``pages``. On a second thread, under the BLAS limit its caller set
    (:func:`~snapcorr._threads.one_blas_thread`)."""
    table = _unlimited_width_table(sensor, lens, f, cra_max, tolerance_nm)
    kv = _kernel_variance(table.cra_deg, n_eff, np.asarray(sensor.cwl_nm, float), f, lens)
    if pages is not None:
        pages.touch()
    return table, kv


def _output_buffer(cube, cwl):
    """For an in-memory cube, the array the harmonising pass writes into (its pages not yet
    touched: :class:`~snapcorr._threads.OutputPages`). None for a dask cube (written block by
    block) and for bands not in increasing wavelength (the pass writes them in order, then
    they are put back)."""
    if cube.chunks is not None or not np.all(np.diff(np.asarray(cwl, float)) > 0):
        return None
    return np.empty(cube.shape, _output_dtype(cube))
