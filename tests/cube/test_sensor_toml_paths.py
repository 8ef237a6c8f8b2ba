"""A sensor TOML naming a vendor file: its n_eff line, and a relative vendor_file that loads
the right file wherever the TOML is read from (a symlinked folder, a decoy beside the link)."""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest
import vendorfiles

from snapcorr.cube import Sensor


@pytest.fixture
def layout(tmp_path):
    """``vend/imec_4x4.xml`` (the real file), ``real/sub`` (a folder), ``link`` -> ``real/sub``,
    and a decoy ``real/vend/imec_4x4.xml`` (another sensor) where a relative path computed
    on the link's name would land."""
    (tmp_path / "real" / "sub").mkdir(parents=True)
    (tmp_path / "vend").mkdir()
    (tmp_path / "real" / "vend").mkdir()
    fx = vendorfiles.imec_4x4()
    real = vendorfiles.write_older(tmp_path / "vend" / "imec_4x4.xml",
                                   dataclasses.replace(fx, size=(96, 128), area=(0, 0, 96, 128)))
    vendorfiles.write_older(tmp_path / "real" / "vend" / "imec_4x4.xml",
                            dataclasses.replace(fx, size=(48, 64), area=(0, 0, 48, 64)))
    try:
        os.symlink(tmp_path / "real" / "sub", tmp_path / "link")
    except OSError:
        pytest.skip("no symlinks here")
    return tmp_path, real


def test_a_toml_written_into_a_symlinked_folder_loads_the_file_it_names(layout):
    d, real = layout
    sensor = Sensor.load(real)
    out = sensor.save(d / "link" / "out.toml")
    back = Sensor.load(out)
    assert os.path.samefile(back.vendor_file, real)
    assert back.size_px == sensor.size_px == (96, 128)  # not the decoy's 48 x 64
    assert np.array_equal(back.responses.curves, sensor.responses.curves)


def test_the_n_eff_line_to_fill_in_names_the_command(layout, cli):
    d, real = layout
    res = cli("sensor", real, "--toml", d / "link" / "s.toml")
    assert res.returncode == 0, res.stderr
    assert "n_eff line is commented out" in res.stdout
    text = (d / "link" / "s.toml").read_text()
    assert "\n# n_eff = 1.7\n" in text and "snapcorr pupil --fit-n-eff" in text
    assert Sensor.load(d / "link" / "s.toml").n_eff is None
    # filled in, as --sensor-out writes it: the value loads, the note stays
    fitted = dataclasses.replace(Sensor.load(real), n_eff=(1.83,) * 16)
    fitted.save(d / "link" / "fitted.toml")
    text = (d / "link" / "fitted.toml").read_text()
    assert "\nn_eff = 1.83\n" in text and "# n_eff = 1.7" not in text
    assert Sensor.load(d / "link" / "fitted.toml").n_eff == (1.83,) * 16


def test_a_toml_moved_away_from_its_vendor_file_says_where_it_looked(layout, cli):
    """A sensor TOML copied to another folder: its relative vendor_file is not found there.
    The message names the TOML, the vendor_file as written and the path it was looked for at
    (it gave only '../vend/imec_4x4.xml', which the user cannot place)."""
    d, real = layout
    out = Sensor.load(real).save(d / "real" / "sub" / "s.toml")
    moved = d / "elsewhere"
    moved.mkdir()
    (moved / "s.toml").write_text(out.read_text())
    with pytest.raises(FileNotFoundError) as info:
        Sensor.load(moved / "s.toml")
    text = str(info.value)
    assert str(moved / "s.toml") in text and "vendor_file" in text
    import tomllib

    vendor = tomllib.loads(out.read_text())["sensor"]["vendor_file"]
    assert repr(vendor) in text and f"looked for {(moved / vendor).resolve()}," in text
    res = cli("sensor", moved / "s.toml")
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert "looked for" in res.stderr


@pytest.mark.parametrize("kind", ["loop", "folder"])
def test_a_vendor_file_that_is_no_file_is_one_line(tmp_path, kind):
    """A vendor_file that is a loop of symbolic links raised pathlib's RuntimeError (a
    traceback from the command line); now it is refused naming the TOML and the link."""
    if kind == "loop":
        os.symlink(tmp_path / "b.xml", tmp_path / "a.xml")
        os.symlink(tmp_path / "a.xml", tmp_path / "b.xml")
    else:
        (tmp_path / "a.xml").mkdir()
    toml = tmp_path / "s.toml"
    toml.write_text('[sensor]\nvendor_file = "a.xml"\n')
    words = "a loop of symbolic links" if kind == "loop" else "is a folder"
    with pytest.raises(ValueError, match=rf"s\.toml: its vendor_file 'a\.xml': .*{words}"):
        Sensor.load(toml)
