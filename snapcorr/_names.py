"""Names the command line offers as choices, kept here (no imports) so that building the
parser, ``--help`` and usage errors load none of the physics. The library's modules take their
tuples from here; :data:`MEAN_SHIFT_METHOD_NAMES` are the keys of
:data:`snapcorr.optics.MEAN_SHIFT_METHODS`."""

#: The correction models, cheapest first (:data:`snapcorr.optics.CORRECTION_MODELS`).
CORRECTION_MODELS = ("none", "asymptotic", "ideal", "vignetted", "harmonised")

#: The ways of computing a mean shift (the keys of :data:`snapcorr.optics.MEAN_SHIFT_METHODS`).
MEAN_SHIFT_METHOD_NAMES = ("vignetted", "ideal", "asymptotic", "riemann", "table", "grid",
                           "auto")
#: The earlier name of :data:`MEAN_SHIFT_METHOD_NAMES`.
SHIFT_METHODS = MEAN_SHIFT_METHOD_NAMES

#: Estimators of a lens's vignetting circles (:data:`snapcorr.calibrate.METHODS`).
CALIBRATION_METHODS = ("auto", "joint", "onset-ratio", "onset-model")
