"""Settings the panel shows and the operators read (``scene.render_inspect``).

``preset`` picks one of the scenes shipped with render_inspect; ``scene_path``, when set,
is used instead.  The scene's main numbers (design, tool, process, simulation) are listed
in ``params``: a changed value becomes a ``section.key=value`` override.
"""

import json
import math

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       IntProperty, PointerProperty, StringProperty)

from . import _callbacks
from ._scenes import (DEFAULT_PRESET, PARAM_SECTIONS, load_params, preset_path, scan_presets,
                      scene_file, scenes_folder)

#: Property callbacks live in _callbacks.py, a module without ``bpy`` in its globals (why:
#: its docstring).
variant_items = _callbacks.variant_items


#: The panel's file fields that become scene keys: (property, scene key).
FILE_FIELDS = (("program_path", "process.program"), ("edge_path", "tool.edge_profile"))
#: What the panel calls each file field (its errors name it).
FIELD_NAMES = {"scene_path": "Scene file", "program_path": "Program file",
               "edge_path": "Tool edge file", "measured_path": "Measured file",
               "output_dir": "Output folder"}


def file_field(settings, field: str) -> str:
    """The absolute path in the panel's file field ``field`` ('//' relative to the .blend
    file), or '' when it is empty."""
    text = getattr(settings, field).strip()
    return bpy.path.abspath(text) if text else ""


def overrides(settings) -> list[str]:
    """The ``section.key=value`` overrides the panel stands for."""
    out = []
    if settings.params_source == scene_file(settings):
        for item in settings.params:
            if not math.isclose(item.value, item.original, rel_tol=1e-9, abs_tol=0.0):
                # a FloatProperty is single precision: 7 significant digits are what was
                # typed; a whole number stays an integer where the file had one
                value = float(f"{item.value:.7g}")
                if item.is_int and value.is_integer():
                    value = int(value)
                out.append(f"{item.key}={value!r}")
    if settings.compensation != "SCENE":
        out.append(f'process.compensation="{settings.compensation}"')
    for field, key in FILE_FIELDS:
        path = file_field(settings, field)
        if path:
            out.append(f"{key}={json.dumps(path)}")
    out.extend(item.strip() for item in settings.extra_overrides.split(";") if item.strip())
    return out


class RenderInspectParam(bpy.types.PropertyGroup):
    """One number of the scene file."""

    key: StringProperty(name="Key", description="section.key in the scene file")
    section: StringProperty(name="Section")
    value: FloatProperty(name="Value", precision=6, description="Changed values become overrides")
    original: FloatProperty(name="Scene value", precision=6)
    is_int: BoolProperty(name="Integer")


