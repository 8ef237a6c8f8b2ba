"""PNG figures, written atomically and marked as snapcorr's (``Software``)."""

from __future__ import annotations

from .marks import MARK
from .safety import atomic_write

__all__ = ["save_png"]


def save_png(fig, path, *, dpi=120, inputs=()):
    """Write a matplotlib figure as PNG atomically, marked as snapcorr's (``Software``, tied
    to the file's name and image when it is moved in).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or Path
        The PNG to write; one that exists is replaced only if snapcorr wrote it.
    dpi : int
    inputs : iterable of str or Path
        Input paths the PNG must not be, contain or lie inside.

    Returns
    -------
    Path
    """
    from .. import __version__

    return atomic_write(path, lambda tmp: fig.savefig(
        tmp, format="png", dpi=dpi, metadata={"Software": f"{MARK} {__version__}"}),
        inputs=inputs)
