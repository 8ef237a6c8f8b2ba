"""The bundled data: the paper's lens and the sensors by name, and the simulated mosaic frames
against the target and the offsets their docstring promises."""

import numpy as np
import pytest

from snapcorr.cube import Sensor
from snapcorr.data import lens_path, mosaic_frames, mosaic_target, sensor_path
from snapcorr.optics import Lens


def test_the_default_lens_is_goossens_edmund_optics_16mm():
    # Goossens et al. 2019, Sec. 3.2 and Eq. 31: x = 21 mm, P = 7.4236 mm, h = 16.991 mm,
    # m = 0.06, m_P = 1.3
    lens = Lens.load(lens_path())
    assert lens_path().stem == "edmund_optics_16mm"
    assert lens.exit_pupil_mm == 21.0
    assert lens.vignetting == ((7.4236, 16.991),)
    assert (lens.magnification, lens.pupil_magnification) == (0.06, 1.3)


@pytest.mark.parametrize("name", ["mosaic_4x4_vis", "mosaic_5x5_nir", "imec_5x5_nir",
                                  "snapscan_vnir"])
def test_every_bundled_sensor_is_found_by_name(name):
    path = sensor_path(name)
    assert path.stem == name and path.is_file()
    assert Sensor.load(path).name


def test_an_unknown_name_lists_what_is_bundled():
    with pytest.raises(FileNotFoundError, match="mosaic_4x4_vis"):
        sensor_path("mosaic_9x9")
    with pytest.raises(FileNotFoundError, match="edmund_optics_16mm"):
        lens_path("../sensors/mosaic_4x4_vis")


def test_the_target_peaks_in_the_middle_of_the_bands():
    # 470-620 nm: the peak at 545 nm, sigma = 150 / 5 = 30 nm
    target = mosaic_target(Sensor.load(sensor_path("mosaic_4x4_vis")))
    assert target(545.0) == pytest.approx(0.75, rel=1e-12)
    assert target([515.0, 575.0]) == pytest.approx(0.15 + 0.6 * np.exp(-0.5), rel=1e-12)
    assert target(2000.0) == pytest.approx(0.15, rel=1e-12)


def test_the_frames_hold_the_target_seen_bluer_at_the_edge_of_the_field():
    sensor = Sensor.load(sensor_path("mosaic_4x4_vis"))
    raw, dark, white = mosaic_frames("mosaic_4x4_vis", f_number=2.8, seed=3)
    assert raw.shape == dark.shape == white.shape == tuple(sensor.size_px)
    assert raw.dtype == dark.dtype == white.dtype == np.uint16
    # the dark offset: 64 DN with 2 DN of read noise
    assert dark.mean() == pytest.approx(64.0, abs=0.05)
    assert dark.std() == pytest.approx(2.0, abs=0.1)
    ratio = (raw - dark.astype(float)) / (white - dark.astype(float))
    tr, tc = sensor.mosaic_shape
    r0, c0 = sensor.tile_origin_px
    ny, nx = raw.shape
    target = mosaic_target(sensor)
    for b, (r, c) in enumerate(np.asarray(sensor.band_offset)):
        rows, cols = slice((r + r0) % tr, None, tr), slice((c + c0) % tc, None, tc)
        band = ratio[rows, cols]
        by, bx = band.shape
        centre = band[by // 2 - 8:by // 2 + 8, bx // 2 - 8:bx // 2 + 8].mean()
        corner = band[:16, :16].mean()
        cwl = sensor.cwl_nm[b]
        # on the axis the band sees the target at its nominal wavelength, smoothed by its width
        assert centre == pytest.approx(target(cwl), abs=0.025), cwl
        # in the corner the filter moved to the blue: the peak at 545 nm appears in the bands
        # above it, and leaves those below (where the target's slope is steep)
        if 560 <= cwl <= 600:
            assert corner > centre + 0.02, cwl
        elif 490 <= cwl <= 530:
            assert corner < centre - 0.02, cwl
    # the white frame falls off to the corner (vignetting)
    middle = white[ny // 2 - 8:ny // 2 + 8, nx // 2 - 8:nx // 2 + 8]
    assert white[:16, :16].mean() < 0.8 * middle.mean()


def test_frames_of_a_sensor_that_is_no_mosaic_are_refused():
    with pytest.raises(ValueError, match="not a mosaic"):
        mosaic_frames("snapscan_vnir")
