"""The pipeline: the only place where stages are chained.  The command line and the
Blender add-on call these functions.

Every stage is a function with typed inputs and outputs in its own layer: the process
(:class:`~render_inspect.processes.Process`: inputs, plan, cut, traits), the instruments
(:mod:`render_inspect.instruments`), the metrology, the writers of :mod:`render_inspect.io`
and the figures of :mod:`render_inspect.report`; the pipeline calls them in order and
asks nothing of a process but its hooks.

``simulate`` (scene -> plan -> cut -> height map and metrics), ``run_simulate``,
``run_toolpath``, ``run_render``, ``run_compare``, ``run_analyze``, ``run_measure``,
``run_characterise``, ``run_demo``, ``run_fit`` (a measured surface -> the scene's
settings), ``run_sweep`` (many points on Dask), ``run_regress``
(the image regression suite); the Blender add-on's ``simulate_variants``,
``render_variant``, ``compare_scene``, ``export_variant`` (and ``surfaces_into_blender``,
``load_render_images`` to show their results in Blender).  Every ``metrics.json`` is
built in one place (``render_inspect.pipeline._metrics``; ``simulation_metrics``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..instruments import interferogram_summary
    from ..io import completed_outputs, refuse_inputs_inside
    from ..metrology import lenslet_metrics
    from ._analyze import ANALYZE_FILES, run_analyze
    from ._analyze_profile import PROFILE_FILES, run_analyze_profile
    from ._blender import (EXPORT_FORMATS, PANEL_METRICS, VARIANT_PROPERTY, blender_output_dir,
                           blender_presets, blender_surfaces, compare_scene, export_variant,
                           load_render_images, remove_blender_surfaces, render_variant,
                           simulate_into_blender, simulate_variants, surface_info,
                           surfaces_into_blender)
    from ._characterise import characterise_instrument, run_characterise
    from ._compare import (COMPARE_MAX_CAMERA_PIXELS, COMPARE_MAX_DIFFUSE_RESOLUTION,
                           COMPARE_MAX_DIFFUSE_SPP, PROFILE_ANGLES_DEG, VARIANTS, check_measured,
                           common_window, compare_pair, compare_summary, compare_variants,
                           expected_sq_mm, parse_vary, preview_render_configs, run_compare,
                           variant_scene)
    from ._compare_profile import run_compare_command, run_compare_profile
    from ._demo import DEMO_SCENE, run_demo
    from ._fit import FIT_FILES, predict_measurement, preset_value, run_fit
    from ._fit_profile import PROFILE_FIT_FILES, is_profile_measurement, run_fit_profile
    from ._measure import (analyze_summary, measure_and_evaluate, measure_summary,
                           measurement_outputs, read_frames, run_measure)
    from ._metrics import simulation_metrics
    from ._regress import IMAGE_SETTINGS, case_images, regression_cases_dir, run_regress
    from ._render import (check_render_limits, part_heightmap, part_outline, render_diffuse_views,
                          render_heightmap, render_kinds, run_render, tool_marks,
                          write_diffuse_outputs, write_instrument_outputs,
                          write_interferogram_outputs)
    from ._simulate import Simulation, design_heightmap, simulate, write_simulation
    from ._simulate_command import TILED_SAMPLES, run_simulate, run_simulate_tiled, wants_tiles
    from ._summaries import PROFILE_COLUMNS, command_summary, profile_compare_summary
    from ._sweep import (find_sweep, run_point, run_sweep, shipped_sweeps, sweep_failure, sweep_morris,
                         sweep_tasks)
    from ._toolpath import check_tool_edge, edge_warnings, plan_program, program_formats, run_toolpath

#: where each name lives (module -> names): a stage's module is imported when one of its
#: names is first used, so that a command imports only the stages it runs (``simulate``
#: does not import the fit, the renderers' stages or the batch commands' own modules)
_LAZY = {
    '..instruments': ('interferogram_summary',),
    '..io': ('completed_outputs', 'refuse_inputs_inside'),
    '..metrology': ('lenslet_metrics',),
    '._analyze': ('ANALYZE_FILES', 'run_analyze'),
    '._analyze_profile': ('PROFILE_FILES', 'run_analyze_profile'),
    '._blender': ('EXPORT_FORMATS', 'PANEL_METRICS', 'VARIANT_PROPERTY', 'blender_output_dir',
                  'blender_presets', 'blender_surfaces', 'compare_scene', 'export_variant',
                  'load_render_images', 'remove_blender_surfaces', 'render_variant',
                  'simulate_into_blender', 'simulate_variants', 'surface_info',
                  'surfaces_into_blender'),
    '._characterise': ('characterise_instrument', 'run_characterise'),
    '._compare': ('COMPARE_MAX_CAMERA_PIXELS', 'COMPARE_MAX_DIFFUSE_RESOLUTION',
                  'COMPARE_MAX_DIFFUSE_SPP', 'PROFILE_ANGLES_DEG', 'VARIANTS', 'check_measured',
                  'common_window', 'compare_pair', 'compare_summary', 'compare_variants',
                  'expected_sq_mm', 'parse_vary', 'preview_render_configs', 'run_compare',
                  'variant_scene'),
    '._compare_profile': ('run_compare_command', 'run_compare_profile'),
    '._demo': ('DEMO_SCENE', 'run_demo'),
    '._fit': ('FIT_FILES', 'predict_measurement', 'preset_value', 'run_fit'),
    '._fit_profile': ('PROFILE_FIT_FILES', 'is_profile_measurement', 'run_fit_profile'),
    '._measure': ('analyze_summary', 'measure_and_evaluate', 'measure_summary',
                  'measurement_outputs', 'read_frames', 'run_measure'),
    '._metrics': ('simulation_metrics',),
    '._regress': ('IMAGE_SETTINGS', 'case_images', 'regression_cases_dir', 'run_regress'),
    '._render': ('check_render_limits', 'part_heightmap', 'part_outline', 'render_diffuse_views',
                 'render_heightmap', 'render_kinds', 'run_render', 'tool_marks',
                 'write_diffuse_outputs', 'write_instrument_outputs',
                 'write_interferogram_outputs'),
    '._simulate': ('Simulation', 'design_heightmap', 'simulate', 'write_simulation'),
    '._simulate_command': ('TILED_SAMPLES', 'run_simulate', 'run_simulate_tiled', 'wants_tiles'),
    '._summaries': ('PROFILE_COLUMNS', 'command_summary', 'profile_compare_summary'),
    '._sweep': ('find_sweep', 'run_point', 'run_sweep', 'shipped_sweeps', 'sweep_failure',
                'sweep_morris', 'sweep_tasks'),
    '._toolpath': ('check_tool_edge', 'edge_warnings', 'plan_program', 'program_formats', 'run_toolpath'),
}
_WHERE = {name: module for module, names in _LAZY.items() for name in names}

__all__ = ["completed_outputs", "refuse_inputs_inside", "Simulation", "simulate", "design_heightmap", "write_simulation", "run_simulate",
           "run_simulate_tiled", "wants_tiles", "TILED_SAMPLES",
           "plan_program", "run_toolpath", "program_formats", "edge_warnings", "check_tool_edge", "run_render", "render_heightmap", "render_kinds",
           "write_interferogram_outputs", "write_instrument_outputs", "write_diffuse_outputs",
           "interferogram_summary",
           "part_heightmap", "part_outline", "render_diffuse_views", "tool_marks",
           "run_compare", "compare_variants", "compare_pair", "compare_summary", "parse_vary",
           "variant_scene", "common_window", "preview_render_configs", "check_measured",
           "expected_sq_mm", "run_analyze", "ANALYZE_FILES", "run_analyze_profile", "PROFILE_FILES",
           "run_compare_profile", "run_compare_command", "run_demo", "DEMO_SCENE",
           "measure_and_evaluate", "run_measure", "read_frames", "measurement_outputs",
           "measure_summary", "analyze_summary", "command_summary",
           "profile_compare_summary", "PROFILE_COLUMNS",
           "run_characterise", "characterise_instrument", "simulation_metrics", "lenslet_metrics",
           "simulate_into_blender", "simulate_variants", "surfaces_into_blender",
           "blender_surfaces", "remove_blender_surfaces", "surface_info", "render_variant",
           "load_render_images", "compare_scene", "export_variant", "blender_output_dir",
           "blender_presets", "VARIANT_PROPERTY", "EXPORT_FORMATS", "PANEL_METRICS",
           "VARIANTS", "PROFILE_ANGLES_DEG", "COMPARE_MAX_CAMERA_PIXELS",
           "COMPARE_MAX_DIFFUSE_RESOLUTION", "COMPARE_MAX_DIFFUSE_SPP",
           "run_sweep", "run_point", "sweep_tasks", "find_sweep", "shipped_sweeps", "sweep_failure",
           "sweep_morris",
           "run_regress", "case_images", "regression_cases_dir", "IMAGE_SETTINGS",
           "check_render_limits", "run_fit", "predict_measurement", "preset_value", "FIT_FILES",
           "run_fit_profile", "PROFILE_FIT_FILES", "is_profile_measurement"]


def __getattr__(name: str) -> Any:
    """A stage's name, its module imported on first use (see ``_LAZY``)."""
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
