"""``[machine]`` and ``[material]``: the turning machine's dynamics and error motions
(:mod:`render_inspect.machining._axes`), and the workpiece material's response to the cut
(:mod:`render_inspect.machining._material`); docs/machine_and_material.md.

Both start from a preset (the names are the presets of :mod:`render_inspect.machining`);
every key left out keeps the preset's value.  ``preset = "ideal"`` (the default) is the
commanded geometry: no dynamics, no error motions, no material response, exactly the
result of a scene without these sections.  Scene units (nm, urad, deg) become the
machining units (mm, rad) here.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Protocol

from pydantic import Field, model_validator

from ..core.errors import InputError, SceneError
from ..core.section import OrInfinity, Section
from ..core.units import NM_TO_MM, URAD_TO_RAD
from ..machining import (
    MACHINE_PRESET_NAMES,
    MATERIAL_PRESET_NAMES,
    Machine,
    MaterialResponse,
    machine_preset,
    material_preset,
    material_response,
)
from ._contract import SceneSections
from ._registry import register_section

__all__ = ["MachineConfig", "MaterialConfig", "LinearAxisConfig", "SpindleAxisConfig",
           "ErrorMotionsConfig", "CouplingConfig", "machine_of", "material_of", "ProcessScene"]


class LinearAxisConfig(Section):
    """A slide (X, Z) or the fast tool servo; keys left out keep the preset's values."""
    bandwidth_hz: OrInfinity | None = Field(None, gt=0, description="closed-loop natural frequency; inf = ideal")
    damping: float | None = Field(None, gt=0, le=10)
    velocity_ff: float | None = Field(None, ge=0, le=1, description="velocity feed-forward gain")
    acceleration_ff: float | None = Field(None, ge=0, le=1, description="acceleration feed-forward gain")
    velocity_limit_mm_s: float | None = Field(None, gt=0)
    acceleration_limit_mm_s2: float | None = Field(
        None, gt=0, description="the drive's limit: peak motor force / moving mass (not a "
                                "program's planned acceleration: process.*_acceleration_limit_mm_s2)")
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


#: a synchronous error motion's harmonic (once per turn = 1) and amplitude (nm, or urad
#: for tilt: at most 1 mm or 1 rad, the model's own limits)
Harmonic = Annotated[int, Field(ge=1, le=100_000)]
SyncAmplitude = Annotated[float, Field(ge=0, le=1e6)]
#: one synchronous error motion [harmonic, amplitude, phase_deg]
SyncTerm = tuple[Harmonic, SyncAmplitude, float]


