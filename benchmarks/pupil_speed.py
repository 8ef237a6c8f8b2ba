"""How long the exit-pupil fit takes on a whole vendor sensor with measured responses.

The bundled ``imec_5x5_nir`` sensor (1088 x 2048 pixels of 5.5 um, 25 bands, measured curves
behind their band-pass, 400-1000 nm) behind the paper lens (x = 21 mm, one circle), the
rare-earth glass of ``tests/oracles/spectralsim.py`` at f/1.4 and f/8, n_eff 1.85 (the file says
1.8: fitted from there), 0.5 % noise, the optical centre found. The raw frames come from
``tests/oracles/mosaicsim.py`` (every pupil ray scales each band's whole curve, the band-pass does
not move; it does not import snapcorr) at 96 distances from the axis, interpolated in ``d^2`` to
every pixel, and are split with ``mosaic_to_cube`` into 216 x 409 x 25 cubes.

``--case 4x4``: the frames of ``tests/calibrate/pupil/test_measured_target.py`` instead (the real 4
x 4 VIS curves in a vendor file, 320 x 640 pixels of 17.6 um, 80 x 160 x 16 cubes).

``python -m benchmarks.pupil_speed [--case 5x5|4x4] [--before CHECKOUT] [--n-bins N]`` fits
them with this checkout's snapcorr and, with ``--before``, with another checkout's (each in
its own process, one after the other, the same cubes), and prints each fit's x, n_eff, their
errors, CPU and wall seconds and the share of the machine's CPUs other processes used
meanwhile.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
X_MM = 21.0
N_EFF = 1.85
CENTER_RC = (547.4, 1015.8)
F_NUMBERS = (1.4, 8.0)
NOISE = 0.005


def frames(folder, seed=1, n_nodes=96):
    """The raw frames (saved in ``folder``) of the glass at :data:`F_NUMBERS`."""
    sys.path.insert(0, str(ROOT / "tests"))
    sys.path.insert(0, str(ROOT / "tests" / "oracles"))
    import mosaicsim
    import spectralsim as sim
    from conftest import PAPER_TRUTH

    from snapcorr import data
    from snapcorr.cube import Sensor

    sensor = Sensor.load(data.sensor_path("imec_5x5_nir"))
    R = sensor.responses  # the file's curves, as numbers: the forward model is mosaicsim's
    mf = mosaicsim.MosaicFile(np.asarray(R.wavelength_nm, float), np.asarray(R.curves, float),
                              np.asarray(R.system, float), np.zeros((1, sensor.n_bands)),
                              np.zeros(1), 10.0, np.asarray(sensor.cwl_nm, float))
    rows, cols = sensor.size_px
    pitch = sensor.pixel_pitch_um * 1e-3
    r_max2 = (max(CENTER_RC[0], rows - CENTER_RC[0]) ** 2
              + max(CENTER_RC[1], cols - CENTER_RC[1]) ** 2) * pitch**2
    d2n = np.linspace(0.0, r_max2 * 1.001, n_nodes)
    rho = sim.rare_earth_glass(mf.grid)[None]
    rr, cc = np.mgrid[0:rows, 0:cols]
    d2 = ((rr - CENTER_RC[0]) ** 2 + (cc - CENTER_RC[1]) ** 2) * pitch**2
    tr, tc = sensor.mosaic_shape
    r0, c0 = sensor.tile_origin_px
    band = np.empty((rows, cols), int)
    for b, (r, c) in enumerate(np.asarray(sensor.band_offset)):
        band[(r + r0) % tr::tr, (c + c0) % tc::tc] = b
    rng = np.random.default_rng(seed)
    paths = {}
    for f in F_NUMBERS:
        table = np.array([mosaicsim.band_values(mosaicsim.responses(
            mf, PAPER_TRUTH, f, np.rad2deg(np.arctan(np.sqrt(d) / X_MM)), N_EFF,
            nodes=(16, 8)), rho)[0] for d in d2n]).T
        raw = np.empty((rows, cols))
        for b in range(table.shape[0]):
            m = band == b
            raw[m] = np.interp(d2[m], d2n, table[b])
        raw += rng.normal(0.0, NOISE, raw.shape)
        paths[f] = folder / f"glass_f{f:g}.npy"
        np.save(paths[f], raw)
    return paths


_FIT = """
import json, sys, time
sys.path = [p for p in sys.path if p not in ("", ".")]  # the checkout's snapcorr, not cwd's
sys.path.insert(0, {tests!r})
import snapcorr
import numpy as np
from benchmarks import cpu_seconds, others_share
from conftest import PAPER_LENS
from snapcorr import data
from snapcorr.calibrate import locate_pupil
from snapcorr.cube import Sensor, mosaic_to_cube
sensor = Sensor.load({sensor!r})
cubes = {{f: mosaic_to_cube(np.load(p), sensor) for f, p in {paths!r}.items()}}
start = cpu_seconds()
got = locate_pupil(cubes, sensor, lens=PAPER_LENS, fit_n_eff=True, n_bins={n_bins})
end = cpu_seconds()
print(json.dumps(dict(x_mm=got.exit_pupil_mm, x_stderr_mm=got.exit_pupil_stderr_mm,
    n_eff=float(got.n_eff[0]), n_eff_stderr=float(got.n_eff_stderr[0]),
    mode=got.n_eff_fitted, chi2_red=got.chi2_red, cpu_s=end[1] - start[1],
    wall_s=end[2] - start[2], others_share=others_share(start),
    cube_shape=list(next(iter(cubes.values())).shape), snapcorr=snapcorr.__file__)))
