"""A command's inputs: a cube or a raw mosaic frame, its stated sensor origin checked against
the positions a file records."""

import numpy as np
import pytest

from snapcorr.cli._frames import _read
from snapcorr.cube import Sensor, make_cube, sensor_positions
from snapcorr.cube.model import with_positions
from snapcorr.data import sensor_path
from snapcorr.pipeline import _check_origin, tile_rows


def _placed(origin):
    sensor = Sensor.load(sensor_path("snapscan_vnir"))
    cube = make_cube(np.ones((6, 8, sensor.n_bands), np.float32), sensor.cwl_nm)
    rows, cols = sensor_positions(sensor, 6, 8, origin)
    return sensor, with_positions(cube, rows, cols)


def test_a_stated_origin_must_agree_with_the_recorded_one():
    sensor, cube = _placed((10, 20))
    rows, cols = sensor_positions(sensor, 6, 8, (10, 20))
    _check_origin("c.nc", cube, rows, cols, (10, 20))  # agrees: nothing said
    rows, cols = sensor_positions(sensor, 6, 8, (12, 20))
    with pytest.raises(ValueError, match=r"sensor_origin_px \(12, 20\) disagrees with the sensor "
                       r"positions c.nc records \(its first pixel at row 10, col 20\)"):
        _check_origin("c.nc", cube, rows, cols, (12, 20))


def test_a_raw_frame_is_read_in_whole_tiles_and_split_into_bands(tmp_path):
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    np.save(tmp_path / "f.npy", np.arange(32 * 48, dtype=np.uint16).reshape(32, 48))
    cube = _read(tmp_path / "f.npy", sensor, (400, 800))
    assert cube.sizes["band"] == 16 and (cube.sizes["y"], cube.sizes["x"]) == (8, 12)
    frame = type("F", (), {"sizes": {"x": 48}})()
    assert tile_rows(frame, sensor) % 4 == 0
