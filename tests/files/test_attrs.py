"""Attributes as files hold them: every kind of value round trips through netCDF and Zarr;
what the encoding makes of a value read with plain ``json``; sensor positions stored as an
offset and a step only when that gives every value back; and values that cannot be stored
refused before anything is written."""

import json

import numpy as np
import pytest
import xarray as xr
from numpy.testing import assert_array_equal

from snapcorr.cube import make_cube
from snapcorr.files import read_cube, write_cube
from snapcorr.files.attrs import (
    JSON_PREFIX,
    _decode_positions,
    _encode_positions,
    _json_attrs,
    decode_attrs,
    encode_attrs,
)


def test_what_is_not_stored_as_itself_is_json_that_json_reads():
    attrs = {"dict": {"a": [1, None], "b": "µm"}, "true": True, "none": None,
             "words": ["a", "b"], "big": 2**70, "looks": "json:not really",
             "text": "plain", "int": -3, "float": 2.5, "array": np.array([1.0, 2.0])}
    enc = encode_attrs(attrs)
    for key in ("dict", "true", "none", "words", "big", "looks"):
        assert enc[key].startswith(JSON_PREFIX)
        want = attrs[key]
        assert json.loads(enc[key][len(JSON_PREFIX):]) == want
    assert enc["text"] == "plain" and enc["int"] == -3 and enc["float"] == 2.5
    assert_array_equal(enc["array"], [1.0, 2.0])
    back = decode_attrs(enc)
    assert {k: v for k, v in back.items() if k != "array"} == \
        {k: v for k, v in attrs.items() if k != "array"}
    # a file's own attribute that starts like ours but is no JSON stays as it is
    assert decode_attrs({"x": "json:{oops", "y": b"bytes"}) == {"x": "json:{oops",
                                                                "y": "bytes"}
    assert _json_attrs({"n": np.int32(5), "a": np.arange(2)}, "t") == {"n": 5, "a": [0, 1]}


def test_positions_are_an_offset_and_a_step_only_when_that_is_exact():
    rows = 40 + 4 * np.arange(6)[:, None] + np.array([0, 1, 2, 3])[None, :]
    spec = _encode_positions(rows)
    assert spec == {"offset": [40, 41, 42, 43], "step": 4}
    assert_array_equal(_decode_positions(json.loads(json.dumps(spec)), rows.shape, "r", "t"),
                       rows)
    bent = rows.copy()
    bent[5, 2] += 1
    assert _encode_positions(bent) == {"values": bent.tolist()}
    half = rows + 0.5  # not integers: every value
    assert_array_equal(_decode_positions(_encode_positions(half), half.shape, "r", "t"), half)
    with pytest.raises(ValueError, match="has shape"):
        _decode_positions(spec, (6, 3), "sensor_row", "f.npy")
    with pytest.raises(ValueError, match="not a list of sensor positions"):
        _decode_positions({"offset": "a"}, (6, 4), "sensor_row", "f.npy")


def test_boolean_attributes_survive_netcdf(tmp_path):
    cube = make_cube(np.ones((3, 4, 2), np.float32), [500.0, 650.25], attrs={"f_number": 2.8})
    cube.attrs["calibrated"] = True
    write_cube(cube, tmp_path / "b.nc")
    assert read_cube(tmp_path / "b.nc").attrs["calibrated"] == 1


EVERY_KIND = {"text": "a string", "empty": "", "unicode": "\u00b5m \u00e9t\u00e9",
              "looks_encoded": "json:not really", "int": 7, "big_int": 2**70,
              "negative": -3, "float": 2.8, "nan": float("nan"), "true": True,
              "false": False, "none": None, "floats": [1.5, 2.5], "ints": [1, 2, 3],
              "one": [4.0], "empty_list": [], "mixed": [1, 2.5], "tuple": (3, 4),
              "words": ["a", "b"], "dict": {"a": 1, "b": [1, 2], "c": {"d": None}},
              "array": np.array([1.0, 2.0, 3.0]), "np_int": np.int32(5),
              "np_float": np.float32(0.25), "np_bool": np.bool_(True)}


