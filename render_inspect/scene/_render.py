"""``[render]``: the virtual instruments (interferometer, diffuse light)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from ._base import Section


class InterferometerConfig(Section):
    mode: Literal["psi", "csi"] = "psi"
    objective: Literal["5x", "10x", "20x", "50x"] = "20x"
    wavelength_nm: float | None = Field(None, gt=100, lt=2000, description="PSI wavelength / CSI centre")
    bandwidth_nm: float | None = Field(None, gt=0, lt=1000, description="CSI source FWHM")
    numerical_aperture: float | None = Field(None, gt=0, lt=1)
    pixel: float | None = Field(None, gt=0, description="mm at the part")
    field_of_view: tuple[float, float, float, float] | None = Field(None, description="mm, [x0, y0, x1, y1]")
    steps: int = Field(4, ge=3, le=16, description="PSI frames")
    step_rad: float = Field(1.5707963267948966, gt=0, description="PSI phase step")
    scan_step_nm: float = Field(80.0, gt=0, description="CSI scan step")
    subsamples: int = Field(2, ge=1, le=8, description="sub-pixel samples per axis")
    noise: bool = True
    bit_depth: int = Field(12, ge=1, le=16)
    full_well: float = Field(20000.0, gt=0, description="electrons")
    read_noise: float = Field(5.0, ge=0, description="electrons rms")
    reference_height: float | None = Field(None, description="z_ref, mm (default: mean height in the field)")


class DiffuseConfig(Section):
    light: Literal["dome", "ring"] = "dome"
    material: Literal["aluminium"] = "aluminium"
    roughness: float = Field(0.0, ge=0, le=1, description="0 = smooth conductor")
    exaggeration: float | None = Field(None, gt=0, le=1e6,
                                       description="vertical exaggeration of the mesh; None = auto "
                                                   "(the steepest 1 % of slopes become ~0.2 rad)")
    spp: int = Field(64, ge=1, le=65536)
    resolution: int = Field(256, ge=16, le=8192)
    window: tuple[float, float, float, float] | None = Field(None, description="mm, microscope view")


class RenderConfig(Section):
    interferometer: InterferometerConfig = Field(default_factory=InterferometerConfig)
    diffuse: DiffuseConfig = Field(default_factory=DiffuseConfig)
