"""Frames: what the interference microscope records, and the settings it knows.

Frames carry the camera images and the instrument's own settings (nominal phase steps
or scan positions, wavelengths, objective, camera): what a real instrument stores with
its data.  They carry no truth: the surface that made them is not in here, so a height
measured from them is a measurement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.grid import GridCoordinates
from ..core.errors import InputError

__all__ = ["PHASE_CONVENTION", "Frames"]

PHASE_CONVENTION = ("I_k = a + b cos(4 pi (h - z_k) / lambda_eff); PSI: z_k = z_ref - "
                    "phase_steps_rad[k] lambda_eff / (4 pi); CSI: z_k = scan_positions_mm[k]")


@dataclass
class Frames(GridCoordinates):
    """Interferometer frames and the instrument settings.

    Attributes
    ----------
    frames : (N, H, W) float32
        Camera frames, ADC value / full scale (0..1).  PSI: one per phase step; CSI: one
        per scan position.
    mode : {"psi", "csi"}
    pixel : float
        Working pixel, mm.
    origin : (float, float)
        x, y of the centre of pixel [0, 0], mm.  Row 0 is the smallest y.
    wavelength_nm : float
        Centre wavelength of the source, nm.
    effective_wavelength_nm : float
        Calibrated fringe wavelength ``4 pi / K_eff``, nm (longer than
        ``wavelength_nm`` by the NA factor); heights are ``phase * lambda_eff / (4 pi)``.
    bandwidth_nm : float
        Source FWHM, nm (0 for a line).
    numerical_aperture : float
        Objective NA.
    phase_steps_rad : (N,) float64
        Nominal phase shifts (PSI; empty for CSI).
    scan_positions_mm : (N,) float64
        Nominal position of the scanner (focus and zero path difference) for each frame,
        mm; PSI: ``z_ref - phase_steps_rad * lambda_eff / (4 pi)``.
    z_ref : float
        PSI: scanner position of the zero phase step, mm (CSI: the scan's mid-point).
    seed : int
        Seed of the camera's temporal noise and of the disturbances.
    settings : dict
        Everything else the instrument knows (objective, illumination, source, camera,
        disturbance settings, model resolution); plain JSON-able values.
    """

    frames: np.ndarray
    mode: str
    pixel: float
    origin: tuple
    wavelength_nm: float
    effective_wavelength_nm: float
    bandwidth_nm: float
    numerical_aperture: float
    phase_steps_rad: np.ndarray
    scan_positions_mm: np.ndarray
    z_ref: float
    seed: int = 0
    settings: dict = field(default_factory=dict)

    def __post_init__(self):
        f = np.asarray(self.frames)
        if f.ndim != 3 or f.shape[0] < 1:
            raise InputError(f"frames must be an (N, H, W) stack, got shape {f.shape}")
        if self.mode not in ("psi", "csi"):
            raise InputError(f"mode must be 'psi' or 'csi', got {self.mode!r}")
        self.phase_steps_rad = np.asarray(self.phase_steps_rad, dtype=np.float64)
        self.scan_positions_mm = np.asarray(self.scan_positions_mm, dtype=np.float64)
        if self.scan_positions_mm.shape != (f.shape[0],):
            raise InputError(f"scan_positions_mm must have one entry per frame ({f.shape[0]}), "
                             f"got shape {self.scan_positions_mm.shape}")
        if self.mode == "psi" and self.phase_steps_rad.shape != (f.shape[0],):
            raise InputError(f"phase_steps_rad must have one entry per frame ({f.shape[0]}), "
                             f"got shape {self.phase_steps_rad.shape}")

    @property
    def shape(self):
        return self.frames.shape[1:]

    @property
    def intensity(self) -> np.ndarray:
        """The zero-phase-step frame (PSI) or the frame nearest ``z_ref`` (CSI)."""
        i = int(np.argmin(np.abs(self.scan_positions_mm - self.z_ref)))
        return self.frames[0] if self.mode == "psi" else self.frames[i]

    @property
    def effective_wavenumber(self) -> float:
        """``K_eff = 4 pi / lambda_eff``, rad/mm."""
        return 4 * math.pi / (self.effective_wavelength_nm * 1e-6)

    def header(self) -> dict:
        """Plain-number attributes (for file headers)."""
        return {"mode": self.mode, "pixel_size_mm": float(self.pixel),
                "origin_mm": [float(self.origin[0]), float(self.origin[1])],
                "wavelength_nm": float(self.wavelength_nm),
                "effective_wavelength_nm": float(self.effective_wavelength_nm),
                "bandwidth_nm": float(self.bandwidth_nm),
                "numerical_aperture": float(self.numerical_aperture),
                "phase_steps_rad": [float(v) for v in self.phase_steps_rad],
                "scan_positions_mm": [float(v) for v in self.scan_positions_mm],
                "z_ref_mm": float(self.z_ref), "seed": int(self.seed),
                "phase_convention": PHASE_CONVENTION, "units": "mm",
                "instrument": dict(self.settings)}
