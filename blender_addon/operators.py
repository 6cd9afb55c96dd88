"""Operators: Simulate, Render, Compare, Export (and Cancel, Open report, Load parameters).

Each long operator reads its settings on the main thread (``prepare``), runs a task of
``_tasks.py`` (one :mod:`render_inspect.pipeline` call) and then, on the main thread
again, shows the result in Blender through the pipeline (``finish``).  Started from the
panel (``INVOKE_DEFAULT``) the task runs in a worker process while a modal timer updates
the progress bar and the status bar; Esc cancels it and nothing is created.  From scripts (``bpy.ops.render_inspect.simulate()``) and in background
mode the same task runs synchronously and the operator returns ``{'FINISHED'}``.  Errors of
render_inspect reach the user through ``self.report`` in one line.

No operator carries UNDO: Simulate makes meshes of up to millions of vertices, and Blender
would keep a copy of them for undo.
"""

import json
import webbrowser
from pathlib import Path

import bpy

from . import _deps, _jobs, _lib
from .properties import FIELD_NAMES, FILE_FIELDS, file_field, load_params, overrides, scene_file


#: The custom property on the meshes Simulate makes (``render_inspect.pipeline``'s
#: ``VARIANT_PROPERTY``), read here so that drawing the panel never imports the pipeline.
VARIANT_PROPERTY = "render_inspect_variant"


def has_variant(variant: str) -> bool:
    return any(o.get(VARIANT_PROPERTY) == variant for o in bpy.data.objects)


class AddonError(Exception):
    """A problem with the panel's settings, reported in one line."""


def one_line(text: str) -> str:
    """A message of several lines (render_inspect lists every bad key on its own line) as
    one line for the status bar."""
    lines = [line.strip() for line in str(text).splitlines() if line.strip()]
    if not lines:
        return ""
    return lines[0] + ("" if len(lines) == 1 else " " + "; ".join(lines[1:]))


def _error_text(err) -> str:
    try:
        RenderInspectError = _lib.module("errors").RenderInspectError  # noqa: N806
    except ImportError:
        RenderInspectError = ()  # noqa: N806
    if isinstance(err, (AddonError, OSError)) or (RenderInspectError and
                                                  isinstance(err, RenderInspectError)):
        return str(err)
    return f"{type(err).__name__}: {err}"


def _settings(context):
    return context.scene.render_inspect


def output_root(settings) -> Path:
    """The output folder: the panel's, else ``render_inspect_out/<scene>`` next to the saved
    .blend file, else in the system's temporary folder."""
    pipeline = _lib.module("pipeline")

    if settings.output_dir.strip():
        return Path(bpy.path.abspath(settings.output_dir.strip())).resolve()
    name = settings.scene_name or Path(scene_file(settings) or "scene").stem
    return pipeline.blender_output_dir(name).resolve()


def variant_objects() -> dict:
    """{variant: object} of the meshes Simulate made."""
    pipeline = _lib.module("pipeline")

    return pipeline.blender_surfaces()


def _variant_source(settings) -> dict:
    """Height map, surface, exaggeration of the variant the panel chose."""
    pipeline = _lib.module("pipeline")

    obj = variant_objects().get(settings.variant)
    if obj is None:
        raise AddonError(f"no {settings.variant} surface: run Simulate first")
    return pipeline.surface_info(obj)


def check_file(settings, field: str) -> str:
    """The file in the panel's field ``field`` ('' when empty); one line naming the field
    when it is not a file."""
    path = file_field(settings, field)
    if path and not Path(path).is_file():
        what = "is a folder" if Path(path).is_dir() else "does not exist"
        raise AddonError(f"{FIELD_NAMES[field]}: {path!r} {what}; choose a file")
    return path


def _scene_params(settings) -> dict:
    for field in ("scene_path", *(f for f, _ in FILE_FIELDS)):
        check_file(settings, field)
    path = scene_file(settings)
    if not path:
        raise AddonError("scene: choose a preset or a scene file (.toml) first")
    if settings.params_source != path:
        load_params(settings)
    return {"scene_path": path, "overrides": overrides(settings)}


def _redraw(context):
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type in {"VIEW_3D", "STATUSBAR"}:
                area.tag_redraw()


