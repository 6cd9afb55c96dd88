"""Settings the panel shows and the operators read (``scene.render_inspect``)."""

import bpy
from bpy.props import (
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)


class RenderInspectSettings(bpy.types.PropertyGroup):
    """Scene file, a few ``--set`` overrides and the render settings.

    A value of 0 (or "From scene") keeps what the scene file says.
    """

    scene_path: StringProperty(
        name="Scene file", subtype="FILE_PATH", default="",
        description="render_inspect scene (TOML)")
    output_dir: StringProperty(
        name="Output folder", subtype="DIR_PATH", default="",
        description="Where heightmap.exr and the renders go (empty: a folder in Blender's "
                    "temporary directory)")
    spindle_rpm: FloatProperty(
        name="Spindle (rpm)", default=0.0, min=0.0, max=20000.0,
        description="process.spindle_rpm; 0 keeps the scene's value")
    feed_mm_per_min: FloatProperty(
        name="Feed (mm/min)", default=0.0, min=0.0, max=1000.0, precision=4,
        description="process.feed_mm_per_min; 0 keeps the scene's value")
    nose_radius: FloatProperty(
        name="Nose radius (mm)", default=0.0, min=0.0, max=50.0, precision=4,
        description="tool.nose_radius; 0 keeps the scene's value")
    compensation: EnumProperty(
        name="Compensation",
        items=(("SCENE", "From scene", "Keep the scene's process.compensation"),
               ("none", "None", "No tool-radius compensation"),
               ("normal", "Normal", "Offset along the surface normal"),
               ("z", "Z", "Z-direction compensation (max over the tool contacts)")),
        default="SCENE", description="process.compensation")
    extra_overrides: StringProperty(
        name="More overrides", default="",
        description="Further section.key=value overrides (TOML values), separated by ';'")
    surface: EnumProperty(
        name="Surface",
        items=(("machined", "Machined", "The simulated machined surface"),
               ("design", "Design", "The design surface"),
               ("residual", "Residual", "Machined minus design")),
        default="machined", description="Which height layer becomes the mesh")
    exaggeration: FloatProperty(
        name="Exaggeration", default=0.0, min=0.0, max=1e7,
        description="Vertical exaggeration of the mesh; 0 uses render.diffuse.exaggeration "
                    "(or, when the scene leaves it unset, the renderer's automatic choice)")
    view: EnumProperty(
        name="View",
        items=(("macro", "Macro", "The whole part, perspective, tilted 20 degrees"),
               ("micro", "Micro", "render.diffuse.window straight down (a microscope view)")),
        default="macro", description="Camera of the diffuse-light render")
    resolution: IntProperty(
        name="Resolution (px)", default=256, min=16, max=8192,
        description="Image width of the Cycles render (render.diffuse.resolution)")
    samples: IntProperty(
        name="Samples", default=64, min=1, max=65536, description="Cycles samples per pixel")
    seed: IntProperty(name="Seed", default=0, min=0, description="Cycles sampling seed")


CLASSES = (RenderInspectSettings,)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.render_inspect = PointerProperty(type=RenderInspectSettings)


def unregister():
    del bpy.types.Scene.render_inspect
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
