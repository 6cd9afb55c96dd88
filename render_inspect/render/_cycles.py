"""Blender Cycles adapter: a height map as a ``bpy`` mesh and a Cycles CPU render of it.

The Cycles render reproduces the Mitsuba diffuse-light scene that
:func:`render_inspect.render.diffuse_scene_spec` describes (the same mesh, camera,
vertical exaggeration, environment light, aluminium conductor, samples per pixel, box
filter and path depth) so that the two engines can be compared image for image
(``benchmarks/bench_cycles.py``).  Blender units are mm: a
vertex is ``(x, y, exaggeration * z)`` with x, y, z in mm.

``bpy`` is imported lazily, inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

import json
import math
import re
import tempfile
import time
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from .. import __version__
from ..core.errors import InputError, SceneError, check_positive, check_range
from ..core.heightmap import HeightMap
from ..io import atomic_output_dir, read_exr, save_png, write_exr
from ._diffuse import DiffuseConfig, diffuse_mesh, diffuse_scene_spec, mitsuba_seed

__all__ = ["heightmap_object", "surface_object", "gridmesh_object", "object_heights",
           "remove_object", "render_spec", "render_cycles", "render_object",
           "default_output_dir", "fresnel_conductor", "f82_tint_colours",
           "material_model", "load_image", "surface_material", "blend_objects", "ALUMINIUM_ETA", "ALUMINIUM_K",
           "OBJECT_NAME", "RENDER_SCENE_NAME"]

#: Name of the mesh object the add-on and :func:`heightmap_object` create.
OBJECT_NAME = "render_inspect_surface"
#: Name of the private Blender scene the Cycles renders are made in.
RENDER_SCENE_NAME = "render_inspect_cycles"
#: Aluminium complex index of refraction in RGB, as Mitsuba 3's ``conductor`` with
#: ``material = "Al"`` reports it in its RGB variants (eta, k).
ALUMINIUM_ETA = (1.6575, 0.880405, 0.521244)
ALUMINIUM_K = (9.22381, 6.2695, 4.837)

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


def surface_object(heightmap, *, surface: str = "machined", exaggeration: float = 1.0,
                   name: str = OBJECT_NAME, collection=None):
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


def object_heights(obj) -> np.ndarray:
    """The (ny, nx) z values of a mesh made by :func:`heightmap_object`, divided by its
    exaggeration (mm)."""
    ny, nx = (int(v) for v in obj[PROP_SHAPE])
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(ny, nx, 3)[..., 2].astype(np.float64) / float(obj[PROP_EXAGGERATION])


# ------------------------------------------------------------------------------------
# the diffuse-light scene in Cycles (render_inspect.render.diffuse_scene_spec)


def _srgb(linear: np.ndarray) -> np.ndarray:
    """Linear -> sRGB display values in [0, 1]."""
    a = np.clip(np.nan_to_num(linear), 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)


def _node_tree(bpy, idblock):
    if bpy.app.version < (5, 0, 0):
        idblock.use_nodes = True
    return idblock.node_tree


def _render_scene(bpy):
    """A fresh private Blender scene for the render; what an earlier render left (its
    camera, world, render mesh) is removed first.  The user's scenes are not touched."""
    old = bpy.data.scenes.get(RENDER_SCENE_NAME)
    if old is not None:
        bpy.data.scenes.remove(old)
    for obj in [o for o in bpy.data.objects if o.name.startswith(RENDER_SCENE_NAME)]:
        bpy.data.objects.remove(obj, do_unlink=True)
    for coll in (bpy.data.cameras, bpy.data.meshes, bpy.data.worlds, bpy.data.images,
                 bpy.data.lights):
        for block in [b for b in coll if b.name.startswith(RENDER_SCENE_NAME) and b.users == 0]:
            coll.remove(block)
    return bpy.data.scenes.new(RENDER_SCENE_NAME)


