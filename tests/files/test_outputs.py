"""check_outputs: a command's outputs checked before any long work."""

import os

import pytest
from hostile import read_only

from snapcorr.files.outputs import check_outputs
from snapcorr.files.toml import write_toml


def _check(outputs, inputs=(), *, overwrite=False, suffixes=None, protected=()):
    suffixes = suffixes or [(".nc", ".zarr")] * len(outputs)
    check_outputs(outputs, inputs, overwrite=overwrite, suffixes=suffixes, protected=protected)


def test_a_new_output_in_a_folder_passes(tmp_path):
    _check([tmp_path / "out.nc", None])


def test_an_output_that_is_an_input_is_refused(tmp_path):
    src = tmp_path / "cube.nc"
    src.write_bytes(b"x")
    with pytest.raises(ValueError, match="is also an input"):
        _check([src], [src])


def test_an_output_inside_an_input_folder_is_refused(tmp_path):
    store = tmp_path / "in.zarr"
    store.mkdir()
    with pytest.raises(ValueError, match="holds or lies in the input"):
        _check([store / "x.nc"], [store])


def test_a_hard_link_to_an_input_is_refused(tmp_path):
    src = tmp_path / "cube.nc"
    src.write_bytes(b"x")
    os.link(src, tmp_path / "link.nc")
    with pytest.raises(ValueError, match="is also an input"):
        _check([tmp_path / "link.nc"], [src], overwrite=True)
    # without overwrite too, and whatever its suffix: the link is the input, not an output
    # that exists ("exists", or "a TOML file snapcorr did not write", named the wrong cause)
    os.link(src, tmp_path / "link.toml")
    for overwrite in (False, True):
        with pytest.raises(ValueError, match="is also an input"):
            _check([tmp_path / "link.toml"], [src], overwrite=overwrite,
                   suffixes=[(".toml",)])


def test_the_data_file_of_an_envi_input_is_refused(tmp_path):
    hdr = tmp_path / "cube.hdr"
    hdr.write_text("ENVI\n")
    (tmp_path / "cube.img").write_bytes(b"\0")
    with pytest.raises(ValueError, match="is also an input"):
        _check([tmp_path / "cube.img"], [hdr], overwrite=True, suffixes=[(".img",)])


@pytest.mark.parametrize("given, belongs", [("cube.img", "cube.hdr"), ("cube.npy", "cube.npy.json"),
                                            ("cube.HDR", "cube.raw")])
def test_the_files_of_every_input_format_are_refused(tmp_path, given, belongs):
    """A file that belongs to an input (from the format registry) is never an output."""
    (tmp_path / given).write_bytes(b"\0")
    with pytest.raises(ValueError, match="is also an input"):
        _check([tmp_path / belongs], [tmp_path / given], overwrite=True,
               suffixes=[(os.path.splitext(belongs)[1].lower(),)])


def test_an_input_of_no_cube_format_is_checked_as_itself(tmp_path):
    lens = tmp_path / "lens.toml"
    lens.write_text("[lens]\n")
    _check([tmp_path / "lens.nc"], [lens])
    with pytest.raises(ValueError, match="is also an input"):
        _check([lens], [lens], suffixes=[(".toml",)], overwrite=True)


def test_two_outputs_one_inside_the_other_are_refused(tmp_path):
    with pytest.raises(ValueError, match="one lies in the other"):
        _check([tmp_path / "a.zarr", tmp_path / "a.zarr" / "b.nc"])


def test_a_wrong_suffix_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"must end in \.toml or \.png"):
        _check([tmp_path / "x.nc"], suffixes=[(".toml", ".png")])


def test_an_existing_output_needs_overwrite(tmp_path):
    out = tmp_path / "lens.toml"
    write_toml(out, {"lens": {"name": "a"}})
    with pytest.raises(FileExistsError, match="pass overwrite=True"):
        _check([out], suffixes=[(".toml",)])
    _check([out], suffixes=[(".toml",)], overwrite=True)


def test_overwrite_refuses_a_toml_snapcorr_did_not_write(tmp_path):
    out = tmp_path / "lens.toml"
    out.write_text("[lens]\n")
    with pytest.raises(ValueError, match="did not write"):
        _check([out], suffixes=[(".toml",)], overwrite=True)


def test_a_folder_is_never_replaced_by_a_file(tmp_path):
    (tmp_path / "x.nc").mkdir()
    with pytest.raises(ValueError, match="is a folder"):
        _check([tmp_path / "x.nc"], overwrite=True)


def test_an_output_without_its_folder_is_refused(tmp_path):
    with pytest.raises(ValueError, match="create it first"):
        _check([tmp_path / "no" / "x.nc"])


def test_an_output_in_a_read_only_folder_is_refused_by_its_option(tmp_path, monkeypatch):
    (tmp_path / "ro").mkdir()
    read_only(monkeypatch, tmp_path / "ro")
    with pytest.raises(ValueError, match=r"--plot .*x\.png: cannot write in the folder"):
        check_outputs([tmp_path / "x.nc", tmp_path / "ro" / "x.png"], [], overwrite=False,
                      suffixes=[(".nc",), (".png",)], names=["--out", "--plot"])
    assert os.listdir(tmp_path / "ro") == []  # the probe left nothing behind


def test_the_probe_leaves_nothing_behind(tmp_path):
    _check([tmp_path / "x.nc", tmp_path / "y.zarr"])
    assert os.listdir(tmp_path) == []


def test_a_library_write_to_a_read_only_folder_names_the_target(tmp_path, monkeypatch):
    import numpy as np

    from snapcorr.cube import make_cube, write_cube

    (tmp_path / "ro").mkdir()
    read_only(monkeypatch, tmp_path / "ro")
    cube = make_cube(np.ones((2, 3, 4), np.float32), [500.0, 520.0, 540.0, 560.0])
    for name in ("c.nc", "c.zarr", "c.hdr"):
        with pytest.raises(ValueError, match="cannot write in the folder") as err:
            write_cube(cube, tmp_path / "ro" / name)
        message = str(err.value)  # an ENVI pair: its header or its data file
        assert "/ro/c." in message and "/." not in message, message


@pytest.mark.parametrize("protected", ["folder", ["folder"]])
def test_a_protected_file_is_never_replaced(tmp_path, protected):
    folder = tmp_path / "bundled"
    folder.mkdir()
    (folder / "lens.toml").write_text("[lens]\n")
    given = folder if protected == "folder" else [folder]
    with pytest.raises(ValueError, match="bundled files"):
        _check([folder / "lens.toml"], suffixes=[(".toml",)], overwrite=True,
               protected=given)
    _check([folder / "new.toml"], suffixes=[(".toml",)], protected=given)
