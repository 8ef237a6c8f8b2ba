"""Record the compiled passes of ``snapcorr.correct`` (resampling and harmonising) on small
random cubes, as a reference for later versions of those passes.

Generated from commit 2a152ec (before the per-pixel pass shared by ``resample.py`` and
``harmonise.py`` was factored into ``snapcorr/correct/_spectra.py``). Run it against a
checkout of that commit to regenerate:

    git worktree add /tmp/snap_ref 2a152ec
    NUMBA_CACHE_DIR=$(mktemp -d) PYTHONPATH=/tmp/snap_ref \
        python tests/data/make_correct_kernels_reference.py

(with a fresh Numba cache: at that commit the last bit of the float64 harmonised values
depended on which pass was compiled first, the direct one here).

It writes ``correct_kernels_reference.npz`` next to itself: the seeded inputs and the outputs
of ``resample_to_nominal`` (the general pass, float64 and float32, with corrected wavelengths
that cross; the evenly spaced float32 pass) and of ``harmonise_spectra`` (the direct pass,
float64 and float32, some widenings zero; the tabulated Snapscan pass, float32 and
float64).
``tests/correct/test_harmonise_kernels.py`` checks that the current passes reproduce them. The
direct harmonising values (``harmonise_64``, ``harmonise_32``) record a fault of that commit: where
a value's Gaussian was wider than the last one's, the segments it reached back over were left
out (67 of the 400 values); the test compares them only elsewhere, and the direct pass
everywhere against a brute-force average.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from snapcorr.correct.harmonise import harmonise_spectra
from snapcorr.correct.resample import resample_to_nominal


def inputs(seed=7):
    rng = np.random.default_rng(seed)
    ny, nx, nb, m = 4, 5, 20, 3
    uneven = np.sort(rng.uniform(450.0, 900.0, nb))
    even = np.linspace(470.0, 900.0, nb)
    column = rng.integers(0, m, nb)
    return {
        "data": rng.uniform(-1.0, 2.0, (ny, nx, nb)),
        "cwl_uneven": uneven,
        "cwl_even": even,
        # columns of different scales: neighbouring bands' corrected wavelengths cross
        "scale": rng.uniform(0.975, 1.01, (ny, nx, m)),
        "column": column,
        "scale_one": rng.uniform(0.975, 1.0, (ny, nx, 1)),
        "sigma": np.where(rng.random((ny, nx, nb)) < 0.3, 0.0,
                          rng.uniform(0.0, 12.0, (ny, nx, nb))),
        "cra": rng.uniform(0.0, 20.0, (ny, nx)),
        "nodes": np.linspace(0.0, 20.0, 11),
        "node_scale": np.linspace(1.0, 0.999, 11),  # some values tabulated, some direct
        "node_sigma": np.abs(rng.normal(3.0, 2.0, (11, nb))) * (rng.random((11, nb)) > 0.2),
    }


def outputs(x):
    d64, d32 = x["data"], x["data"].astype(np.float32)
    one = np.zeros(x["data"].shape[2], int)
    return {
        "resample_64": resample_to_nominal(d64, x["scale"], x["column"], x["cwl_uneven"]),
        "resample_32": resample_to_nominal(d32, x["scale"], x["column"], x["cwl_uneven"]),
        "resample_uniform_32": resample_to_nominal(d32, x["scale_one"], one, x["cwl_even"]),
        "harmonise_64": harmonise_spectra(d64, x["scale"], x["column"], x["cwl_uneven"],
                                          x["sigma"]),
        "harmonise_32": harmonise_spectra(d32, x["scale"], x["column"], x["cwl_uneven"],
                                          x["sigma"]),
        **{f"harmonise_tabulated_{bits}": harmonise_spectra(
            d, x["scale_one"], one, x["cwl_even"], cra=x["cra"], nodes=x["nodes"],
            node_scale=x["node_scale"], node_sigma=x["node_sigma"])
           for bits, d in (("32", d32), ("64", d64))},
    }


if __name__ == "__main__":
    x = inputs()
    np.savez_compressed(Path(__file__).with_name("correct_kernels_reference.npz"), **x,
                        **outputs(x))
