"""Blender Cycles adapter: a height map as a ``bpy`` mesh and a Cycles CPU render of it.

The Cycles render reproduces the Mitsuba diffuse-light scene that
:func:`render_inspect.render.diffuse_scene_spec` describes (the same mesh, camera,
vertical exaggeration, environment light, aluminium conductor, samples per pixel, box
filter and path depth; built by :mod:`._cycles_scene`) so that the two engines can be
compared image for image (``benchmarks/bench_cycles.py``).  Blender units are mm: a
vertex is ``(x, y, exaggeration * z)`` with x, y, z in mm.

``bpy`` is imported lazily, inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

import json
import re
import tempfile
import time
from pathlib import Path
from collections.abc import Callable, Sequence
from typing import Any, cast

import numpy as np
from pydantic import ValidationError

from .. import __version__
from ..core.errors import InputError, SceneError, check_positive, check_range
from ..core.heightmap import HeightMap
from ..io import atomic_output_dir, save_png, write_exr
from ..mesh import GridMesh
from ._cycles_scene import (  # the scene (importable from here as before)
    ALUMINIUM_ETA,
    ALUMINIUM_K,
    F82_COS,
    RENDER_SCENE_NAME,
    _add_camera,
    _add_lamp,
    _add_world,
    _aluminium_material,
    _configure_cycles,
    _render,
    _render_scene,
    _srgb,
    f82_tint_colours,
    fresnel_conductor,
    material_model,
)
from ._diffuse import DiffuseConfig, diffuse_mesh, diffuse_scene_spec, mitsuba_seed

__all__ = ["heightmap_object", "surface_object", "gridmesh_object", "object_heights",
           "remove_object", "render_spec", "render_cycles", "render_object",
           "default_output_dir", "fresnel_conductor", "f82_tint_colours",
           "material_model", "load_image", "surface_material", "blend_objects", "ALUMINIUM_ETA", "ALUMINIUM_K",
           "OBJECT_NAME", "RENDER_SCENE_NAME"]

#: Name of the mesh object the add-on and :func:`heightmap_object` create.
OBJECT_NAME = "render_inspect_surface"

#: Largest grid turned into a Blender mesh (about 1.5 GB in Blender at this size).
MAX_VERTICES = 16_000_000

# custom properties on the mesh object (the add-on and tests read them)
PROP_EXAGGERATION = "render_inspect_exaggeration"
PROP_PIXEL = "render_inspect_pixel_mm"
PROP_ORIGIN = "render_inspect_origin_mm"
PROP_SHAPE = "render_inspect_shape"
PROP_SURFACE = "render_inspect_surface"
PROP_UNITS = "render_inspect_units"
PROP_SCENE = "render_inspect_scene"
PROP_HEIGHTMAP = "render_inspect_heightmap_path"
PROP_VARIANT = "render_inspect_variant"
PROP_OFFSET = "render_inspect_offset_mm"


def _bpy():
    import bpy

    return bpy


# ------------------------------------------------------------------------------------
# mesh


def _grid_mesh_arrays(heights: np.ndarray, *, pixel: float, origin, exaggeration: float):
    """Vertices (N, 3) float32 and quads (M, 4) int32 of a regular grid; quads that touch
    a NaN height are dropped (NaN vertices keep their place at the lowest valid height)."""
    ny, nx = heights.shape
    x = origin[0] + pixel * np.arange(nx)
    y = origin[1] + pixel * np.arange(ny)
    finite = np.isfinite(heights)
    if not finite.any():
        raise InputError("heights: every value is NaN; nothing to turn into a mesh")
    z = np.where(finite, heights, np.nanmin(heights)) * exaggeration
    verts = np.empty((ny, nx, 3), dtype=np.float64)
    verts[..., 0] = x[None, :]
    verts[..., 1] = y[:, None]
    verts[..., 2] = z
    idx = np.arange(ny * nx, dtype=np.int64).reshape(ny, nx)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1)
    keep = finite[:-1, :-1] & finite[:-1, 1:] & finite[1:, 1:] & finite[1:, :-1]
    return verts.reshape(-1, 3).astype(np.float32), quads[keep].reshape(-1, 4).astype(np.int32)


def heightmap_object(heights: np.ndarray, *, pixel: float, origin: Sequence[float] = (0.0, 0.0),
                     exaggeration: float = 1.0, name: str = OBJECT_NAME, collection: Any = None,
                     surface: str = "machined", metadata: dict | None = None) -> Any:
    """Build (or replace) a Blender mesh object from a height grid.

    Parameters
    ----------
    heights : (ny, nx) array, mm
        Row 0 is the smallest y, column 0 the smallest x.  NaN marks points no pass
        reached: their quads are left out of the mesh.
    pixel : float
        Grid spacing, mm (> 0).
    origin : (float, float)
        x, y of ``heights[0, 0]``, mm.
    exaggeration : float
        Vertical exaggeration (> 0): a vertex is ``(x, y, exaggeration * z)``.  Stored in
        the object's custom property ``render_inspect_exaggeration``.
    name : str
        Object and mesh name; an existing object of that name is removed first.
    collection : bpy.types.Collection or None
        Where to link the object; the active scene's collection when None.
    surface : {"machined", "design", "residual"}
        Recorded in the custom property ``render_inspect_surface``.
    metadata : dict or None
        Extra custom properties (str -> str/float/int).

    Returns
    -------
    bpy.types.Object
        Vertex ``iy * nx + ix`` is grid point ``(ix, iy)``.
    """
    bpy = _bpy()
    h = np.asarray(heights, dtype=np.float64)
    if h.ndim != 2 or min(h.shape) < 2:
        raise InputError(f"heights must be a 2-D array of at least 2 x 2 points, got shape {h.shape}")
    check_positive("pixel (mm)", pixel)
    check_positive("exaggeration", exaggeration)
    if h.size > MAX_VERTICES:
        raise InputError(f"heights: {h.shape[0]} x {h.shape[1]} = {h.size} points is more than "
                         f"the {MAX_VERTICES} vertices a Blender mesh is built from here; "
                         f"raise simulation.pixel or shrink simulation.region")
    verts, quads = _grid_mesh_arrays(h, pixel=float(pixel), origin=origin,
                                     exaggeration=float(exaggeration))
    remove_object(name)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.ravel())
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    (collection or bpy.context.scene.collection).objects.link(obj)
    obj[PROP_EXAGGERATION] = float(exaggeration)
    obj[PROP_PIXEL] = float(pixel)
    obj[PROP_ORIGIN] = [float(origin[0]), float(origin[1])]
    obj[PROP_SHAPE] = [int(h.shape[0]), int(h.shape[1])]
    obj[PROP_SURFACE] = str(surface)
    obj[PROP_UNITS] = "mm (z scaled by render_inspect_exaggeration)"
    for k, v in (metadata or {}).items():
        obj[k] = v
    return obj


def surface_object(heightmap: HeightMap, *, surface: str = "machined", exaggeration: float = 1.0,
                   name: str = OBJECT_NAME, collection: Any = None) -> Any:
    """:func:`heightmap_object` for a :class:`~render_inspect.machining.HeightMap`.

    ``surface`` picks the layer: "machined", "design" or "residual" (machined - design).
    """
    layers = {"machined": heightmap.machined, "design": heightmap.design,
              "residual": heightmap.residual}
    if surface not in layers:
        raise InputError(f"surface must be one of {sorted(layers)}, got {surface!r}")
    meta = {}
    if heightmap.scene:
        meta[PROP_SCENE] = json.dumps(heightmap.scene, sort_keys=True)
    return heightmap_object(layers[surface], pixel=heightmap.pixel, origin=heightmap.origin,
                            exaggeration=exaggeration, name=name, collection=collection,
                            surface=surface, metadata=meta)


def remove_object(name: str) -> None:
    """Remove the object ``name`` and its mesh, if they exist."""
    bpy = _bpy()
    obj = bpy.data.objects.get(name)
    if obj is not None:
        mesh = obj.data if obj.type == "MESH" else None
        bpy.data.objects.remove(obj, do_unlink=True)
        if mesh is not None and mesh.users == 0:
            bpy.data.meshes.remove(mesh)


def object_heights(obj: Any) -> np.ndarray:
    """The (ny, nx) z values of a mesh made by :func:`heightmap_object`, divided by its
    exaggeration (mm)."""
    ny, nx = (int(v) for v in obj[PROP_SHAPE])
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(ny, nx, 3)[..., 2].astype(np.float64) / float(obj[PROP_EXAGGERATION])


# ------------------------------------------------------------------------------------
# rendering (the scene: :mod:`._cycles_scene`)


def render_spec(obj: Any, spec: dict, *, seed: int = 0, z_shift: float = 0.0,
                threads: int | None = None, progress: Callable[[int, int], Any] | None = None) -> tuple[np.ndarray, float]:
    """Render a mesh object in the scene ``spec`` describes (:func:`diffuse_scene_spec`).

    Parameters
    ----------
    obj : bpy.types.Object
        The part's mesh (mm; z already exaggerated).
    spec : dict
        Camera, light, material, ``spp`` and ``max_depth``.
    seed : int
        Sampling seed, an integer >= 0 (same seed, same image, bit for bit); seeds from
        2^31 on are hashed into Cycles' range (:func:`mitsuba_seed`, 31 bits).
    z_shift : float
        mm added to the camera's z: the object's z minus the spec's mesh z (the light is
        at infinity, so this moves nothing else).
    threads : int or None
        CPU threads; None: all.
    progress : callable or None
        ``progress(samples_done, samples_total)`` while Cycles renders.

    Returns
    -------
    rgb : (H, W, 3) float32, linear RGB, row 0 at the top
    seconds : float, the render alone
    """
    bpy = _bpy()
    check_range("seed", seed, 0, None)
    if int(seed) != seed:
        raise InputError(f"seed must be an integer >= 0, received {seed!r}")
    seed = int(seed) if int(seed) < 2 ** 31 else mitsuba_seed(int(seed), 1) & 0x7FFFFFFF
    scene = _render_scene(bpy)
    scene.collection.objects.link(obj)
    mat = _aluminium_material(bpy, spec["material"])
    obj.data.materials.clear()
    obj.data.materials.append(mat)
    _add_camera(bpy, scene, spec["camera"], z_shift)
    _add_world(bpy, scene, spec["light"])
    if spec.get("lamp") is not None and spec["lamp"].get("irradiance"):
        _add_lamp(bpy, scene, spec["lamp"])
    _configure_cycles(scene, spec, seed=seed, threads=threads)
    return _render(bpy, scene, progress)


def gridmesh_object(gm: GridMesh, *, name: str = "render_inspect_part",
                    collection: Any = None) -> Any:
    """A Blender mesh object from a :class:`~render_inspect.mesh.GridMesh` (triangles,
    float32 vertices; its vertex normals become custom normals), via ``foreach_set``."""
    bpy = _bpy()
    remove_object(name)
    mesh = bpy.data.meshes.new(name)
    faces = np.ascontiguousarray(gm.faces, dtype=np.int32)
    mesh.vertices.add(gm.n_vertices)
    mesh.vertices.foreach_set("co", np.ascontiguousarray(gm.vertices, dtype=np.float32).ravel())
    mesh.loops.add(faces.size)
    mesh.loops.foreach_set("vertex_index", faces.ravel())
    mesh.polygons.add(len(faces))
    mesh.polygons.foreach_set("loop_start", np.arange(0, faces.size, 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.shade_smooth()
    if gm.normals is not None:
        mesh.normals_split_custom_set_from_vertices(np.asarray(gm.normals, dtype=np.float32))
    obj = bpy.data.objects.new(name, mesh)
    if collection is not None:
        collection.objects.link(obj)
    for k, v in gm.metadata.items():
        if isinstance(v, (int, float, str)):
            obj[f"render_inspect_{k}"] = v
    return obj


def _diffuse_config(dcfg, **overrides):
    """A validated ``[render.diffuse]`` (DiffuseConfig, dict or None) with ``overrides``
    (None values ignored) applied; bad values raise SceneError naming the key."""
    base = {} if dcfg is None else (dict(dcfg) if isinstance(dcfg, dict) else dcfg.model_dump())
    base.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return DiffuseConfig(**base)
    except ValidationError as err:
        lines = [f"render.diffuse.{'.'.join(map(str, e['loc']))}: {e['msg']}; "
                 f"received {e.get('input')!r}" for e in err.errors()]
        raise SceneError("invalid render settings:\n  " + "\n  ".join(lines)) from None


def render_cycles(heightmap: HeightMap, dcfg: DiffuseConfig | None = None, *, view: str = "macro", surface: str = "machined",
                  seed: int = 0, threads: int | None = None) -> tuple[np.ndarray, dict]:
    """Cycles counterpart of :func:`render_inspect.render.render_diffuse`: the same scene
    (:func:`~render_inspect.render.diffuse_scene_spec`: the same mesh, camera, light,
    aluminium, exaggeration, samples and path depth) rendered with Blender Cycles on the CPU.

    Resets Blender to an empty factory scene first: call it from scripts and tests, not
    from a Blender session you want to keep (the add-on uses :func:`render_object`).

    Parameters
    ----------
    heightmap : HeightMap
    dcfg : DiffuseConfig, dict or None
        ``[render.diffuse]`` (defaults when None).
    view : {"macro", "micro"};  surface : {"machined", "design"}
    seed : int
        Cycles sampling seed.
    threads : int or None
        CPU threads (None: all).

    Returns
    -------
    rgb : (height, width, 3) float32, linear radiance; row 0 at the top of the image
    meta : dict
        the spec plus ``renderer``, ``render_time_s``, ``mesh_time_s``, mesh sizes and
        ``vertical_exaggeration``
    """
    bpy = _bpy()
    dcfg = _diffuse_config(dcfg)
    spec = diffuse_scene_spec(heightmap, dcfg, view=view, surface=surface, seed=seed)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    t0 = time.perf_counter()
    gm, factor = diffuse_mesh(heightmap, spec)  # the very mesh Mitsuba renders
    obj = gridmesh_object(gm)
    mesh_time = time.perf_counter() - t0
    rgb, seconds = render_spec(obj, spec, seed=seed, threads=threads)
    meta = dict(spec)
    meta.update(renderer=f"blender-cycles {bpy.app.version_string}", render_time_s=seconds,
                mesh_time_s=mesh_time, vertical_exaggeration=spec["exaggeration"],
                mesh_vertices=gm.n_vertices, mesh_triangles=gm.n_faces,
                mesh_stride=int(factor))
    return rgb, meta


def _scene_diffuse(obj) -> dict:
    """The ``[render.diffuse]`` section recorded on the object (empty if none)."""
    try:
        return dict(json.loads(obj.get(PROP_SCENE, "{}")).get("render", {}).get("diffuse", {}))
    except (TypeError, ValueError, AttributeError):
        return {}


def render_object(obj: Any, *, view: str = "macro", out: str | Path | None = None,
                  resolution: int | None = None,
                  spp: int | None = None, seed: int = 0, threads: int | None = None,
                  load_image: bool = False,
                  progress: Callable[[int, int], Any] | None = None) -> dict:
    """Cycles render of a surface mesh made by :func:`heightmap_object` (the add-on's
    Render) under the diffuse light of the scene it was simulated from.

    The render happens in a private Blender scene (``render_inspect_cycles``) holding the
    object, the camera, the light and the aluminium material of
    :func:`~render_inspect.render.diffuse_scene_spec`; the user's scenes are left alone.

    Parameters
    ----------
    obj : bpy.types.Object
        Made by :func:`heightmap_object` / :func:`surface_object`.
    view : {"macro", "micro"}
    out : str, Path or None
        Folder for ``cycles.png`` (sRGB) and ``cycles.exr`` (linear RGB); None writes
        nothing.
    resolution, spp : int or None
        Override ``render.diffuse.resolution`` / ``spp`` of the recorded scene.
    seed : int
        Cycles sampling seed (same seed, same image, bit for bit).
    threads : int or None
    load_image : bool
        Also load ``cycles.png`` into ``bpy.data.images`` (to look at it in Blender).
    progress : callable or None
        ``progress(samples_done, samples_total)`` while Cycles renders.

    Returns
    -------
    dict
        ``image`` (H, W, 3) float32 linear RGB, row 0 at the top; ``time_s``; ``spec``;
        ``png``/``exr`` paths when ``out`` is given.
    """
    if obj is None or PROP_EXAGGERATION not in obj or PROP_SHAPE not in obj:
        raise InputError("render needs the render_inspect surface mesh: run Simulate first "
                         f"(no object named {OBJECT_NAME!r} with render_inspect properties)")
    ex = float(obj[PROP_EXAGGERATION])
    dcfg = _diffuse_config(_scene_diffuse(obj), resolution=resolution, spp=spp, exaggeration=ex)
    h = object_heights(obj)
    hm = HeightMap(h, h, float(obj[PROP_PIXEL]),
                   cast(tuple[float, float], tuple(float(v) for v in obj[PROP_ORIGIN])))
    spec = diffuse_scene_spec(hm, dcfg, view=view, surface="machined", seed=seed)
    # the object's z is exaggeration * h; the spec's mesh is offset by z_offset_mm.  The
    # camera is placed for the map's own coordinates: an object shown shifted beside
    # another (the second variant) is rendered where the map is, then put back
    where = tuple(obj.location)
    obj.location = (0.0, 0.0, 0.0)
    try:
        rgb, seconds = render_spec(obj, spec, seed=seed, z_shift=ex * spec["z_offset_mm"],
                                   threads=threads, progress=progress)
    finally:
        obj.location = where
    result: dict[str, Any] = {"image": rgb, "time_s": seconds, "spec": spec, "seed": int(seed)}
    if out is not None:
        result.update(_write_outputs(rgb, out, spec=spec, seed=seed))
        if load_image:  # the argument hides the module's function of the same name
            result["bpy_image"] = _load_bpy_image(result["png"])
    return result


def load_image(path: str | Path, name: str | None = None) -> Any:
    """Load (or reload) an image file into ``bpy.data.images``, named ``name``."""
    bpy = _bpy()
    img = bpy.data.images.load(str(path), check_existing=True)
    img.reload()
    if name:
        img.name = name
    return img


_load_bpy_image = load_image


def remove_image(name: str) -> None:
    """Remove the image ``name`` from ``bpy.data.images``, if it exists."""
    bpy = _bpy()
    img = bpy.data.images.get(name)
    if img is not None:
        bpy.data.images.remove(img)


def blend_objects() -> list:
    """Every object of the open Blender file."""
    return list(_bpy().data.objects)


def surface_material() -> Any:
    """The aluminium material of the renders (for the meshes on screen too)."""
    return _aluminium_material(_bpy(), {"material": "Al", "alpha": 0.0})


def _write_outputs(image: np.ndarray, out, *, spec: dict, seed: int) -> dict:
    attrs = {"renderer": f"blender-cycles {_bpy().app.version_string}",
             "spp": int(spec["spp"]), "seed": int(seed),
             "vertical_exaggeration": float(spec["exaggeration"]),
             "window_mm": list(spec["window_mm"]), "view": spec["view"],
             "light": spec["light"]["type"], "camera": json.dumps(spec["camera"]),
             "material_model": material_model(_bpy()),
             "software_version": __version__}
    with atomic_output_dir(out, merge=True, command="cycles", option="output folder") as tmp:
        write_exr(tmp / "cycles.exr", {"R": image[..., 0], "G": image[..., 1],
                                       "B": image[..., 2]}, attrs)
        save_png(tmp / "cycles.png", _srgb(image))
    out = Path(out).resolve()
    return {"png": out / "cycles.png", "exr": out / "cycles.exr"}


# ------------------------------------------------------------------------------------
# entry points


def default_output_dir(scene_name: str) -> Path:
    """Where the add-on writes when no output folder is set: ``render_inspect_out/<scene>``
    next to the saved .blend file, else in the system's temporary folder."""
    bpy = _bpy()
    base = Path(bpy.path.abspath("//")) if bpy.data.filepath else Path(tempfile.gettempdir())
    return base / "render_inspect_out" / scene_name
