"""Diffuse-light images of the machined part: Mitsuba path tracing of aluminium.

The scene, engine-neutral (camera, light, lamp, material, exaggeration, mesh as plain
numbers), is :func:`diffuse_scene_spec` of :mod:`._diffuse_scene`, so that another
renderer (the Blender add-on's Cycles benchmark, ``render/_cycles.py``) can build the same
scene; this module meshes the height map for it (area-averaged when it is larger than the
mesh budget), builds the Mitsuba scene (the turned-aluminium BSDF of
:mod:`render_inspect.render._turned_bsdf` for a part with tool marks) and renders it, in
passes of at most :data:`MAX_SAMPLES_PER_PASS` samples.

Images are returned with row 0 at the top (camera convention), linear RGB.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import cast

import numpy as np

from ..core.errors import InputError
from ..core.heightmap import HeightMap
from ..core.progress import report
from ..core.units import MIB_TO_BYTES
from ..mesh import GridMesh, disc_mesh, heightmap_mesh, window_indices
# the engine-neutral scene (importable from here as before; _default_window for pipeline/)
from ._diffuse_scene import (
    AL_REFLECTANCE_RGB,
    DEFAULT_MICROROUGHNESS,
    ENV_ROWS,
    LAMP_ORDER_RADIANCE,
    LIGHTS,
    MACRO_DOME_RADIANCE,
    MAX_FILM_SIDE,
    PORT_PROFILES,
    DiffuseConfig,
    _default_window,
    auto_exaggeration,
    diffuse_scene_spec,
    environment_map,
    light_profile,
)
from ._scene_dicts import (
    load_scene_dict,
    mitsuba_mesh,
    ortho_sensor,
    perspective_sensor,
)
from ._studio import studio_environment
from ._turned_bsdf import efficiency_tables, register_turned_bsdf, store_tables
from ._variant import import_mitsuba, spectral_variant

__all__ = ["DiffuseConfig", "diffuse_scene_spec", "diffuse_mesh", "environment_map", "light_profile",
           "render_diffuse", "auto_exaggeration", "render_passes", "mitsuba_seed",
           "diffuse_memory", "LIGHTS", "PORT_PROFILES", "AL_REFLECTANCE_RGB", "MACRO_DOME_RADIANCE",
           "DEFAULT_MICROROUGHNESS", "MAX_FILM_SIDE", "MAX_SAMPLES_PER_PASS"]

#: Largest number of Monte Carlo samples (pixels x samples per pixel) given to Mitsuba in
#: one call: its JIT variants index one wavefront with 32-bit integers, and it crashes
#: (segmentation fault) when it splits a task of >= 2^32 samples itself.  Larger requests
#: are rendered in passes of at most this many samples and averaged.
MAX_SAMPLES_PER_PASS = 2 ** 26
#: Bytes per image pixel while rendering the turned-aluminium BSDF (a spectral variant):
#: Mitsuba's film and the Dr.Jit arrays of the wavefront that stay per pixel (they do not
#: grow with the samples per pixel), the image returned and the float64 sum of the
#: passes.  Measured as the peak resident set of a design render of the turned
#: sinusoidal grid at 256^2, 512^2 and 1024^2 pixels (llvm spectral variant, 4-32 spp):
#: 960-1510 bytes per pixel above a fixed part (tests/test_memory_estimate.py checks it
#: at two sizes).
FILM_BYTES_PER_PIXEL = 1024
#: The same for an RGB variant (a part without tool marks, or no spectral variant):
#: 8192 x 8192 pixels x 1 spp peaked at 4.3 GiB, 4096 x 4096 x 300 spp at 2.2 GiB
#: (llvm_ad_rgb, docs/limits.md)
FILM_BYTES_PER_PIXEL_RGB = 96
#: Bytes a diffuse render holds whatever its size: Mitsuba and Dr.Jit loaded, the scene
#: and its JIT kernels (the intercept of the same measurements: 160-300 MB)
DIFFUSE_FIXED_BYTES = 300 * MIB_TO_BYTES
#: Bytes per mesh cell (render_inspect's arrays and Mitsuba's copy: 2 triangles, a vertex
#: with its normal)
MESH_BYTES_PER_CELL = 2 * (24 + 24)


def _block_heightmap(heightmap, window, factor: int, channel: str) -> HeightMap:
    """The ``channel`` of ``heightmap`` inside ``window`` (or whole), area-averaged over
    ``factor x factor`` blocks (NaN-aware) on a grid of ``factor`` times the pixel."""
    z = getattr(heightmap, channel)
    i0, j0 = 0, 0
    if window is not None:
        i0, i1, j0, j1 = window_indices(heightmap, window, margin=factor)
        z = z[i0:i1, j0:j1]
    f = int(factor)
    ny, nx = (z.shape[0] // f) * f, (z.shape[1] // f) * f
    blocks = z[:ny, :nx].reshape(ny // f, f, nx // f, f)
    ok = np.isfinite(blocks)
    n = ok.sum(axis=(1, 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        zb = np.where(n > 0, np.where(ok, blocks, 0.0).sum(axis=(1, 3)) / np.maximum(n, 1), np.nan)
    p = heightmap.pixel
    origin = (heightmap.origin[0] + (j0 + (f - 1) / 2) * p, heightmap.origin[1] + (i0 + (f - 1) / 2) * p)
    return HeightMap(zb, zb, p * f, origin)


def diffuse_mesh(heightmap: HeightMap, spec: dict, *,
                 memory_budget: int | None = None) -> tuple[GridMesh, int]:
    """The mesh of a diffuse scene spec (:func:`diffuse_scene_spec`): the spec's channel,
    window and exaggeration, area-averaged (block means) when the map has more than
    ``mesh.max_cells`` samples across; ``memory_budget``: bytes the mesh may take (default:
    the mesh module's).  Returns (GridMesh, block factor)."""
    ms = spec["mesh"]
    z = getattr(heightmap, ms["channel"])
    shape = z.shape
    if ms["window"] is not None:
        i0, i1, j0, j1 = window_indices(heightmap, ms["window"], margin=1)
        shape = (i1 - i0, j1 - j0)
    factor = max(1, int(math.ceil(max(shape) / ms["max_cells"])))
    hm = heightmap
    channel = ms["channel"]
    window = ms["window"]
    if factor > 1:
        hm = _block_heightmap(heightmap, window, factor, channel)
        channel = "machined"
    elif ms.get("refine", 1) > 1 and window is not None:
        hm = _refined_heightmap(heightmap, window, int(ms["refine"]), channel)
        channel = "machined"
    if ms.get("kind") == "disc":
        z = getattr(hm, channel)
        gm = disc_mesh(z, pixel=hm.pixel, origin=hm.origin, center=ms["center"],
                       radius=ms["radius"], exaggeration=spec["exaggeration"],
                       z_offset=spec["z_offset_mm"], rings=ms["rings"], sectors=ms["sectors"],
                       chamfer=ms["chamfer_mm"], wall=ms["wall_mm"], memory_budget=memory_budget,
                       channel=ms["channel"])
        return gm, factor
    gm = heightmap_mesh(hm, channel=channel, exaggeration=spec["exaggeration"], window=window,
                        z_offset=spec["z_offset_mm"], skirt=ms["skirt"], normals=True,
                        memory_budget=memory_budget)
    return gm, factor


def _refined_heightmap(heightmap, window, factor: int, channel: str) -> HeightMap:
    """The ``channel`` inside ``window`` resampled ``factor`` times finer by a cubic spline
    through the samples (a map with holes: bilinear), so that a micro view finer than the
    simulation grid shows a smooth surface through the samples instead of the grid's
    triangles (whose diagonals turn every curved tool mark into a staircase)."""
    from scipy import ndimage

    z = getattr(heightmap, channel)
    i0, i1, j0, j1 = window_indices(heightmap, window, margin=2)
    z = z[i0:i1, j0:j1]
    f = int(factor)
    ny, nx = z.shape
    yy = np.arange((ny - 1) * f + 1) / f
    xx = np.arange((nx - 1) * f + 1) / f
    ok = np.isfinite(z)
    order = 3 if ok.all() else 1
    zf = np.where(ok, z, np.nanmean(z)) if not ok.all() else z
    grid = np.meshgrid(yy, xx, indexing="ij")
    zr = ndimage.map_coordinates(zf, grid, order=order, mode="nearest")
    if not ok.all():
        holes = ndimage.map_coordinates((~ok).astype(np.float64), grid, order=1) > 0
        zr = np.where(holes, np.nan, zr)
    p = heightmap.pixel / f
    origin = (heightmap.origin[0] + j0 * heightmap.pixel, heightmap.origin[1] + i0 * heightmap.pixel)
    return HeightMap(zr, zr, p, origin)


def _material_dict(spec, key: str) -> dict:
    m = spec["material"]
    if m["type"] == "turned_al":
        mk = m["marks"]
        d = {"type": "turned_al", "table_key": key,
             "period_mm": float(mk["period_mm"]) if m["grating"] else 0.0,
             "sigma_u": float(m["sigma_u"]), "sigma_v": float(m["sigma_v"])}
        if mk["kind"] == "circular":
            d.update(kind=0, cx=float(mk.get("center_mm", (0.0, 0.0))[0]),
                     cy=float(mk.get("center_mm", (0.0, 0.0))[1]))
        else:
            dx, dy = mk.get("direction", (0.0, 1.0))[:2]
            d.update(kind=1, dx=float(dx), dy=float(dy))
        return d
    bsdf = {"type": m["type"], "material": "Al"}
    if m["type"] == "roughconductor":
        bsdf.update(alpha=m["alpha"], distribution="ggx")
    return bsdf


def _mitsuba_scene(gm, spec, bsdf):
    mi, _, _ = import_mitsuba()
    cam = spec["camera"]
    if cam["type"] == "perspective":
        sensor = perspective_sensor(origin=cam["origin"], target=cam["target"], up=cam["up"],
                                    fov_deg=cam["fov_deg"], nx=cam["width"], ny=cam["height"],
                                    spp=spec["spp"])
    else:
        wmm = cam["width_mm"]
        sensor = ortho_sensor(x0=cam["origin"][0] - wmm / 2,
                              y0=cam["origin"][1] - wmm * cam["height"] / cam["width"] / 2,
                              width_mm=wmm, nx=cam["width"], ny=cam["height"],
                              z_top=cam["origin"][2], spp=spec["spp"], jitter=True)
        sensor["sampler"] = {"type": "independent", "sample_count": int(spec["spp"])}
    lt = spec["light"]
    if lt["type"] == "studio":
        env = _studio_environment(lt, height=int(lt.get("env_rows", ENV_ROWS)))
    else:
        env = environment_map(lt["type"], height=int(lt.get("env_rows", ENV_ROWS)),
                              axis=lt["axis"], radiance=lt["radiance"],
                              zenith_falloff=lt.get("zenith_falloff", 0.0),
                              profile=lt.get("port_profile"))
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(spec["max_depth"])},
        "sensor": sensor,
        # the envmap's own up axis is +y: rotate it onto +z
        "light": {"type": "envmap", "bitmap": mi.Bitmap(env),
                  "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], 90)},
        "part": mitsuba_mesh(gm, bsdf=bsdf),
    }
    lamp = spec.get("lamp")
    if lamp is not None:
        d["lamp"] = {"type": "directional", "direction": list(lamp["direction"]),
                     "irradiance": float(lamp["irradiance"])}
    return d