def fresnel_conductor(cos_theta, eta, k) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a conductor of complex index ``eta + i k``.

    Parameters
    ----------
    cos_theta : float or (n,) array
        Cosine of the angle of incidence.
    eta, k : float or (3,) array
        Real and imaginary parts of the index (per RGB channel).

    Returns
    -------
    ndarray
        Reflectance in [0, 1], broadcast over ``cos_theta`` and the channels.
    """
    n = np.asarray(eta, dtype=np.float64) + 1j * np.asarray(k, dtype=np.float64)
    c = np.asarray(cos_theta, dtype=np.float64)[..., None] if np.ndim(eta) else \
        np.asarray(cos_theta, dtype=np.float64)
    ct = np.sqrt(n**2 - (1.0 - c**2))
    rs = (c - ct) / (c + ct)
    rp = (n**2 * c - ct) / (n**2 * c + ct)
    return (np.abs(rs) ** 2 + np.abs(rp) ** 2) / 2


#: cos(theta) of the angle where the F82-tint model of the Principled BSDF is pinned
#: (Hoffman 2019, "Fresnel equations considered harmful"; Kutz et al. 2021): 1/7, 81.8 deg.
F82_COS = 1.0 / 7.0


def f82_tint_colours(eta=ALUMINIUM_ETA, k=ALUMINIUM_K) -> tuple[tuple, tuple]:
    """Base colour (F0) and specular tint of the Principled BSDF's metallic F82-tint model
    that reproduce a conductor's Fresnel reflectance at normal incidence and at 81.8 deg.

    The model is Schlick's curve minus a term that vanishes at 0 and 90 deg; its
    ``Specular Tint`` is the ratio of the wanted reflectance at ``cos = 1/7`` to Schlick's
    there.  For aluminium the curve stays within 0.1 % of the exact conductor Fresnel
    up to 30 deg incidence and within 1 % up to 65 deg.
    """
    f0 = fresnel_conductor(1.0, eta, k)
    schlick = f0 + (1.0 - f0) * (1.0 - F82_COS) ** 5
    tint = np.clip(fresnel_conductor(F82_COS, eta, k) / schlick, 0.0, 1.0)
    return tuple(float(v) for v in f0), tuple(float(v) for v in tint)


def material_model(bpy) -> str:
    """Which aluminium shader this Blender has: ``"metallic_bsdf"`` (Blender 4.3 and later:
    the Metallic BSDF with physical-conductor Fresnel, exact) or ``"principled_f82"``
    (Blender 4.2: the Principled BSDF's metallic F82-tint approximation)."""
    return "metallic_bsdf" if hasattr(bpy.types, "ShaderNodeBsdfMetallic") else "principled_f82"


def _aluminium_material(bpy, material: dict):
    """Aluminium with its complex IOR, the counterpart of Mitsuba's ``conductor`` /
    ``roughconductor`` with ``material="Al"``.

    Blender 4.3+: the Metallic BSDF with physical-conductor Fresnel (exact).  Blender 4.2
    has no Metallic BSDF: the Principled BSDF, fully metallic, single-scatter GGX, with the
    base colour and specular tint of :func:`f82_tint_colours` (its F82-tint Fresnel).
    Mitsuba's GGX ``alpha`` is Blender's roughness squared in both.  The turned-aluminium
    BSDF (diffraction by the feed marks, anisotropic roughness) has no Cycles counterpart:
    its microroughness ``alpha`` is used as an isotropic GGX roughness."""
    if material.get("material", "Al") != "Al":
        raise InputError(f"material must be 'Al' (aluminium), got {material.get('material')!r}")
    name = f"{RENDER_SCENE_NAME}_aluminium"
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    tree = _node_tree(bpy, mat)
    tree.nodes.clear()
    roughness = math.sqrt(max(float(material.get("alpha", 0.0)), 0.0))
    if material_model(bpy) == "metallic_bsdf":
        bsdf = tree.nodes.new("ShaderNodeBsdfMetallic")
        bsdf.fresnel_type = "PHYSICAL_CONDUCTOR"
        bsdf.distribution = "GGX"
        bsdf.inputs["IOR"].default_value = ALUMINIUM_ETA
        bsdf.inputs["Extinction"].default_value = ALUMINIUM_K
        bsdf.inputs["Roughness"].default_value = roughness
    else:
        f0, tint = f82_tint_colours()
        bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.distribution = "GGX"
        bsdf.inputs["Metallic"].default_value = 1.0
        bsdf.inputs["Base Color"].default_value = (*f0, 1.0)
        bsdf.inputs["Specular Tint"].default_value = (*tint, 1.0)
        bsdf.inputs["Roughness"].default_value = roughness
    mat["render_inspect_material_model"] = material_model(bpy)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.target = "CYCLES"
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _add_world(bpy, scene, light: dict):
    """The light at infinity (:func:`~render_inspect.render.diffuse_scene_spec`'s
    ``light``): the piecewise-linear ``port_profile`` (``[angle_deg, radiance]`` pairs)
    of the angle from the camera port's ``axis``, times the horizon step (0.5 degree
    wide), times ``1 - zenith_falloff (1 - cos^2 theta)``, times ``radiance``; a spec
    without an axis gives ``zenith_profile`` about +z (the same light for a camera
    looking straight down).

    Built as a world shader, ray direction -> angle = acos(d . axis) -> a linear colour
    ramp with one stop per profile point, so the profile is reproduced exactly (Mitsuba
    gets the same light as an ``envmap`` bitmap)."""
    axis = light.get("axis")
    key = "port_profile" if axis is not None and "port_profile" in light else "zenith_profile"
    profile = np.asarray(light[key], dtype=np.float64)
    if profile.ndim != 2 or profile.shape[1] != 2 or not 2 <= len(profile) <= 32:
        raise InputError(f"light {key} must be 2..32 [angle_deg, radiance] pairs, "
                         f"got {light[key]!r}")
    if tuple(light.get("up", (0.0, 0.0, 1.0))) != (0.0, 0.0, 1.0):
        raise InputError(f"light up must be [0, 0, 1], got {light.get('up')!r}")
    peak = float(profile[:, 1].max()) or 1.0
    world = bpy.data.worlds.new(f"{RENDER_SCENE_NAME}_world")
    tree = _node_tree(bpy, world)
    nodes, links = tree.nodes, tree.links
    coord = nodes.new("ShaderNodeTexCoord")  # "Generated" = the ray's direction in a world
    xyz = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coord.outputs["Generated"], xyz.inputs["Vector"])
    acos = nodes.new("ShaderNodeMath")
    acos.operation = "ARCCOSINE"
    acos.use_clamp = False
    if axis is not None:
        dot = nodes.new("ShaderNodeVectorMath")
        dot.operation = "DOT_PRODUCT"
        dot.inputs[1].default_value = tuple(float(v) for v in axis)
        links.new(coord.outputs["Generated"], dot.inputs[0])
        clamp = nodes.new("ShaderNodeClamp")
        clamp.inputs["Min"].default_value = -1.0
        clamp.inputs["Max"].default_value = 1.0
        links.new(dot.outputs["Value"], clamp.inputs["Value"])
        links.new(clamp.outputs["Result"], acos.inputs[0])
    else:
        links.new(xyz.outputs["Z"], acos.inputs[0])
    scale = nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = 1.0 / math.pi  # angle / pi in [0, 1]
    ramp = nodes.new("ShaderNodeValToRGB")
    cr = ramp.color_ramp
    cr.interpolation = "LINEAR"
    cr.color_mode = "RGB"
    while len(cr.elements) > 1:
        cr.elements.remove(cr.elements[-1])
    for i, (theta_deg, radiance) in enumerate(profile):
        el = cr.elements[0] if i == 0 else cr.elements.new(float(theta_deg) / 180.0)
        el.position = float(theta_deg) / 180.0
        v = float(radiance) / peak
        el.color = (v, v, v, 1.0)
    links.new(acos.outputs["Value"], scale.inputs[0])
    links.new(scale.outputs["Value"], ramp.inputs["Fac"])
    background = nodes["Background"]
    background.inputs["Strength"].default_value = peak * float(light.get("radiance", 1.0))
    if axis is not None:
        # horizon step (90 .. 90.5 degrees: linear in cos theta there) and the falloff
        horizon = nodes.new("ShaderNodeMapRange")
        horizon.clamp = True
        horizon.inputs["From Min"].default_value = math.cos(math.radians(90.5))
        horizon.inputs["From Max"].default_value = 0.0
        links.new(xyz.outputs["Z"], horizon.inputs["Value"])
        zc = nodes.new("ShaderNodeMath")
        zc.operation = "MAXIMUM"
        zc.inputs[1].default_value = 0.0
        links.new(xyz.outputs["Z"], zc.inputs[0])
        z2 = nodes.new("ShaderNodeMath")
        z2.operation = "MULTIPLY"
        links.new(zc.outputs["Value"], z2.inputs[0])
        links.new(zc.outputs["Value"], z2.inputs[1])
        f = float(light.get("zenith_falloff", 0.0))
        fall = nodes.new("ShaderNodeMath")
        fall.operation = "MULTIPLY_ADD"
        fall.inputs[1].default_value = f
        fall.inputs[2].default_value = 1.0 - f
        links.new(z2.outputs["Value"], fall.inputs[0])
        both = nodes.new("ShaderNodeMath")
        both.operation = "MULTIPLY"
        links.new(horizon.outputs["Result"], both.inputs[0])
        links.new(fall.outputs["Value"], both.inputs[1])
        mul = nodes.new("ShaderNodeVectorMath")
        mul.operation = "SCALE"
        links.new(ramp.outputs["Color"], mul.inputs[0])
        links.new(both.outputs["Value"], mul.inputs["Scale"])
        links.new(mul.outputs["Vector"], background.inputs["Color"])
    else:
        links.new(ramp.outputs["Color"], background.inputs["Color"])
    # importance-sample the light on a 0.25-degree map ("AUTOMATIC" builds a far larger
    # one: seconds per render)
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = 720
    scene.world = world


