"""`snapcorr stream`: its options are checked together before any frame is read."""

import pytest


@pytest.mark.parametrize(("extra", "words"), [
    (["--sensor", "snapscan_vnir"], "stream takes raw mosaic frames: --sensor snapscan_vnir is "
                                    "not a mosaic (layout 'snapscan')"),
    (["--sensor", "mosaic_4x4_vis", "--lens", "edmund_optics_16mm"],
     "correcting a stream needs both --lens and --f-number"),
    (["--sensor", "mosaic_4x4_vis", "--resample"], "--resample needs --lens and --f-number"),
    (["--sensor", "mosaic_4x4_vis", "--virtual-bands", "fitted"],
     "--virtual-bands needs --lens and --f-number"),
])
def test_options_that_do_not_go_together_are_one_line(tmp_path, cli, extra, words):
    rc, out, err = cli("stream", "frames.zarr", "--dark", "d.npy", "--white", "w.npy",
                       *extra, "--out", "s.zarr", cwd=tmp_path)
    assert rc == 1 and not out and err.count("\n") == 1, err
    assert err.startswith("snapcorr stream: error: ") and words in err, err
    assert not (tmp_path / "s.zarr").exists()
