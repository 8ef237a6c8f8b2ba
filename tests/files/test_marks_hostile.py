"""The writer's mark is tied to the file it was written as: a user's file made from a snapcorr
output (xarray, Spectral Python, a copy, an edit) is not replaced with ``overwrite``, a mark of
an earlier version is refused, and reading is unchanged by the mark."""

from __future__ import annotations

import json
import os
import shutil

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
import xarray as xr
from hostile import WL_OUT, only_line, output_cube, snapcorr_png, snapcorr_toml, snapshot_bounded

from snapcorr import _io
from snapcorr.cube import read_cube, write_cube, write_dataset


def _resave(src, dst):
    """A user's own file made from a snapcorr output by another program, its attributes
    (snapcorr's mark among them) copied."""
    suffix = src.suffix
    if suffix == ".nc":
        with xr.open_dataset(src) as ds:
            ds.load().assign_attrs(note="mine").to_netcdf(dst, engine="h5netcdf")
    elif suffix == ".zarr":
        with xr.open_zarr(src) as ds:
            ds.load().assign_attrs(note="mine").to_zarr(dst, consolidated=False)
    elif suffix == ".hdr":
        from spectral.io import envi

        img = envi.open(str(src))
        envi.save_image(str(dst), np.asarray(img.load()) + 1, metadata=dict(img.metadata),
                        ext=".raw", force=True)
    elif suffix == ".npy":
        np.save(dst, np.load(src) + 1)
        shutil.copy(src.with_name(src.name + ".json"), dst.with_name(dst.name + ".json"))
    else:
        raise AssertionError(suffix)


def _move(src, dst):
    """A file and its companions (ENVI data, .npy sidecar) moved to another name."""
    for a, b in ((src, dst), (src.with_suffix(".raw"), dst.with_suffix(".raw")),
                 (src.with_name(src.name + ".json"), dst.with_name(dst.name + ".json"))):
        if os.path.lexists(a):
            os.replace(a, b)


def _remove(path):
    for p in (path, path.with_suffix(".raw"), path.with_name(path.name + ".json")):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        elif os.path.lexists(p):
            p.unlink()


EXTS = [".nc", ".zarr", ".hdr", ".npy"]


@pytest.mark.parametrize("ext", EXTS)
@pytest.mark.parametrize("how", ["resaved-under-another-name", "copied-under-another-name",
                                 "resaved-then-renamed-to-the-output"])
def test_overwrite_never_replaces_a_users_file_made_from_a_snapcorr_output(tmp_path, ext,
                                                                          how):
    prev = write_cube(output_cube(), tmp_path / f"prev{ext}")
    mine = tmp_path / f"mine{ext}"
    if how == "copied-under-another-name":
        for a, b in ((prev, mine), (prev.with_suffix(".raw"), mine.with_suffix(".raw")),
                     (prev.with_name(prev.name + ".json"), mine.with_name(mine.name + ".json"))):
            if a.is_dir():
                shutil.copytree(a, b)
            elif a.exists():
                shutil.copy(a, b)
        target = mine
    else:
        _resave(prev, mine)
        target = mine
        if how == "resaved-then-renamed-to-the-output":
            _remove(prev)
            _move(mine, prev)
            target = prev
    before = snapshot_bounded(tmp_path)
    with pytest.raises(ValueError, match="move it away or choose another name") as err:
        write_cube(output_cube(2), target, overwrite=True)
    message = only_line(err.value)
    if how == "resaved-then-renamed-to-the-output":
        assert "but not as snapcorr wrote it" in message, message
    else:
        given = f"prev{ext}" + (".json" if ext == ".npy" else "")  # .npy: its sidecar's mark
        assert f"the mark snapcorr gave {given}, copied or saved under this name" in message
    assert snapshot_bounded(tmp_path) == before
    if ext in (".nc", ".zarr"):
        with pytest.raises(ValueError, match="move it away"):
            write_dataset(output_cube(2).to_dataset(), target, overwrite=True)
        assert snapshot_bounded(tmp_path) == before


@pytest.mark.parametrize("ext", EXTS)
def test_overwrite_still_replaces_snapcorrs_own_output(tmp_path, ext):
    path = write_cube(output_cube(), tmp_path / f"c{ext}")
    write_cube(output_cube(2), path, overwrite=True)
    write_cube(output_cube(3), path, overwrite=True)
    np.testing.assert_array_equal(read_cube(path).values, output_cube(3).values)


