from pathlib import Path

import numpy as np
import pytest

from snapcorr import Lens

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "reference"
DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="session")
def edmund():
    """The paper's Edmund Optics 16 mm lens (Goossens 2019, Sec. 3.2, Eq. 31)."""
    return Lens(21.0, [(7.4236, 16.991)], 0.06, 1.3, name="Edmund Optics 16 mm C Series")


def brute_force_mean(cwl, n_eff, x, R, d, P=None, dv=None, N=1500):
    """Average Eq. (3) over the pupil plane by brute force (no eta/nu/gamma, no kernel).

    Midpoint grid over the exit pupil's bounding square (mm); a point counts if it lies in the
    pupil and, if given, in the vignetting circle centred at ``dv`` on the same axis as the
    pixel's foot ``d``. Its ray to the pixel has ``tan(phi) = |p - F| / x``.
    """
    h = 2 * R / N
    c = (np.arange(N) + 0.5) * h - R
    X, Y = np.meshgrid(c, c, indexing="ij")
    inside = X**2 + Y**2 <= R * R
    if P is not None:
        inside &= (X - dv) ** 2 + Y**2 <= P * P
    r2 = (X[inside] - d) ** 2 + Y[inside] ** 2
    sin2 = r2 / (r2 + x * x)
    return float(np.mean(-cwl * (1 - np.sqrt(1 - sin2 / n_eff**2)))), int(inside.sum())


def load_reference_csv():
    path = SHARED / "mean_shift_edmund16mm.csv"
    if not path.exists():
        path = DATA / "mean_shift_edmund16mm.csv"
    rows = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    assert rows[0].startswith("f_number")
    return np.array([[float(v) for v in ln.split(",")] for ln in rows[1:]])
