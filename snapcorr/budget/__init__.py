"""Radiometric error budget: how much a filter's shift changes the signal of a scene.

A wavelength shift matters only as much as the scene's spectrum changes within the filter's
band. Flittner & Slater (1991) define the signal change of a band whose passband moves from
``lambda`` to ``lambda + dlambda`` as

    ERROR(lambda, dlambda) = (P(lambda + dlambda) - P(lambda)) / P(lambda),

where ``P`` integrates the filter profile times the source spectrum. Behind a lens a pixel's
filter is not only moved but also smeared by the angular kernel (Goossens et al. 2019,
Eq. 13 and Sec. 3.4): the pixel measures ``sum_k w_k P(cwl + mu_k)`` over the kernel's bins
(:func:`~snapcorr.optics.response.kernel_bins`). A correction model places the filter at
``cwl + mean_shift``; what it leaves is the *residual*

    residual = P_pixel / P(cwl + mean_shift_model) - 1,

which for ``"none"`` is the error of not correcting at all, and which even the exact mean
(``"vignetted"``) leaves where the scene's spectrum is curved within the band (the kernel
changes the filter's shape). :func:`scene_budget` tabulates it over band and chief-ray angle;
:meth:`Budget.recommend` picks the cheapest model whose residual is below a radiometric
tolerance, :meth:`Budget.radius_mm` gives Mishev & Bakalova's radius of the field inside which
the effect stays below a tolerance, and :func:`tolerance_ranges` is Flittner & Slater's
Table 1 analysis. :func:`recommend_model` gives :func:`~snapcorr.correct.correct_cube` the
model a scene needs. The scene's spectra come from :mod:`snapcorr.spectra`.

Modules: :mod:`.signal` (the signal of a shifted band), :mod:`.scene` (the budget over band
and CRA), :mod:`.report` (:class:`Budget`: choice, radius, table, plot) and
:mod:`.flittner_slater` (Table 1).

References
----------
.. [1] D. E. Flittner, P. N. Slater, "Stability of narrow-band filter radiometers in the
   solar-reflective range", Photogramm. Eng. Remote Sens. 57, 165 (1991).
.. [2] D. N. Mishev, K. P. Bakalova, "Multispectral imagery and interference filter effects".
.. [3] T. Goossens et al., "Vignetted-aperture correction for spectral cameras with integrated
   thin-film Fabry-Perot filters", Appl. Opt. 58, 1789 (2019).
"""

from ..optics import CORRECTION_MODELS, MODELS
from .flittner_slater import tolerance_ranges
from .report import Budget
from .scene import recommend_model, scene_budget
from .signal import PROFILES, SIGNAL_PROFILES, band_signal, relative_signal, shift_error

__all__ = [
    "CORRECTION_MODELS",
    "MODELS",
    "PROFILES",
    "SIGNAL_PROFILES",
    "Budget",
    "band_signal",
    "recommend_model",
    "relative_signal",
    "scene_budget",
    "shift_error",
    "tolerance_ranges",
]
