"""The interference microscope as an instrument: what it is (:class:`Microscope`: objective,
illumination, source, camera, reflectances) and what disturbs a measurement
(:class:`Disturbances`: scanner miscalibration and nonlinearity, vibration, the reference
mirror's figure), with the sampling the imaging model needs
(:func:`recommended_subsamples`).  The image they form is :mod:`._imaging`'s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from ..core.lazy import lazy_attr

from ..core.errors import InputError, check_range
from ..core.units import NM_TO_MM
from ._camera import Camera
from ._objectives import OBJECTIVES, Objective
from ._sources import Source, monochromatic
from ._transfer import flat_moments, linear_itf

#: SciPy, imported on first use (render_inspect.core.lazy)
gaussian_filter = lazy_attr("scipy.ndimage", "gaussian_filter")
distance_transform_edt = lazy_attr("scipy.ndimage", "distance_transform_edt")

__all__ = ["Disturbances", "Microscope", "recommended_subsamples"]


@dataclass(frozen=True)
class Microscope:
    """The interference microscope: objective, illumination, source, camera.

    Attributes
    ----------
    objective : Objective
        Default the 20x preset (NA 0.4).
    source : Source
        Default :func:`monochromatic` 550 nm, 10 nm FWHM (PSI).  Use :func:`led` for CSI.
    camera : Camera
    illumination_na : float or None
        Condenser (illumination) NA, 0 .. objective NA; None fills the pupil (Koehler
        illumination with the aperture stop open), 0 is a single on-axis plane wave.
    reflectance : float
        Power reflectance of the part (0..1].
    reference_reflectance : float
        Power reflectance of the reference mirror (0..1]; equal to ``reflectance`` for
        balanced beams.
    """

    objective: Objective = OBJECTIVES["20x"]
    source: Source = field(default_factory=lambda: monochromatic(550.0, bandwidth_nm=10.0))
    camera: Camera = field(default_factory=Camera)
    illumination_na: float | None = None
    reflectance: float = 1.0
    reference_reflectance: float = 1.0

    def __post_init__(self):
        na = self.objective.numerical_aperture
        if self.illumination_na is not None:
            check_range("illumination_na", self.illumination_na, 0, na)
        check_range("reflectance", self.reflectance, 0, 1, lo_open=True)
        check_range("reference_reflectance", self.reference_reflectance, 0, 1, lo_open=True)

    @property
    def na(self) -> float:
        return float(self.objective.numerical_aperture)

    @property
    def na_ill(self) -> float:
        return self.na if self.illumination_na is None else float(self.illumination_na)

    @property
    def obscuration(self) -> float:
        return float(self.objective.central_obscuration)

    def effective_wavelength_nm(self) -> float:
        """Fringe wavelength on a flat mirror, ``4 pi / K_eff`` (nm): the NA factor."""
        k, w = self.source.sample(dk=self._dk_fine())
        k_eff, _ = flat_moments(self.na, self.na_ill, self.obscuration, k, w)
        return 4 * math.pi / k_eff / NM_TO_MM

    def itf(self, frequency: ArrayLike) -> np.ndarray:
        """Instrument transfer function in the linear regime (:func:`linear_itf`) at
        ``frequency`` (cycles/mm), without the camera pixel's box filter."""
        return linear_itf(self.na, self.na_ill, self.obscuration, self.source, frequency)

    def lateral_response(self, heights: ArrayLike, *, pixel: float, camera_pixel: float) -> np.ndarray:
        """``heights`` (mm; a profile along its only axis, or a map; ``pixel`` mm apart) as
        the objective and the camera see them laterally: the imaging model's Kirchhoff
        field ``exp(i K_eff h)`` (docs/instrument.md) filtered by the linear transfer
        function (:meth:`itf`) times the camera pixel's box filter ``sinc(f w)`` (``w`` its
        sensitive width, ``sqrt(fill_factor) camera_pixel``, mm, along each axis), its phase
        read back as heights at the effective wavelength.  Small heights (``K a << 1``)
        come back filtered by the transfer function itself; a facet the pupil accepts comes
        back as it is, and a sharp edge or cusp rounded over the objective's resolution,
        as the instrument's own image rounds it.  One wavenumber (``K_eff``), in focus, no
        spectrum, acceptance or noise: the lateral response alone.  The returned heights
        differ from ``heights`` by at most a quarter of the effective wavelength either way
        (the phase is read modulo one fringe order).  The data are mirrored at their ends
        (as far as the response reaches) so that the FFT's wrap-around does not join the
        two ends; NaN (no surface) is filled with the nearest heights for the filter and
        stays NaN."""
        check_range("pixel", pixel, 0, None, lo_open=True)
        check_range("camera_pixel", camera_pixel, 0, None, lo_open=True)
        z = np.asarray(heights, dtype=np.float64)
        if z.ndim not in (1, 2) or z.size == 0:
            raise InputError(f"heights must be a profile or a map, received shape {z.shape}")
        bad = ~np.isfinite(z)
        if bad.all():
            return z.copy()
        f = _nearest_filled(z, bad) if bad.any() else z
        w = math.sqrt(self.camera.fill_factor) * camera_pixel
        k_eff = 4 * math.pi / (self.effective_wavelength_nm() * NM_TO_MM)
        # the response falls to its tails within a few of its widths: the pixel's and the
        # optics' (1 / cut-off); the data are mirrored that far beyond each end
        cutoff = (self.na + self.na_ill) / (self.source.wavelength_nm * NM_TO_MM)
        reach = int(math.ceil(8 * (w + 1.0 / cutoff) / pixel))
        pads = [(min(reach, n - 1), min(reach, n - 1)) for n in f.shape]
        g = np.pad(f - float(np.mean(f)), pads, mode="reflect")
        field = np.exp(1j * k_eff * g)
        freqs = [np.fft.fftfreq(n, d=pixel) for n in g.shape]
        if g.ndim == 1:
            h = self.itf(freqs[0]) * np.sinc(freqs[0] * w)
            seen = np.fft.ifft(np.fft.fft(field) * h)
        else:
            fy, fx = freqs[0][:, None], freqs[1][None, :]
            h = self.itf(np.hypot(fy, fx)) * np.sinc(fy * w) * np.sinc(fx * w)
            seen = np.fft.ifft2(np.fft.fft2(field) * h)
        # the phase the objective adds to each point, read back as a height
        dz = np.angle(seen * np.conj(field)) / k_eff
        dz = dz[tuple(slice(a, a + n) for (a, _), n in zip(pads, f.shape))]
        out = f + dz
        out[bad] = np.nan
        return out

    def coherence_sigma(self) -> float:
        """Rms width of the axial frequency for a flat mirror, rad/mm."""
        k, w = self.source.sample(dk=self._dk_fine())
        return flat_moments(self.na, self.na_ill, self.obscuration, k, w)[1]

    def _dk_fine(self) -> float:
        k_lo, k_hi = self.source.wavenumber_range()
        return max((k_hi - k_lo) / 400, 1e-3)

    def describe(self) -> dict:
        """Plain numbers (recorded in the frames' settings)."""
        return {"objective": self.objective.describe(), "source": self.source.describe(),
                "camera": self.camera.describe(), "illumination_na": self.na_ill,
                "reflectance": float(self.reflectance),
                "reference_reflectance": float(self.reference_reflectance)}