def _add_lamp(bpy, scene, lamp: dict):
    """The spec's lamp: a sun (directional light, angle 0) whose light travels along
    ``direction`` with ``irradiance`` (Blender's sun strength is an irradiance too)."""
    import mathutils

    d = np.asarray(lamp["direction"], dtype=np.float64)
    d /= np.linalg.norm(d)
    data = bpy.data.lights.new(f"{RENDER_SCENE_NAME}_lamp", type="SUN")
    data.energy = float(lamp["irradiance"])
    data.angle = 0.0
    obj = bpy.data.objects.new(f"{RENDER_SCENE_NAME}_lamp", data)
    # a sun shines along its local -Z
    z = -d
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, y, z
    obj.matrix_world = mathutils.Matrix(m.tolist())
    scene.collection.objects.link(obj)
    return obj


def _look_at_matrix(origin, target, up):
    """4 x 4 camera-to-world matrix of a Blender camera at ``origin`` looking at
    ``target`` (its -Z) with ``up`` (its +Y) as in Mitsuba's ``look_at``."""
    o = np.asarray(origin, dtype=np.float64)
    f = np.asarray(target, dtype=np.float64) - o
    f /= np.linalg.norm(f)
    r = np.cross(f, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(r) < 1e-12:
        raise InputError(f"camera up {list(up)} is parallel to the view direction {f.tolist()}")
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = r, u, -f, o
    return m


def _add_camera(bpy, scene, cam: dict, z_shift: float):
    import mathutils

    data = bpy.data.cameras.new(f"{RENDER_SCENE_NAME}_camera")
    data.sensor_fit = "HORIZONTAL"
    if cam["type"] == "perspective":
        data.type = "PERSP"
        data.angle = math.radians(float(cam["fov_deg"]))  # horizontal field of view
    elif cam["type"] == "orthographic":
        data.type = "ORTHO"
        data.ortho_scale = float(cam["width_mm"])  # the image's width, mm
    else:
        raise InputError(f"camera type must be 'perspective' or 'orthographic', got {cam['type']!r}")
    shift = np.array([0.0, 0.0, z_shift])
    origin = np.asarray(cam["origin"], dtype=np.float64) + shift
    target = np.asarray(cam["target"], dtype=np.float64) + shift
    dist = float(np.linalg.norm(target - origin))
    data.clip_start = 1e-4 * dist
    data.clip_end = 1e4 * dist
    obj = bpy.data.objects.new(f"{RENDER_SCENE_NAME}_camera", data)
    obj.matrix_world = mathutils.Matrix(_look_at_matrix(origin, target, cam["up"]).tolist())
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


def _configure_cycles(scene, spec: dict, *, seed: int, threads: int | None):
    cam = spec["camera"]
    c = scene.cycles
    scene.render.engine = "CYCLES"
    c.device = "CPU"
    c.samples = int(spec["spp"])
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = int(seed)
    c.use_animated_seed = False
    c.pixel_filter_type = "BOX"  # Mitsuba's films use a box filter too
    c.filter_width = 1.0
    # Mitsuba's max_depth counts path segments (2 = one surface hit lit by the light);
    # Cycles' max_bounces counts bounces after the first hit (0 = that same direct
    # light), so bounces = max_depth - 2.  No clamping, no glossy blur (both bias).
    bounces = max(int(spec.get("max_depth", 6)) - 2, 0)
    c.max_bounces = bounces
    for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces",
                 "transparent_max_bounces", "volume_bounces"):
        setattr(c, name, bounces)
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    scene.render.threads_mode = "FIXED" if threads else "AUTO"
    if threads:
        scene.render.threads = int(threads)
    scene.render.resolution_x = int(cam["width"])
    scene.render.resolution_y = int(cam["height"])
    scene.render.resolution_percentage = 100
    scene.render.use_persistent_data = False
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    fmt = scene.render.image_settings
    fmt.file_format = "OPEN_EXR"
    fmt.color_mode = "RGB"
    fmt.color_depth = "32"
    fmt.exr_codec = "ZIP"