class ErrorMotionsConfig(Section):
    """Spindle and slide error motions and tool-part vibration (tool relative to part)."""
    radial_sync: list[SyncTerm] | None = Field(
        None, description="[[harmonic, amplitude_nm, phase_deg], ...] radial (X) synchronous")
    radial_async_nm: float | None = Field(None, ge=0, le=1e5, description="rms, radial asynchronous")
    axial_sync: list[SyncTerm] | None = Field(
        None, description="[[harmonic, amplitude_nm, phase_deg], ...] axial (Z) synchronous")
    axial_async_nm: float | None = Field(None, ge=0, le=1e5, description="rms, axial asynchronous")
    tilt_sync: list[SyncTerm] | None = Field(
        None, description="[[harmonic, amplitude_urad, phase_deg], ...] tilt synchronous")
    async_bandwidth_hz: float | None = Field(None, gt=0, description="bandwidth of the asynchronous noise")
    x_straightness_nm: float | None = Field(None, ge=0, le=1e5, description="rms of the X slide's Z deviation")
    x_straightness_length: float | None = Field(None, gt=0, description="mm, its correlation length")
    vibration: list[tuple[Annotated[float, Field(gt=0, le=1e7)], SyncAmplitude,
                          Literal["x", "y", "z"], float]] | None = Field(
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
    # (the presets' names, read from the presets at import: mypy cannot follow them)
    preset: Literal[MACHINE_PRESET_NAMES] = Field(  # type: ignore[valid-type]
        "ideal", description="ideal = the commanded path; sts_lathe; fts (sts_lathe + a piezo FTS)")
    servo_rate_hz: float | None = Field(None, gt=0, le=1e7, description="interpolation / servo rate")
    interpolation: Literal["pvt", "linear"] | None = None
    fts_sync: Literal["position", "time"] | None = Field(
        None, description="FTS stroke timed by the measured spindle angle or by the clock")
    fts_sync_delay_s: float | None = Field(
        None, ge=-1, le=1, description="s, signed timing of the FTS stroke against the spindle "
                                       "position (or clock) it is synchronised to: > 0 late, "
                                       "< 0 early")
    c: SpindleAxisConfig = Field(default_factory=SpindleAxisConfig)
    x: LinearAxisConfig = Field(default_factory=LinearAxisConfig)
    z: LinearAxisConfig = Field(default_factory=LinearAxisConfig)
    fts: LinearAxisConfig = Field(default_factory=LinearAxisConfig)
    errors: ErrorMotionsConfig = Field(default_factory=ErrorMotionsConfig)
    coupling: CouplingConfig = Field(default_factory=CouplingConfig)

    def overrides(self) -> dict:
        """The keys set, nested, in the scene's units (what the preset is changed by)."""
        return self.model_dump(exclude_none=True, exclude={"preset"}, exclude_defaults=False)


_MATERIAL_PROPS = ("youngs_modulus_gpa", "poisson", "hardness_gpa", "friction",
                   "elongation_percent", "burr_coefficient", "texture_nm", "texture_length_um",
                   "adhesion_layer_nm", "adhesion_roughness_nm")


class MaterialConfig(Section):
    """The workpiece material and its response to the cut."""
    # (the presets' names, read from the presets at import: mypy cannot follow them)
    preset: Literal[MATERIAL_PRESET_NAMES] = Field(  # type: ignore[valid-type]
        "ideal", description="ideal = geometric cut (no material response)")
    edge_radius_nm: float = Field(50.0, ge=0, le=1e4, description="cutting-edge radius of the tool")
    side_flow: bool = Field(True, description="ploughed material flows onto the cusps")
    burrs: bool = Field(True, description="burrs on the machined edges from the material model "
                                          "([artifacts.burrs] height > 0 replaces them)")
    youngs_modulus_gpa: float | None = Field(None, gt=0, le=2000)
    poisson: float | None = Field(None, ge=0, lt=0.5)
    hardness_gpa: float | None = Field(None, gt=0, le=100)
    friction: float | None = Field(None, ge=0, le=2)
    elongation_percent: float | None = Field(None, ge=0, le=100,
                                             description="elongation at break: the ductility "
                                                         "that scales the burrs")
    burr_coefficient: float | None = Field(None, ge=0, le=10,
                                           description="burr height per unit uncut chip "
                                                       "thickness on a square exit edge")
    texture_nm: float | None = Field(None, ge=0, le=1e5, description="Sq of the part's own texture")
    texture_length_um: float | None = Field(None, gt=0, le=1e5,
                                            description="correlation length of the part's texture")
    adhesion_layer_nm: float | None = Field(
        None, ge=0, le=1e5, description="empirical: an adhered layer blunting the edge, as measured")
    adhesion_roughness_nm: float | None = Field(
        None, ge=0, le=1e5, description="empirical: Sq of the grooves an adhered layer ploughs "
                                        "along the cut, as measured")
    groove_across_um: float = Field(1.0, gt=0, le=1000, description="correlation length of the "
                                                                    "adhesion grooves across the cut")
    groove_along_mm: float = Field(0.05, gt=0, le=1000, description="correlation length of the "
                                                                    "adhesion grooves along the cut")

    @model_validator(mode="after")
    def _ideal_has_no_properties(self):
        if self.preset == "ideal" and any(getattr(self, k) is not None for k in _MATERIAL_PROPS):
            raise ValueError(f"preset must name a material ({', '.join(MATERIAL_PRESET_NAMES[1:])}) "
                             "when material properties are set; 'ideal' has none")
        return self

    def overrides(self) -> dict:
        """The material properties set (field name -> value)."""
        return {k: getattr(self, k) for k in _MATERIAL_PROPS if getattr(self, k) is not None}


# ---------------------------------------------------------------------------------------
# sections -> machining objects (scene units -> mm, rad)
# ---------------------------------------------------------------------------------------
def _linear_axis(cfg) -> dict:
    d = {}
    for k, v in cfg.model_dump(exclude_none=True).items():
        if k == "bandwidth_hz":
            d[k] = None if math.isinf(v) else v
        elif k == "noise_nm":
            d["noise_rms"] = v * NM_TO_MM
        elif k == "velocity_limit_mm_s":
            d["velocity_limit"] = v
        elif k == "acceleration_limit_mm_s2":
            d["acceleration_limit"] = v
        else:
            d[k] = v
    return d


def _spindle_axis(cfg) -> dict:
    d = {}
    for k, v in cfg.model_dump(exclude_none=True).items():
        if k == "bandwidth_hz":
            d[k] = None if math.isinf(v) else v
        elif k == "noise_urad":
            d["noise_rms"] = v * URAD_TO_RAD
        else:
            d[k] = v
    return d


def _errors(cfg) -> dict:
    d: dict[str, Any] = {}
    for k, v in cfg.model_dump(exclude_none=True).items():
        if k in ("radial_sync", "axial_sync", "tilt_sync"):   # nm (urad for tilt), deg
            scale = URAD_TO_RAD if k == "tilt_sync" else NM_TO_MM
            d[k] = tuple((int(n), a * scale, math.radians(p)) for n, a, p in v)
        elif k in ("radial_async_nm", "axial_async_nm"):
            d[k.replace("_nm", "_rms")] = v * NM_TO_MM
        elif k == "x_straightness_nm":
            d["x_straightness_rms"] = v * NM_TO_MM
        elif k == "vibration":
            d[k] = tuple((f, a * NM_TO_MM, direction, math.radians(p)) for f, a, direction, p in v)
        else:
            d[k] = v
    return d


class ProcessScene(SceneSections, Protocol):
    """What a turning or sculpturing process's checks and settings read of a validated
    scene: the sections of :class:`~render_inspect.processes.SceneSections`, and
    ``[machine]`` and ``[material]``."""

    @property
    def machine(self) -> MachineConfig:
        ...

    @property
    def material(self) -> MaterialConfig:
        ...


def machine_of(cfg: "MachineConfig") -> Machine:
    """The :class:`~render_inspect.machining.Machine` of a ``[machine]`` section."""
    ov = {k: getattr(cfg, k) for k in ("servo_rate_hz", "interpolation", "fts_sync",
                                       "fts_sync_delay_s")
          if getattr(cfg, k) is not None}
    for k in ("x", "z", "fts"):
        d = _linear_axis(getattr(cfg, k))
        if d:
            ov[k] = d
    d = _spindle_axis(cfg.c)
    if d:
        ov["c"] = d
    d = _errors(cfg.errors)
    if d:
        ov["errors"] = d
    d = cfg.coupling.model_dump(exclude_none=True)
    if d:
        ov["coupling"] = d
    try:
        return machine_preset(cfg.preset, ov)
    except InputError as err:
        raise SceneError(f"machine (preset {cfg.preset!r}): {err}") from None


def material_of(cfg: "MaterialConfig", *, contact: float = 1.0) -> MaterialResponse | None:
    """The :class:`~render_inspect.machining.MaterialResponse` of a ``[material]`` section
    at the contact ratio ``contact`` (1 = continuous cutting), or None for
    ``preset = "ideal"``."""
    if cfg.preset == "ideal":
        return None
    try:
        mat = material_preset(cfg.preset, cfg.overrides())
        return material_response(mat, edge_radius=cfg.edge_radius_nm * NM_TO_MM,
                                 contact_ratio=contact, side_flow=cfg.side_flow)
    except InputError as err:
        raise SceneError(f"material (preset {cfg.preset!r}): {err}") from None


register_section("machine", MachineConfig)
register_section("material", MaterialConfig)
