"""The values a scene's ``[machine]`` and ``[material]`` stand at, their presets' included,
in the scene's own keys and units (nm, urad, degrees): what a key the scene leaves out takes
from its preset (the conversions of :mod:`._machine` read backwards), and which keys are
the amplitudes of the cut's seeded random parts."""

from __future__ import annotations

import math
from typing import Any

from ..core.units import MM_TO_NM, RAD_TO_URAD
from ..machining import material_preset
from ._machine import MachineConfig, MaterialConfig, ProcessScene, machine_of

__all__ = ["machine_settings", "material_settings", "preset_settings", "random_parts",
           "RANDOM_PART_KEYS"]

#: scene keys that are the amplitudes of seeded random parts of the cut: the slides' and
#: the spindle's following-error noise, the spindle's asynchronous error motion (drawn along
#: the cut's time) and the material's grooves (drawn along the cutting distance)
RANDOM_PART_KEYS = ("machine.x.noise_nm", "machine.z.noise_nm", "machine.fts.noise_nm",
                    "machine.c.noise_urad", "machine.errors.radial_async_nm",
                    "machine.errors.axial_async_nm", "material.texture_nm",
                    "material.adhesion_roughness_nm")


def _axis(a: dict, *, spindle: bool) -> dict:
    bw = a.get("bandwidth_hz")
    d = {"bandwidth_hz": math.inf if bw is None else bw, "damping": a["damping"],
         "velocity_ff": a["velocity_ff"], "acceleration_ff": a["acceleration_ff"],
         "delay_s": a["delay_s"]}
    if spindle:
        d["noise_urad"] = a["noise_rms"] * RAD_TO_URAD
    else:
        d["noise_nm"] = a["noise_rms"] * MM_TO_NM
        d["velocity_limit_mm_s"] = a.get("velocity_limit")
        d["acceleration_limit_mm_s2"] = a.get("acceleration_limit")
    return d


def machine_settings(cfg: MachineConfig) -> dict:
    """The machine of a ``[machine]`` section (its preset with the section's changes) as
    the section's keys in its units: ``{"servo_rate_hz": ..., "x": {"noise_nm": ...},
    "errors": {"axial_sync": [[2, 3.0, 40.1], ...], ...}, ...}``."""
    m = machine_of(cfg).to_dict()
    out = {"servo_rate_hz": m["servo_rate_hz"], "interpolation": m["interpolation"],
           "fts_sync": m["fts_sync"], "c": _axis(m["c"], spindle=True)}
    for k in ("x", "z", "fts"):
        out[k] = _axis(m[k], spindle=False)
    e = m["errors"] or {}
    errs: dict[str, Any] = {
        k: [[int(n), a * MM_TO_NM, math.degrees(p)] for n, a, p in e.get(k, ())]
        for k in ("radial_sync", "axial_sync")}
    errs["tilt_sync"] = [[int(n), a * RAD_TO_URAD, math.degrees(p)]
                         for n, a, p in e.get("tilt_sync", ())]
    for key, name in (("radial_async_nm", "radial_async_rms"),
                      ("axial_async_nm", "axial_async_rms"),
                      ("x_straightness_nm", "x_straightness_rms")):
        errs[key] = e.get(name, 0.0) * MM_TO_NM
    errs["async_bandwidth_hz"] = e.get("async_bandwidth_hz")
    errs["x_straightness_length"] = e.get("x_straightness_length")
    errs["vibration"] = [[f, a * MM_TO_NM, d, math.degrees(p)]
                         for f, a, d, p in e.get("vibration", ())]
    out["errors"] = errs
    out["coupling"] = dict(m["coupling"])
    return out


def material_settings(cfg: MaterialConfig) -> dict:
    """The material of a ``[material]`` section (its preset with the section's changes) as
    the section's keys; ``{}`` for ``preset = "ideal"``."""
    if cfg.preset == "ideal":
        return {}
    mat = material_preset(cfg.preset, cfg.overrides()).to_dict()
    mat.pop("name", None)
    return {**mat, "edge_radius_nm": cfg.edge_radius_nm, "side_flow": cfg.side_flow,
            "groove_across_um": cfg.groove_across_um, "groove_along_mm": cfg.groove_along_mm}


def preset_settings(scene: ProcessScene) -> dict:
    """``{"machine": machine_settings, "material": material_settings}`` of a scene."""
    return {"machine": machine_settings(scene.machine),
            "material": material_settings(scene.material)}


def random_parts(scene: ProcessScene) -> dict:
    """The amplitudes (scene key -> value, scene units) of the scene's seeded random parts
    (:data:`RANDOM_PART_KEYS`) that are not zero, presets included."""
    settings = preset_settings(scene)
    out: dict[str, float] = {}
    for key in RANDOM_PART_KEYS:
        node: Any = settings
        for part in key.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if isinstance(node, (int, float)) and node > 0:
            out[key] = float(node)
    return out
