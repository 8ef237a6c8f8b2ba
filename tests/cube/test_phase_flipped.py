"""A camera set to mirror or flip its frames puts every band where another's pattern says it
is. Such a white fits no phase of the tile as it is, or a wrong one (and a wrong origin was
advised), and flat-fielding went on without a word; flipped back, it fits one far better:
refused, naming the flip. The whites are those of
``test_phase`` (an independent simulator through the real imec 4x4 VIS responses)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import run_cli

from cube.test_phase import lamp, vendor, white_frame  # noqa: F401 (a fixture)
from snapcorr.cube.phase import check_mosaic_phase

ORIGIN = (400, 700)


@pytest.mark.parametrize("how, flip", [
    ("mirrored left-right", (slice(None), slice(None, None, -1))),
    ("upside down", (slice(None, None, -1), slice(None))),
    (r"turned half round \(mirrored both ways\)", (slice(None, None, -1),
                                                   slice(None, None, -1))),
])
@pytest.mark.parametrize("light", ["tungsten", "D65"])
def test_a_flipped_white_is_refused_naming_the_flip(vendor, how, flip, light):  # noqa: F811
    fx, sensor, _ = vendor
    white, dark = white_frame(fx, (64, 96), ORIGIN, lamp(light, fx.grid), seed=2)
    assert check_mosaic_phase(white, sensor, ORIGIN, dark=dark).agrees  # as read out: fine
    with pytest.raises(ValueError, match=rf"fits the .* tile far better {how} than as it is "
                                         r".* the camera flips its frames"):
        check_mosaic_phase(white[flip], sensor, ORIGIN, dark=dark[flip])


def test_the_command_line_refuses_a_flipped_white_before_any_work(vendor, tmp_path):  # noqa: F811
    fx, _, path = vendor
    white, dark = white_frame(fx, (64, 96), ORIGIN, lamp("tungsten", fx.grid), seed=2)
    for name, a in (("white.npy", white), ("dark.npy", dark), ("raw.npy", 0.5 * white)):
        np.save(tmp_path / name, a[:, ::-1].astype(np.uint16))
    code, _, err = run_cli("flatfield", "raw.npy", "--dark", "dark.npy", "--white",
                           "white.npy", "--sensor", str(path), "--sensor-origin-px",
                           f"{ORIGIN[0]},{ORIGIN[1]}", "--out", "ff.nc", cwd=tmp_path)
    assert code == 1 and "--white white.npy fits the" in err, err
    assert "mirrored left-right" in err and not (tmp_path / "ff.nc").exists()


def test_sensor_phase_from_says_the_flip(vendor, tmp_path):  # noqa: F811
    """``snapcorr sensor --phase-from`` on the mirrored white said only that it cannot tell."""
    fx, _, path = vendor
    white, dark = white_frame(fx, (64, 96), ORIGIN, lamp("tungsten", fx.grid), seed=2)
    for name, a in (("white.npy", white), ("dark.npy", dark)):
        np.save(tmp_path / name, a[:, ::-1].astype(np.uint16))
    code, _, err = run_cli("sensor", str(path), "--phase-from", "white.npy", "--dark",
                           "dark.npy", "--sensor-origin-px", f"{ORIGIN[0]},{ORIGIN[1]}",
                           cwd=tmp_path)
    assert code == 1 and "far better mirrored left-right than as it is" in err, err
