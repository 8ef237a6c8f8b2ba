"""Sensor.load: a sensor TOML, a vendor .xml, or a bundled sensor by name."""

import re

import pytest

from snapcorr.cube import Sensor
from snapcorr.data import sensor_path


def test_a_bundled_sensor_by_name(tmp_path):
    assert Sensor.load("mosaic_4x4_vis") == Sensor.load(sensor_path("mosaic_4x4_vis"))
    with pytest.raises(FileNotFoundError, match=r"no bundled sensor named 'nope'; bundled "
                       r"sensors: \[.*'snapscan_vnir'"):
        Sensor.load("nope")
    for name in ("snapscan_vnir.toml", "snapscan_vnir.xml"):  # a suffix: a file, never a name
        with pytest.raises((FileNotFoundError, ValueError), match=re.escape(name)):
            Sensor.load(tmp_path / name)


def test_a_file_of_a_bundled_name_is_read_as_the_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Sensor("mine", "snapscan", 5.5, [500.0, 600.0], 10.0, 1.7).save(tmp_path / "snapscan_vnir")
    assert Sensor.load("snapscan_vnir").name == "mine"  # an existing file wins over the name
