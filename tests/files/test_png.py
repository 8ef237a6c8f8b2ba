"""PNG figures, written atomically with snapcorr's mark tied to the file."""

import pytest

from snapcorr.files.marks import written_by_snapcorr
from snapcorr.files.png import save_png


def test_a_saved_figure_is_snapcorrs_and_a_copy_is_not(tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot")
    fig = plt.figure(figsize=(1, 1))
    try:
        path = save_png(fig, tmp_path / "plot.png", dpi=20)
    finally:
        plt.close(fig)
    assert written_by_snapcorr(path) == (True, "")
    copy = tmp_path / "copy.png"
    copy.write_bytes(path.read_bytes())
    assert not written_by_snapcorr(copy)[0]


def test_an_input_is_never_written_over(tmp_path):
    src = tmp_path / "in.png"
    src.write_bytes(b"x")
    with pytest.raises(ValueError, match="is also an input"):
        save_png(None, src, inputs=[src])
