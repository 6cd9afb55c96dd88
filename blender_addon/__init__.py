"""render_inspect for Blender: simulate a diamond-machined surface in the two variants
its process is compared in (compensated and uncompensated for turning; servo lag on and
off, vibration on and off, RCSE and conventional paths), side by side, render it with
Cycles and the virtual interference microscope, compare the two in a report and export
EXR, PLY/GLB and X3P.

A self-contained extension: render_inspect comes as source inside the extension and its
dependencies as wheels (NumPy comes with Blender).  The add-on imports them only when an
operator runs, so it enables even where a wheel is missing; the panel then names what is
missing.  Numba keeps its compiled kernels in the extension's user folder.
"""

import os

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


def _numba_cache() -> None:
    """Numba's cache in the extension's user folder (it would write beside the installed
    code otherwise); read by numba when it is first imported, so set here, before any
    operator imports render_inspect.  Only for the installed extension (a package of
    Blender's ``bl_ext``), and not over a folder the user chose."""
    if not __package__.startswith("bl_ext.") or "NUMBA_CACHE_DIR" in os.environ:
        return
    folder = os.path.join(bpy.utils.extension_path_user(__package__, create=True), "numba_cache")
    os.environ["NUMBA_CACHE_DIR"] = folder


def register():
    _numba_cache()
    for module in _MODULES:
        module.register()
    bpy.app.handlers.load_post.append(_reset_job_state)


def unregister():
    if _reset_job_state in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_reset_job_state)
    for module in reversed(_MODULES):
        module.unregister()
