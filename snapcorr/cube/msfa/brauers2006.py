"""Weighted bilinear (WB) interpolation of each band from its own samples.

Brauers & Aach [1]_ interpolate each band of a multispectral filter array by convolving its
sparse samples with the bilinear ("tent") kernel ``H`` of size ``(2n - 1) x (2m - 1)``,
``H[i, j] = (n - |i|)(m - |j|) / (n m)`` for an ``n x m`` tile; on a band's regular sub-grid
that convolution is exactly bilinear interpolation between the four surrounding samples
(Mihoubi et al. 2017 [2]_, Eq. 9-10, call it WB). At the frame's edges, and around missing
samples, the weights of the samples that exist are renormalised.

References
----------
.. [1] J. Brauers, T. Aach, "A color filter array based multispectral camera", 12. Workshop
   Farbbildverarbeitung, Ilmenau (2006).
.. [2] S. Mihoubi, O. Losson, B. Mathon, L. Macaire, "Multispectral demosaicing using
   pseudo-panchromatic image", IEEE Trans. Comput. Imaging 3, 982-995 (2017).
"""

from __future__ import annotations

import numpy as np

from ._grid import interpolate, sub_grids


def weighted_bilinear(frame, y0, x0, n, m, *, fill_missing=False):
    """Every band bilinearly interpolated from its own samples (WB).

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        Float values; NaN where missing.
    y0, x0 : ndarray of int, shape (n_bands,)
        Each band's first sample row and column in the frame.
    n, m : int
        Tile rows and columns.
    fill_missing : bool
        Estimate a missing sample from the band's samples around it (else it stays NaN).

    Returns
    -------
    ndarray, shape (rows, cols, n_bands)
    """
    out = np.empty((*frame.shape, y0.size), frame.dtype)
    return interpolate(sub_grids(frame, y0, x0, n, m), frame, y0, x0, n, m, out,
                       fill=fill_missing)