class RenderInspectSettings(bpy.types.PropertyGroup):
    """Scene, overrides, what to render and export, and the state the panel shows."""

    # preset: an EnumProperty of the shipped scenes, added in register()
    scene_path: StringProperty(
        name="Scene file", subtype="FILE_PATH", default="", update=_callbacks.scene_changed,
        description="A render_inspect scene (TOML); used instead of the preset when set")
    program_path: StringProperty(
        name="Program file", subtype="FILE_PATH", default="",
        description="A machine program (NC / G-code / C X Z point list) simulated in place of "
                    "the planned path (process.program; the scene gives the rest)")
    edge_path: StringProperty(
        name="Tool edge file", subtype="FILE_PATH", default="",
        description="The measured cutting edge of your tool (tool.edge_profile: a table "
                    "'angle_deg, deviation_nm', 'angle_deg, radius_um' or 'x_um, z_um'); "
                    "empty: the scene's")
    measured_path: StringProperty(
        name="Measured file", subtype="FILE_PATH", default="",
        description="Compare against this measurement (compare --measured): a height map "
                    "(X3P, EXR, SUR, ...) as a third column, or a profile (text export, "
                    ".opdx, X3P PRF) along a line of the part")
    measured_units: StringProperty(
        name="Profile units", default="",
        description="A measured profile's units when its file does not state them (compare "
                    "--units): um, mm, nm or POSITION,HEIGHT, e.g. um,nm")
    measured_line: StringProperty(
        name="Profile line", default="",
        description="The line of a measured profile on the part, X0,Y0,X1,Y1 in mm (compare "
                    "--line); empty: for a turned part a diameter through the spindle axis")
    output_dir: StringProperty(
        name="Output folder", subtype="DIR_PATH", default="",
        description="Where the simulation, renders, report and exports go (empty: "
                    "render_inspect_out/<scene> next to the saved .blend file, else in the "
                    "system's temporary folder)")
    params: CollectionProperty(type=RenderInspectParam)
    params_source: StringProperty(name="Parameters read from", default="")
    design_type: StringProperty(name="Design", default="")
    scene_name: StringProperty(name="Scene name", default="")
    compensation: EnumProperty(
        name="Compensation",
        items=(("SCENE", "From scene", "Keep the scene's process.compensation"),
               ("none", "None", "No tool-radius compensation"),
               ("normal", "Normal", "Offset along the surface normal"),
               ("z", "Z", "Z-direction compensation (max over the tool contacts)")),
        default="SCENE",
        description="process.compensation of the compensated variant (the other is cut "
                    "without compensation)")
    extra_overrides: StringProperty(
        name="More overrides", default="",
        description="Further section.key=value overrides (TOML values), separated by ';'")
    surface: EnumProperty(
        name="Surface",
        items=(("machined", "Machined", "The simulated machined surface"),
               ("design", "Design", "The design surface"),
               ("residual", "Residual", "Machined minus design")),
        default="machined", description="Which height layer becomes the meshes")
    exaggeration: FloatProperty(
        name="Exaggeration", default=0.0, min=0.0, max=1e7,
        description="Vertical exaggeration of the meshes; 0 uses render.diffuse.exaggeration "
                    "(or, when the scene leaves it unset, the renderer's automatic choice)")
    variant: EnumProperty(
        name="Variant", items=variant_items,
        description="Which simulated surface Render and Export use (the variants of the last "
                    "Simulate)")
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
    render_interferogram: BoolProperty(
        name="Interferogram", default=True,
        description="Also render the scene's interference microscope (needs Mitsuba)")
    export_formats: EnumProperty(
        name="Formats", options={"ENUM_FLAG"},
        items=(("EXR", "EXR", "heightmap.exr: design, machined, residual (mm)"),
               ("PLY", "PLY", "The mesh in mm, +Z up"),
               ("GLB", "GLB", "The mesh as glTF: metres, +Y up"),
               ("X3P", "X3P", "The machined surface as ISO 25178-72 X3P")),
        default={"EXR", "PLY", "X3P"}, description="What Export writes")
    open_report: BoolProperty(
        name="Open report", default=True,
        description="Open report.html in the web browser when Compare is done")
    # state drawn by the panel
    job_running: BoolProperty(name="Running", default=False)
    job_label: StringProperty(name="Job", default="")
    job_message: StringProperty(name="Step", default="")
    job_progress: FloatProperty(name="Progress", default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    cancel_requested: BoolProperty(name="Cancel requested", default=False)
    last_error: StringProperty(name="Error", default="")
    last_message: StringProperty(name="Message", default="")
    last_warnings: StringProperty(name="Warnings", default="",
                                  description="The last run's warnings, one a line")
    output_path: StringProperty(name="Output", default="", subtype="DIR_PATH")
    simulation_json: StringProperty(name="Simulation", default="")
    compare_json: StringProperty(name="Comparison", default="")
    report_path: StringProperty(name="Report", default="", subtype="FILE_PATH")


CLASSES = (RenderInspectParam, RenderInspectSettings)


def _preset_property() -> EnumProperty:
    items = tuple(scan_presets())
    names = [i[0] for i in items]
    return EnumProperty(name="Preset", items=items, update=_callbacks.scene_changed,
                        default=DEFAULT_PRESET if DEFAULT_PRESET in names else names[0],
                        description="A scene shipped with render_inspect")


def register():
    RenderInspectSettings.__annotations__["preset"] = _preset_property()
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.render_inspect = PointerProperty(type=RenderInspectSettings)


def unregister():
    del bpy.types.Scene.render_inspect
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