def _dataset_with_every_attribute():
    from snapcorr.cube.derived import corrected_wavelength

    rng = np.random.default_rng(2)
    ds = xr.Dataset(
        {"radiance": (("y", "x", "band"), rng.random((4, 5, 3), dtype=np.float32),
                      {**EVERY_KIND, "units": "W m-2 sr-1 nm-1"}),
         "wavelength_scale": (("y", "x", "scale"), 1 + rng.random((4, 5, 1)) / 100),
         "scale_index": ("band", np.zeros(3, np.int64))},
        coords={"wavelength": ("band", [500.0, 600.0, 700.0], {"units": "nm", **EVERY_KIND}),
                "sensor_row": (("y", "band"), np.repeat(np.arange(4)[:, None], 3, axis=1))},
        attrs=dict(EVERY_KIND))
    return ds.assign_coords(wavelength_corrected=corrected_wavelength(ds))


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_every_attribute_round_trips_through_write_and_read_dataset(tmp_path, ext):
    from snapcorr.cube import read_dataset, write_dataset

    ds = _dataset_with_every_attribute()
    before = ds.copy(deep=True)
    write_dataset(ds, tmp_path / f"r{ext}")
    xr.testing.assert_identical(ds, before)  # the Dataset in memory is not changed
    assert "written_by" not in ds.attrs
    back = read_dataset(tmp_path / f"r{ext}")
    xr.testing.assert_identical(back, ds)
    for attrs in (back.attrs, back["radiance"].attrs, back["wavelength"].attrs):
        assert attrs["true"] is True and attrs["false"] is False and attrs["none"] is None
        assert attrs["dict"] == EVERY_KIND["dict"] and attrs["words"] == ["a", "b"]
        assert attrs["one"] == [4.0] and attrs["empty_list"] == [] and attrs["mixed"] == [1, 2.5]
        assert attrs["big_int"] == 2**70 and attrs["looks_encoded"] == "json:not really"
        assert attrs["tuple"] == [3, 4] and np.isnan(attrs["nan"])
    raw = xr.open_dataset(tmp_path / f"r{ext}", engine="zarr" if ext == ".zarr" else None)
    assert "wavelength_corrected" not in raw.variables  # rebuilt, not stored
    assert raw.attrs["derived_variables"] == 'json:["wavelength_corrected"]'
    assert raw.attrs["written_by"].startswith("snapcorr")
    raw.close()


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_an_attribute_that_cannot_be_stored_is_refused_before_writing(tmp_path, ext):
    import datetime

    from snapcorr.cube import write_dataset

    ds = xr.Dataset({"a": ("y", np.arange(3.0))})
    ds["a"].attrs["taken"] = datetime.datetime(2024, 5, 1)
    with pytest.raises(TypeError, match="variable 'a': attribute 'taken' is a datetime"):
        write_dataset(ds, tmp_path / f"r{ext}")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_a_file_name_that_is_no_utf8_is_stored_escaped(tmp_path, ext):
    """A frame named by bytes that are no UTF-8 (b'fr\\xe9me.npy', held by Python as a lone
    surrogate) in the attributes: netCDF's writer failed after the work with "'utf-8' codec
    can't encode character '\\udce9'"."""
    import xarray as xr

    from snapcorr.cube import read_dataset, write_dataset

    name = b"fr\xe9me.npy".decode("utf-8", "surrogateescape")
    ds = xr.Dataset({"reflectance": (("y", "x", "band"), np.zeros((2, 2, 1), np.float32),
                                     {"units": "1", "source": name})},
                    coords={"wavelength": ("band", [500.0])}, attrs={"inputs": [name],
                                                                     "source": name})
    write_dataset(ds, tmp_path / f"o{ext}")
    back = read_dataset(tmp_path / f"o{ext}")
    assert back.attrs["source"] == "fr\\xe9me.npy" == back["reflectance"].attrs["source"]