@dataclass(frozen=True)
class Disturbances:
    """Disturbances of the measurement (all off by default).

    Attributes
    ----------
    step_error : float
        Relative miscalibration of the phase shifter / scanner: it moves
        ``(1 + step_error)`` times the nominal distance.
    step_nonlinearity : float
        Quadratic phase-shifter error (PSI): the actual phase shift is
        ``delta (1 + step_error + step_nonlinearity * delta / (2 pi))``.
    vibration_amplitude_nm : float
        Amplitude of a sinusoidal vibration of the part along the optical axis, nm.
    vibration_frequency_hz : float
        Its frequency, Hz; the phase is drawn from the measurement's seed.
    frame_rate_hz : float
        Camera frame rate, Hz (frame ``f`` starts at ``f / frame_rate_hz``).
    exposure_time_s : float or None
        Integration time of each frame, s (None: ``1 / frame_rate_hz``); the intensity
        is averaged over it (8 sub-steps).
    reference_figure_rms_nm : float
        Rms of the reference mirror's figure error, nm: smooth random (Gaussian
        correlation), drawn from ``reference_figure_seed`` (a property of the
        objective).  It adds to the measured height with the opposite sign.
    reference_figure_correlation_mm : float
        Correlation length of that figure, mm.
    reference_figure_seed : int
    """

    step_error: float = 0.0
    step_nonlinearity: float = 0.0
    vibration_amplitude_nm: float = 0.0
    vibration_frequency_hz: float = 0.0
    frame_rate_hz: float = 100.0
    exposure_time_s: float | None = None
    reference_figure_rms_nm: float = 0.0
    reference_figure_correlation_mm: float = 0.02
    reference_figure_seed: int = 0

    def __post_init__(self):
        check_range("step_error", self.step_error, -0.5, 0.5)
        check_range("step_nonlinearity", self.step_nonlinearity, -0.5, 0.5)
        check_range("vibration_amplitude_nm", self.vibration_amplitude_nm, 0, 1e4)
        check_range("vibration_frequency_hz", self.vibration_frequency_hz, 0, 1e6)
        check_range("frame_rate_hz", self.frame_rate_hz, 0, 1e6, lo_open=True)
        if self.exposure_time_s is not None:
            check_range("exposure_time_s", self.exposure_time_s, 0, 1.0 / self.frame_rate_hz,
                        lo_open=True)
        check_range("reference_figure_rms_nm", self.reference_figure_rms_nm, 0, 1e3)
        check_range("reference_figure_correlation_mm", self.reference_figure_correlation_mm, 0,
                    None, lo_open=True)

    def describe(self) -> dict:
        return asdict(self)

    def reference_figure(self, shape: Sequence[int], pixel: float) -> np.ndarray | None:
        """The reference mirror's figure error on the camera grid, mm (None if off)."""
        if self.reference_figure_rms_nm <= 0:
            return None
        rng = np.random.default_rng([int(self.reference_figure_seed), 0x524546])  # "REF"
        white = rng.standard_normal(shape)
        sig = self.reference_figure_correlation_mm / pixel / math.sqrt(2)
        w = gaussian_filter(white, sig, mode="wrap")
        w -= w.mean()
        rms = float(np.sqrt(np.mean(w * w)))
        return w * (self.reference_figure_rms_nm * NM_TO_MM / rms) if rms > 0 else np.zeros(shape)

    def positions(self, nominal_mm: np.ndarray, *, seed: int, origin_mm: float | None = None,
                  scale: bool = True) -> np.ndarray:
        """Actual scanner positions during each frame's exposure, mm.

        Parameters
        ----------
        nominal_mm : (N,) float
            Nominal positions.
        origin_mm : float, optional
            Where the actuator's travel starts (default the first nominal position).
        scale : bool
            Apply ``step_error`` to the travel (False when the caller already has).

        Returns
        -------
        (N, T) float64: T = 1 without vibration, else 8 sub-steps of the exposure.
        """
        z = np.asarray(nominal_mm, dtype=np.float64)
        z0 = float(z[0]) if origin_mm is None else float(origin_mm)
        if scale:
            z = z0 + (z - z0) * (1.0 + self.step_error)
        if self.vibration_amplitude_nm <= 0 or self.vibration_frequency_hz <= 0:
            return z[:, None]
        rng = np.random.default_rng([int(seed), 0x564942])  # "VIB"
        phase0 = rng.uniform(0, 2 * math.pi)
        texp = self.exposure_time_s if self.exposure_time_s is not None else 1.0 / self.frame_rate_hz
        t = (np.arange(z.size)[:, None] / self.frame_rate_hz
             + texp * (np.arange(8)[None, :] + 0.5) / 8)
        v = self.vibration_amplitude_nm * NM_TO_MM * np.sin(
            2 * math.pi * self.vibration_frequency_hz * t + phase0)
        return z[:, None] + v