#: the last studio image made: (its light as JSON, its rows) -> the image
_STUDIO_LAST: dict = {}


def _studio_environment(light: dict, *, height: int) -> np.ndarray:
    """:func:`studio_environment`, made once for the passes of an image (the same light
    every pass; 0.16 s of CPU each time at 721 rows); a copy of it each call."""
    try:
        key = (json.dumps(light, sort_keys=True), int(height))
    except (TypeError, ValueError):  # not plain JSON: made anew
        return studio_environment(light, height=height)
    env = _STUDIO_LAST.get(key)
    if env is None:
        env = studio_environment(light, height=height)
        _STUDIO_LAST.clear()
        _STUDIO_LAST[key] = env
    return env.copy()


def render_passes(width: int, height: int, spp: int) -> list[int]:
    """Samples per pixel of each pass so that no pass gives Mitsuba more than
    :data:`MAX_SAMPLES_PER_PASS` samples (one pass when the whole image fits)."""
    pixels = int(width) * int(height)
    if pixels > MAX_SAMPLES_PER_PASS:
        raise InputError(f"a diffuse image of {width} x {height} pixels is larger than "
                         f"{MAX_SAMPLES_PER_PASS} pixels; lower render.diffuse.resolution")
    per = max(1, MAX_SAMPLES_PER_PASS // pixels)
    spp = int(spp)
    return [per] * (spp // per) + ([spp % per] if spp % per else [])


def mitsuba_seed(seed: int, index: int = 0) -> int:
    """The 32-bit seed Mitsuba takes for pass ``index`` of a render with ``seed`` (any
    integer >= 0): ``seed`` itself for the first pass of a seed below 2^32, else a
    SplitMix64 hash of both, so every pass and every seed draws its own samples."""
    seed, index = int(seed), int(index)
    if index == 0 and 0 <= seed < 2 ** 32:
        return seed
    mask = (1 << 64) - 1
    z = (seed * 0x9E3779B97F4A7C15 + (index + 1) * 0xBF58476D1CE4E5B9) & mask
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
    return (z ^ (z >> 31)) & 0xFFFFFFFF


def diffuse_memory(dcfg: DiffuseConfig, grid_shape: Sequence[int], *, view: str = "macro",
                   window: Sequence[float] | None = None, pixel: float | None = None,
                   spectral: bool = True) -> int:
    """Bytes a diffuse view needs at its peak: Mitsuba's fixed part, the film and the
    wavefront's per-pixel arrays (with the passes' sum) and the mesh (render_inspect's
    arrays and Mitsuba's copy).

    Parameters
    ----------
    dcfg : DiffuseConfig
    grid_shape : (ny, nx)
        The height map's grid.
    view : {"macro", "micro"}
    window : [x0, y0, x1, y1], optional
        The micro view's window (mm) and ``pixel`` the height map's pixel (mm): the mesh
        covers only the window.
    spectral : bool
        The part is rendered with the turned-aluminium BSDF (its tool marks) in a
        spectral variant (:data:`FILM_BYTES_PER_PIXEL`); False: an RGB variant
        (:data:`FILM_BYTES_PER_PIXEL_RGB`).
    """
    res = int(dcfg.resolution)
    ny_img = res
    ny, nx = (int(v) for v in grid_shape)
    if view == "micro" and window is not None and pixel:
        x0, y0, x1, y1 = window
        ny_img = max(16, int(round(res * (y1 - y0) / (x1 - x0))))
        nx = min(nx, int((x1 - x0) / pixel) + 3)
        ny = min(ny, int((y1 - y0) / pixel) + 3)
    stride = max(1, -(-max(ny, nx) // (2 * res)))
    cells = -(-ny // stride) * -(-nx // stride)
    per_pixel = FILM_BYTES_PER_PIXEL if spectral else FILM_BYTES_PER_PIXEL_RGB
    return int(DIFFUSE_FIXED_BYTES + res * ny_img * per_pixel + cells * MESH_BYTES_PER_CELL)


def render_diffuse(heightmap: HeightMap, dcfg: DiffuseConfig | None = None, *, view: str = "macro", surface: str = "machined",
                   seed: int = 0, marks: dict | None = None, part: dict | None = None,
                   memory_budget: int | None = None) -> tuple[np.ndarray, dict]:
    """Path-trace the part (aluminium) under the diffuse dome or ring light.

    Parameters
    ----------
    heightmap : HeightMap
    dcfg : DiffuseConfig, optional
    view : {"macro", "micro"};  surface : {"machined", "design"};  seed : int
    marks : dict, optional
        The tool marks (:func:`diffuse_scene_spec`): the turned-aluminium BSDF, rendered
        with the spectral counterpart of the Mitsuba variant (diffraction colours); on
        ``scalar_rgb`` the part is a rough conductor instead, and the metadata says so.
    part : dict, optional
        What the macro view shows (recorded in the metadata).
    memory_budget : int, optional
        Bytes the mesh may take (default: the mesh module's).

    Images of more than :data:`MAX_SAMPLES_PER_PASS` samples (pixels x spp) are rendered
    in passes (:func:`render_passes`, seeds :func:`mitsuba_seed`) and averaged.

    Returns
    -------
    rgb : (height, width, 3) float32, linear radiance; row 0 at the top of the image
    meta : dict, :func:`diffuse_scene_spec` plus ``mitsuba_variant``, mesh sizes,
        ``vertical_exaggeration`` and, for the turned-aluminium BSDF, the grating's
        ``orders`` and efficiencies
    """
    if int(seed) != seed or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    spec = diffuse_scene_spec(heightmap, dcfg, view=view, surface=surface, seed=seed,
                              marks=marks, part=part)
    gm, factor = diffuse_mesh(heightmap, spec, memory_budget=memory_budget)
    m = spec["material"]
    with spectral_variant() if m["type"] == "turned_al" else _no_switch() as spectral:
        mi, dr, variant = import_mitsuba()
        if m["type"] == "turned_al" and spectral is None:
            # no spectral JIT variant: aluminium with the same (isotropic) roughness
            spec["material"] = m = {**m, "type": "roughconductor", "distribution": "ggx",
                                    "grating": False,
                                    "note": "turned-aluminium BSDF needs a spectral JIT variant"}
        extra = {}
        key = ""
        if m["type"] == "turned_al":
            register_turned_bsdf(mi, dr)
            mk = m["marks"]
            tables = efficiency_tables(period=mk["period_mm"] if m["grating"] else None,
                                       nose_radius=mk.get("nose_radius_mm"))
            key = f"{id(tables)}"
            store_tables(key, tables)
            extra = {"orders": tables["orders"],
                     "zero_order_efficiency_550nm": tables["zero_order_efficiency_550nm"],
                     "first_order_efficiency_550nm": tables["first_order_efficiency_550nm"]}
            m.update(extra)
        lamp = spec.get("lamp")
        if lamp is not None and lamp["irradiance"] is None:
            lamp["irradiance"] = _auto_lamp_irradiance(m)
        bulb = spec["light"].get("lamp") if spec["light"]["type"] == "studio" else None
        if bulb is not None and bulb["radiance"] is None:
            bulb["radiance"] = _auto_lamp_radiance(m)
        scene = load_scene_dict(_mitsuba_scene(gm, spec, _material_dict(spec, key)))
        cam = spec["camera"]
        passes = render_passes(cam["width"], cam["height"], spec["spp"])
        if len(passes) == 1:
            rgb = np.array(mi.render(scene, seed=mitsuba_seed(seed), spp=passes[0]),
                           dtype=np.float32)[..., :3]
        else:
            acc = None
            for k, n in enumerate(passes):
                report(k, len(passes))  # (and stop between passes when a signal asked)
                img = np.array(mi.render(scene, seed=mitsuba_seed(seed, k), spp=n),
                               dtype=np.float64)[..., :3]
                acc = img * n if acc is None else acc + img * n
            rgb = (cast(np.ndarray, acc) / float(sum(passes))).astype(np.float32)
    meta = dict(spec)
    meta.update(mitsuba_variant=variant, vertical_exaggeration=spec["exaggeration"],
                passes=len(passes),
                mesh_vertices=gm.n_vertices, mesh_triangles=gm.n_faces,
                mesh_stride=int(factor))
    return rgb, meta


def _auto_lamp_irradiance(material: dict) -> float:
    """Irradiance that gives the lamp's first diffraction order a peak radiance of
    :data:`LAMP_ORDER_RADIANCE` (the order's share ``first_order_efficiency_550nm`` of the
    light, spread over the roughness lobe); the lamp's own mirror reflection is then far
    brighter (a highlight, as in a photograph)."""
    su = material.get("sigma_u") or math.sqrt(2.0) * max(material.get("alpha", 0.0), 1e-3)
    sv = material.get("sigma_v") or su
    peak = 1.0 / (2 * math.pi * su * sv)
    eta = material.get("first_order_efficiency_550nm") or 0.01
    return float(min(max(LAMP_ORDER_RADIANCE / (0.9 * eta * peak), 1e-4), 1e4))


#: the studio lamp's radiance at most: brighter, its few paths through the narrow grating
#: orders would be single bright pixels (Monte Carlo fireflies) at a few dozen samples
LAMP_MAX_RADIANCE = 50.0


def _auto_lamp_radiance(material: dict) -> float:
    """Radiance of the studio's lamp disc that makes its first diffraction order (the
    share ``first_order_efficiency_550nm`` of its light) :data:`LAMP_ORDER_RADIANCE`
    bright: a lamp disc wider than the roughness lobe is imaged at its own radiance times
    each order's efficiency.  The lamp's own mirror image is far brighter (a highlight)."""
    eta = material.get("first_order_efficiency_550nm") or 0.01
    return float(min(max(LAMP_ORDER_RADIANCE / eta, 5.0), LAMP_MAX_RADIANCE))


class _no_switch:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False
