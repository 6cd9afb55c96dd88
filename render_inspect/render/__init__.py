"""Engine adapters: Mitsuba 3 (ray tracing of height/normal grids for the instruments,
diffuse-light images) and Blender Cycles.  They take engine-neutral inputs (height maps,
meshes, scene specs as plain dicts) and return arrays.

Mitsuba, Dr.Jit and bpy are imported inside functions only, so importing this package is
cheap.  The Mitsuba variant (``llvm_ad_rgb``, ``scalar_rgb`` or ``cuda_ad_rgb``) is chosen
once per process by :func:`mitsuba_variant` and recorded in every output.
"""

from __future__ import annotations

from ._cycles import (
                      ALUMINIUM_ETA,
                      ALUMINIUM_K,
                      OBJECT_NAME,
                      PROP_EXAGGERATION,
                      PROP_HEIGHTMAP,
                      PROP_OFFSET,
                      PROP_SURFACE,
                      PROP_VARIANT,
                      RENDER_SCENE_NAME,
                      blend_objects,
                      default_output_dir,
                      f82_tint_colours,
                      fresnel_conductor,
                      gridmesh_object,
                      heightmap_object,
                      load_image,
                      material_model,
                      object_heights,
                      remove_image,
                      remove_object,
                      render_cycles,
                      render_object,
                      render_spec,
                      surface_material,
                      surface_object,
)
from ._diffuse import (
                      AL_REFLECTANCE_RGB,
                      LIGHTS,
                      MAX_FILM_SIDE,
                      MAX_SAMPLES_PER_PASS,
                      PORT_PROFILES,
                      DiffuseConfig,
                      auto_exaggeration,
                      diffuse_memory,
                      diffuse_mesh,
                      diffuse_scene_spec,
                      environment_map,
                      light_profile,
                      mitsuba_seed,
                      render_diffuse,
                      render_passes,
)
from ._diffuse import _default_window as default_window
from ._scene_dicts import load_scene_dict, trace_grids
from ._turned_bsdf import efficiency_tables, grating_efficiencies
from ._variant import (
                      import_mitsuba,
                      mitsuba_variant,
                      single_thread,
                      spectral_variant,
                      start_mitsuba,
                      variant_info,
)

__all__ = ["render_diffuse", "diffuse_scene_spec", "environment_map", "light_profile",
           "auto_exaggeration", "DiffuseConfig", "LIGHTS", "AL_REFLECTANCE_RGB",
           "trace_grids", "load_scene_dict", "mitsuba_variant", "variant_info", "start_mitsuba",
           "single_thread", "import_mitsuba", "render_cycles", "render_object",
           "render_spec", "surface_object", "heightmap_object", "gridmesh_object",
           "object_heights", "remove_object", "remove_image", "default_output_dir", "load_image", "blend_objects",
           "surface_material", "material_model", "fresnel_conductor", "f82_tint_colours",
           "ALUMINIUM_ETA", "ALUMINIUM_K", "OBJECT_NAME", "RENDER_SCENE_NAME", "PORT_PROFILES",
           "diffuse_mesh", "spectral_variant", "efficiency_tables", "grating_efficiencies",
           "render_passes", "mitsuba_seed", "diffuse_memory", "MAX_FILM_SIDE", "MAX_SAMPLES_PER_PASS",
           "default_window", "PROP_EXAGGERATION", "PROP_HEIGHTMAP", "PROP_OFFSET", "PROP_SURFACE",
           "PROP_VARIANT"]
