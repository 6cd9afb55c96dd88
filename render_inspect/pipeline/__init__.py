"""The pipeline: the only place where stages are chained.  The command line and the
Blender add-on call these functions.

``simulate`` (scene -> plan -> cut -> height map and metrics), ``run_simulate``,
``run_toolpath``, ``run_render``, ``run_compare``, ``run_demo``; ``simulation_metrics``
is the one metrics builder every command's ``metrics.json`` comes from.
"""

from ._blender import simulate_into_blender
from ._compare import (
                       COMPARE_MAX_CAMERA_PIXELS,
                       COMPARE_MAX_DIFFUSE_RESOLUTION,
                       COMPARE_MAX_DIFFUSE_SPP,
                       PROFILE_ANGLES_DEG,
                       VARIANTS,
                       compare_variants,
                       preview_render_configs,
                       run_compare,
)
from ._demo import DEMO_SCENE, run_demo
from ._measure import measure_and_evaluate
from ._metrics import lenslet_metrics, simulation_metrics
from ._render import (
                       check_render_limits,
                       interferogram_summary,
                       render_heightmap,
                       run_render,
                       write_diffuse_outputs,
                       write_interferogram_outputs,
)
from ._simulate import (
                       Simulation,
                       design_heightmap,
                       run_simulate,
                       simulate,
                       write_simulation,
)
from ._toolpath import plan_program, run_toolpath

__all__ = ["Simulation", "simulate", "design_heightmap", "write_simulation", "run_simulate",
           "plan_program", "run_toolpath", "run_render", "render_heightmap",
           "write_interferogram_outputs", "write_diffuse_outputs", "interferogram_summary",
           "run_compare", "compare_variants", "preview_render_configs", "run_demo",
           "DEMO_SCENE", "measure_and_evaluate", "simulation_metrics", "lenslet_metrics",
           "simulate_into_blender", "VARIANTS", "PROFILE_ANGLES_DEG",
           "COMPARE_MAX_CAMERA_PIXELS", "COMPARE_MAX_DIFFUSE_RESOLUTION",
           "COMPARE_MAX_DIFFUSE_SPP", "check_render_limits"]
