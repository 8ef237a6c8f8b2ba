"""``.npy`` cubes and frames: arrays numpy wrote (C and Fortran order, header versions 1 and 2,
frames) read back whole and in row blocks as numpy reads them; what snapcorr writes read by
numpy and its sidecar by ``json``; a truncated file refused."""

import json

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from snapcorr.cube import make_cube
from snapcorr.data import sensor_path
from snapcorr.files import read_cube, read_frame, write_cube
from snapcorr.files.npy import NPY, _npy_layout

WAVELENGTHS = [500.0, 600.0, 700.0]


def _data(dtype, order="C"):
    values = np.random.default_rng(1).integers(0, 4000, (13, 7, 3)).astype(dtype)
    return np.asarray(values, order=order)


@pytest.mark.parametrize("dtype", [np.uint16, np.int32, np.float32, np.float64])
@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("chunks", [None, {"y": 4}])
def test_an_array_numpy_saved_reads_back_as_numpy_loads_it(tmp_path, dtype, order, chunks):
    path = tmp_path / "cube.npy"
    np.save(path, _data(dtype, order))
    cube = read_cube(path, wavelength_nm=WAVELENGTHS, chunks=chunks)
    assert cube.dims == ("y", "x", "band") and cube.dtype == np.dtype(dtype)
    assert_array_equal(cube.values, np.load(path))
    assert_array_equal(cube["wavelength"].values, WAVELENGTHS)


def test_the_layout_is_numpys_header_for_both_versions(tmp_path):
    data = _data(np.float32)
    for version in [(1, 0), (2, 0)]:
        path = tmp_path / f"v{version[0]}.npy"
        with open(path, "wb") as fh:
            np.lib.format.write_array(fh, data, version=version)
        offset = path.stat().st_size - data.nbytes  # the header, then the values
        assert _npy_layout(path) == (data.shape, data.dtype, offset)
        assert_array_equal(read_cube(path, wavelength_nm=WAVELENGTHS).values, data)
    np.save(tmp_path / "f.npy", np.asfortranarray(data))
    assert _npy_layout(tmp_path / "f.npy") is None  # read through numpy instead


def test_a_frame_numpy_saved_reads_as_a_frame(tmp_path):
    frame = np.arange(35, dtype=np.uint16).reshape(5, 7)
    np.save(tmp_path / "frame.npy", frame)
    got = read_frame(tmp_path / "frame.npy")
    assert got.dims == ("y", "x")
    assert_array_equal(got.values, frame)


def test_what_snapcorr_writes_numpy_and_json_read(tmp_path):
    data = _data(np.float32)
    path = tmp_path / "out.npy"
    write_cube(make_cube(data, WAVELENGTHS, name="scene"), path)
    assert [p.name for p in NPY.targets(path)] == ["out.npy", "out.npy.json"]
    assert_array_equal(np.load(path, allow_pickle=False), data)
    side = json.loads((tmp_path / "out.npy.json").read_text())
    assert side["wavelength_nm"] == WAVELENGTHS
    assert_array_equal(read_cube(path).values, data)


def test_a_truncated_file_is_refused(tmp_path):
    path = tmp_path / "cut.npy"
    np.save(path, _data(np.uint16))
    raw = path.read_bytes()
    path.write_bytes(raw[:-10])
    with pytest.raises(ValueError, match="truncated"):
        read_cube(path, wavelength_nm=WAVELENGTHS)


def _mosaic_cube():
    from snapcorr.cube import Sensor, mosaic_to_cube

    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    frame = np.random.default_rng(3).integers(0, 4096, (32, 48)).astype(np.uint16)
    return mosaic_to_cube(frame, sensor, sensor_origin_px=(8, 12))


def test_npy_sidecar_carries_the_metadata_and_a_bare_npy_needs_wavelengths(tmp_path):
    cube = _mosaic_cube()
    cube.attrs.update({"f_number": 2.8, "calibrated": True})
    write_cube(cube, tmp_path / "c.npy")
    meta = json.loads((tmp_path / "c.npy.json").read_text())
    assert meta["written_by"].startswith("snapcorr") and meta["shape"] == list(cube.shape)
    back = read_cube(tmp_path / "c.npy")
    assert back.attrs["f_number"] == 2.8 and back.attrs["calibrated"] is True
    assert_array_equal(back.fwhm.values, cube.fwhm.values)
    np.save(tmp_path / "bare.npy", cube.values)  # a user's own array, no sidecar
    with pytest.raises(ValueError, match="pass wavelength_nm"):
        read_cube(tmp_path / "bare.npy")
    assert read_cube(tmp_path / "bare.npy", wavelength_nm=cube.wavelength.values).shape == \
        cube.shape
    (tmp_path / "bare.npy.json").write_text('{"shape": [3, 4, 5]}')
    with pytest.raises(ValueError, match="do not belong together"):
        read_cube(tmp_path / "bare.npy", wavelength_nm=cube.wavelength.values)


