"""render_inspect for Blender: simulate a diamond-machined surface (compensated and
uncompensated, side by side), render it with Cycles and the virtual interference
microscope, compare the two in a report and export EXR, PLY/GLB and X3P.

A self-contained extension: render_inspect and its dependencies come as wheels inside the
extension (NumPy comes with Blender).  The add-on imports them only when an operator runs,
so it enables even where a wheel is missing; the panel then names what is missing.
"""

import bpy

from . import operators, panel, properties

_MODULES = (properties, operators, panel)


@bpy.app.handlers.persistent
def _reset_job_state(*_):
    """A .blend saved while a job ran must not open as busy."""
    for scene in bpy.data.scenes:
        settings = getattr(scene, "render_inspect", None)
        if settings is not None and settings.job_running:
            settings.job_running = False
            settings.cancel_requested = False


def register():
    for module in _MODULES:
        module.register()
    bpy.app.handlers.load_post.append(_reset_job_state)


def unregister():
    if _reset_job_state in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_reset_job_state)
    for module in reversed(_MODULES):
        module.unregister()
