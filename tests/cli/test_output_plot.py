"""``--plot`` of `snapcorr flatfield` and `snapcorr correct` writes a readable PNG."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import pytest
from hostile import FF, correct_args, save_cubes


@pytest.mark.parametrize("command", ["flatfield", "correct"])
def test_plot_writes_a_png(tmp_path, monkeypatch, command, cli):
    import matplotlib.image

    monkeypatch.chdir(tmp_path)
    save_cubes(tmp_path)
    if command == "flatfield":
        args = (*FF, "--out", "o.nc", "--plot", "look.png")
    else:
        args = correct_args("raw.npy", "o.nc", "--plot", "look.png")
    rc, _, err = cli(*args)
    assert rc == 0, err
    img = matplotlib.image.imread(tmp_path / "look.png")
    assert img.ndim == 3 and min(img.shape[:2]) > 50
