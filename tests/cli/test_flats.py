"""The flats of `snapcorr calibrate`: the mosaic they are raw frames of, and their pixel pitch."""

import types

import pytest

from snapcorr.cli._flats import _flat_sensor, _pitch_option


def test_the_pitch_is_given_or_the_sensors(capsys):
    args = types.SimpleNamespace(pixel_pitch_um=3.0, sensor="imec_5x5_nir")
    _pitch_option(args, None)
    assert args.pixel_pitch_um == 3.0
    args = types.SimpleNamespace(pixel_pitch_um=None, sensor=None)
    with pytest.raises(ValueError, match=r"give the flats' pixel pitch: --pixel-pitch-um UM$"):
        _pitch_option(args, None)


def test_only_a_mosaic_sensor_goes_with_flats_alone():
    args = types.SimpleNamespace(sensor="snapscan_vnir", sensor_origin_px=None)
    with pytest.raises(ValueError, match="--sensor snapscan_vnir is not a mosaic"):
        _flat_sensor(args)
    args = types.SimpleNamespace(sensor=None, sensor_origin_px=(0, 0))
    with pytest.raises(ValueError, match="--sensor-origin-px needs --sensor"):
        _flat_sensor(args)
    assert _flat_sensor(types.SimpleNamespace(sensor="mosaic_4x4_vis")).layout == "mosaic"
