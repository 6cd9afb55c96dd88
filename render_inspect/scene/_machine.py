"""``[machine]`` and ``[material]``: the turning machine's dynamics and error motions, and
the workpiece material's response (docs/machine_and_material.md).

Both start from a preset; every key left out keeps the preset's value.  ``preset =
"ideal"`` (the default) is the commanded geometry: no dynamics, no error motions, no
material response, exactly the result of a scene without these sections.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from ..core.section import OrInfinity, Section

__all__ = ["MachineConfig", "MaterialConfig", "LinearAxisConfig", "SpindleAxisConfig",
           "ErrorMotionsConfig", "CouplingConfig", "MACHINE_PRESET_NAMES",
           "MATERIAL_PRESET_NAMES"]

#: the machine presets of :mod:`render_inspect.machining` (kept equal by a test)
MACHINE_PRESET_NAMES = ("ideal", "sts_lathe", "fts")
#: the material presets of :mod:`render_inspect.machining` (kept equal by a test)
MATERIAL_PRESET_NAMES = ("ideal", "al6061", "al6082", "ofhc_copper", "nip", "die_steel")


class LinearAxisConfig(Section):
    """A slide (X, Z) or the fast tool servo; keys left out keep the preset's values."""
    bandwidth_hz: OrInfinity | None = Field(None, gt=0, description="closed-loop natural frequency; inf = ideal")
    damping: float | None = Field(None, gt=0, le=10)
    velocity_ff: float | None = Field(None, ge=0, le=1, description="velocity feed-forward gain")
    acceleration_ff: float | None = Field(None, ge=0, le=1, description="acceleration feed-forward gain")
    velocity_limit_mm_s: float | None = Field(None, gt=0)
    acceleration_limit_mm_s2: float | None = Field(None, gt=0)
    noise_nm: float | None = Field(None, ge=0, le=1e5, description="following-error rms from disturbance")
    delay_s: float | None = Field(None, ge=0, le=10, description="output latency")


class SpindleAxisConfig(Section):
    """The spindle as a C axis; keys left out keep the preset's values."""
    bandwidth_hz: OrInfinity | None = Field(None, gt=0, description="closed-loop natural frequency; inf = ideal")
    damping: float | None = Field(None, gt=0, le=10)
    velocity_ff: float | None = Field(None, ge=0, le=1)
    acceleration_ff: float | None = Field(None, ge=0, le=1)
    noise_urad: float | None = Field(None, ge=0, le=1e5, description="following-error rms from disturbance")
    delay_s: float | None = Field(None, ge=0, le=10)


class ErrorMotionsConfig(Section):
    """Spindle and slide error motions and tool-part vibration (tool relative to part)."""
    radial_sync: list[tuple[int, float, float]] | None = Field(
        None, description="[[harmonic, amplitude_nm, phase_deg], ...] radial (X) synchronous")
    radial_async_nm: float | None = Field(None, ge=0, le=1e5, description="rms, radial asynchronous")
    axial_sync: list[tuple[int, float, float]] | None = Field(
        None, description="[[harmonic, amplitude_nm, phase_deg], ...] axial (Z) synchronous")
    axial_async_nm: float | None = Field(None, ge=0, le=1e5, description="rms, axial asynchronous")
    tilt_sync: list[tuple[int, float, float]] | None = Field(
        None, description="[[harmonic, amplitude_urad, phase_deg], ...] tilt synchronous")
    async_bandwidth_hz: float | None = Field(None, gt=0, description="bandwidth of the asynchronous noise")
    x_straightness_nm: float | None = Field(None, ge=0, le=1e5, description="rms of the X slide's Z deviation")
    x_straightness_length: float | None = Field(None, gt=0, description="mm, its correlation length")
    vibration: list[tuple[float, float, Literal["x", "y", "z"], float]] | None = Field(
        None, description="[[frequency_hz, amplitude_nm, direction, phase_deg], ...]")


class CouplingConfig(Section):
    """Reaction-force coupling of the X slide into the tool-part loop."""
    mass_kg: float | None = Field(None, ge=0, le=1e5, description="moving mass of the X slide")
    z_compliance_nm_per_n: float | None = Field(None, ge=0, le=1e4)
    y_compliance_nm_per_n: float | None = Field(None, ge=0, le=1e4)
    mode_hz: float | None = Field(None, gt=0, description="frame mode")
    mode_damping: float | None = Field(None, gt=0, le=10)


class MachineConfig(Section):
    """The turning machine: a preset and what to change in it."""
    preset: Literal[MACHINE_PRESET_NAMES] = Field(
        "ideal", description="ideal = the commanded path; sts_lathe; fts (sts_lathe + a piezo FTS)")
    servo_rate_hz: float | None = Field(None, gt=0, le=1e7, description="interpolation / servo rate")
    interpolation: Literal["pvt", "linear"] | None = None
    fts_sync: Literal["position", "time"] | None = Field(
        None, description="FTS stroke timed by the measured spindle angle or by the clock")
    c: SpindleAxisConfig = Field(default_factory=SpindleAxisConfig)
    x: LinearAxisConfig = Field(default_factory=LinearAxisConfig)
    z: LinearAxisConfig = Field(default_factory=LinearAxisConfig)
    fts: LinearAxisConfig = Field(default_factory=LinearAxisConfig)
    errors: ErrorMotionsConfig = Field(default_factory=ErrorMotionsConfig)
    coupling: CouplingConfig = Field(default_factory=CouplingConfig)

    def overrides(self) -> dict:
        """The keys set, nested, in the scene's units (what the preset is changed by)."""
        return self.model_dump(exclude_none=True, exclude={"preset"}, exclude_defaults=False)


class MaterialConfig(Section):
    """The workpiece material and its response to the cut."""
    preset: Literal[MATERIAL_PRESET_NAMES] = Field(
        "ideal", description="ideal = geometric cut (no material response)")
    edge_radius_nm: float = Field(50.0, ge=0, le=1e4, description="cutting-edge radius of the tool")
    side_flow: bool = Field(True, description="ploughed material flows onto the cusps")
    youngs_modulus_gpa: float | None = Field(None, gt=0, le=2000)
    poisson: float | None = Field(None, ge=0, lt=0.5)
    hardness_gpa: float | None = Field(None, gt=0, le=100)
    friction: float | None = Field(None, ge=0, le=2)
    adhesion_layer_nm: float | None = Field(None, ge=0, le=1e5)
    adhesion_roughness_nm: float | None = Field(None, ge=0, le=1e5)
    texture_nm: float | None = Field(None, ge=0, le=1e5)
    groove_across_um: float = Field(1.0, gt=0, le=1000, description="correlation length of the grooves across the cut")
    groove_along_mm: float = Field(0.05, gt=0, le=1000, description="correlation length of the grooves along the cut")

    @model_validator(mode="after")
    def _ideal_has_no_properties(self):
        props = ("youngs_modulus_gpa", "poisson", "hardness_gpa", "friction", "adhesion_layer_nm",
                 "adhesion_roughness_nm", "texture_nm")
        if self.preset == "ideal" and any(getattr(self, k) is not None for k in props):
            raise ValueError("preset must name a material (al6061, al6082, ofhc_copper, nip, "
                             "die_steel) when material properties are set; 'ideal' has none")
        return self

    def overrides(self) -> dict:
        """The material properties set (field name -> value)."""
        keys = ("youngs_modulus_gpa", "poisson", "hardness_gpa", "friction", "adhesion_layer_nm",
                "adhesion_roughness_nm", "texture_nm")
        return {k: getattr(self, k) for k in keys if getattr(self, k) is not None}