@pytest.mark.parametrize("shape", [(12, -10, 4), (-1, 8), (3, 4, -2)])
@pytest.mark.parametrize("fortran", [False, True])
def test_a_header_with_a_negative_size_is_refused_naming_the_file(tmp_path, shape, fortran):
    """numpy's header reader takes a negative size; a raw, dark and white all of (12, -10, 4)
    then failed with "length should not be negative", naming no file."""
    import numpy.lib.format as npformat

    path = tmp_path / "neg.npy"
    with open(path, "wb") as fh:
        npformat.write_array_header_1_0(fh, {"descr": "<f4", "fortran_order": fortran,
                                             "shape": shape})
        fh.write(b"\0" * 64)
    with pytest.raises(ValueError, match=r"neg\.npy: its header gives the shape .* negative"):
        read_cube(path, wavelength_nm=[500.0, 520.0, 540.0, 560.0])


def test_a_sidecar_nested_past_the_json_readers_depth_is_one_line(tmp_path, cli):
    """100 000 brackets in a .npy's sidecar: refused as unreadable JSON naming the sidecar, as
    a malformed one is (it gave a RecursionError message, and the JSON readers of every other
    format the same)."""
    cube = _mosaic_cube()
    write_cube(cube, tmp_path / "c.npy")
    (tmp_path / "c.npy.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ValueError, match=r"sidecar c.npy.json is not readable JSON \(JSON "
                                         r"nested too deeply"):
        read_cube(tmp_path / "c.npy")
    from snapcorr._validation import parse_json

    with pytest.raises(ValueError, match="nested too deeply"):
        parse_json('{"a": ' * 50_000 + "1" + "}" * 50_000)
    assert parse_json('{"a": [1, 2]}') == {"a": [1, 2]}


def _with_sidecar(tmp_path, stored=np.float32, order="C", **fields):
    """A cube of ``stored`` values snapcorr wrote as .npy, its sidecar's ``fields`` replaced."""
    path = tmp_path / "c.npy"
    write_cube(make_cube(_data(stored), WAVELENGTHS), path, overwrite=True)
    if order == "F":  # the same array stored in Fortran order (read through numpy's map)
        np.save(path, _data(stored, order))
    side = tmp_path / "c.npy.json"
    meta = json.loads(side.read_text())
    side.write_text(json.dumps({**meta, **fields}))
    return path


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize(("stored", "said"), [(np.float32, "uint16"), (np.uint16, "float32"),
                                              (np.float64, "float32"), (np.int32, "uint32")])
def test_a_sidecar_of_another_dtype_is_refused(tmp_path, order, stored, said):
    path = _with_sidecar(tmp_path, stored, order, dtype=said)
    with pytest.raises(ValueError, match=rf"c\.npy: its sidecar c\.npy\.json describes {said} "
                                         rf"values but the array holds {np.dtype(stored)}"):
        read_cube(path)
    with pytest.raises(ValueError, match="describes"):
        read_cube(path, chunks={"y": 4})


@pytest.mark.parametrize("said", ["nonsense", 5, ["float32"]])
def test_a_sidecar_naming_no_dtype_is_refused(tmp_path, said):
    with pytest.raises(ValueError, match=r"names the dtype .* which is no numpy type"):
        read_cube(_with_sidecar(tmp_path, dtype=said))


def test_a_sidecar_dtype_in_another_spelling_or_byte_order_is_read(tmp_path):
    for said in ("float32", "<f4", ">f4", "f4"):
        assert read_cube(_with_sidecar(tmp_path, dtype=said)).dtype == np.float32
    path = tmp_path / "c.npy"  # the array big-endian, the sidecar as snapcorr writes it
    np.save(path, _data(np.float32).astype(">f4"))
    assert read_cube(path).dtype.kind == "f"


@pytest.mark.parametrize(("fields", "words"), [
    ({"shape": [13.0, 7, 3]}, r"gives the shape \[13.0, 7, 3\], not a list of whole numbers"),
    ({"shape": 13}, "gives the shape 13, not a list"),
    ({"shape": [True, 7, 3]}, "gives the shape"),
    ({"name": 5}, "gives the name 5, not a string"),
    ({"attrs": [1, 2]}, "gives attrs as list, not a JSON object"),
    ({"sensor_row": [0, 1]}, "gives sensor_row as list, not a JSON object"),
])
def test_sidecar_fields_of_another_kind_are_refused(tmp_path, fields, words):
    with pytest.raises(ValueError, match=rf"c\.npy: its sidecar c\.npy\.json {words}"):
        read_cube(_with_sidecar(tmp_path, **fields))
