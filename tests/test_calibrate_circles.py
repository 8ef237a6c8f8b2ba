"""The judge of the lens calibration's circles, under the name the Cramer-Rao oracle's tests
and ``benchmarks/calibration_circles.py`` import it by; its home and its tests are
``tests/calibrate/lens/test_calibration_circles.py``. No tests here."""

from calibrate.lens.test_calibration_circles import (  # noqa: F401
    F_NUMBERS,
    FULL,
    HALF,
    TRUTHS,
    calibrate,
    cramer_rao,
    field_cra_deg,
    shift_errors_by_f,
)
