"""The pipeline as the Blender add-on drives it: simulate a scene and load the surface
into Blender as a mesh object."""

from __future__ import annotations

from pathlib import Path

from ..core.errors import InputError, check_positive
from ..io import atomic_output_dir, write_heightmap_exr
from ..render import auto_exaggeration, default_output_dir, surface_object
from ..render._cycles import PROP_HEIGHTMAP
from ..scene import load_scene
from ._simulate import simulate

__all__ = ["simulate_into_blender"]


def simulate_into_blender(scene_path, *, overrides=(), out=None, surface: str = "machined",
                          exaggeration: float | None = None, collection=None) -> dict:
    """Load a scene file, simulate the machined surface and load it as a mesh object.

    Parameters
    ----------
    scene_path : str or Path
        render_inspect scene (TOML) or the name of a shipped scene.
    overrides : sequence of str
        ``section.key=value`` overrides (the CLI's ``--set``).
    out : str, Path or None
        Folder for ``heightmap.exr``, replaced as a whole (a non-empty folder render_inspect
        did not write is refused); None: :func:`~render_inspect.render.default_output_dir`.
    surface : {"machined", "design", "residual"}
        The height layer that becomes the mesh.
    exaggeration : float or None
        Vertical exaggeration; None uses the scene's ``render.diffuse.exaggeration``, and
        when that is unset too, :func:`~render_inspect.render.auto_exaggeration` of the
        simulated surface (as the Mitsuba renders do).
    collection : bpy.types.Collection or None
        Where to link the object (the active scene's collection when None).

    Returns
    -------
    dict
        ``object`` (bpy.types.Object named ``render_inspect_surface``), ``heightmap``
        (Path of the EXR), ``result`` (Simulation), ``scene`` (Scene).
    """
    if not str(scene_path).strip():
        raise InputError("scene file: choose a render_inspect scene (.toml) first; received an empty path")
    scene = load_scene(scene_path, list(overrides))
    if exaggeration is not None:
        check_positive("exaggeration", exaggeration)
    own = not out  # the add-on's own default folder may be replaced whatever it holds
    out = Path(out) if out else default_output_dir(scene.name)
    # the folder is checked and locked before the simulation, swapped in when complete
    with atomic_output_dir(out, command="blender", scene=scene, option="output folder",
                           overwrite=own) as tmp:
        result = simulate(scene)
        hm = result.heightmap
        write_heightmap_exr(tmp / "heightmap.exr", hm)
    if exaggeration is None:
        exaggeration = scene.render.diffuse.exaggeration
    if exaggeration is None:  # the renderer's automatic choice for this height map
        exaggeration = auto_exaggeration(hm, surface)
    exaggeration = float(exaggeration)
    path = out.resolve() / "heightmap.exr"
    obj = surface_object(hm, surface=surface, exaggeration=exaggeration, collection=collection)
    obj[PROP_HEIGHTMAP] = str(path)
    return {"object": obj, "heightmap": path, "result": result, "scene": scene}
