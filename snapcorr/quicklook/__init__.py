"""Quick-look figures of a flat-fielded cube and of a wavelength correction, as PNG.

:func:`plot_flatfield` shows a result of :func:`snapcorr.cube.flatfield`: one band, the
masked fraction of every band and a few pixels' spectra. :func:`plot_correction` shows a
result of :func:`snapcorr.correct.correct_cube`: one band of the cube, the chief-ray angle,
the shift of the band that moves most and mean spectra around three pixels at their nominal
and corrected wavelengths (and their virtual bands, when computed). :func:`plot_sensor` shows
a sensor's filters.

Both read only what they draw: images are subsampled with a stride to at most
:data:`MAX_PX` pixels a side and selected before they are loaded, so a dask-backed cube
larger than memory is read piece by piece. Both draw on a :class:`matplotlib.figure.Figure`
without pyplot (no global state) and write the PNG atomically.

One module per picture: :mod:`.flatfield`, :mod:`.correction`, :mod:`.sensor`; the pixels
whose spectra are shown are picked in :mod:`.picking`, and what all draw with is in
:mod:`.drawing`.
"""

from .correction import CORRECTION_WIDTH_IN, SPECTRA_HEIGHT_IN, plot_correction
from .drawing import MARKER_MAX_BANDS, MASKED_COLOUR, MAX_PX
from .flatfield import plot_flatfield
from .picking import CANDIDATES_PX, EDGE_SHARE, ON_AXIS_DEG, SPECTRA_SHOWN, SPECTRUM_WINDOW_PX
from .sensor import RESPONSE_FLOOR, RESPONSE_MARGIN, plot_sensor

__all__ = ["CANDIDATES_PX", "CORRECTION_WIDTH_IN", "EDGE_SHARE", "MARKER_MAX_BANDS",
           "MASKED_COLOUR", "MAX_PX", "ON_AXIS_DEG", "RESPONSE_FLOOR", "RESPONSE_MARGIN",
           "SPECTRA_HEIGHT_IN", "SPECTRA_SHOWN", "SPECTRUM_WINDOW_PX", "plot_correction",
           "plot_flatfield", "plot_sensor"]
