"""One effective index per band where the target pins it, on a mosaic sensor with measured
responses whose bands truly have different indices.

The cubes are made here, not by snapcorr, as in ``test_measured_target.py``: the real imec
4 x 4 VIS responses behind a band-pass, written to a vendor file and read back element by
element (``mosaicsim.read_older``); every band's response at a pixel is the sum over the paper
lens's vignetted pupil, sampled point by point, of its whole curve scaled by each ray with the
band's own index, ``T_b(lambda / a_b)``, ``a_b = sqrt(1 - sin^2 phi / n_b^2)``, times the
band-pass, which does not move (``mosaicsim.responses``). The target is a neodymium glass from a
public library (``mosaicsim.neodymium_glass``: colour-science's measured light sources):
its absorption bands at 510-530 and 570-600 nm fall in a few of the sixteen bands, so the data
pin some bands' indices and not others.
"""

from __future__ import annotations

import functools

import mosaicsim
import numpy as np
import pytest
from conftest import PAPER_LENS, PAPER_TRUTH

from calibrate.pupil.test_measured_target import CENTER_RC, PITCH_UM, SIZE, X_MM, vendor_file
from snapcorr.calibrate import locate_pupil
from snapcorr.cube import Sensor, mosaic_to_cube


def true_n_eff(peak_nm):
    """The bands' indices: two families of cavities (1.78 below 585 nm, 1.95 above), each
    band a little off its family's value."""
    peak = np.asarray(peak_nm, float)
    wobble = 0.02 * np.sin(peak / 7.0)
    return np.where(peak < 585.0, 1.78, 1.95) + wobble


def straight_line(lam):
    """Nearly featureless: a reflectance rising in a straight line, 0.45 -> 0.75 over 470-900 nm."""
    return 0.45 + 0.30 * (np.asarray(lam, float) - 470.0) / 430.0


TARGETS = {"neodymium glass": mosaicsim.neodymium_glass, "straight line": straight_line}


@functools.cache
def band_table(folder, f_number, n_nodes, target="neodymium glass"):
    """Every band's flat-fielded value (pattern order) at ``n_nodes`` distances, even in d^2."""
    _, mf = vendor_file(folder)
    return mosaicsim.radial_table(mf, PAPER_TRUTH, f_number, TARGETS[target](mf.grid),
                                  true_n_eff(mf.peaks_nm), center_rc=CENTER_RC, size=SIZE,
                                  pitch_um=PITCH_UM, n_nodes=n_nodes)


def cubes(folder, *, noise, seed, n_nodes=96, f_numbers=(1.4, 8.0), target="neodymium glass"):
    path, _ = vendor_file(folder)
    sensor = Sensor.load(path)
    rng = np.random.default_rng(seed)
    out = {}
    for f in f_numbers:
        d2n, table = band_table(folder, f, n_nodes, target)
        raw = mosaicsim.radial_frame(d2n, table, center_rc=CENTER_RC, size=SIZE,
                                     pitch_um=PITCH_UM)
        out[f] = mosaic_to_cube(raw + rng.normal(0.0, noise, SIZE), sensor)
    return out, sensor


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("per_band")


def fit(folder, seed, *, noise=0.001, n_nodes=96):
    data, sensor = cubes(folder, noise=noise, seed=seed, n_nodes=n_nodes)
    return locate_pupil(data, sensor, lens=PAPER_LENS, fit_n_eff=True, n_bins=16), sensor


@pytest.mark.slow  # three fits of the 16-band sensor: about a minute and a half
def test_each_pinned_band_has_its_own_index_and_the_others_are_said_not_pinned(folder):
    """Bands the glass's features pin get their own index, within 1 % with errors that
    cover; the others are named as not pinned and do not carry a confident number."""
    from snapcorr.calibrate.pupil.index import N_EFF_BAND_STDERR

    z_pinned, z_x = [], []
    for seed in (1, 2, 3):
        got, sensor = fit(folder, seed)
        n_true = true_n_eff(sensor.cwl_nm)
        assert got.n_eff_fitted == "per band"
        assert abs(got.exit_pupil_mm - X_MM) < 0.01 * X_MM
        z_x.append((got.exit_pupil_mm - X_MM) / got.exit_pupil_stderr_mm)
        err = np.asarray(got.n_eff_stderr)
        pinned = err < N_EFF_BAND_STDERR * got.n_eff
        # the glass's bands at 570-600 nm pin the bands about them, not those at 465-570 nm
        assert 1 <= pinned.sum() <= 8, err / got.n_eff
        assert not pinned[np.asarray(sensor.cwl_nm) < 560].any()
        assert np.all(np.abs(got.n_eff[pinned] / n_true[pinned] - 1) < 0.01)
        z_pinned += list((got.n_eff[pinned] - n_true[pinned]) / err[pinned])
        note = next(t for t in got.notes if t.startswith("n_eff one per band"))
        assert "not pinned" in note
        for c in np.asarray(sensor.cwl_nm)[~pinned]:
            assert f"{c:.4g}" in note.split("not pinned")[1]
        # a band not pinned is not given a number known to 1 %: its error is at least the
        # shared model's widened by the pinned bands' scatter, and it covers the truth
        assert np.all(err[~pinned] > N_EFF_BAND_STDERR * got.n_eff[~pinned])
        assert np.all(np.abs(got.n_eff[~pinned] - n_true[~pinned]) < 4 * err[~pinned])
    z = np.array(z_pinned)
    print("z of the pinned bands:", np.round(z, 2).tolist(), "z of x:", np.round(z_x, 2).tolist())
    assert 0.5 < np.sqrt(np.mean(z**2)) < 2.0, z
    assert np.sqrt(np.mean(np.square(z_x))) < 2.0, z_x


@pytest.mark.slow  # the coarse scan before the refusal: about 30 s
def test_a_straight_line_is_refused_before_the_fit_on_measured_responses(folder):
    """Nearly featureless: the prediction from the cubes themselves refuses it in one line, as
    the command line does by default (``--tolerance-nm`` 0.05 nm)."""
    from snapcorr.calibrate import ImpreciseTargetError
    from snapcorr.calibrate.pupil.precision import DEFAULT_TOLERANCE_NM

    data, sensor = cubes(folder, noise=0.005, seed=4, n_nodes=48, target="straight line")
    said = []
    with pytest.raises(ImpreciseTargetError, match="cannot pin x and n_eff") as err:
        locate_pupil(data, sensor, lens=PAPER_LENS, fit_n_eff=True, n_bins=16,
                     tolerance_nm=DEFAULT_TOLERANCE_NM, report=said.append)
    assert "\n" not in str(err.value) and said[0].startswith("predicted:")
