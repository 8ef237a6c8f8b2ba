"""Virtual bands of a stream: chosen on the first frame, applied to every frame."""

import numpy as np
import pytest
import xarray as xr

import snapcorr
import snapcorr.data
from snapcorr.correct import correct_cube
from snapcorr.cube import Sensor, demosaic, flatfield
from snapcorr.pipeline import process_stream

ORIGIN = (300, 500)
CROP = (slice(300, 360), slice(500, 575))


@pytest.fixture(scope="module")
def stream():
    sensor = Sensor.load(snapcorr.data.sensor_path("imec_5x5_nir"))
    lens = snapcorr.Lens.load(snapcorr.data.lens_path())
    raw, dark, white = snapcorr.data.mosaic_frames("imec_5x5_nir", seed=1)
    rng = np.random.default_rng(0)
    scene = raw[CROP].astype(float)
    frames = np.stack([scene, 64 / 4 + (scene - 64 / 4) * rng.uniform(0.5, 1.0, scene.shape)])
    frames = xr.DataArray(frames, dims=("frame", "y", "x"))
    return sensor, lens, frames, dark[CROP], white[CROP]


@pytest.mark.parametrize("method", ["vendor", "fitted", "angle-aware"])
def test_every_frame_gets_the_first_frames_virtual_bands(stream, method):
    sensor, lens, frames, dark, white = stream
    kw = {"lens": lens, "f_number": 2.8, "sensor_origin_px": ORIGIN, "demosaic_method": "bilinear"}
    out = process_stream(frames, dark, white, sensor, virtual_bands=method, **kw)
    v = out["virtual"]
    assert v.dims == ("frame", "y", "x", "virtual_band")
    assert v.attrs["virtual_bands"] == method and "virtual_wavelength" in v.coords
    if method == "vendor":  # the first frame as correct_cube gives it (the others: the same)
        ff = demosaic(flatfield(frames.isel(frame=0), dark, white, saturation=1023), sensor,
                      "bilinear", sensor_origin_px=ORIGIN)
        one = correct_cube(ff["reflectance"], sensor, 2.8, lens, virtual_bands=method)
        np.testing.assert_allclose(v.isel(frame=0).values, one["virtual"].values, rtol=1e-5,
                                   atol=1e-6)
    # every frame by the stream's one matrix (or table), computed here by hand
    for i in range(frames.sizes["frame"]):
        ff = demosaic(flatfield(frames.isel(frame=i), dark, white, saturation=1023), sensor,
                      "bilinear", sensor_origin_px=ORIGIN)["reflectance"].values.astype(np.float64)
        if method == "angle-aware":
            cra = out["cra_deg"].values  # (y, x) at full resolution
            nodes, mats = out["virtual_cra_deg"].values, out["virtual_table"].values
            k = np.clip(np.searchsorted(nodes, cra) - 1, 0, nodes.size - 2)
            t = np.clip((cra - nodes[k]) / (nodes[k + 1] - nodes[k]), 0, 1)[..., None, None]
            want = np.einsum("yxvb,yxb->yxv", (1 - t) * mats[k] + t * mats[k + 1], ff)
        else:
            want = ff @ out["virtual_matrix"].values.T
        np.testing.assert_allclose(v.isel(frame=i).values, want, rtol=2e-4, atol=2e-5)
    assert not np.allclose(v.isel(frame=1).values, v.isel(frame=0).values)


def test_stream_virtual_bands_on_the_command_line(stream, tmp_path):
    from conftest import run_cli

    _, _, frames, dark, white = stream
    np.save(tmp_path / "frames.npy", np.rint(frames.values).astype(np.uint16))
    np.save(tmp_path / "dark.npy", dark)
    np.save(tmp_path / "white.npy", white)
    common = ("stream", tmp_path / "frames.npy", "--dark", tmp_path / "dark.npy", "--white",
              tmp_path / "white.npy", "--sensor", "imec_5x5_nir", "--sensor-origin-px",
              f"{ORIGIN[0]},{ORIGIN[1]}", "--demosaic", "bilinear")
    code, out, err = run_cli(*common, "--lens", "edmund_optics_16mm", "--f-number", "2.8",
                             "--virtual-bands", "fitted", "--out", tmp_path / "v.zarr")
    assert code == 0, err
    assert "virtual bands: 25 from" in out
    ds = snapcorr.cube.read_dataset(tmp_path / "v.zarr")
    assert ds["virtual"].dims == ("frame", "y", "x", "virtual_band")
    code, _, err = run_cli(*common, "--virtual-bands", "fitted", "--out", tmp_path / "w.zarr")
    assert code != 0 and "--virtual-bands needs --lens" in err and err.count("\n") == 1
