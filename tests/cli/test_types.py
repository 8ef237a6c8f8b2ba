"""The commands' argument types (snapcorr/cli/_types.py): what no camera or lens has is a
usage error with the range."""

from __future__ import annotations

import argparse

import pytest

from snapcorr.cli import _types


@pytest.mark.parametrize("value", ["0", "-1", "1e200", "1.1e6", "inf", "nan", "f/2"])
def test_an_f_number_outside_any_lens_is_refused_with_the_range(value):
    with pytest.raises(argparse.ArgumentTypeError, match=r"> 0 and at most 1e\+06"):
        _types._f_number(value)


def test_an_f_number_is_a_float():
    assert _types._f_number("2.8") == 2.8
    assert _types._flat_arg("f/2.8=f.npy")[0] == 2.8


@pytest.mark.parametrize(("kind", "good", "bad"), [
    ("_distance_mm", "21", ["0", "1e200", "inf", "nan"]),
    ("_magnification", "0", ["-0.1", "10.5", "1e200", "inf"]),
    ("_pupil_magnification", "1.3", ["0", "0.05", "11", "1e200", "nan"]),
])
def test_a_lens_number_past_any_lens_is_refused(kind, good, bad):
    parse = getattr(_types, kind)
    assert parse(good) == float(good)
    for value in bad:
        with pytest.raises(argparse.ArgumentTypeError, match=r"at most|between|finite"):
            parse(value)


@pytest.mark.parametrize("value", ["1e200,5", "nan,5", "5"])
def test_a_centre_no_sensor_has_is_refused(value):
    with pytest.raises(argparse.ArgumentTypeError):
        _types._center_rc_arg(value)


@pytest.mark.parametrize("kind", ["_magnification", "_pupil_magnification"])
@pytest.mark.parametrize("text", ["True", "", "0.06mm"])
def test_a_magnification_that_is_no_number_is_echoed(kind, text):
    """It was said to be NaN (``m must be a finite number, got nan``)."""
    with pytest.raises(argparse.ArgumentTypeError, match=f"got {text!r}"):
        getattr(_types, kind)(text)
