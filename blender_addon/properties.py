"""Settings the panel shows and the operators read (``scene.render_inspect``).

``preset`` picks one of the scenes shipped with render_inspect; ``scene_path``, when set,
is used instead.  The scene's main numbers (design, tool, process, simulation) are listed
in ``params``: a changed value becomes a ``section.key=value`` override.
"""

import json
import math
import tomllib
from pathlib import Path

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       IntProperty, PointerProperty, StringProperty)

from . import _callbacks, _lib

#: Sections of a scene file whose numbers the panel lists.
PARAM_SECTIONS = ("design", "tool", "process", "simulation")

# Blender keeps only pointers to enum item strings: the tuples live here.
_PRESET_ITEMS: list[tuple[str, str, str]] = []
_PRESET_PATHS: dict[str, str] = {}


def scenes_folder() -> Path | None:
    """The folder of the scenes shipped with render_inspect (package data of the copy in
    the extension or of an installed render_inspect; ``scenes/`` beside the package in a
    source checkout), found without importing render_inspect."""
    pkg = _lib.folder()
    if pkg is None:
        return None
    for folder in (pkg / "scenes", pkg / "data" / "scenes", pkg.parent / "scenes"):
        if any(folder.glob("*.toml")):
            return folder
    return None


def scan_presets() -> list[tuple[str, str, str]]:
    """(identifier, label, description) of every shipped scene, sorted by name."""
    _PRESET_ITEMS.clear()
    _PRESET_PATHS.clear()
    folder = scenes_folder()
    for path in sorted(folder.glob("*.toml")) if folder else ():
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError):
            continue
        name = path.stem
        desc = str(data.get("description", ""))[:200]
        _PRESET_ITEMS.append((name, name, desc))
        _PRESET_PATHS[name] = str(path)
    if not _PRESET_ITEMS:
        _PRESET_ITEMS.append(("NONE", "No shipped scenes", "render_inspect's scenes were not found"))
    return _PRESET_ITEMS


#: Property callbacks live in _callbacks.py, a module without ``bpy`` in its globals (why:
#: its docstring).
variant_items = _callbacks.variant_items


#: The preset chosen when nothing else is.
DEFAULT_PRESET = "sts_sinusoidal_grid"


def preset_path(name: str) -> str | None:
    return _PRESET_PATHS.get(name)


def scene_file(settings) -> str:
    """The scene file in use: ``scene_path`` when set, else the preset's file."""
    if settings.scene_path.strip():
        return bpy.path.abspath(settings.scene_path.strip())
    return preset_path(settings.preset) or ""


def load_params(settings) -> None:
    """Fill ``settings.params`` with the numbers of the scene file in use (empty when it
    cannot be read: Simulate then reports why)."""
    path = scene_file(settings)
    settings.params.clear()
    settings.params_source = path
    settings.design_type = ""
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    settings.design_type = str(data.get("design", {}).get("type", ""))
    settings.scene_name = str(data.get("name", Path(path).stem))
    for section in PARAM_SECTIONS:
        table = data.get(section, {})
        if not isinstance(table, dict):
            continue
        for key, value in table.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                continue
            item = settings.params.add()
            item.key = f"{section}.{key}"
            item.section = section
            item.is_int = isinstance(value, int)
            item.original = float(value)
            item.value = float(value)


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
    if settings.program_path.strip():
        program = bpy.path.abspath(settings.program_path.strip())
        out.append(f"process.program={json.dumps(program)}")
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
