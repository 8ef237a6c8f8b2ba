"""A package's public names load at their first use, and only then."""

import subprocess
import sys

import pytest


def _fresh(code):
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    return res.stdout.split()


def test_a_name_is_loaded_when_first_asked_for_and_kept():
    before, after, same = _fresh(
        "import sys, snapcorr.files as f\n"
        "print('snapcorr.files.api' in sys.modules)\n"
        "r = f.read_cube\n"
        "print('snapcorr.files.api' in sys.modules, r is f.read_cube)")
    assert (before, after, same) == ("False", "True", "True")


def test_an_unknown_name_is_an_attribute_error_and_dir_lists_the_lazy_ones():
    import snapcorr.cube
    import snapcorr.files

    with pytest.raises(AttributeError, match=r"'snapcorr\.files' has no attribute 'nope'"):
        snapcorr.files.nope  # noqa: B018
    assert {"read_cube", "check_outputs"} <= set(dir(snapcorr.files))
    assert {"Sensor", "demosaic", "flatfield"} <= set(dir(snapcorr.cube))
    assert snapcorr.cube.read_cube is snapcorr.files.read_cube
