"""The options ``--magnification`` and ``--pupil-magnification``: m and m_P refused outside
physics (:func:`snapcorr.optics.lens.check_magnification`), naming the option, before anything
is read."""

from __future__ import annotations

import argparse

from ._options import _number


def _magnification(value):
    """``--magnification``: m, finite, >= 0 and within the bound a lens profile has
    (:data:`snapcorr.optics.lens.MAX_MAGNIFICATION`), refused before anything is read."""
    from ..optics.lens import check_magnification

    try:
        return check_magnification(_number(value), "m")
    except (TypeError, ValueError) as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _pupil_magnification(value):
    """``--pupil-magnification``: m_P, finite, > 0 and within
    :data:`snapcorr.optics.lens.PUPIL_MAGNIFICATION_BOUNDS`."""
    from ..optics.lens import check_pupil_magnification

    try:
        return check_pupil_magnification(_number(value), "m_P")
    except (TypeError, ValueError) as err:
        raise argparse.ArgumentTypeError(str(err)) from None
