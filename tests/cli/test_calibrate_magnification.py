"""`snapcorr calibrate` without magnifications: said, recorded, and in the errors.

Flats from the independent simulator (tests/oracles/flatsim.py) of the paper's lens at
m = 0.06, m_P = 1.3 (Goossens 2019, Sec. 5).
"""

import numpy as np
import pytest
from conftest import PAPER_TRUTH
from flatsim import make_flats

from snapcorr import Lens

F_NUMBERS = (1.4, 2.8, 11.0)
SCENE = dict(shape=(128, 160), pitch_um=56.8, center_px=(87.4, 59.9))
RUN = ["--exit-pupil-mm", "21", "--pixel-pitch-um", str(SCENE["pitch_um"]), "--method", "joint",
       "--max-circles", "1"]


@pytest.fixture(scope="module")
def flats(tmp_path_factory):
    d = tmp_path_factory.mktemp("flats")
    for f, img in make_flats(PAPER_TRUTH, F_NUMBERS, noise=0.005, seed=5, **SCENE).items():
        np.save(d / f"f{f:g}.npy", img)
    return d


FLATS = [a for f in F_NUMBERS for a in ("--flat", f"{f:g}=f{f:g}.npy")]


def test_magnifications_left_out_are_said_recorded_and_in_the_errors(flats, cli):
    res = cli("calibrate", *FLATS, *RUN, "--out", "assumed.toml", cwd=flats)
    assert res.returncode == 0, res.stderr
    assert "note: no magnifications given: m = 0 (focused at infinity)" in res.stdout
    assert "--magnification, --pupil-magnification" in res.stdout
    assert "magnifications assumed" in res.stdout
    assert "no magnifications given" in res.stderr  # the warning, one line
    cal = Lens.load(flats / "assumed.toml").calibration
    rec = cal["magnification"]
    assert rec["assumed"] is True and rec["m_over_m_P_range"] == [0.0, 0.1]
    P = Lens.load(flats / "assumed.toml").vignetting[0][0]
    # P is 4.6 % high (the flats fix P (1 + m / m_P)); its error says as much
    assert P / PAPER_TRUTH.circles[0][0] - 1 > 0.04
    assert 0.5 < (P - PAPER_TRUTH.circles[0][0]) / rec["P_stderr_mm"][0] < 2
    assert cal["shift_stderr_nm"][0] > 0.3  # f/1.4: the truth is ~1 nm away


def test_magnifications_given_are_taken_as_exact(flats, cli):
    given = cli("calibrate", *FLATS, *RUN, "--magnification", "0.06", "--pupil-magnification",
                "1.3", "--out", "given.toml", cwd=flats)
    assert given.returncode == 0, given.stderr
    assert "magnification" not in given.stdout.replace("--magnification", "")
    cal = Lens.load(flats / "given.toml").calibration
    assert "magnification" not in cal and cal["shift_stderr_nm"][0] < 0.05


def test_focused_at_infinity_needs_no_pupil_magnification(flats, cli):
    res = cli("calibrate", *FLATS, *RUN, "--magnification", "0", "--out", "inf.toml", cwd=flats)
    assert res.returncode == 0, res.stderr
    assert "assumed" not in res.stdout and "magnification" not in res.stderr
    assert "magnification" not in Lens.load(flats / "inf.toml").calibration


def test_a_lens_profile_that_states_no_magnifications_does_not_give_them(flats, cli):
    """--lens with a profile whose [lens] table leaves out m and m_P: assumed, so widened and
    said, as without --lens; the same profile stating them: exact."""
    for name, stated in (("none.toml", ""), ("both.toml", "magnification = 0.06\n"
                                                         "pupil_magnification = 1.3\n")):
        (flats / name).write_text(f"[lens]\nname = 'x known'\nexit_pupil_mm = 21.0\n{stated}")
    run = [a for a in RUN if a not in ("--exit-pupil-mm", "21")]
    res = cli("calibrate", *FLATS, *run, "--lens", "none.toml", "--out", "from_none.toml",
              cwd=flats)
    assert res.returncode == 0, res.stderr
    assert "no magnifications given" in res.stderr and "magnifications assumed" in res.stdout
    rec = Lens.load(flats / "from_none.toml").calibration["magnification"]
    assert rec["assumed"] is True and rec["m_over_m_P_range"] == [0.0, 0.1]
    P = Lens.load(flats / "from_none.toml").vignetting[0][0]
    assert 0.5 < (P - PAPER_TRUTH.circles[0][0]) / rec["P_stderr_mm"][0] < 2
    res = cli("calibrate", *FLATS, *run, "--lens", "both.toml", "--out", "from_both.toml",
              cwd=flats)
    assert res.returncode == 0, res.stderr
    assert "magnification" not in res.stderr
    assert "magnification" not in Lens.load(flats / "from_both.toml").calibration
