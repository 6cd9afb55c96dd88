"""The camera: exposure, photon (shot) noise, read noise, fixed-pattern noise, full-well
saturation and quantisation.

Model of one frame (electrons, ``e``), per pixel::

    e_signal = g I (1 + prnu_map)                 g: electrons per unit model intensity
    e        = Poisson(e_signal) + N(0, read_noise_e^2) + dsnu_map
    e        = clip(e, 0, full_well_e)            saturation at the full well
    adu      = round(e / full_well_e * (2^bit_depth - 1))
    frame    = adu / (2^bit_depth - 1)            0..1, float32

``g`` is chosen so that the brightest noise-free value of the whole stack (after the
gain pattern) fills ``exposure`` of the full well: nothing saturates by default.
``prnu_map`` (relative gain, rms ``prnu``) and ``dsnu_map`` (offset, rms ``dsnu_e``
electrons) are fixed patterns of the camera, drawn from ``fixed_pattern_seed``, the same
for every frame and every measurement; shot and read noise are drawn from the
measurement's ``seed``.  All noise is spatially white.  Shot noise is Poisson; for
expected counts of 100 electrons and more its Gaussian limit ``N(e, e)`` is drawn
(skewness below 0.1), which is what makes 256-frame stacks affordable.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass

import numpy as np

from ..core.errors import InputError, check_range

__all__ = ["POISSON_EXACT_BELOW", "Camera", "expose", "make_fixed_patterns"]

#: Expected electron counts below this draw exact Poisson shot noise.
POISSON_EXACT_BELOW = 100.0


@dataclass(frozen=True)
class Camera:
    """Camera settings.

    Attributes
    ----------
    full_well_e : float
        Full-well capacity, electrons.
    read_noise_e : float
        Read noise, electrons rms.
    bit_depth : int
        ADC bits (1..16).
    prnu : float
        Photo-response non-uniformity: rms of the fixed relative gain pattern.
    dsnu_e : float
        Dark-signal non-uniformity: rms of the fixed offset pattern, electrons.
    fill_factor : float
        Light-sensitive fraction of the pixel area (0..1]; the sensitive area is a
        centred square.
    exposure : float
        Fraction of the full well reached by the brightest noise-free pixel (> 0; above
        1 the brightest pixels saturate).
    fixed_pattern_seed : int
        Seed of the fixed patterns (a property of the camera).
    noise : bool
        False: the frames are the exact model intensities scaled by the exposure (no
        noise, no fixed pattern, no quantisation).
    """

    full_well_e: float = 20000.0
    read_noise_e: float = 5.0
    bit_depth: int = 12
    prnu: float = 0.005
    dsnu_e: float = 2.0
    fill_factor: float = 1.0
    exposure: float = 0.8
    fixed_pattern_seed: int = 0
    noise: bool = True

    def __post_init__(self):
        check_range("camera.full_well_e", self.full_well_e, 1, None)
        check_range("camera.read_noise_e", self.read_noise_e, 0, None)
        if int(self.bit_depth) != self.bit_depth:
            raise InputError(f"camera.bit_depth must be an integer in [1, 16], got {self.bit_depth!r}")
        check_range("camera.bit_depth", self.bit_depth, 1, 16)
        check_range("camera.prnu", self.prnu, 0, 0.5)
        check_range("camera.dsnu_e", self.dsnu_e, 0, None)
        check_range("camera.fill_factor", self.fill_factor, 0, 1, lo_open=True)
        check_range("camera.exposure", self.exposure, 0, 10, lo_open=True)
        if int(self.fixed_pattern_seed) != self.fixed_pattern_seed or self.fixed_pattern_seed < 0:
            raise InputError(f"camera.fixed_pattern_seed must be an integer >= 0, got "
                             f"{self.fixed_pattern_seed!r}")

    @property
    def levels(self) -> int:
        """Largest ADC value, ``2^bit_depth - 1``."""
        return 2 ** int(self.bit_depth) - 1

    def describe(self) -> dict:
        return asdict(self)


def make_fixed_patterns(camera: Camera, shape: tuple[int, int]) -> None:
    """Make the fixed patterns of ``camera`` over ``shape`` pixels ahead of an exposure
    (the interferometer makes them in a thread while the ray tracer works): the exposure
    then takes the ones kept (:func:`_fixed_patterns` keeps the last set made)."""
    if camera.noise:
        _fixed_patterns(camera, tuple(int(v) for v in shape))


@functools.lru_cache(maxsize=1)
def _fixed_patterns(camera: Camera, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The camera's gain (PRNU) and offset (DSNU) maps over ``shape`` pixels, from its
    ``fixed_pattern_seed``: the same arrays for the same camera and shape, so the last set
    is kept (read-only) for the exposures that follow."""
    rng = np.random.default_rng([int(camera.fixed_pattern_seed), 0x46504E])  # "FPN"
    gain = np.ones(shape, dtype=np.float32)
    offset = np.zeros(shape, dtype=np.float32)
    if camera.prnu > 0:
        gain += rng.normal(0.0, camera.prnu, size=shape).astype(np.float32)
        np.maximum(gain, 0.0, out=gain)
    if camera.dsnu_e > 0:
        offset = rng.normal(0.0, camera.dsnu_e, size=shape).astype(np.float32)
    gain.flags.writeable = offset.flags.writeable = False
    return gain, offset


