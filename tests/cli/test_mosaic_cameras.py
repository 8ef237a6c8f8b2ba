"""Mosaic cameras as they ship, on the command line: `snapcorr sensor`, raw whole-sensor frames
cut to the vendor file's active area, and virtual bands from `snapcorr correct`; every
foreseeable mistake is one line."""

import numpy as np
import pytest
from conftest import VENDOR_XML
from vendorfiles import imec_4x4, write_newer

from snapcorr.cube import Sensor, read_dataset

LENS = "edmund_optics_16mm"


def _frames(tmp_path, sensor):
    """Whole-sensor raw, dark and white frames of a flat grey target: 0.4 of the white."""
    rng = np.random.default_rng(0)
    white = rng.normal(800.0, 8.0, sensor.size_px)  # the sensor's codes are 10-bit
    raw = 64 + 0.4 * (white - 64) + rng.normal(0, 5, sensor.size_px)
    dark = rng.normal(64.0, 2.0, sensor.size_px)
    for name, frame in (("raw", raw), ("dark", dark), ("white", white)):
        np.save(tmp_path / f"{name}.npy", np.clip(frame, 0, 4095).astype(np.uint16))


def test_whole_frames_are_cut_to_the_active_area_and_give_virtual_bands(tmp_path, cli):
    sensor = Sensor.load(VENDOR_XML)
    _frames(tmp_path, sensor)
    rc, out, err = cli("flatfield", str(tmp_path / "raw.npy"), "--dark",
                       str(tmp_path / "dark.npy"), "--white", str(tmp_path / "white.npy"),
                       "--sensor", "imec_5x5_nir", "--out", str(tmp_path / "ff.zarr"))
    assert rc == 0, err
    ff = read_dataset(tmp_path / "ff.zarr")
    assert ff.sizes["y"] == 216 and ff.sizes["x"] == 409 and ff.sizes["band"] == 25
    assert int(ff["sensor_row"].min()) == 3  # the active area starts at row 3
    rc, out, err = cli("correct", str(tmp_path / "ff.zarr"), "--lens", LENS, "--sensor",
                       "imec_5x5_nir", "--f-number", "2.8", "--virtual-bands", "vendor",
                       "--out", str(tmp_path / "c.zarr"))
    assert rc == 0, err
    assert "virtual bands: 25 from 608.2 to 867.0 nm, vendor" in out
    ds = read_dataset(tmp_path / "c.zarr")
    assert ds["virtual"].dims == ("y", "x", "virtual_band")
    assert ds["virtual"].attrs["units"] == "1"
    assert "virtual_stderr" in ds and "virtual_matrix" in ds
    # a grey target stays grey: the vendor's rows (a white folded in) sum to 1
    assert np.nanmedian(ds["virtual"].values) == pytest.approx(0.4, abs=0.01)


def test_virtual_band_mistakes_are_one_line(tmp_path, cli):
    fx = imec_4x4()
    fx.matrices = []
    write_newer(tmp_path / "bare.xml", fx)
    rng = np.random.default_rng(1)
    np.save(tmp_path / "c16.npy", rng.uniform(0.2, 0.6, (40, 60)).astype(np.float32))
    (tmp_path / "bare.toml").write_text('[sensor]\nvendor_file = "bare.xml"\nn_eff = 1.7\n')
    common = ("--lens", LENS, "--f-number", "2", "--sensor-origin-px", "500,900")
    cases = [
        (("--sensor", "mosaic_4x4_vis", "--virtual-bands", "fitted"), "measured responses"),
        (("--sensor", str(tmp_path / "bare.toml"), "--virtual-bands", "vendor"),
         "no correction matrix"),
        (("--sensor", str(tmp_path / "bare.toml"), "--virtual-bands", "fitted",
          "--virtual-matrix", "x"), "--virtual-matrix"),
        (("--sensor", str(tmp_path / "bare.toml"), "--virtual-matrix", "x"), "--virtual-bands"),
        (("--sensor", str(VENDOR_XML), "--virtual-bands", "vendor"), "pixel pitch"),
    ]
    for extra, words in cases:
        rc, _, err = cli("correct", str(tmp_path / "c16.npy"), *common, *extra, "--out",
                         str(tmp_path / "o.nc"))
        assert rc == 1 and err.count("\n") == 1 and words in err, (extra, err)
        assert not (tmp_path / "o.nc").exists()


def test_a_cube_of_another_sensor_and_a_missing_n_eff_are_refused(tmp_path, cli):
    np.save(tmp_path / "t.npy", np.full((20, 30, 16), 0.5, np.float32))
    rc, _, err = cli("correct", str(tmp_path / "t.npy"), "--lens", LENS, "--f-number", "2",
                     "--sensor", "imec_5x5_nir", "--out", str(tmp_path / "o.nc"))
    assert rc == 1 and "16 bands" in err and "25" in err
    (tmp_path / "s.toml").write_text(f'[sensor]\nvendor_file = "{VENDOR_XML}"\n'
                                     "pixel_pitch_um = 5.5\n")
    rng = np.random.default_rng(2)
    for name, value in (("raw", 500.0), ("dark", 64.0), ("white", 900.0)):
        np.save(tmp_path / f"{name}.npy", rng.normal(value, 5.0, (50, 50)).astype(np.float32))
    rc, _, err = cli("flatfield", str(tmp_path / "raw.npy"), "--dark", str(tmp_path / "dark.npy"),
                     "--white", str(tmp_path / "white.npy"), "--sensor", str(tmp_path / "s.toml"),
                     "--sensor-origin-px", "500,900", "--out", str(tmp_path / "ff.nc"))
    assert rc == 0, err  # flat-fielding needs no n_eff
    args = ("correct", str(tmp_path / "ff.nc"), "--lens", LENS, "--f-number", "2", "--sensor",
            str(tmp_path / "s.toml"))
    rc, _, err = cli(*args, "--out", str(tmp_path / "o.nc"))
    assert rc == 1 and "n_eff" in err and "snapcorr pupil --fit-n-eff" in err
    assert "--method none" in err
    rc, out, err = cli(*args, "--method", "none", "--virtual-bands", "fitted", "--out",
                       str(tmp_path / "o.nc"))
    assert rc == 0, err
    assert "virtual bands: 25" in out
