"""Sensor positions that reach beyond the sensor are refused where they are made, for every
layout: a Snapscan crop at row 2000 of a 2048 px sensor was written with positions to 2063,
and only a later correct refused it."""

from __future__ import annotations

import pytest

from snapcorr.cube import Sensor, sensor_positions


@pytest.mark.parametrize(("name", "shape", "origin"), [
    ("snapscan_vnir", (64, 64), (2000, 2000)),
    ("snapscan_vnir", (64, 64), (0, 1985)),
    ("snapscan_vnir", (4, 4), (-1, 0)),
    ("mosaic_4x4_vis", (300, 10), (0, 0)),
])
def test_positions_beyond_the_sensor_are_refused(name, shape, origin):
    with pytest.raises(ValueError, match=r"reaches beyond the sensor .* check "
                       r"sensor_origin_px="):
        sensor_positions(Sensor.load(name), *shape, origin)


def test_positions_up_to_the_last_pixel_are_made():
    rows, cols = sensor_positions(Sensor.load("snapscan_vnir"), 64, 64, (1984, 1984))
    assert rows.max() == 2047 and cols.max() == 2047
