"""``chunks="rows"``: a file opened once and read in blocks of whole rows, as ``row_blocks``
would cut it; the command line opens each input once."""

import numpy as np
import pytest

import snapcorr.files.api as api
from snapcorr.cube import make_cube, read_cube, read_frame, row_blocks, write_cube

WL = np.linspace(500, 900, 40)


@pytest.mark.parametrize("ext", [".hdr", ".npy", ".nc", ".zarr", ".tif"])
@pytest.mark.parametrize("dtype", [np.float32, np.uint16])
def test_rows_are_row_blocks_read_from_one_open(tmp_path, ext, dtype, monkeypatch):
    rng = np.random.default_rng(0)
    cube = make_cube((rng.random((300, 400, WL.size)) * 1000).astype(dtype), WL)
    path = tmp_path / f"c{ext}"
    write_cube(cube, path)
    expected = row_blocks(read_cube(path, chunks={}))
    calls = []
    real = api._read_file
    monkeypatch.setattr(api, "_read_file", lambda *a, **k: calls.append(a) or real(*a, **k))
    got = read_cube(path, chunks="rows")
    assert len(calls) == 1
    assert got.chunks == expected.chunks and len(got.chunks[0]) > 1  # blocks, not one
    np.testing.assert_array_equal(got.values, cube.values)


def test_a_frame_in_rows(tmp_path):
    frame = (np.arange(3000 * 2000) % 4093).astype(np.uint16).reshape(3000, 2000)
    np.save(tmp_path / "f.npy", frame)
    got = read_frame(tmp_path / "f.npy", chunks="rows")
    assert len(got.chunks[0]) > 1 and got.chunks[1] == (2000,)
    np.testing.assert_array_equal(got.values, frame)


def test_flatfield_opens_each_input_once(tmp_path, cli, monkeypatch):
    rng = np.random.default_rng(1)
    for name, level in (("raw", 2000), ("dark", 100), ("white", 3000)):
        data = (level + rng.integers(0, 50, (10, 12, 6))).astype(np.uint16)
        write_cube(make_cube(data, WL[:6]), tmp_path / f"{name}.hdr")
    opened = []
    real = api._read_file
    counted = lambda path, **k: opened.append(str(path)) or real(path, **k)  # noqa: E731
    for module in (api,):
        monkeypatch.setattr(module, "_read_file", counted)
    res = cli("flatfield", "raw.hdr", "--dark", "dark.hdr", "--white", "white.hdr",
              "--out", "ff.nc", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert sorted(opened) == ["dark.hdr", "raw.hdr", "white.hdr"], opened


@pytest.mark.parametrize("ext", [".nc", ".zarr"])
def test_correct_opens_its_input_once_and_keeps_its_mask(tmp_path, cli, monkeypatch, ext):
    """A flat-field result's cube and mask come from one opening of the file."""
    import snapcorr.files.datasets as cds
    from snapcorr.cube import read_dataset
    from snapcorr.data import lens_path

    rng = np.random.default_rng(2)
    for name, level in (("raw", 2000), ("dark", 100), ("white", 3000)):
        data = (level + rng.integers(0, 50, (16, 20, 4))).astype(np.uint16)
        if name == "white":
            data[3, 4, 1] = 50  # below the dark: masked
        write_cube(make_cube(data, [500.0, 520.0, 540.0, 560.0]), tmp_path / f"{name}.hdr")
    (tmp_path / "sensor.toml").write_text(
        '[sensor]\nname = "p4"\nlayout = "snapscan"\npixel_pitch_um = 5.5\n'
        "cwl_nm = [500.0, 520.0, 540.0, 560.0]\nfwhm_nm = 10.0\nn_eff = 1.7\n")
    res = cli("flatfield", "raw.hdr", "--dark", "dark.hdr", "--white", "white.hdr",
              "--out", f"ff{ext}", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    mask = read_dataset(tmp_path / f"ff{ext}")["mask"].values
    assert mask.any() and not mask.all()
    opened = []
    real = cds._open_dataset
    monkeypatch.setattr(cds, "_open_dataset",
                        lambda path, *a: opened.append(str(path)) or real(path, *a))
    res = cli("correct", f"ff{ext}", "--lens", str(lens_path("edmund_optics_16mm")),
              "--sensor", "sensor.toml", "--f-number", "2", "--out", "c.nc", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert [p.rsplit("/", 1)[-1] for p in opened] == [f"ff{ext}"], opened
    np.testing.assert_array_equal(read_dataset(tmp_path / "c.nc")["mask"].values, mask)
