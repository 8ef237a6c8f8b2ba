"""The shared checks and the one way a renamed name keeps working: what each refuses and says,
and the float32 packing range against the codes unpacked one by one."""

import math
import warnings

import numpy as np
import pytest

from snapcorr._validation import (
    REMOVAL_VERSION,
    check_center,
    check_center_rc,
    check_curve,
    check_integers,
    check_pack_range,
    check_pair,
    check_pixel_pitch_um,
    check_positive,
    check_positive_array,
    check_wavelengths_nm,
    renamed_keywords,
    shown,
    validate_method,
    warn_renamed,
)


@renamed_keywords(origin_px="sensor_origin_px")
def _place(frame, sensor_origin_px=None):
    return frame, sensor_origin_px


def test_a_renamed_keyword_still_works_and_warns_at_the_callers_line():
    with pytest.warns(FutureWarning, match=rf"origin_px is the earlier name of sensor_origin_px "
                                           rf"and will be removed in snapcorr {REMOVAL_VERSION}"
                      ) as record:
        assert _place(1, origin_px=(2, 3)) == (1, (2, 3))
    assert record[0].filename == __file__  # the caller's line, not the decorator's
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _place(1, sensor_origin_px=(2, 3)) == (1, (2, 3))  # the new name: silent
    assert _place.__name__ == "_place"


@pytest.mark.parametrize("call", [lambda: _place(1, (0, 0), origin_px=(2, 3)),
                                  lambda: _place(1, sensor_origin_px=(0, 0), origin_px=(2, 3))],
                         ids=["positional", "keyword"])
def test_a_renamed_keyword_given_with_its_new_name_is_refused(call):
    with pytest.raises(TypeError, match="give sensor_origin_px once"):
        call()


def test_a_renamed_keyword_used_inside_snapcorr_does_not_warn():
    scope = {"__name__": "snapcorr.somewhere", "_place": _place}
    exec("def inner():\n    return _place(1, origin_px=(4, 5))\n", scope)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert scope["inner"]() == (1, (4, 5))


def test_warn_renamed_says_what_to_give_instead():
    with pytest.warns(FutureWarning, match=r"Lens\.pupil is the earlier name of "
                                           r"Lens\.pupil_radiance .* give Lens\.pupil_radiance"):
        warn_renamed("Lens.pupil", "Lens.pupil_radiance", stacklevel=2)


def test_shown_cuts_long_values():
    assert shown(12) == "12"
    big = shown(10**400)
    assert len(big) == 40 and big.endswith("...") and big.startswith("1000")


def test_shown_cuts_a_long_string_before_taking_its_repr():
    """Ten megabytes of digits from a file are shown as 40 characters, the repr taken of the
    cut (a string of quotes and backslashes grows under repr, and is cut after)."""
    text = "1" * 10 * 2**20
    assert shown(text) == "'" + "1" * 36 + "..."
    assert shown(text, quote=False) == "1" * 37 + "..."
    assert shown("short") == "'short'" and shown("short", quote=False) == "short"
    assert len(shown("\\" * 1000)) == 40 and len(shown("a" * 39)) == 40
    assert shown("a" * 38) == "'" + "a" * 38 + "'"


@pytest.mark.parametrize(("value", "msg"), [
    (True, "a number, got a boolean"), ("1.7", "a number, got text"), ([1.0], "a number"),
    (0.0, "a finite number > 0"), (-2, "a finite number > 0"),
    (math.nan, "a finite number > 0"), (math.inf, "a finite number > 0"),
    (10**400, "a finite number > 0, got 1000"), (None, "a number")],
    ids=["bool", "text", "list", "zero", "negative", "nan", "inf", "huge-int", "none"])
def test_check_positive_refuses(value, msg):
    with pytest.raises(ValueError, match=f"f_number must be {msg}"):
        check_positive("f_number", value)


def test_check_positive_takes_any_real_number_type():
    for v in (2, 2.0, np.float32(2.0), np.int64(2), np.array(2.0)):
        assert check_positive("x", v) == 2.0 and type(check_positive("x", v)) is float


def test_a_pixel_pitch_in_the_wrong_unit_is_refused():
    assert check_pixel_pitch_um("pitch", 5.5) == 5.5
    assert check_pixel_pitch_um("pitch", 44.0) == 44.0  # 8 x 8 binned
    for v in (0.0055, 5500e3):  # mm, nm
        with pytest.raises(ValueError, match="check the unit"):
            check_pixel_pitch_um("pitch", v)