"""


def fit(checkout, paths, n_bins, sensor=None):
    """One fit in its own process with ``checkout``'s snapcorr (this checkout's benchmarks)."""
    from snapcorr import data

    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(checkout), str(ROOT)]))
    code = _FIT.format(tests=str(ROOT / "tests"), paths={f: str(p) for f, p in paths.items()},
                       n_bins=n_bins, sensor=str(sensor or data.sensor_path("imec_5x5_nir")))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=False)
    if out.returncode:
        raise RuntimeError(out.stderr)
    return json.loads(out.stdout.strip().splitlines()[-1])


def frames_4x4(folder, seed=1):
    """``tests/calibrate/pupil/test_measured_target.py``'s frames (the real 4 x 4 VIS curves in a
    vendor file, 320 x 640 pixels of 17.6 um, n_eff 1.85) and the file."""
    sys.path.insert(0, str(ROOT / "tests"))
    sys.path.insert(0, str(ROOT / "tests" / "oracles"))
    from calibrate.pupil import test_measured_target as tpm

    path, _ = tpm.vendor_file(folder)
    rng = np.random.default_rng(seed)
    paths = {}
    for f in F_NUMBERS:
        paths[f] = folder / f"glass4x4_f{f:g}.npy"
        np.save(paths[f], tpm.raw_frame(folder, "rare_earth_glass", f, NOISE, rng))
    return paths, path


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", type=Path, help="another checkout to time on the same cubes")
    ap.add_argument("--n-bins", type=int, default=96)
    ap.add_argument("--case", choices=("5x5", "4x4"), default="5x5",
                    help="the bundled 5x5 NIR sensor (default) or the 4x4 test cubes")
    a = ap.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="snapcorr_pupil_speed_"))
    paths, sensor = (frames(folder), None) if a.case == "5x5" else frames_4x4(folder)
    runs = [("this", ROOT)] + ([("before", a.before)] if a.before else [])
    for name, checkout in runs:
        got = fit(checkout, paths, a.n_bins, sensor)
        print(name, json.dumps(got), flush=True)
        print(f"  {name}: x = {got['x_mm']:.4f} +- {got['x_stderr_mm']:.4f} mm (truth {X_MM}), "
              f"n_eff = {got['n_eff']:.4f} +- {got['n_eff_stderr']:.4f} (truth {N_EFF}), "
              f"{got['cpu_s']:.1f} CPU s, {got['wall_s']:.1f} s wall, others used "
              f"{100 * got['others_share']:.0f} % of the CPUs", flush=True)


if __name__ == "__main__":
    main()