def test_the_command_line_refuses_a_users_netcdf_made_from_a_result(tmp_path, cli):
    """The reported case: a result re-saved by xarray (attributes kept) under the name
    given as --out with --overwrite."""
    raw = np.random.default_rng(0).uniform(100, 200, (6, 7, 4)).astype(np.float32)
    np.save(tmp_path / "raw.npy", raw)
    np.save(tmp_path / "dark.npy", np.zeros_like(raw))
    np.save(tmp_path / "white.npy", np.full_like(raw, 400.0))
    for name in ("raw", "dark", "white"):
        (tmp_path / f"{name}.npy.json").write_text(json.dumps({"wavelength_nm": WL_OUT}))
    args = ("flatfield", "raw.npy", "--dark", "dark.npy", "--white", "white.npy")
    rc, _, err = cli(*args, "--out", "prev.nc", cwd=tmp_path)
    assert rc == 0, err
    with xr.open_dataset(tmp_path / "prev.nc") as ds:
        var = next(iter(ds.data_vars))
        ds[[var]].load().assign_attrs(note="mine").to_netcdf(tmp_path / "mine.nc")
    before = snapshot_bounded(tmp_path)
    rc, _, err = cli(*args, "--out", "mine.nc", "--overwrite", cwd=tmp_path)
    line = only_line(err)
    assert rc == 1 and "mine.nc exists and is a netCDF file with the mark snapcorr gave " \
        "prev.nc" in line, err
    assert snapshot_bounded(tmp_path) == before
    rc, _, err = cli(*args, "--out", "prev.nc", "--overwrite", cwd=tmp_path)
    assert rc == 0, err  # its own result is replaced


@pytest.mark.parametrize("ext", [".nc", ".zarr", ".hdr", ".npy"])
def test_a_mark_of_an_earlier_version_is_refused(tmp_path, ext):
    """Files whose mark names no file (``snapcorr <version>`` as earlier versions wrote it, or
    ``snapcorr_version`` alone) cannot be told from a re-save by another program that kept
    the attributes: refused, with a message saying so."""
    path = write_cube(output_cube(), tmp_path / f"c{ext}")
    if ext == ".nc":
        import h5py

        with h5py.File(path, "r+") as fh:
            fh.attrs["written_by"] = "snapcorr 0.0.9"
    elif ext == ".zarr":
        doc = json.loads((path / "zarr.json").read_text())
        doc["attributes"]["written_by"] = "snapcorr 0.0.9"
        (path / "zarr.json").write_text(json.dumps(doc))
    elif ext == ".hdr":
        text = path.read_text().splitlines()
        path.write_text("\n".join(x for x in text if not x.startswith("snapcorr written by"))
                        + "\n")
    else:
        side = path.with_name(path.name + ".json")
        meta = json.loads(side.read_text())
        meta["written_by"] = "snapcorr 0.0.9"
        side.write_text(json.dumps(meta))
    before = snapshot_bounded(tmp_path)
    with pytest.raises(ValueError, match="snapcorr's mark of an earlier version, which does "
                                         "not name the file"):
        write_cube(output_cube(2), path, overwrite=True)
    assert snapshot_bounded(tmp_path) == before


def test_reading_is_unchanged_by_the_tied_mark(tmp_path):
    cube = output_cube()
    for ext in EXTS:
        path = write_cube(cube, tmp_path / f"c{ext}")
        back = read_cube(path)
        np.testing.assert_array_equal(back.values, cube.values)
        assert "written_by" not in back.attrs and back.attrs["f_number"] == 2.0
    with xr.open_dataset(tmp_path / "c.nc") as ds:  # plain readers see a plain mark
        assert ds.attrs["written_by"].startswith('snapcorr ') and 'as "c.nc"' in \
            ds.attrs["written_by"]
    from spectral.io import envi

    assert envi.open(str(tmp_path / "c.hdr")).load().shape == (5, 6, 4)


@pytest.mark.parametrize("kind", ["toml", "png"])
@pytest.mark.parametrize("how", ["copied", "edited"])
def test_pngs_and_tomls_are_replaced_only_as_the_file_snapcorr_wrote(tmp_path, kind, how):
    write = snapcorr_toml if kind == "toml" else snapcorr_png
    prev = tmp_path / f"prev.{kind}"
    write(prev)
    if how == "copied":
        target = tmp_path / f"mine.{kind}"
        shutil.copy(prev, target)
        found = f"the mark snapcorr gave prev.{kind}, copied or saved under this name"
    else:
        target = prev
        if kind == "toml":
            target.write_text(target.read_text().replace('"x"', '"my own lens"'))
        else:
            from PIL import Image, PngImagePlugin

            with Image.open(prev) as im:
                info = PngImagePlugin.PngInfo()
                info.add_text("Software", im.info["Software"])  # an editor keeping the text
                im.convert("L").save(target, pnginfo=info)
        found = "but not as snapcorr wrote it"
    before = snapshot_bounded(tmp_path)
    with pytest.raises(ValueError, match=found):
        _io.check_replaceable(target)
    with pytest.raises(ValueError, match=found):
        write(target, overwrite=True) if kind == "toml" else write(target)
    assert snapshot_bounded(tmp_path) == before
    write(prev, overwrite=True) if kind == "toml" and how == "copied" else None
