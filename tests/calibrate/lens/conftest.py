"""The paper's lens calibrated from simulated sphere flats, once for every file that judges
it (``test_calibration.py``, ``test_table.py``, ``test_report.py``)."""

import pytest

from calibrate.lens.test_calibration import PAPER, _calibrate, _flats


@pytest.fixture(scope="session")
def paper_sphere():
    return _calibrate(_flats(PAPER), PAPER)
