"""`snapcorr stream`: its options are checked together before any frame is read."""

import pytest


@pytest.mark.parametrize(("extra", "words"), [
    (["--sensor", "snapscan_vnir"], "stream takes raw mosaic frames: --sensor snapscan_vnir is "
                                    "not a mosaic (layout 'snapscan')"),
    (["--sensor", "mosaic_4x4_vis", "--lens", "edmund_optics_16mm"],
     "correcting a stream needs both --lens and --f-number"),
    (["--sensor", "mosaic_4x4_vis", "--resample"], "--resample needs --lens and --f-number"),
    # accepted, and nothing derived stored without a lens
    (["--sensor", "mosaic_4x4_vis", "--store-derived"],
     "--store-derived stores the corrected wavelengths: it needs --lens and --f-number"),
    (["--sensor", "mosaic_4x4_vis", "--virtual-bands", "fitted"],
     "--virtual-bands needs --lens and --f-number"),
])
def test_options_that_do_not_go_together_are_one_line(tmp_path, cli, extra, words):
    rc, out, err = cli("stream", "frames.zarr", "--dark", "d.npy", "--white", "w.npy",
                       *extra, "--out", "s.zarr", cwd=tmp_path)
    assert rc == 1 and not out and err.count("\n") == 1, err
    assert err.startswith("snapcorr stream: error: ") and words in err, err
    assert not (tmp_path / "s.zarr").exists()


@pytest.mark.parametrize("given", [["--center", "3,5"], ["--center-px", "5,3"]],
                         ids=["center", "center-px"])
def test_center_places_the_lens_centre_of_a_stream(tmp_path, monkeypatch, cli, given):
    """The optical centre the corrected wavelengths need can be given (a lens profile from
    another pixel pitch asks for --center), row first, as to correct; --center-px, x first,
    is its deprecated form and reaches the stream as the same row-first pair."""
    import numpy as np

    import snapcorr.pipeline

    for name, shape in (("frames", (2, 8, 8)), ("d", (8, 8)), ("w", (8, 8))):
        np.save(tmp_path / f"{name}.npy", np.full(shape, 100 if name == "d" else 900,
                                                    np.uint16))
    seen = {}

    def capture(*args, **kwargs):
        seen.update(kwargs)
        raise ValueError("stopped here")

    monkeypatch.setattr(snapcorr.pipeline, "process_stream", capture)
    _, _, err = cli("stream", "frames.npy", "--dark", "d.npy", "--white", "w.npy", "--sensor",
                     "mosaic_4x4_vis", "--lens", "edmund_optics_16mm", "--f-number", "2",
                     *given, "--out", "s.zarr", cwd=tmp_path)
    assert "stopped here" in err, err
    assert seen["center_rc"] == (3.0, 5.0) and "center_px" not in seen
    assert ("--center-px CX,CY is deprecated" in err) == (given[0] == "--center-px"), err


def test_center_without_a_lens_is_one_line(tmp_path, cli):
    rc, _, err = cli("stream", "frames.zarr", "--dark", "d.npy", "--white", "w.npy",
                       "--sensor", "mosaic_4x4_vis", "--center", "3,5", "--out", "s.zarr",
                       cwd=tmp_path)
    assert rc == 1 and "--center" in err and "--lens" in err, err


def test_a_stream_whose_every_value_is_masked_fails_and_says_its_saturation(tmp_path, cli):
    """Frames all at 65535 (saturated): every value masked, which flatfield refuses; the
    stream said 'wrote ... 100.00 % masked' with exit status 0. Now status 1 and why; the
    default saturation of the frames' uint16 type is said, as flatfield says it."""
    import numpy as np

    np.save(tmp_path / "frames.npy", np.full((3, 8, 8), 65535, np.uint16))
    np.save(tmp_path / "d.npy", np.full((8, 8), 100, np.uint16))
    np.save(tmp_path / "w.npy", np.full((8, 8), 900, np.uint16))
    args = ("stream", "frames.npy", "--dark", "d.npy", "--white", "w.npy", "--sensor",
            "mosaic_4x4_vis", "--sensor-origin-px", "0,0")
    rc, out, err = cli(*args, "--out", "s.zarr", cwd=tmp_path)
    assert rc == 1 and "every value of the 3 frames is masked" in err, (out, err)
    assert "saturation level 65535" in err and "--saturation" in err, err
    assert "saturation: 65535 DN, the largest code of the whites' type, uint16" in err, err
    np.save(tmp_path / "frames.npy", np.full((3, 8, 8), 500, np.uint16))
    rc, out, err = cli(*args, "--out", "t.zarr", cwd=tmp_path)
    assert rc == 0 and "0 of 3072 values masked" in out, (out, err)
    assert "saturation: 65535 DN, the largest code of the whites' type, uint16" in err, err
