"""Frames: what an interference microscope's camera records, with the instrument settings
needed to turn them into heights.  No true height travels with them: measuring uses the
frames and these settings alone (:mod:`render_inspect.metrology`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from .errors import InputError
from .grid import GridCoordinates
from .units import NM_TO_MM

__all__ = ["Frames", "PHASE_CONVENTION"]

#: How a frame's intensity depends on the height, the phase steps and the scan positions
#: (recorded with the frames).
PHASE_CONVENTION = ("I_k = a + b cos(4 pi (h - z_k) / lambda_eff); PSI: z_k = z_ref - "
                    "phase_steps_rad[k] lambda_eff / (4 pi); CSI: z_k = scan_positions_mm[k]")


@dataclass
class Frames(GridCoordinates):
    """Interferometer camera frames and the settings they were taken with.

    Attributes
    ----------
    frames : (N, H, W) float32, 0..1
        PSI: one frame per phase step; CSI: one per scan position.
    valid : (H, W) bool
        Pixels the recording holds (rendered frames: every pixel).  Measuring never reads
        it: which pixels hold fringes is decided from the frames themselves.
    pixel : float, mm at the part;  origin : (x, y) of pixel [0, 0]'s centre, mm.
        Row 0 = smallest y.
    mode : {"psi", "csi"}
    wavelength_nm : float
        PSI wavelength, or the CSI source's centre wavelength.
    numerical_aperture : float
    phase_steps : (N,) float64, rad
        PSI nominal phase shifts delta_k (empty for CSI).
    scan_positions : (N,) float64, mm
        Nominal scanner positions (focus and zero path difference move together): CSI
        one per frame; PSI the phase shifter's positions (or empty).
    z_ref : float, mm
        Scanner position of the zero phase step (PSI: the zero of the measured height).
    bandwidth_nm : float or None
        CSI source FWHM.
    objective : str
    intensity_index : int
        The frame reported as ``intensity`` (PSI: the zero-shift frame; CSI: the frame
        nearest ``z_ref``).
    variant, subsamples, seed, noise : provenance of the rendering
    meta : dict
        Further settings (provenance).
    effective_wavelength_nm : float or None
        The calibrated fringe wavelength ``4 pi / K_eff`` (nm): longer than
        ``wavelength_nm`` by the objective's NA factor.  Heights are
        ``phase * lambda_eff / (4 pi)``; None = ``wavelength_nm``.
    settings : dict
        Everything else the instrument knows (objective, illumination, source spectrum,
        camera, disturbance settings, model resolution), plain JSON-able values.
    """

    frames: np.ndarray
    valid: np.ndarray
    pixel: float
    origin: tuple[float, float]
    mode: str
    wavelength_nm: float
    numerical_aperture: float
    phase_steps: np.ndarray
    scan_positions: np.ndarray
    z_ref: float = 0.0
    bandwidth_nm: float | None = None
    objective: str = ""
    intensity_index: int = 0
    variant: str = ""
    subsamples: int = 1
    seed: int = 0
    noise: bool = False
    meta: dict = field(default_factory=dict)
    effective_wavelength_nm: float | None = None
    settings: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        f = np.asarray(self.frames)
        if f.ndim != 3:
            raise InputError(f"frames must be an (N, H, W) array, got shape {f.shape}")
        if np.shape(self.valid) != f.shape[1:]:
            raise InputError(f"valid must have the frames' image shape {f.shape[1:]}, got "
                             f"{np.shape(self.valid)}")
        if self.mode not in ("psi", "csi"):
            raise InputError(f"mode must be 'psi' or 'csi', got {self.mode!r}")
        self.phase_steps = np.asarray(self.phase_steps, dtype=np.float64)
        self.scan_positions = np.asarray(self.scan_positions, dtype=np.float64)
        n = f.shape[0]
        if self.mode == "psi" and self.phase_steps.shape != (n,):
            raise InputError(f"phase_steps must hold one phase shift per frame ({n}), got "
                             f"shape {self.phase_steps.shape}")
        if self.mode == "csi" and self.scan_positions.shape != (n,):
            raise InputError(f"scan_positions must hold one position per frame ({n}), got "
                             f"shape {self.scan_positions.shape}")

    @property
    def shape(self) -> tuple[int, int]:
        return cast("tuple[int, int]", tuple(np.shape(self.frames)[1:]))

    @property
    def lambda_eff_nm(self) -> float:
        """The fringe wavelength heights are measured with, nm."""
        return float(self.effective_wavelength_nm or self.wavelength_nm)

    @property
    def effective_wavenumber(self) -> float:
        """``K_eff = 4 pi / lambda_eff``, rad/mm."""
        return 4 * math.pi / (self.lambda_eff_nm * NM_TO_MM)

    @property
    def intensity(self) -> np.ndarray:
        """The frame shown as the interferogram (``frames[intensity_index]``)."""
        return self.frames[self.intensity_index]

    def header(self) -> dict:
        """The instrument settings as EXR header attributes (docs/formats.md names plus
        provenance)."""
        return {"pixel_size_mm": float(self.pixel),
                "origin_mm": [float(self.origin[0]), float(self.origin[1])],
                "wavelength_nm": float(self.wavelength_nm),
                "bandwidth_nm": float(self.bandwidth_nm or 0.0),
                "numerical_aperture": float(self.numerical_aperture),
                "mode": self.mode, "mitsuba_variant": self.variant,
                "objective": self.objective, "subsamples": int(self.subsamples),
                "z_ref_mm": float(self.z_ref), "seed": int(self.seed),
                "noise": bool(self.noise), "intensity_index": int(self.intensity_index),
                "phase_steps_rad": [float(d) for d in self.phase_steps],
                "scan_positions_mm": [float(z) for z in self.scan_positions],
                "phase_convention": PHASE_CONVENTION, "units": "mm",
                "effective_wavelength_nm": self.lambda_eff_nm,
                "instrument": dict(self.settings)}