def test_arrays_and_pairs_are_checked_element_by_element():
    np.testing.assert_array_equal(check_positive_array("fwhm", [[1, 2], [3, 4]]),
                                  [[1.0, 2.0], [3.0, 4.0]])
    with pytest.raises(ValueError, match=r"fwhm must be finite and > 0 \(nm\), got \[1\.0, 0\.0"):
        check_positive_array("fwhm", [1, 0, 3], "nm")
    with pytest.raises(ValueError, match="must be numbers"):
        check_positive_array("fwhm", ["a", 1])
    assert check_pair("p", np.array([1, 2])) == (1.0, 2.0)
    for bad, msg in (((1, 2, 3), "two numbers"), ((1,), "two numbers"), (5, "two numbers"),
                     ((1, math.inf), "finite")):
        with pytest.raises(ValueError, match=msg):
            check_pair("p", bad)
    with pytest.raises(ValueError, match=r"\(cx, cy\) in pixels \(column, row\)"):
        check_center((1, 2, 3))
    with pytest.raises(ValueError, match=r"center_rc must be two numbers \(row, col\)"):
        check_center_rc("ab")


def test_validate_method_lists_the_choices():
    assert validate_method("b", ("a", "b")) == "b"
    with pytest.raises(ValueError, match=r"unknown profile 'c'; choose one of 'a', 'b'"):
        validate_method("c", {"a": 1, "b": 2}, "profile")


@pytest.mark.parametrize(("w", "t"), [([1, 2], [1]), ([2, 1], [0, 1]), ([1, 1], [0, 1]),
                                      ([1], [1]), ([[1, 2]], [[1, 2]]), ([1, np.nan], [0, 1]),
                                      ([1, 2], [0, np.inf])])
def test_a_bad_curve_is_refused(w, t):
    with pytest.raises(ValueError, match="transmission curve"):
        check_curve(w, t)


def test_wavelengths_in_another_unit_or_repeated_are_refused():
    np.testing.assert_array_equal(check_wavelengths_nm("cwl", [450, 550]), [450.0, 550.0])
    with pytest.raises(ValueError, match="look like micrometres: multiply by 1000"):
        check_wavelengths_nm("cwl", [0.45, 0.55])
    with pytest.raises(ValueError, match=r"^a\.hdr: cwl must be in nanometres"):
        check_wavelengths_nm("cwl", [4500e3], where="a.hdr")
    with pytest.raises(ValueError, match=r"repeats \[550\.0\] nm"):
        check_wavelengths_nm("cwl", [450, 550, 550])
    check_wavelengths_nm("cwl", [[450, 550], [450, 550]])  # per-pixel maps may repeat
    for bad, msg in (([True, False], "booleans"), ([450, np.nan], "finite"), (["x"], "numbers")):
        with pytest.raises(ValueError, match=msg):
            check_wavelengths_nm("cwl", bad)


def test_check_integers_takes_whole_numbers_only():
    got = check_integers("offset", [[0, 1.0], [2, 3]])
    assert got.dtype == np.int64 and got.tolist() == [[0, 1], [2, 3]]
    for bad, msg in ((4.7, "whole numbers"), ([1, True], "a boolean"), ([1, "2"], "text"),
                     (np.nan, "whole numbers")):
        with pytest.raises(ValueError, match=msg):
            check_integers("offset", bad)


def _unpacked(lo, hi, codes=65534):
    """Every code unpacked as CF does it: float32 scale_factor and add_offset, float32 sums."""
    scale, offset = np.float32((hi - lo) / codes), np.float32(lo)
    return np.arange(codes + 1, dtype=np.float32) * scale + offset


@pytest.mark.parametrize(("lo", "hi"), [(-0.5, 3.5), (0.0, 1.0), (1e4, 1e4 + 256.0),
                                        (-1e30, 1e30)])
def test_an_accepted_pack_range_unpacks_to_distinct_increasing_values(lo, hi):
    assert check_pack_range("--pack-range", lo, hi) == (lo, hi)
    v = _unpacked(lo, hi)
    assert np.all(np.isfinite(v)) and np.all(np.diff(v) > 0)


@pytest.mark.parametrize(("lo", "hi", "msg"), [(1e4, 1e4 + 1.0, "finer than float32"),
                                               (0.0, 1e-40, "smallest normal"),
                                               (0.0, 1e39, "largest number"),
                                               (1.0, 1.0, "LO < HI"), (0.0, math.nan, "LO < HI")])
def test_a_refused_pack_range_would_not_unpack(lo, hi, msg):
    with pytest.raises(ValueError, match=msg):
        check_pack_range("--pack-range", lo, hi)
    if msg == "finer than float32":  # the brute force agrees: codes collide
        assert np.any(np.diff(_unpacked(lo, hi)) <= 0)
