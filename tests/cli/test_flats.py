"""The flats of `snapcorr calibrate`: the mosaic they are raw frames of, and their pixel pitch."""

import re
import types

import pytest

from snapcorr.cli._flats import _check_crop, _flat_sensor, _mosaic_of, _pitch_option


def test_the_pitch_is_given_or_the_sensors(capsys):
    args = types.SimpleNamespace(pixel_pitch_um=3.0, sensor="imec_5x5_nir")
    _pitch_option(args, None)
    assert args.pixel_pitch_um == 3.0
    args = types.SimpleNamespace(pixel_pitch_um=None, sensor=None)
    with pytest.raises(ValueError, match=r"give the flats' pixel pitch: --pixel-pitch-um UM$"):
        _pitch_option(args, None)


def test_any_sensor_goes_with_flats_alone():
    """A mosaic's band gains are divided out; a sensor of another layout gives the pitch and
    bounds a crop (:func:`_check_crop`)."""
    args = types.SimpleNamespace(sensor="snapscan_vnir", sensor_origin_px=None)
    assert _mosaic_of(_flat_sensor(args)) is None
    assert _flat_sensor(types.SimpleNamespace(sensor=None, sensor_origin_px=(0, 4))) is None
    sensor = _flat_sensor(types.SimpleNamespace(sensor="mosaic_4x4_vis"))
    assert _mosaic_of(sensor) is sensor


@pytest.mark.parametrize("origin, words", [
    (None, "--flat 2=f2.tif is 100 x 200 px, a crop of the sensor snapscan_vnir (2048 x 2048 "
           "px): give --sensor-origin-px ROW,COL"),
    ((2000, 0), "--flat 2=f2.tif: 100 x 200 px at sensor row 2000, column 0 reaches beyond "
                "the sensor snapscan_vnir (2048 x 2048 px)"),
    ((0, 1900), "reaches beyond the sensor"),
])
def test_a_crop_of_a_snapscan_sensor_is_placed_or_refused(origin, words):
    import numpy as np

    args = types.SimpleNamespace(sensor="snapscan_vnir", sensor_origin_px=origin,
                                 flat=[(8.0, "f8.tif"), (2.0, "f2.tif")], pixel_pitch_um=5.5)
    sensor = _flat_sensor(args)
    flats = {2.0: np.ones((100, 200)), 8.0: np.ones((100, 200))}
    with pytest.raises(ValueError, match=re.escape(words)):
        _check_crop(args, sensor, flats)
    args.sensor_origin_px = (1948, 1848)  # the last place it fits
    _check_crop(args, sensor, flats)
    args.sensor_origin_px = None  # the whole sensor needs no origin
    _check_crop(args, sensor, {2.0: np.ones((2048, 2048))})


def test_binned_flats_of_a_snapscan_sensor_are_placed_by_millimetres():
    """Flats of another pitch than the sensor's are not compared with its size in pixels; an
    origin in the sensor's pixels cannot place them."""
    import numpy as np

    args = types.SimpleNamespace(sensor="snapscan_vnir", sensor_origin_px=None,
                                 flat=[(2.0, "f2.tif")], pixel_pitch_um=44.0)
    sensor = _flat_sensor(args)
    _check_crop(args, sensor, {2.0: np.ones((256, 256))})
    args.sensor_origin_px = (0, 0)
    with pytest.raises(ValueError, match="a crop's origin needs the sensor's own pixels"):
        _check_crop(args, sensor, {2.0: np.ones((100, 100))})
