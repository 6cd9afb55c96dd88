"""Blender Cycles adapter: a height map as a ``bpy`` mesh and a Cycles CPU render of it.

The Cycles render reproduces the Mitsuba diffuse-light scene (same camera, same vertical
exaggeration, same light, the same aluminium conductor) so that the two engines can be
compared image for image (``benchmarks/bench_cycles.py``).  Blender units are mm: a
vertex is ``(x, y, exaggeration * z)`` with x, y, z in mm.

``bpy`` is imported lazily, inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import InputError, check_positive, check_range

__all__ = ["heightmap_object", "render_cycles", "render_object", "simulate_into_blender",
           "surface_object", "ALUMINIUM_ETA", "ALUMINIUM_K", "OBJECT_NAME", "RENDER_SCENE_NAME"]

#: Name of the mesh object the add-on and :func:`heightmap_object` create.
OBJECT_NAME = "render_inspect_surface"
#: Name of the private Blender scene the Cycles renders are made in.
RENDER_SCENE_NAME = "render_inspect_cycles"
#: Aluminium complex index of refraction in RGB, as Mitsuba 3's ``conductor`` with
#: ``material = "Al"`` reports it in its RGB variants (eta, k).
ALUMINIUM_ETA = (1.6575, 0.880405, 0.521244)
ALUMINIUM_K = (9.22381, 6.2695, 4.837)

# custom properties on the mesh object (the add-on and tests read them)
PROP_EXAGGERATION = "render_inspect_exaggeration"
PROP_PIXEL = "render_inspect_pixel_mm"
PROP_ORIGIN = "render_inspect_origin_mm"
PROP_SHAPE = "render_inspect_shape"
PROP_SURFACE = "render_inspect_surface"
PROP_UNITS = "render_inspect_units"
PROP_SCENE = "render_inspect_scene"
PROP_HEIGHTMAP = "render_inspect_heightmap_path"


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


def heightmap_object(heights: np.ndarray, *, pixel: float, origin=(0.0, 0.0),
                     exaggeration: float = 1.0, name: str = OBJECT_NAME, collection=None,
                     surface: str = "machined", metadata: dict | None = None):
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


def surface_object(heightmap, *, surface: str = "machined", exaggeration: float = 1.0,
                   name: str = OBJECT_NAME, collection=None):
    """:func:`heightmap_object` for a :class:`~render_inspect.machining.HeightMap`.

    ``surface`` picks the layer: "machined", "design" or "residual" (machined - design).
    """
    layers = {"machined": heightmap.machined, "design": heightmap.design,
              "residual": heightmap.residual}
    if surface not in layers:
        raise InputError(f"surface must be one of {sorted(layers)}, got {surface!r}")
    import json

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


def object_heights(obj) -> np.ndarray:
    """The (ny, nx) z values of a mesh made by :func:`heightmap_object`, divided by its
    exaggeration (mm)."""
    ny, nx = (int(v) for v in obj[PROP_SHAPE])
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(ny, nx, 3)[..., 2].astype(np.float64) / float(obj[PROP_EXAGGERATION])


# ------------------------------------------------------------------------------------
# the diffuse-light scene in Cycles


def _srgb(linear: np.ndarray) -> np.ndarray:
    """Linear -> sRGB display values in [0, 1]."""
    a = np.clip(np.nan_to_num(linear), 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)


def _render_scene(bpy):
    """A fresh private Blender scene for the render; what an earlier render left (its
    camera, lights, world) is removed first.  The user's scenes are not touched."""
    old = bpy.data.scenes.get(RENDER_SCENE_NAME)
    if old is not None:
        bpy.data.scenes.remove(old)
    for obj in [o for o in bpy.data.objects if o.name.startswith(RENDER_SCENE_NAME)]:
        bpy.data.objects.remove(obj, do_unlink=True)
    for coll in (bpy.data.cameras, bpy.data.lights, bpy.data.meshes, bpy.data.worlds):
        for block in [b for b in coll if b.name.startswith(RENDER_SCENE_NAME) and b.users == 0]:
            coll.remove(block)
    return bpy.data.scenes.new(RENDER_SCENE_NAME)


