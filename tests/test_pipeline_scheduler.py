"""A command's computations run on dask's threads without importing ``distributed``: named by
a string, dask's scheduler imports it (0.2-0.3 s) at a process's first compute."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def test_flatfield_demosaic_to_zarr_does_not_import_distributed(tmp_path):
    rng = np.random.default_rng(0)
    np.save(tmp_path / "raw.npy", rng.integers(100, 3000, (32, 32)).astype(np.uint16))
    np.save(tmp_path / "dark.npy", np.full((32, 32), 64, np.uint16))
    np.save(tmp_path / "white.npy", np.full((32, 32), 3500, np.uint16))
    code = textwrap.dedent(f"""
        import sys
        from snapcorr.cli import main
        t = {str(tmp_path)!r}
        rc = main(["flatfield", t + "/raw.npy", "--dark", t + "/dark.npy", "--white",
                   t + "/white.npy", "--sensor", "mosaic_4x4_vis", "--sensor-origin-px",
                   "400,800", "--demosaic", "ri", "--out", t + "/ff.zarr", "--quiet"])
        print(rc, "dask" in sys.modules, "distributed" in sys.modules)
    """)
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert res.stdout.split()[-3:] == ["0", "True", "False"], res.stderr[-2000:]
    assert (tmp_path / "ff.zarr").is_dir()