class _Work:
    """Mixin of the long operators: prepare -> task (worker or here) -> finish."""

    _job = None

    task = ""
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        settings = getattr(context.scene, "render_inspect", None)
        if settings is None:
            return False
        if settings.job_running:
            cls.poll_message_set("render_inspect is running a job: wait, or press Esc")
            return False
        miss = _deps.missing_for(cls.task)
        if miss:
            cls.poll_message_set("not available on this platform: "
                                 + ", ".join(m[1] for m in miss))
            return False
        return cls.ready(context, settings)

    @classmethod
    def ready(cls, context, settings) -> bool:
        return True

    # Each operator defines the two main-thread steps around its task:
    #   prepare(context) -> (task parameters, output folders the task writes); raises
    #       AddonError (or render_inspect's errors) on bad settings;
    #   finish(context, params, result) -> message; creates the Blender data.

    # -- synchronous: scripts and background mode --------------------------------------
    def execute(self, context):
        settings = _settings(context)
        try:
            params, _ = self.prepare(context)
        except Exception as err:
            return self._fail(context, err)
        settings.last_error = settings.last_warnings = ""
        settings.job_label = self.bl_label
        try:
            result = _jobs.run_here(self.task, params)
            message = self.finish(context, params, result)
        except Exception as err:
            return self._fail(context, err)
        return self._done(context, message, result)

    def _done(self, context, message: str, result) -> set:
        """Report the result and, as the command line does, each of its warnings (one
        line each: also kept for the panel)."""
        settings = _settings(context)
        warns = [one_line(w) for w in (result or {}).get("warnings") or [] if str(w).strip()]
        settings.last_warnings = "\n".join(warns)
        if warns:
            message += f" ({len(warns)} warning{'s' if len(warns) > 1 else ''}, in the panel)"
        settings.last_message = message
        for text in warns:
            self.report({"WARNING"}, text)
        self.report({"INFO"}, message)
        return {"FINISHED"}

    # -- in the UI: a worker process and a modal timer -----------------------------------
    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        settings = _settings(context)
        try:
            params, outs = self.prepare(context)
            self._job = _jobs.start(self.task, params, out_dirs=outs)
        except Exception as err:
            return self._fail(context, err)
        self._params = params
        settings.last_error = settings.last_warnings = ""
        settings.job_running = True
        settings.cancel_requested = False
        settings.job_label = self.bl_label
        settings.job_progress = 0.0
        settings.job_message = "starting"
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.25, window=context.window)
        wm.modal_handler_add(self)
        self._status(context)
        return {"RUNNING_MODAL"}

    def _status(self, context, clear=False):
        settings = _settings(context)
        text = None if clear else (f"render_inspect {settings.job_label}: {settings.job_message} "
                                   f"({100 * settings.job_progress:.0f} %), Esc to cancel")
        if context.workspace is not None:
            context.workspace.status_text_set(text)
        _redraw(context)

    def _end(self, context):
        settings = _settings(context)
        context.window_manager.event_timer_remove(self._timer)
        settings.job_running = False
        settings.cancel_requested = False
        self._status(context, clear=True)
        _jobs.finish_current()

    def modal(self, context, event):
        settings = _settings(context)
        job = self._job
        if (event.type == "ESC" and event.value == "PRESS") or settings.cancel_requested:
            job.cancel()
            self._end(context)
            settings.last_message = f"{self.bl_label} cancelled: nothing was created"
            self.report({"WARNING"}, settings.last_message)
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        state = job.state
        settings.job_progress = job.progress
        settings.job_message = job.message
        if state == "running":
            self._status(context)
            return {"PASS_THROUGH"}
        job.clean()
        self._end(context)
        if state != "finished":
            return self._fail(context, AddonError(job.error or state))
        try:
            message = self.finish(context, self._params, job.result)
        except Exception as err:
            return self._fail(context, err)
        return self._done(context, message, job.result)

    def _fail(self, context, err):
        settings = _settings(context)
        settings.last_warnings = ""
        settings.last_error = one_line(f"{self.bl_label}: {_error_text(err)}")
        self.report({"ERROR"}, settings.last_error)
        return {"CANCELLED"}


class RENDER_INSPECT_OT_simulate(_Work, bpy.types.Operator):
    """Simulate the two variants of the process (compensated and uncompensated for
    turning) and show them side by side"""

    bl_idname = "render_inspect.simulate"
    bl_label = "Simulate"
    task = "simulate"

    def prepare(self, context):
        settings = _settings(context)
        p = _scene_params(settings)
        out = output_root(settings)
        p.update(out=str(out), surface=settings.surface,
                 exaggeration=float(settings.exaggeration) or None)
        return p, [out]

    def finish(self, context, params, result):
        pipeline = _lib.module("pipeline")

        settings = _settings(context)
        made = pipeline.surfaces_into_blender(result, collection=context.scene.collection)
        settings.output_path = result["out"]
        settings.simulation_json = json.dumps(result)
        settings.compare_json = ""
        settings.report_path = ""
        names = ", ".join(o.name for o in made.values())
        return (f"simulated {result['scene_name']}: {names} "
                f"(heights x{result['exaggeration']:g}) -> {result['out']}")


