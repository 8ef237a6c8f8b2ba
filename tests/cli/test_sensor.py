"""`snapcorr sensor`: what a sensor file holds, its equivalent TOML, and a bundled sensor by
name."""

from conftest import VENDOR_XML

from snapcorr.cube import Sensor


def test_sensor_prints_what_the_file_holds_and_writes_an_equivalent_toml(tmp_path, cli):
    rc, out, err = cli("sensor", str(VENDOR_XML), "--toml", str(tmp_path / "s.toml"),
                       "--plot", str(tmp_path / "s.png"))
    assert rc == 0, err
    for words in ("25 bands", "5 x 5 tile", "filter area rows 3-1082, columns 0-2044",
                  "pixel pitch not given", "n_eff: not given", "snapcorr pupil --fit-n-eff",
                  "bandpass_600xi-875eo", "606-873 nm", "correction matrix 'custom' (irradiance)",
                  "  2  (0,2)", "add n_eff"):
        assert words in out, words
    assert Sensor.load(tmp_path / "s.toml") == Sensor.load(VENDOR_XML)
    assert (tmp_path / "s.png").stat().st_size > 10_000
    rc, _, err = cli("sensor", str(tmp_path / "missing.xml"))
    assert rc == 1 and err.count("\n") == 1 and "not found" in err


def test_a_bundled_sensor_is_named_and_an_unknown_name_is_one_line(tmp_path, cli):
    rc, out, err = cli("sensor", "mosaic_4x4_vis")
    assert rc == 0, err
    assert "16 bands" in out and "4 x 4 tile" in out
    rc, out, err = cli("sensor", "no_such_sensor")
    assert rc == 1 and not out and err.count("\n") == 1
    assert "no bundled sensor named 'no_such_sensor'; bundled sensors: [" in err


def test_dark_and_origin_go_with_phase_from(cli):
    for extra in (["--dark", "d.npy"], ["--sensor-origin-px", "0,0"]):
        rc, _, err = cli("sensor", "mosaic_4x4_vis", *extra)
        assert rc == 1 and f"{extra[0]} goes with --phase-from WHITE" in err
