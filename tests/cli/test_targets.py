"""A fit to a target's cubes, shared by `pupil` and `calibrate --target-cube`."""

import types

import pytest

from snapcorr.calibrate.pupil.precision import DEFAULT_TOLERANCE_NM
from snapcorr.cli._targets import _check_target_outputs, _target_spectrum, _target_tolerance


def _args(tmp_path, **given):
    values = dict(out=tmp_path / "lens.toml", plot=None, sensor_out=None, fit_n_eff=True,
                  overwrite=False)
    return types.SimpleNamespace(**{**values, **given})


def test_the_tolerance_defaults_to_the_libraries():
    assert _target_tolerance(None) == DEFAULT_TOLERANCE_NM
    assert _target_tolerance(0.2) == 0.2
    assert _target_spectrum(None) is None


def test_the_sensor_out_needs_two_f_numbers_and_its_own_path(tmp_path):
    one = _args(tmp_path, sensor_out=tmp_path / "s.toml")
    with pytest.raises(ValueError, match="--sensor-out needs --fit-n-eff and cubes at two"):
        _check_target_outputs(one, {2.0: "a.nc"}, [], "cubes")
    same = _args(tmp_path, sensor_out=tmp_path / "lens.toml")
    with pytest.raises(ValueError, match="the same or one lies in the other"):
        _check_target_outputs(same, {2.0: "a.nc", 8.0: "b.nc"}, [], "cubes")
    _check_target_outputs(_args(tmp_path, sensor_out=tmp_path / "s.toml"),
                          {2.0: "a.nc", 8.0: "b.nc"}, [], "cubes")