def _aluminium_material(bpy, *, roughness_alpha: float):
    """Cycles Metallic BSDF with aluminium's complex IOR (physical conductor Fresnel).

    ``roughness_alpha`` is the GGX alpha (Mitsuba's ``alpha``); Blender's roughness is
    its square root (Blender squares it)."""
    name = f"{RENDER_SCENE_NAME}_aluminium"
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfMetallic")
    bsdf.fresnel_type = "PHYSICAL_CONDUCTOR"
    bsdf.distribution = "GGX"
    bsdf.inputs["IOR"].default_value = ALUMINIUM_ETA
    bsdf.inputs["Extinction"].default_value = ALUMINIUM_K
    bsdf.inputs["Roughness"].default_value = math.sqrt(max(roughness_alpha, 0.0))
    out = nodes.new("ShaderNodeOutputMaterial")
    out.target = "CYCLES"
    mat.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _object_window(obj) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) of the mesh (first to last grid point), mm, from the object's
    properties: the camera sees the surface and nothing beside it."""
    ny, nx = (int(v) for v in obj[PROP_SHAPE])
    p = float(obj[PROP_PIXEL])
    ox, oy = (float(v) for v in obj[PROP_ORIGIN])
    return (ox, oy, ox + p * (nx - 1), oy + p * (ny - 1))


def _add_camera(bpy, scene, spec: dict, z_top: float):
    cam = bpy.data.cameras.new(f"{RENDER_SCENE_NAME}_camera")
    x0, y0, x1, y1 = spec["window"]
    cam.type = "ORTHO"
    cam.sensor_fit = "AUTO"
    cam.ortho_scale = max(x1 - x0, y1 - y0)
    height = max(x1 - x0, y1 - y0)
    cam.clip_start = 1e-3 * height
    cam.clip_end = 1e3 * height + 2 * abs(z_top)
    obj = bpy.data.objects.new(f"{RENDER_SCENE_NAME}_camera", cam)
    # Blender cameras look down their local -Z with +Y up: straight down onto the part,
    # image up = +y, image right = +x (the height map's axes).
    obj.location = ((x0 + x1) / 2, (y0 + y1) / 2, z_top + height)
    obj.rotation_euler = (0.0, 0.0, 0.0)
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


def _add_light(bpy, scene, spec: dict, z_mid: float):
    world = bpy.data.worlds.new(f"{RENDER_SCENE_NAME}_world")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    scene.world = world
    light = spec["light"]
    if light["type"] == "dome":
        background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        background.inputs["Strength"].default_value = float(light["radiance"])
        return
    # ring: an emissive torus around the optical axis at the given elevation
    background.inputs["Strength"].default_value = 0.0
    x0, y0, x1, y1 = spec["window"]
    size = max(x1 - x0, y1 - y0)
    radius = light["radius_factor"] * size
    elev = light["elevation_rad"]
    n_major, n_minor = 96, 12
    r_minor = light["tube_factor"] * size
    u = np.linspace(0, 2 * np.pi, n_major, endpoint=False)
    v = np.linspace(0, 2 * np.pi, n_minor, endpoint=False)
    U, V = np.meshgrid(u, v, indexing="ij")
    R = radius + r_minor * np.cos(V)
    verts = np.stack([(x0 + x1) / 2 + R * np.cos(U), (y0 + y1) / 2 + R * np.sin(U),
                      z_mid + radius * math.tan(elev) + r_minor * np.sin(V)], -1)
    idx = np.arange(n_major * n_minor).reshape(n_major, n_minor)
    i1 = np.roll(idx, -1, axis=0)
    quads = np.stack([idx, i1, np.roll(i1, -1, axis=1), np.roll(idx, -1, axis=1)], -1)
    mesh = bpy.data.meshes.new(f"{RENDER_SCENE_NAME}_ring")
    mesh.from_pydata(verts.reshape(-1, 3).tolist(), [], quads.reshape(-1, 4).tolist())
    mat = bpy.data.materials.get(f"{RENDER_SCENE_NAME}_emitter") or \
        bpy.data.materials.new(f"{RENDER_SCENE_NAME}_emitter")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    em = nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = float(light["radiance"])
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(em.outputs["Emission"], out.inputs["Surface"])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(f"{RENDER_SCENE_NAME}_ring", mesh)
    scene.collection.objects.link(obj)


def diffuse_spec(window, *, light: str = "dome", roughness: float = 0.0,
                 resolution: int = 256, spp: int = 64) -> dict:
    """The diffuse-light inspection scene as plain data (shared with the Mitsuba side).

    Parameters
    ----------
    window : (x0, y0, x1, y1), mm
        The part of the surface the camera sees (pixel edges).
    light : {"dome", "ring"}
        "dome": uniform radiance from every direction (Mitsuba ``constant``, Cycles world
        background); "ring": an emissive ring of radius 2 x the window size at 30 deg
        elevation.
    roughness : float
        GGX alpha of the aluminium conductor (0 = smooth).
    resolution : int
        Pixels along the longer side of the window.
    spp : int
        Samples per pixel.
    """
    x0, y0, x1, y1 = (float(v) for v in window)
    if not (x1 > x0 and y1 > y0):
        raise InputError(f"window must be (x0, y0, x1, y1) with x1 > x0 and y1 > y0, got {window}")
    check_range("resolution", resolution, 1, 16384)
    check_range("spp", spp, 1, 65536)
    check_range("roughness", roughness, 0.0, 1.0)
    if light == "dome":
        light_spec = {"type": "dome", "radiance": 1.0}
    elif light == "ring":
        light_spec = {"type": "ring", "radiance": 4.0, "radius_factor": 2.0,
                      "tube_factor": 0.1, "elevation_rad": math.radians(30.0)}
    else:
        raise InputError(f"light must be 'dome' or 'ring', got {light!r}")
    w, h = x1 - x0, y1 - y0
    if w >= h:
        width, height = int(resolution), max(1, int(round(resolution * h / w)))
    else:
        width, height = max(1, int(round(resolution * w / h))), int(resolution)
    return {"window": (x0, y0, x1, y1), "camera": "orthographic_top",
            "resolution": (width, height), "spp": int(spp), "light": light_spec,
            "material": {"type": "conductor", "eta": ALUMINIUM_ETA, "k": ALUMINIUM_K,
                         "alpha": float(roughness)}}


def _scene_diffuse(obj) -> dict:
    """The ``[render.diffuse]`` section recorded on the object (empty if none)."""
    import json

    try:
        return dict(json.loads(obj.get(PROP_SCENE, "{}")).get("render", {}).get("diffuse", {}))
    except (TypeError, ValueError, AttributeError):
        return {}


def render_object(obj, *, out=None, resolution: int = 256, spp: int = 64, seed: int = 0,
                  light: str | None = None, roughness: float | None = None, window=None,
                  threads: int | None = None, load_image: bool = False) -> dict:
    """Cycles CPU render of a mesh made by :func:`heightmap_object`.

    The render happens in a private Blender scene (``render_inspect_cycles``) holding the
    object, an orthographic camera looking straight down, the light and the aluminium
    material; the user's own scenes are left as they are.

    Parameters
    ----------
    obj : bpy.types.Object
        Made by :func:`heightmap_object` (it carries the grid's custom properties).
    out : str, Path or None
        Folder for ``cycles.png`` (sRGB) and ``cycles.exr`` (linear RGB); None writes
        nothing.
    resolution, spp, light, roughness, window
        See :func:`diffuse_spec`; ``window`` defaults to the whole grid; ``light`` and
        ``roughness`` default to the ``[render.diffuse]`` section of the scene the object
        was simulated from (else "dome" and 0).
    seed : int
        Cycles sampling seed: same seed, same image, bit for bit.
    threads : int or None
        CPU threads (None: all).
    load_image : bool
        Also load ``cycles.png`` into ``bpy.data.images`` (to look at it in Blender).

    Returns
    -------
    dict
        ``image`` (H, W, 3) float32 linear RGB, row 0 at the top (largest y);
        ``time_s`` (the render alone); ``spec``; ``png``/``exr`` paths when ``out``.
    """
    bpy = _bpy()
    if obj is None or PROP_EXAGGERATION not in obj or PROP_SHAPE not in obj:
        raise InputError("render needs the render_inspect surface mesh: run Simulate first "
                         f"(no object named {OBJECT_NAME!r} with render_inspect properties)")
    check_range("seed", seed, 0, 2**31 - 1)
    diffuse = _scene_diffuse(obj)
    light = light if light is not None else diffuse.get("light", "dome")
    roughness = roughness if roughness is not None else diffuse.get("roughness", 0.0)
    spec = diffuse_spec(window or _object_window(obj), light=light, roughness=roughness,
                        resolution=resolution, spp=spp)
    scene = _render_scene(bpy)
    scene.collection.objects.link(obj)
    mat = _aluminium_material(bpy, roughness_alpha=spec["material"]["alpha"])
    obj.data.materials.clear()
    obj.data.materials.append(mat)
    zs = [v[2] for v in obj.bound_box]
    _add_camera(bpy, scene, spec, max(zs))
    _add_light(bpy, scene, spec, (min(zs) + max(zs)) / 2)

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = spec["spp"]
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"  # Mitsuba's films use a box filter too
    scene.cycles.filter_width = 1.0
    scene.cycles.seed = int(seed)
    scene.cycles.use_animated_seed = False
    scene.render.use_persistent_data = False
    if threads:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = int(threads)
    scene.render.resolution_x, scene.render.resolution_y = spec["resolution"]
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGB"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"

    from ..io import read_exr

    with tempfile.TemporaryDirectory(prefix="render_inspect_cycles_") as tmp:
        exr_tmp = Path(tmp) / "cycles.exr"
        scene.render.filepath = str(exr_tmp)
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True, scene=scene.name)
        elapsed = time.perf_counter() - t0
        if not exr_tmp.is_file():
            raise InputError(f"Cycles wrote no image to {exr_tmp} (render failed)")
        channels, _ = read_exr(exr_tmp)
    image = np.stack([channels[c] for c in ("R", "G", "B")], axis=-1).astype(np.float32)
    result = {"image": image, "time_s": elapsed, "spec": spec, "seed": int(seed)}
    if out is not None:
        result.update(_write_outputs(image, out, spec=spec, seed=seed, obj=obj))
        if load_image:
            img = bpy.data.images.load(str(result["png"]), check_existing=True)
            img.reload()
            result["bpy_image"] = img
    return result


def _write_outputs(image: np.ndarray, out, *, spec: dict, seed: int, obj) -> dict:
    import json

    from .. import __version__
    from ..io import atomic_output_dir, save_png, write_exr

    attrs = {"renderer": f"blender-cycles {_bpy().app.version_string}",
             "spp": int(spec["spp"]), "seed": int(seed),
             "exaggeration": float(obj[PROP_EXAGGERATION]),
             "window_mm": list(spec["window"]), "light": json.dumps(spec["light"]),
             "software_version": __version__}
    with atomic_output_dir(out) as tmp:
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


def simulate_into_blender(scene_path, *, overrides=(), out=None, surface: str = "machined",
                          exaggeration: float | None = None, collection=None) -> dict:
    """Load a scene file, simulate the machined surface and load it as a mesh object.

    Parameters
    ----------
    scene_path : str or Path
        render_inspect scene (TOML).
    overrides : sequence of str
        ``section.key=value`` overrides (the CLI's ``--set``).
    out : str, Path or None
        Folder for ``heightmap.exr``; None: :func:`default_output_dir`.
    surface : {"machined", "design", "residual"}
        The height layer that becomes the mesh.
    exaggeration : float or None
        Vertical exaggeration; None uses the scene's ``render.diffuse.exaggeration``.
    collection : bpy.types.Collection or None
        Where to link the object (the active scene's collection when None).

    Returns
    -------
    dict
        ``object`` (bpy.types.Object named ``render_inspect_surface``), ``heightmap``
        (Path of the EXR), ``result`` (SimulationResult), ``scene`` (Scene).
    """
    from ..io import atomic_output_dir
    from ..machining import simulate_scene
    from ..scene import load_scene

    if not str(scene_path).strip():
        raise InputError("scene file: choose a render_inspect scene (.toml) first; received an empty path")
    scene = load_scene(scene_path, list(overrides))
    if exaggeration is not None:
        check_positive("exaggeration", exaggeration)
    exaggeration = float(exaggeration or scene.render.diffuse.exaggeration)
    result = simulate_scene(scene)
    hm = result.heightmap
    if hm.scene is None:
        hm.scene = scene.to_dict()
    out = Path(out) if out else default_output_dir(scene.name)
    with atomic_output_dir(out) as tmp:
        hm.to_exr(tmp / "heightmap.exr")
    path = out.resolve() / "heightmap.exr"
    obj = surface_object(hm, surface=surface, exaggeration=exaggeration, collection=collection)
    obj[PROP_HEIGHTMAP] = str(path)
    return {"object": obj, "heightmap": path, "result": result, "scene": scene}


def render_cycles(heightmap, *, surface: str = "machined", exaggeration: float = 200.0,
                  out=None, resolution: int = 256, spp: int = 64, seed: int = 0,
                  light: str | None = None, roughness: float | None = None, window=None,
                  threads: int | None = None) -> dict:
    """Cycles render of a :class:`~render_inspect.machining.HeightMap` in a clean
    Blender session (the headless counterpart of the add-on's Render).

    Resets Blender to an empty factory scene first, so only call it from scripts and
    tests, not from inside a Blender session you want to keep.  Parameters and the
    returned dict as in :func:`render_object`, plus ``mesh_time_s``.
    """
    bpy = _bpy()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    t0 = time.perf_counter()
    obj = surface_object(heightmap, surface=surface, exaggeration=exaggeration)
    mesh_time = time.perf_counter() - t0
    res = render_object(obj, out=out, resolution=resolution, spp=spp, seed=seed, light=light,
                        roughness=roughness, window=window, threads=threads)
    res["mesh_time_s"] = mesh_time
    return res
