"""Bundled calibration data (lens profiles, sensors) and small simulated example frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._bundled import bundled_path, calibration_dir

__all__ = ["DEFAULT_LENS", "calibration_dir", "lens_path", "mosaic_frames", "mosaic_target",
           "sensor_path"]

#: The lens of Goossens et al. 2019, used by ``snapcorr demo``.
DEFAULT_LENS = "edmund_optics_16mm"


def lens_path(name: str = DEFAULT_LENS) -> Path:
    """Path of a bundled lens profile by name (file stem), e.g. ``"edmund_optics_16mm"``.

    >>> lens_path().name
    'edmund_optics_16mm.toml'
    """
    return bundled_path("lens", name)


def sensor_path(name: str) -> Path:
    """Path of a bundled sensor description by name (file stem), e.g. ``"snapscan_vnir"``.

    >>> sensor_path("mosaic_4x4_vis").name
    'mosaic_4x4_vis.toml'
    """
    return bundled_path("sensor", name)


def mosaic_frames(sensor: str = "mosaic_4x4_vis", *, lens: str = DEFAULT_LENS,
                  f_number: float = 2.8, seed=0, target=None):
    """Simulated raw frames of a bundled mosaic sensor: a scene, a dark and a white frame.

    Whole-sensor frames in 12-bit digital numbers (``uint16``, 0-4095), or in the sensor's
    own bit depth where it gives one (``imec_5x5_nir``: 10-bit, 0-1023), as the camera would
    give them: the white frame is an integrating sphere seen through the bundled lens at
    ``f_number`` (optical and natural vignetting, :func:`snapcorr.simulate.flat_frame`) times
    each band's sensitivity (with measured responses, each band's response under the sphere's
    tungsten lamp); the scene is a uniform target whose reflectance
    (:func:`mosaic_target`) peaks in the middle of the sensor's bands, seen through each
    pixel's filter as the lens shifts and widens it
    (:func:`snapcorr.simulate.mosaic_reflectance`), so the bands at the edge of the field
    record it at shorter wavelengths than their nominal ones; both carry shot noise and a dark
    offset of 64 DN, which the dark frame holds alone.

    Parameters
    ----------
    sensor : str
        A bundled ``layout = "mosaic"`` sensor (``"mosaic_4x4_vis"``, ``"mosaic_5x5_nir"``,
        ``"imec_5x5_nir"``).
    lens : str
        A bundled lens.
    f_number : float
    seed : int or numpy.random.Generator
        Random source of the noise.
    target : callable, optional
        ``reflectance(wavelength_nm)`` of the uniform target (a wavelength standard for
        ``snapcorr pupil``, say); default :func:`mosaic_target`.

    Returns
    -------
    raw, dark, white : ndarray, shape ``sensor.size_px``, uint16

    >>> raw, dark, white = mosaic_frames()
    >>> raw.shape, raw.dtype.name, int(dark.max()) < int(raw.min()) < int(white.max()) < 4096
    ((1088, 2048), 'uint16', True)
    >>> int(mosaic_frames("imec_5x5_nir")[2].max()) <= 1023  # a 10-bit sensor
    True
    """
    from .cube import Sensor
    from .optics import Lens
    from .simulate import Detector, flat_frame, mosaic_reflectance

    sens = Sensor.load(sensor_path(sensor))
    if sens.layout != "mosaic":
        raise ValueError(f"sensor {sensor!r} is not a mosaic (layout {sens.layout!r})")
    rng = np.random.default_rng(seed)
    shape = tuple(sens.size_px)
    the_lens = Lens.load(lens_path(lens))
    sensitivity = _band_sensitivity(sens)
    tr, tc = sens.mosaic_shape
    r0, c0 = sens.tile_origin_px
    gain = np.empty(shape)
    for b, (r, c) in enumerate(np.asarray(sens.band_offset)):
        gain[(r + r0) % tr::tr, (c + c0) % tc::tc] = sensitivity[b]
    refl = mosaic_reflectance(sens, mosaic_target(sens) if target is None else target,
                              f_number, the_lens)
    light = flat_frame(shape, sens.pixel_pitch_um, f_number, the_lens,
                       noise=False, dtype=np.float64,
                       detector=Detector(signal_electrons=3500.0)) * gain
    # 12-bit codes at one electron each, or the sensor's own depth at as many electrons each
    full_scale = sens.full_scale_dn or 4095
    per_e = full_scale / 4095
    dark_dn = 64.0 * per_e

    def frame(electrons):
        dn = rng.poisson(electrons) * per_e + rng.normal(dark_dn, 2.0 * per_e, shape)
        return np.clip(np.rint(dn), 0, full_scale).astype(np.uint16)

    return frame(light * refl), frame(np.zeros(shape)), frame(light)


#: Colour temperature of the sphere's lamp in :func:`mosaic_frames` (tungsten halogen).
SPHERE_LAMP_K = 2856.0


def _band_sensitivity(sensor):
    """Each band's signal behind the white, at most 1: with measured responses, each band's
    whole response through the band-pass under the sphere's tungsten lamp (so the white
    carries the tile's fingerprint, :mod:`snapcorr.cube.phase`); else a smooth 0.5-1."""
    if sensor.responses is not None:
        from .spectra import blackbody

        grid = sensor.responses.wavelength_nm
        lamp = blackbody(SPHERE_LAMP_K, grid).values
        signal = sensor.responses.effective @ lamp
        return signal / signal.max()
    cwl = np.asarray(sensor.cwl_nm, float)
    center = 0.5 * (cwl.min() + cwl.max())
    return 0.75 + 0.25 * np.cos(np.pi * (cwl - center) / (np.ptp(cwl) + 1e-9))


def mosaic_target(sensor):
    """The reflectance of :func:`mosaic_frames`' target: 0.15 plus a Gaussian of 0.6 peaking
    in the middle of the sensor's bands, with a standard deviation of a fifth of their span
    (30 nm for the 4x4 VIS sensor's 470-620 nm).

    Parameters
    ----------
    sensor : Sensor

    Returns
    -------
    callable
        ``reflectance(wavelength_nm)``.
    """
    cwl = np.asarray(sensor.cwl_nm, float)
    center, sigma = 0.5 * (cwl.min() + cwl.max()), np.ptp(cwl) / 5.0

    def reflectance(wavelength_nm):
        return 0.15 + 0.6 * np.exp(-0.5 * ((np.asarray(wavelength_nm, float) - center)
                                           / sigma) ** 2)

    return reflectance