class RENDER_INSPECT_OT_render(_Work, bpy.types.Operator):
    """Render the chosen surface with Cycles under its scene's diffuse light, and its
    interferogram with the scene's microscope; both become Blender images"""

    bl_idname = "render_inspect.render"
    bl_label = "Render"
    task = "render"

    @classmethod
    def ready(cls, context, settings):
        if not has_variant(settings.variant):
            cls.poll_message_set("run Simulate first")
            return False
        return True

    def prepare(self, context):
        settings = _settings(context)
        src = _variant_source(settings)
        out = Path(src["heightmap"]).parent
        p = dict(src, view=settings.view, resolution=settings.resolution,
                 samples=settings.samples, seed=settings.seed, out=str(out),
                 interferogram=bool(settings.render_interferogram))
        return p, [out]

    def finish(self, context, params, result):
        pipeline = _lib.module("pipeline")

        names = pipeline.load_render_images(result)
        notes = "; ".join(result.get("notes", []))
        return (f"rendered {', '.join(names)} -> {Path(result['cycles_png']).parent}"
                + (f" ({notes})" if notes else ""))


class RENDER_INSPECT_OT_compare(_Work, bpy.types.Operator):
    """The process's two variants (compensated vs uncompensated for turning): simulate,
    render, measure with the virtual microscope and write report.html (opened in the web
    browser)"""

    bl_idname = "render_inspect.compare"
    bl_label = "Compare"
    task = "compare"

    def prepare(self, context):
        settings = _settings(context)
        p = _scene_params(settings)
        out = output_root(settings) / "compare"
        p["out"] = str(out)
        measured = check_file(settings, "measured_path")
        if measured:
            p.update(measured=measured, units=settings.measured_units.strip() or None,
                     line=settings.measured_line.strip() or None)
        elif settings.measured_units.strip() or settings.measured_line.strip():
            raise AddonError("Profile units and Profile line are for a measured profile: "
                             "choose the Measured file, or empty them")
        return p, [out]

    def finish(self, context, params, result):
        settings = _settings(context)
        settings.compare_json = json.dumps(result)
        settings.report_path = result["report"]
        if settings.open_report and not bpy.app.background:
            webbrowser.open(Path(result["report"]).as_uri())
        against = f" with {Path(params['measured']).name}" if params.get("measured") else ""
        return f"compared{against}: {result['report']}"


class RENDER_INSPECT_OT_export(_Work, bpy.types.Operator):
    """Export the chosen surface: EXR height map, PLY / GLB mesh, X3P"""

    bl_idname = "render_inspect.export"
    bl_label = "Export"
    task = "export"

    @classmethod
    def ready(cls, context, settings):
        if not has_variant(settings.variant):
            cls.poll_message_set("run Simulate first")
            return False
        if "X3P" in settings.export_formats and not _deps.has_x3p():
            cls.poll_message_set("X3P export is not available on this platform")
            return False
        return True

    def prepare(self, context):
        settings = _settings(context)
        src = _variant_source(settings)
        out = Path(src["heightmap"]).parent.parent / "export" / settings.variant
        p = dict(src, formats=sorted(settings.export_formats), out=str(out))
        return p, [out]

    def finish(self, context, params, result):
        return f"exported {', '.join(result['files'])} -> {result['out']}"


class RENDER_INSPECT_OT_cancel(bpy.types.Operator):
    """Stop the running render_inspect job (the same as Esc)"""

    bl_idname = "render_inspect.cancel"
    bl_label = "Cancel"
    bl_options = {"INTERNAL"}

    @classmethod
    def poll(cls, context):
        return context.scene.render_inspect.job_running

    def execute(self, context):
        context.scene.render_inspect.cancel_requested = True
        return {"FINISHED"}


class RENDER_INSPECT_OT_open_report(bpy.types.Operator):
    """Open the comparison report in the web browser"""

    bl_idname = "render_inspect.open_report"
    bl_label = "Open report"
    bl_options = {"INTERNAL"}

    @classmethod
    def poll(cls, context):
        path = context.scene.render_inspect.report_path
        return bool(path) and Path(path).is_file()

    def execute(self, context):
        webbrowser.open(Path(context.scene.render_inspect.report_path).as_uri())
        return {"FINISHED"}


class RENDER_INSPECT_OT_load_parameters(bpy.types.Operator):
    """Read the main numbers of the scene file again (changed values are lost)"""

    bl_idname = "render_inspect.load_parameters"
    bl_label = "Load parameters"
    bl_options = {"INTERNAL"}

    def execute(self, context):
        load_params(context.scene.render_inspect)
        return {"FINISHED"}


CLASSES = (RENDER_INSPECT_OT_simulate, RENDER_INSPECT_OT_render, RENDER_INSPECT_OT_compare,
           RENDER_INSPECT_OT_export, RENDER_INSPECT_OT_cancel, RENDER_INSPECT_OT_open_report,
           RENDER_INSPECT_OT_load_parameters)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    _jobs.cancel_current()
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
