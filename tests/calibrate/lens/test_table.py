"""The calibration's record: the lens profile's [calibration] table, through TOML and back."""

from snapcorr import Lens


def test_profile_and_toml_round_trip(paper_sphere, tmp_path):
    lens = paper_sphere.lens
    cal = lens.calibration
    for key in ("f_numbers", "onset_cra_deg", "center_rc", "center_px", "pixel_pitch_um", "method",
                "model", "date", "snapcorr_version", "joint_fit", "onset_ratio",
                "onset_model"):
        assert key in cal, key
    path = lens.save(tmp_path / "lens.toml")
    back = Lens.load(path)
    assert back == lens and back.calibration["center_rc"] == list(paper_sphere.center_rc)
    # and x first beside it, as snapcorr 0.1 wrote and read it
    assert back.calibration["center_px"] == list(paper_sphere.center_rc[::-1])
    assert "summary" not in cal and "P = " in paper_sphere.summary()
