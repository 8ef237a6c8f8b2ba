"""`snapcorr shift`: a wavelength not in nm is refused by its option's name; an angle past the
cut-off says so and gives the cut-off angle."""

from __future__ import annotations

import re

import pytest
from hostile import LENS, assert_refused


@pytest.mark.parametrize("value", ["0.7", "7e-7"], ids=["micrometres", "metres"])
def test_shift_refuses_a_wavelength_not_in_nm(value, cli):
    rc, out, err = cli("shift", "--f-number", "1.4", "--cra", "5", "--cwl-nm", value)
    assert_refused(rc, err, "--cwl-nm")
    assert "cra_deg" not in out


def test_shift_past_the_cutoff_says_so_and_gives_the_angle(cli):
    from snapcorr import Lens

    cutoff = float(Lens.load(LENS).cutoff_cra_deg(1.4))
    rc, _, err = cli("shift", "--cra", "45", "--f-number", "1.4")
    line = assert_refused(rc, err, "cut")
    numbers = [float(v) for v in re.findall(r"\d+\.\d+", line)]
    assert any(abs(v - cutoff) < 0.051 for v in numbers), f"no {cutoff:.2f} in: {line}"
