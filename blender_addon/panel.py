"""The sidebar panel (3D View > Sidebar > render_inspect).  It only draws."""

import bpy


class RENDER_INSPECT_PT_main(bpy.types.Panel):
    bl_label = "render_inspect"
    bl_idname = "RENDER_INSPECT_PT_main"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "render_inspect"

    def draw(self, context):
        settings = context.scene.render_inspect
        layout = self.layout
        layout.prop(settings, "scene_path")
        layout.prop(settings, "output_dir")
        box = layout.box()
        box.label(text="Overrides (0 = from scene)")
        box.prop(settings, "spindle_rpm")
        box.prop(settings, "feed_mm_per_min")
        box.prop(settings, "nose_radius")
        box.prop(settings, "compensation")
        box.prop(settings, "extra_overrides")
        col = layout.column(align=True)
        col.prop(settings, "surface")
        col.prop(settings, "exaggeration")
        layout.operator("render_inspect.simulate", icon="MOD_DISPLACE")
        col = layout.column(align=True)
        col.prop(settings, "view")
        col.prop(settings, "resolution")
        col.prop(settings, "samples")
        col.prop(settings, "seed")
        layout.operator("render_inspect.render", icon="RENDER_STILL")


CLASSES = (RENDER_INSPECT_PT_main,)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
