"""The sidebar panels (3D View > Sidebar > render_inspect).  They only draw."""

import json

import bpy

from . import _deps
from .properties import PARAM_SECTIONS, scene_file


def _wrapped(layout, text: str, *, icon="NONE", width: int = 48) -> None:
    """Draw ``text`` as a few labels of at most ``width`` characters."""
    words, line, first = text.split(), "", True
    for word in words:
        if line and len(line) + 1 + len(word) > width:
            layout.label(text=line, icon=icon if first else "BLANK1")
            line, first = word, False
        else:
            line = f"{line} {word}".strip()
    if line:
        layout.label(text=line, icon=icon if first else "BLANK1")


def _loads(text: str) -> dict:
    try:
        return json.loads(text) if text else {}
    except ValueError:
        return {}


def _fmt(value) -> str:
    return "-" if value is None else f"{value:.3g}"


class RENDER_INSPECT_PT_main(bpy.types.Panel):
    bl_label = "render_inspect"
    bl_idname = "RENDER_INSPECT_PT_main"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "render_inspect"

    def draw(self, context):
        settings = context.scene.render_inspect
        layout = self.layout
        missing = _deps.missing()
        if missing:
            box = layout.box()
            box.alert = True
            box.label(text="Not available on this platform:", icon="ERROR")
            for module, dist, use in missing:
                box.label(text=f"{dist} ({use})", icon="BLANK1")
        col = layout.column(align=True)
        col.prop(settings, "preset")
        col.prop(settings, "scene_path", text="File")
        if settings.scene_path.strip():
            col.label(text="The file is used instead of the preset", icon="INFO")
        col.prop(settings, "program_path", text="Program")
        if settings.program_path.strip():
            col.label(text="The program is cut instead of the planned path", icon="INFO")
        col.prop(settings, "edge_path", text="Tool edge")
        if settings.edge_path.strip():
            col.label(text="This measured edge replaces the scene's", icon="INFO")
        layout.prop(settings, "output_dir")
        if settings.job_running:
            box = layout.box()
            box.label(text=f"{settings.job_label}: {settings.job_message}", icon="SORTTIME")
            box.progress(factor=settings.job_progress, type="BAR",
                         text=f"{100 * settings.job_progress:.0f} %")
            box.operator("render_inspect.cancel", icon="CANCEL", text="Cancel (Esc)")
        if settings.last_error:
            box = layout.box()
            box.alert = True
            _wrapped(box, settings.last_error, icon="ERROR")
        elif settings.last_message and not settings.job_running:
            _wrapped(layout.box(), settings.last_message, icon="CHECKMARK")
        if settings.last_warnings and not settings.job_running:
            box = layout.box()
            box.alert = True
            for text in settings.last_warnings.splitlines():
                _wrapped(box, text, icon="ERROR")

        col = layout.column(align=True)
        col.prop(settings, "surface")
        col.prop(settings, "exaggeration")
        layout.operator("render_inspect.simulate", icon="MOD_DISPLACE")
        sim = _loads(settings.simulation_json)
        if sim:
            box = layout.box()
            box.label(text=f"{sim.get('scene_name', '')}: heights x{sim.get('exaggeration', 0):g}")
            for variant, info in sim.get("variants", {}).items():
                r = info.get("residual", {})
                box.label(text=f"{variant}: Sq {_fmt(r.get('Sq_nm'))} nm, "
                               f"min {_fmt(r.get('min_nm'))} nm", icon="MESH_GRID")
        layout.prop(settings, "variant", expand=True)
        col = layout.column(align=True)
        col.prop(settings, "view")
        col.prop(settings, "resolution")
        col.prop(settings, "samples")
        col.prop(settings, "seed")
        row = col.row()
        row.enabled = _deps.has_mitsuba()
        row.prop(settings, "render_interferogram")
        layout.operator("render_inspect.render", icon="RENDER_STILL")
        col = layout.column(align=True)
        col.prop(settings, "measured_path", text="Measured")
        if settings.measured_path.strip():
            col.prop(settings, "measured_units")
            col.prop(settings, "measured_line")
        layout.operator("render_inspect.compare", icon="VIEWZOOM")
        layout.prop(settings, "export_formats", expand=True)
        layout.operator("render_inspect.export", icon="EXPORT")


class RENDER_INSPECT_PT_parameters(bpy.types.Panel):
    bl_label = "Scene parameters"
    bl_idname = "RENDER_INSPECT_PT_parameters"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "render_inspect"
    bl_parent_id = "RENDER_INSPECT_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = context.scene.render_inspect
        layout = self.layout
        if settings.params_source != scene_file(settings):
            layout.operator("render_inspect.load_parameters", icon="FILE_REFRESH")
            return
        if settings.design_type:
            layout.label(text=f"Design: {settings.design_type}")
        for section in PARAM_SECTIONS:
            items = [p for p in settings.params if p.section == section]
            if not items:
                continue
            col = layout.column(align=True)
            col.label(text=section.capitalize())
            for item in items:
                changed = abs(item.value - item.original) > 1e-12 * max(1.0, abs(item.original))
                row = col.row(align=True)
                row.alert = changed
                row.prop(item, "value", text=item.key.split(".", 1)[1])
        layout.prop(settings, "compensation")
        layout.prop(settings, "extra_overrides")
        layout.operator("render_inspect.load_parameters", text="Reset to the scene's values",
                        icon="LOOP_BACK")


class RENDER_INSPECT_PT_results(bpy.types.Panel):
    bl_label = "Comparison"
    bl_idname = "RENDER_INSPECT_PT_results"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "render_inspect"
    bl_parent_id = "RENDER_INSPECT_PT_main"

    def draw(self, context):
        settings = context.scene.render_inspect
        layout = self.layout
        comp = _loads(settings.compare_json)
        if not comp:
            layout.label(text="Run Compare to see the metrics here")
            return
        names = list(comp.get("variants") or ("compensated", "uncompensated"))
        heads = list(comp.get("labels") or names) if comp.get("kind") == "profile" else names
        grid = layout.grid_flow(columns=1 + len(names), align=True, row_major=True,
                                even_columns=True)
        for text in ("", *heads):
            grid.label(text=text)
        for row in comp.get("rows", []):
            values = row.get("values") or [row.get(n) for n in names]
            grid.label(text=f"{row['label']} ({row['unit']})")
            for value in values:
                grid.label(text=_fmt(value))
        reg = comp.get("registration") or {}
        if comp.get("kind") == "profile":
            if comp.get("virtual_measurement") == "failed":
                layout.label(text="The virtual measurement failed (see the warnings)",
                             icon="ERROR")
            if reg.get("shift_um") is not None:
                layout.label(text=f"Registered {reg['shift_um']:+.3g} um along the line, "
                                  f"correlation {_fmt(reg.get('correlation'))}"
                                  + ("" if reg.get("reliable") else " (not reliable)"))
        if comp.get("difference_rms_nm") is not None:
            layout.label(text=f"Difference RMS: {comp['difference_rms_nm']:.3g} nm")
        layout.operator("render_inspect.open_report", icon="URL")
        layout.prop(settings, "open_report")


CLASSES = (RENDER_INSPECT_PT_main, RENDER_INSPECT_PT_parameters, RENDER_INSPECT_PT_results)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