def expose(intensity: np.ndarray, camera: Camera | None = None, *, seed: int = 0,
           inplace: bool = False) -> tuple[np.ndarray, dict]:
    """Turn model intensities into camera frames.

    Parameters
    ----------
    intensity : (N, H, W) array
        Noise-free intensities (any positive scale).
    camera : Camera, optional
        Default :class:`Camera()`.
    seed : int
        Seed of the shot and read noise (>= 0).
    inplace : bool
        Write the frames into ``intensity`` (a float32 array), saving its memory.

    Returns
    -------
    frames : (N, H, W) float32
        ADC values / (2^bit_depth - 1), 0..1 (exact scaled intensities when
        ``camera.noise`` is False).
    info : dict
        ``electrons_per_intensity`` (g), ``electrons_per_adu``, ``saturated_fraction``
        (fraction of pixels at full well in at least one frame), ``seed``.
    """
    cam = Camera() if camera is None else camera
    if int(seed) != seed or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    inten = np.asarray(intensity)
    if inten.ndim != 3:
        raise InputError(f"intensity must be an (N, H, W) stack, got shape {inten.shape}")
    shape = inten.shape[1:]
    if cam.noise:
        gain_map, offset_map = _fixed_patterns(cam, tuple(int(v) for v in shape))
    else:
        gain_map, offset_map = np.ones(shape, np.float32), np.zeros(shape, np.float32)
    peak = float(np.max(np.max(inten, axis=0) * gain_map)) if inten.size else 0.0
    if not np.isfinite(peak) or peak <= 0:
        raise InputError("intensity must have a positive, finite maximum (the field is dark)")
    g = cam.exposure * cam.full_well_e / peak
    if inplace and not (isinstance(intensity, np.ndarray) and intensity.dtype == np.float32):
        raise InputError("expose(inplace=True) needs a float32 numpy array")
    out = inten if inplace else np.empty(inten.shape, dtype=np.float32)
    sat = np.zeros(shape, dtype=bool)
    e_per_adu = cam.full_well_e / cam.levels
    rng = np.random.default_rng(int(seed))
    scale = np.float32(g) * gain_map
    z = np.empty(shape, dtype=np.float32)  # the normal deviates of one frame, drawn into it
    for f in range(inten.shape[0]):
        e = inten[f].astype(np.float32) * scale
        if not cam.noise:
            out[f] = np.minimum(e, cam.full_well_e) / np.float32(cam.full_well_e)
            sat |= e >= cam.full_well_e
            continue
        np.maximum(e, 0.0, out=e)
        low = e < POISSON_EXACT_BELOW
        # (the same draws of the same stream as standard_normal(size=shape, dtype=float32))
        noisy = e + rng.standard_normal(dtype=np.float32, out=z) * np.sqrt(
            e + np.float32(cam.read_noise_e) ** 2)
        if low.any():
            # exact Poisson where counts are small (plus the read noise)
            noisy[low] = (rng.poisson(e[low]).astype(np.float32)
                          + np.float32(cam.read_noise_e) * rng.standard_normal(
                              size=int(low.sum()), dtype=np.float32))
        noisy += offset_map
        sat |= noisy >= cam.full_well_e
        np.clip(noisy, 0.0, cam.full_well_e, out=noisy)
        out[f] = np.rint(noisy / np.float32(e_per_adu)) / np.float32(cam.levels)
    info = {"electrons_per_intensity": float(g), "electrons_per_adu": float(e_per_adu),
            "saturated_fraction": float(sat.mean()), "seed": int(seed)}
    return out, info
