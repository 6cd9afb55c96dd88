"""Off-screen renders with Mitsuba 3: the virtual interference microscope and
diffuse-light images of the machined part.

Mitsuba and Dr.Jit are imported lazily (inside functions), so importing this package is
cheap.  The variant (``llvm_ad_rgb``, ``scalar_rgb`` or ``cuda_ad_rgb``) is chosen once
per process by :func:`mitsuba_variant` and recorded in every output.

Entry point of ``render-inspect render``: :func:`run_render`.
"""

from __future__ import annotations

from ._diffuse import (AL_REFLECTANCE_RGB, LIGHTS, diffuse_scene_spec, environment_map,
                       light_profile, render_diffuse)
from ._interferometer import (OBJECTIVES, Interferogram, camera_noise, interference_frames,
                              interferometer_geometry, read_interferogram_exr,
                              render_interferogram, write_interferogram_exr)
from ._run import render_heightmap, run_render, write_diffuse_outputs, write_interferogram_outputs
from ._variant import mitsuba_variant, single_thread, variant_info


def __getattr__(name):
    # the Cycles adapter imports bpy lazily too; re-exported on first use
    if name in ("render_cycles", "render_object", "simulate_into_blender"):
        from . import _cycles

        return getattr(_cycles, name)
    raise AttributeError(name)

__all__ = ["run_render", "render_heightmap", "render_interferogram", "render_diffuse",
           "diffuse_scene_spec", "environment_map", "light_profile", "Interferogram",
           "write_interferogram_exr", "read_interferogram_exr", "write_interferogram_outputs",
           "write_diffuse_outputs", "interference_frames", "interferometer_geometry",
           "camera_noise", "mitsuba_variant", "variant_info", "single_thread", "OBJECTIVES",
           "LIGHTS", "AL_REFLECTANCE_RGB", "render_cycles", "render_object", "simulate_into_blender"]
