"""A vendor file's bit depth: the sensor's largest code is the default saturation."""

import numpy as np
import pytest
from conftest import VENDOR_XML, run_cli

from snapcorr.cube import Sensor
from snapcorr.cube.mosaic import frame_saturation


def test_the_vendor_files_bit_depth_is_read_kept_and_overridable(tmp_path):
    sensor = Sensor.load(VENDOR_XML)  # <input_bpp>10</input_bpp>
    assert sensor.bit_depth == 10 and sensor.full_scale_dn == 1023
    assert "10-bit codes (saturated at 1023)" in sensor.describe()
    sensor.save(tmp_path / "s.toml")
    assert Sensor.load(tmp_path / "s.toml") == sensor
    (tmp_path / "o.toml").write_text(f'[sensor]\nvendor_file = "{VENDOR_XML}"\nbit_depth = 12\n')
    assert Sensor.load(tmp_path / "o.toml").full_scale_dn == 4095


@pytest.mark.parametrize("bits", [0, 33, 4.5, True, "10"])
def test_a_bit_depth_that_is_not_a_number_of_bits_is_refused(tmp_path, bits):
    value = f'"{bits}"' if isinstance(bits, str) else str(bits).lower()
    (tmp_path / "o.toml").write_text(f'[sensor]\nvendor_file = "{VENDOR_XML}"\n'
                                     f"bit_depth = {value}\n")
    with pytest.raises(ValueError, match="bit_depth"):
        Sensor.load(tmp_path / "o.toml")


def test_the_default_saturation_is_the_largest_code_unless_the_white_is_scaled():
    sensor = Sensor.load(VENDOR_XML)
    white = np.full((20, 20), 800, np.uint16)
    assert frame_saturation(sensor, [white]) == 1023
    assert frame_saturation(sensor, [white], 900) == 900  # given: as given
    white[3, 4] = 4000  # a 12-bit frame, or a 10-bit one scaled to 16 bits
    with pytest.raises(ValueError, match=r"up to 4000, above the largest 10-bit code \(1023\)"):
        frame_saturation(sensor, [white])
    assert frame_saturation(sensor, [white], 4095) == 4095


def test_flatfield_masks_pixels_at_the_largest_code_by_default(tmp_path):
    rng = np.random.default_rng(0)
    size = (1088, 2048)
    white = rng.normal(800.0, 8.0, size)
    raw = 64 + 0.4 * (white - 64)
    white[500, 600:610] = 1023  # saturated in the white
    for name, frame in (("raw", raw), ("dark", np.full(size, 64.0)), ("white", white)):
        np.save(tmp_path / f"{name}.npy", np.clip(np.rint(frame), 0, 1023).astype(np.uint16))
    code, out, err = run_cli("flatfield", tmp_path / "raw.npy", "--dark", tmp_path / "dark.npy",
                             "--white", tmp_path / "white.npy", "--sensor", "imec_5x5_nir",
                             "--out", tmp_path / "ff.nc")
    assert code == 0, err
    assert "saturation: 1023 DN, the largest 10-bit code" in err
    assert "10 of" in out  # the ten saturated white pixels, one band value each


def test_raw_mosaic_flats_saturate_at_the_largest_code_or_are_refused(tmp_path):
    frame = np.full((1088, 2048), 900, np.uint16)
    frame[0, 0] = 3000  # not a 10-bit code
    np.save(tmp_path / "f2.npy", frame)
    np.save(tmp_path / "f8.npy", frame)
    code, _, err = run_cli("calibrate", "--flat", f"2={tmp_path / 'f2.npy'}", "--flat",
                           f"8={tmp_path / 'f8.npy'}", "--sensor", "imec_5x5_nir",
                           "--exit-pupil-mm", "21", "--pixel-pitch-um", "5.5",
                           "--out", tmp_path / "lens.toml")
    assert code != 0 and err.count("\n") <= 3, err
    assert "--flat 2=" in err and "above the largest 10-bit code (1023)" in err