def _nearest_filled(z: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """``z`` with each NaN replaced by the nearest finite height."""
    idx = distance_transform_edt(bad, return_distances=False, return_indices=True)
    return z[tuple(idx)]


def recommended_subsamples(pixel: float, microscope: Microscope, *, max_slope: float | None = None) -> int:
    """Sub-samples per pixel side that sample the surface for this microscope.

    The larger of (a) Nyquist sampling of the highest spatial frequency the pupil passes,
    ``(NA + NA_ill) / lambda`` at the short end of the spectrum (1st percentile of the
    power), and (b) less than half a fringe of ``K h`` between sub-samples on slopes up
    to ``max_slope`` (rad; default the largest slope that can return light).  A surface
    that reaches the slope limit (``max_slope`` None or beyond it) gets less than a
    quarter of a fringe there: its facets beyond the limit are then carried by the grid
    far enough to fade out gently (:func:`~._imaging.interference_intensity`), instead of
    aliasing at the limit into false fringes.
    """
    k, w = microscope.source.sample(dk=microscope._dk_fine())
    k_hi = float(k[min(int(np.searchsorted(np.cumsum(w), 0.99)), k.size - 1)])
    f_cut = k_hi * (microscope.na + microscope.na_ill) / (2 * math.pi)
    s_res = math.ceil(2 * pixel * f_cut - 1e-9)
    slope_lim = 0.5 * (math.asin(microscope.na) + math.asin(microscope.na_ill))
    steep = max_slope is None or float(max_slope) >= slope_lim
    slope = slope_lim if max_slope is None else min(float(max_slope), slope_lim)
    s_slope = math.ceil((2 if steep else 1) * pixel * 2 * k_hi * math.tan(slope) / math.pi
                        - 1e-9)
    return int(max(1, s_res, s_slope))
