"""The diffuse-light scene in Blender Cycles: the private render scene, the aluminium
material (the conductor Fresnel equation, or Blender 4.2's F82-tint fallback), the
environment light and the lamp, the camera and the Cycles settings of the scene that
:func:`render_inspect.render.diffuse_scene_spec` describes, and the render itself.
:mod:`._cycles` puts the height map into it as a mesh and is the entry point.

``bpy`` is passed in by the caller (imported lazily there), so importing this module is
cheap.
"""

from __future__ import annotations

import math
import re
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.errors import InputError
from ..io import read_exr

__all__ = ["ALUMINIUM_ETA", "ALUMINIUM_K", "F82_COS", "RENDER_SCENE_NAME", "f82_tint_colours",
           "fresnel_conductor", "material_model"]

#: Name of the private Blender scene the Cycles renders are made in.
RENDER_SCENE_NAME = "render_inspect_cycles"
#: Aluminium complex index of refraction in RGB, as Mitsuba 3's ``conductor`` with
#: ``material = "Al"`` reports it in its RGB variants (eta, k).
ALUMINIUM_ETA = (1.6575, 0.880405, 0.521244)
ALUMINIUM_K = (9.22381, 6.2695, 4.837)


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


def fresnel_conductor(cos_theta: ArrayLike, eta: ArrayLike, k: ArrayLike) -> np.ndarray:
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


def f82_tint_colours(eta: ArrayLike = ALUMINIUM_ETA,
                     k: ArrayLike = ALUMINIUM_K) -> tuple[tuple, tuple]:
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


def material_model(bpy: Any) -> str:
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
