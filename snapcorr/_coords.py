"""Image coordinates: one convention, (row, col), and the deprecation of the x-first centre.

Every pair of pixel coordinates snapcorr takes or gives is ``(row, col)``, the order of the
array's dims ``(y, x)``, as in NumPy and scikit-image: the optical centre (``center_rc``,
``--center ROW,COL``) like the crop's origin (``sensor_origin_px``, ``--sensor-origin-px
ROW,COL``). Rows and columns count from the first pixel's centre, 0.

The optical centre used to be given x first (``center_px=(cx, cy)``, ``--center-px CX,CY``).
Those forms still work and warn (``FutureWarning``); they are never reinterpreted, and giving
both forms is an error. :func:`accepts_center_rc` does it for a public function whose body
takes ``center_rc``, row first, as every body inside snapcorr does (``optics``, ``budget``,
``simulate``, ``correct``, ``pipeline``, the lens calibration in ``calibrate.lens`` and
``calibrate.flats``, the exit-pupil fit in ``calibrate.pupil`` and ``calibrate_with_target``,
and the commands): the old ``center_px`` is turned into it where it comes in. The same
decorator, given the names, does it for a centre argument of another name (the joint fit's
``center`` and ``fix_center``, now ``center_rc`` and ``fix_center_rc``). Renamed arguments
other than the centre go through :func:`snapcorr._validation.renamed_keywords`.
"""

from __future__ import annotations

import functools
import inspect
import warnings

from ._validation import REMOVAL_VERSION, called_from_outside, check_center, check_pair

__all__ = [
    "CENTER_PX_DEPRECATION",
    "accepts_center_rc",
    "called_from_outside",
    "center_from_rc",
    "rc_from_center",
    "warn_x_first_return",
]

#: Said when the old form is used (the tests match on its start).
CENTER_PX_DEPRECATION = ("center_px is the old x-first form (cx, cy) of the optical centre and "
                         "will be removed; give center_rc=(row, col) instead "
                         "(here center_rc=({row:g}, {col:g}))")


def warn_x_first_return(old, new, *, stacklevel=4):
    """Warn (``FutureWarning``) that ``old`` gives the optical centre x first, ``(cx, cy)``, and
    goes in :data:`~snapcorr._validation.REMOVAL_VERSION`; ``new`` gives it row first.

    Called from the body of ``old`` when :func:`called_from_outside` says so.

    Parameters
    ----------
    old, new : str
        The name giving the centre x first and the one giving it row first, as the message
        shows them (``"cube_cra_deg"``, ``"CorrectionPlan.center_rc"``).
    stacklevel : int
        As for :func:`warnings.warn`, counted from here: the default 4 points past ``old``
        and its :func:`accepts_center_rc` wrapper at the code that called it.
    """
    warnings.warn(f"{old} gives the optical centre x first, (cx, cy), and will be removed in "
                  f"snapcorr {REMOVAL_VERSION}; use {new}, which gives it row first, "
                  "(row, col)", FutureWarning, stacklevel=stacklevel)


def center_from_rc(center_rc, name="center_rc"):
    """``(cx, cy)``, the x-first form of 0.1, from ``(row, col)``, checked."""
    row, col = check_pair(name, center_rc, "two numbers (row, col) in pixels")
    return (col, row)


def rc_from_center(center_px):
    """``[row, col]`` from the x-first ``(cx, cy)`` of 0.1."""
    return [float(center_px[1]), float(center_px[0])]


def accepts_center_rc(func=None, *, old="center_px", new="center_rc", many=False):
    """Let ``func``, whose body takes the optical centre row first, ``center_rc=(row, col)``,
    take it also in its deprecated x-first form ``center_px=(cx, cy)``, swapped into
    ``center_rc``, warning when a caller outside snapcorr gives it and refusing both at once.

    ``func`` declares ``center_rc``, and ``center_px`` too: in its old place, for the callers
    that give it by position, or keyword-only. A ``center_rc`` given is checked here, by name;
    an old ``center_px`` is checked, swapped into ``center_rc`` and passed on as None.

    Used as ``@accepts_center_rc(old="center", new="center_rc")``, the same for a centre
    argument of another name (``fix_center`` and ``fix_center_rc``...); where ``func`` does not
    declare ``old``, it is added to the signature, keyword-only. With ``many``, the argument is
    a sequence of centres, each swapped.

    Parameters
    ----------
    func : callable, optional
        The function; left out, a decorator with these names is returned.
    old, new : str
        The x-first argument's name and the row-first one's (default ``center_px`` and
        ``center_rc``); ``func`` must declare ``new``.
    many : bool
        The argument is a sequence of centres (``centers``), each swapped.
    """
    if func is None:
        return functools.partial(accepts_center_rc, old=old, new=new, many=many)
    sig = inspect.signature(func)
    if new not in sig.parameters:
        raise TypeError(f"{func.__name__} takes no {new}")
    declared = old in sig.parameters
    if not declared and old == "center_px" and new == "center_rc":
        raise TypeError(f"{func.__name__} takes center_rc but not its earlier form center_px")
    signature = sig
    if not declared:  # the old keyword, keyword-only, beside the new one
        params = list(sig.parameters.values())
        extra = inspect.Parameter(old, inspect.Parameter.KEYWORD_ONLY, default=None)
        at = len([p for p in params if p.kind != inspect.Parameter.VAR_KEYWORD])
        signature = sig.replace(parameters=[*params[:at], extra, *params[at:]])

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        given = kwargs.pop(old, None) if not declared else None
        bound = sig.bind_partial(*args, **kwargs)
        if declared:
            given = bound.arguments.get(old)
        if given is not None:
            if bound.arguments.get(new) is not None:
                raise TypeError(f"{func.__name__}: give the optical centre once, as "
                                f"{new}=(row, col); {old} is its old x-first form")
            outside = called_from_outside(2)
            swapped = [_swapped(c, old, outside) for c in given] if many else \
                _swapped(given, old, outside)
            if outside:
                row, col = swapped[0] if many else swapped
                warnings.warn(_deprecation(old, new).format(row=row, col=col), FutureWarning,
                              stacklevel=2)
            if declared:
                bound.arguments[old] = None
            bound.arguments[new] = swapped
        elif bound.arguments.get(new) is not None:  # given row first: checked here, by name
            for c in (bound.arguments[new] if many else [bound.arguments[new]]):
                check_pair(new, c, "two numbers (row, col) in pixels")
        return func(*bound.args, **bound.kwargs)

    if not declared:
        wrapper.__signature__ = signature
    return wrapper


def _swapped(center_px, name, outside):
    """``(row, col)`` from an x-first ``(cx, cy)``, checked."""
    if outside:
        cx, cy = check_pair(name, center_px, "two numbers (cx, cy) in pixels")
    else:
        cx, cy = check_center(center_px, name)
    return (cy, cx)


def _deprecation(old, new):
    """The message for the old x-first ``old`` given instead of ``new``."""
    if (old, new) == ("center_px", "center_rc"):
        return CENTER_PX_DEPRECATION
    return (f"{old} is the old x-first form (cx, cy) of the optical centre and will be removed "
            f"in snapcorr {REMOVAL_VERSION}; give {new}=(row, col) instead (here "
            f"{new}=({{row:g}}, {{col:g}}))")
