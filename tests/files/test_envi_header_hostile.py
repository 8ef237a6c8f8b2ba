"""ENVI headers that lie or overwhelm: bounded before they are parsed, parsed in one pass, and
what they say of the values (gains, bad bands, no-data value, units) either applied or refused.
Headers are written here by hand, next to raw float32 data."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from snapcorr.cube import read_cube
from snapcorr.files.api import read_cube_and_mask

WL = "{500.0, 550.0, 600.0, 650.0}"


def _envi(tmp_path, extra="", name="c", data=None):
    data = (np.random.default_rng(4).random((6, 5, 4)).astype(np.float32)
            if data is None else data)
    np.ascontiguousarray(data.transpose(2, 0, 1)).tofile(tmp_path / f"{name}.img")  # bsq
    hdr = tmp_path / f"{name}.hdr"
    hdr.write_text("ENVI\nsamples = 5\nlines = 6\nbands = 4\nheader offset = 0\n"
                   "file type = ENVI Standard\ndata type = 4\ninterleave = bsq\nbyte order = 0\n"
                   f"wavelength units = Nanometers\nwavelength = {WL}\n{extra}")
    return hdr, data


def test_a_header_of_many_keys_is_checked_for_repeats_in_one_pass(tmp_path):
    """40 000 extra keys (660 kB): the check for repeated keys popped each line from the
    front of a list and counted every key among all: 65 s for the whole command, 2.4 s now
    (its speed is not timed here). A key repeated among 20 000, inside and after braces, is
    still found."""
    keys = "".join(f"key{i} = {i}\n" for i in range(20000))
    hdr, _ = _envi(tmp_path, keys + "band names = {a,\n b,\n c, d}\nkey19999 = 5\n")
    with pytest.raises(ValueError, match=r"gives 'key19999' more than once"):
        read_cube(hdr)
    hdr, _ = _envi(tmp_path, keys + "band names = {a,\n key3 = 1,\n c, d}\n", name="ok")
    read_cube(hdr)  # inside braces: no key


def test_a_header_larger_than_any_is_refused_unread(tmp_path):
    hdr, _ = _envi(tmp_path)
    with open(hdr, "a") as f:
        f.write("description = {" + "x" * (9 * 2**20) + "}\n")
    with pytest.raises(ValueError, match=r"the header holds 9\.0 MiB, more than any ENVI header"):
        read_cube(hdr)


@pytest.mark.parametrize(("extra", "words"), [
    ("data gain values = {1, 0, 1, 1}\n", r"'data gain values' is 0 for band 1"),
    ("bbl = {0, 0, 0, 0}\n", r"'bbl' marks every band bad"),
])
def test_values_the_header_makes_meaningless_are_refused(tmp_path, extra, words):
    """A gain of 0 made a band all its offset, bbl all 0 a cube of NaN, both without a word."""
    hdr, _ = _envi(tmp_path, extra)
    with pytest.raises(ValueError, match=words):
        read_cube(hdr)


def test_the_data_ignore_value_is_masked(tmp_path):
    """A no-data value the header states was read as data by correct: it is now in the mask
    read with the cube (the cube keeps the stored values)."""
    data = np.random.default_rng(4).random((6, 5, 4)).astype(np.float32)
    data[2, 3, 1] = data[0, 0, 0] = -9999.0
    hdr, _ = _envi(tmp_path, "data ignore value = -9999\n", data=data)
    cube, mask = read_cube_and_mask(hdr)
    assert mask is not None and int(mask.sum()) == 2
    assert bool(mask[2, 3, 1]) and bool(mask[0, 0, 0]) and float(cube[2, 3, 1]) == -9999.0


def test_wavelengths_in_units_that_are_no_length_are_said_when_the_sensor_gives_them(tmp_path):
    """units GHz: refused without wavelengths given; with the sensor's, the file's are not
    read, and now that is said (it was silent); ENVI's 'Index' (band numbers) is no news."""
    hdr, _ = _envi(tmp_path)
    hdr.write_text(hdr.read_text().replace("Nanometers", "GHz"))
    with pytest.raises(ValueError, match="units 'GHz' are not a length"):
        read_cube(hdr)
    with pytest.warns(UserWarning, match="units 'GHz' are not a length, so its wavelengths are "
                      "not read: the sensor's are used"):
        cube = read_cube(hdr, wavelength_nm=[501.0, 551.0, 601.0, 651.0])
    assert cube.wavelength.values[0] == 501.0
    hdr.write_text(hdr.read_text().replace("GHz", "Index"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_cube(hdr, wavelength_nm=[501.0, 551.0, 601.0, 651.0])


def test_a_results_copy_of_its_raw_ignore_value_masks_nothing(tmp_path):
    """A flat-field result keeps its raw cube's attributes, its ENVI no-data value among
    them: read for correct, every reflectance equal to that number (0 where raw == dark)
    was masked. Only an ENVI header's own value masks."""
    from snapcorr.cube import flatfield, make_cube, write_dataset

    raw = make_cube(np.full((4, 4, 2), 100, np.uint16), [500.0, 600.0])
    raw.attrs["data_ignore_value"] = 0
    ref = [make_cube(np.full((4, 4, 2), v, np.float32), [500.0, 600.0]) for v in (100.0, 900.0)]
    write_dataset(flatfield(raw, *ref), tmp_path / "ff.nc")
    cube, mask = read_cube_and_mask(tmp_path / "ff.nc")
    assert float(cube.max()) == 0.0 and int(mask.sum()) == 0