_SAMPLE = re.compile(r"Sample (\d+)/(\d+)")


def _render(bpy, scene, progress=None) -> tuple[np.ndarray, float]:
    """Render ``scene`` with Cycles; (H, W, 3) float32 linear RGB (row 0 at the top) and
    the seconds the render took.  ``progress(done, total)`` is called with Cycles' sample
    count as it renders (from its ``render_stats`` messages)."""

    def stats(text, *_):
        m = _SAMPLE.search(str(text))
        if m and int(m.group(2)):
            progress(int(m.group(1)), int(m.group(2)))

    with tempfile.TemporaryDirectory(prefix="render_inspect_cycles_") as tmp:
        exr = Path(tmp) / "cycles.exr"
        scene.render.filepath = str(exr)
        if progress is not None:
            bpy.app.handlers.render_stats.append(stats)
        t0 = time.perf_counter()
        try:
            bpy.ops.render.render(write_still=True, scene=scene.name)
        finally:
            if progress is not None:
                bpy.app.handlers.render_stats.remove(stats)
        elapsed = time.perf_counter() - t0
        if not exr.is_file():
            raise InputError(f"Cycles wrote no image to {exr}: the render failed")
        channels, _ = read_exr(exr)
    rgb = np.stack([channels[c] for c in ("R", "G", "B")], axis=-1).astype(np.float32)
    return rgb, elapsed


