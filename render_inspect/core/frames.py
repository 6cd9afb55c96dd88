"""Frames: what an interference microscope's camera records, with the instrument settings
needed to turn them into heights.  No true height travels with them: measuring uses the
frames and these settings alone (:mod:`render_inspect.metrology`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InputError
from .grid import GridCoordinates

__all__ = ["Frames", "PHASE_CONVENTION"]

PHASE_CONVENTION = ("I_k = (1 + |E|^2 + 2 Re(E exp(i delta_k))) / 4, E = mean over sub-samples of "
                    "exp(i 4 pi (h - z_ref) / lambda); delta_k = phase_steps_rad[k]")


@dataclass
class Frames(GridCoordinates):
    """Interferometer camera frames and the settings they were taken with.

    Attributes
    ----------
    frames : (N, H, W) float32, 0..1
        PSI: one frame per phase step; CSI: one per scan position.
    valid : (H, W) bool
        Pixels that returned light (the camera saw fringes there).
    pixel : float, mm at the part;  origin : (x, y) of pixel [0, 0]'s centre, mm.
        Row 0 = smallest y.
    mode : {"psi", "csi"}
    wavelength_nm : float
        PSI wavelength, or the CSI source's centre wavelength.
    numerical_aperture : float
    phase_steps : (N,) float64, rad
        PSI phase shifts delta_k (empty for CSI).
    scan_positions : (N,) float64, mm
        CSI reference positions (empty for PSI).
    z_ref : float, mm
        Reference position of the PSI frames (the zero of the measured height).
    bandwidth_nm : float or None
        CSI source FWHM.
    objective : str
    intensity_index : int
        The frame reported as ``intensity`` (PSI: the zero-shift frame; CSI: the frame
        nearest ``z_ref``).
    variant, subsamples, seed, noise : provenance of the rendering
    meta : dict
        Further settings (provenance).
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

    def __post_init__(self):
        f = np.asarray(self.frames)
        if f.ndim != 3:
            raise InputError(f"frames must be an (N, H, W) array, got shape {f.shape}")
        if np.shape(self.valid) != f.shape[1:]:
            raise InputError(f"valid must have the frames' image shape {f.shape[1:]}, got "
                             f"{np.shape(self.valid)}")
        if self.mode not in ("psi", "csi"):
            raise InputError(f"mode must be 'psi' or 'csi', got {self.mode!r}")

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(np.shape(self.frames)[1:])

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
                "phase_convention": PHASE_CONVENTION, "units": "mm"}
