"""Names the command line offers as choices, kept here (no imports) so that building the
parser, ``--help`` and usage errors load none of the physics. The library's modules take their
tuples from here; :data:`SHIFT_METHODS` are the keys of :data:`snapcorr.optics.METHODS`."""

#: The correction models, cheapest first (:data:`snapcorr.optics.MODELS`).
CORRECTION_MODELS = ("none", "asymptotic", "ideal", "vignetted", "harmonised")

#: The ways of computing a mean shift (the keys of :data:`snapcorr.optics.METHODS`).
SHIFT_METHODS = ("vignetted", "ideal", "asymptotic", "riemann", "table", "grid", "auto")

#: Estimators of a lens's vignetting circles (:data:`snapcorr.calibrate.METHODS`).
CALIBRATION_METHODS = ("auto", "joint", "onset-ratio", "onset-model")
