"""Scene files: TOML, validated on load.

>>> scene = load_scene("scenes/sts_sinusoidal_grid.toml", overrides=["process.spindle_rpm=100"])

Unknown keys, wrong types and non-physical values raise :class:`SceneError` naming the
key (dotted path), what is allowed and the value received.  Retired keys are rewritten
into their successors with a :class:`~render_inspect.core.deprecation.DeprecatedKeyWarning`.

The schema is assembled from the registries: ``[design]`` from the design types,
``[process]`` from the process kinds, ``[render]`` from the instruments, and the sections
the process modules define (``[machine]``, ``[material]``, ``[rcse]``,
``[artifacts.burrs]``, ``[artifacts.vibration]``, ...) from
:func:`~render_inspect.processes.scene_sections`.
"""

from __future__ import annotations

from ._schema import (MAX_SCENE_BYTES, MAX_SCENE_DEPTH, ArtifactsConfig, BurrConfig,
                      DesignConfig, DiffuseConfig, InterferometerConfig, MachineConfig,
                      MaterialConfig, MetrologyConfig, ProcessConfig, RcseConfig, RenderConfig,
                      Scene, SceneError, SimulationConfig, ToolConfig, VibrationConfig,
                      apply_overrides, find_scene, instrument_config, load_scene, scene_from_dict,
                      objective_names, scene_sections, shipped_scenes, unit_warnings)
# the compared variants of a scene (built with the functions above)
from ._variants import compare_pair, compare_variants, parse_vary, variant_scene

__all__ = ["Scene", "load_scene", "scene_from_dict", "apply_overrides", "SceneError",
           "shipped_scenes", "find_scene", "instrument_config", "scene_sections",
           "DesignConfig", "ToolConfig", "ProcessConfig", "SimulationConfig", "RenderConfig",
           "InterferometerConfig", "DiffuseConfig", "ArtifactsConfig", "VibrationConfig",
           "BurrConfig", "MetrologyConfig", "RcseConfig", "MachineConfig", "MaterialConfig",
           "parse_vary", "compare_pair", "variant_scene", "compare_variants", "unit_warnings",
           "objective_names"]