def render_spec(obj, spec: dict, *, seed: int = 0, z_shift: float = 0.0,
                threads: int | None = None, progress=None) -> tuple[np.ndarray, float]:
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


def gridmesh_object(gm, *, name: str = "render_inspect_part", collection=None):
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


def render_cycles(heightmap, dcfg=None, *, view: str = "macro", surface: str = "machined",
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


def render_object(obj, *, view: str = "macro", out=None, resolution: int | None = None,
                  spp: int | None = None, seed: int = 0, threads: int | None = None,
                  load_image: bool = False, progress=None) -> dict:
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
    hm = HeightMap(h, h, float(obj[PROP_PIXEL]), tuple(float(v) for v in obj[PROP_ORIGIN]))
    spec = diffuse_scene_spec(hm, dcfg, view=view, surface="machined", seed=seed)
    # the object's z is exaggeration * h; the spec's mesh is offset by z_offset_mm
    rgb, seconds = render_spec(obj, spec, seed=seed, z_shift=ex * spec["z_offset_mm"],
                               threads=threads, progress=progress)
    result = {"image": rgb, "time_s": seconds, "spec": spec, "seed": int(seed)}
    if out is not None:
        result.update(_write_outputs(rgb, out, spec=spec, seed=seed))
        if load_image:  # the argument hides the module's function of the same name
            result["bpy_image"] = _load_bpy_image(result["png"])
    return result


def load_image(path, name: str | None = None):
    """Load (or reload) an image file into ``bpy.data.images``, named ``name``."""
    bpy = _bpy()
    img = bpy.data.images.load(str(path), check_existing=True)
    img.reload()
    if name:
        img.name = name
    return img


_load_bpy_image = load_image


def blend_objects() -> list:
    """Every object of the open Blender file."""
    return list(_bpy().data.objects)


def surface_material():
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
