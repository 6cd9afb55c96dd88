"""Operators: each reads its settings, calls one render_inspect function and reports
render_inspect's errors in Blender's status bar."""

import bpy

from render_inspect.errors import RenderInspectError


def _overrides(settings) -> list[str]:
    """The ``--set`` overrides the panel's settings stand for (0 / "From scene" = none)."""
    out = []
    if settings.spindle_rpm > 0:
        out.append(f"process.spindle_rpm={settings.spindle_rpm!r}")
    if settings.feed_mm_per_min > 0:
        out.append(f"process.feed_mm_per_min={settings.feed_mm_per_min!r}")
    if settings.nose_radius > 0:
        out.append(f"tool.nose_radius={settings.nose_radius!r}")
    if settings.compensation != "SCENE":
        out.append(f'process.compensation="{settings.compensation}"')
    out.extend(item.strip() for item in settings.extra_overrides.split(";") if item.strip())
    return out


def _output_dir(settings) -> str | None:
    return bpy.path.abspath(settings.output_dir) if settings.output_dir else None


class RENDER_INSPECT_OT_simulate(bpy.types.Operator):
    """Simulate the machined surface of the scene file and load it as a mesh"""

    bl_idname = "render_inspect.simulate"
    bl_label = "Simulate"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        from render_inspect.pipeline import simulate_into_blender

        settings = context.scene.render_inspect
        try:
            result = simulate_into_blender(
                bpy.path.abspath(settings.scene_path), overrides=_overrides(settings),
                out=_output_dir(settings), surface=settings.surface,
                exaggeration=settings.exaggeration or None,
                collection=context.scene.collection)
        except (RenderInspectError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"render_inspect: {result['object'].name} from {result['heightmap']}")
        return {"FINISHED"}


class RENDER_INSPECT_OT_render(bpy.types.Operator):
    """Render the simulated surface with Cycles under the diffuse light of its scene"""

    bl_idname = "render_inspect.render"
    bl_label = "Render"
    bl_options = {"REGISTER"}

    def execute(self, context):
        from render_inspect.render._cycles import OBJECT_NAME, render_object

        settings = context.scene.render_inspect
        try:
            result = render_object(
                bpy.data.objects.get(OBJECT_NAME), view=settings.view,
                out=_output_dir(settings), resolution=settings.resolution,
                spp=settings.samples, seed=settings.seed, load_image=True)
        except (RenderInspectError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"render_inspect: wrote {result['png']}")
        return {"FINISHED"}


CLASSES = (RENDER_INSPECT_OT_simulate, RENDER_INSPECT_OT_render)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
