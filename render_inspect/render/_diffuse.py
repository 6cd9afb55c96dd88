"""Diffuse-light images of the machined part: Mitsuba path tracing of aluminium.

The whole scene is described by :func:`diffuse_scene_spec` as plain numbers (camera,
light, material, exaggeration, mesh decimation) so that another renderer (the Blender add-on's
Blender Cycles benchmark, ``render/_cycles.py``) can build the same scene:

* mesh: :func:`render_inspect.mesh.heightmap_mesh` with ``channel``, ``exaggeration``,
  ``window`` (micro view), ``max_cells``, ``skirt`` (macro view) and smooth vertex normals;
  vertex z = exaggeration * (h - z_offset_mm), mm;
* light: an environment (infinitely distant) whose radiance depends only on the zenith
  angle ``theta`` from +z: linear interpolation of ``light.zenith_profile`` (pairs
  ``[theta_deg, radiance]``), zero below the horizon.  :func:`environment_map` gives the
  same light as a lat-long RGB image (row r at zenith angle r / (rows - 1) * 180 degrees,
  row 0 = +z; columns = azimuth), which Mitsuba's ``envmap`` uses;
* material: Mitsuba ``conductor`` / ``roughconductor`` with ``material = "Al"``
  (GGX ``alpha`` = roughness); ``reflectance_rgb`` is aluminium's normal-incidence
  reflectance for renderers without complex IOR;
* camera: ``perspective`` (macro: ``fov_deg`` horizontal) or ``orthographic`` (micro:
  ``width_mm`` across the image), ``origin``/``target``/``up`` in mm, ``width`` x ``height``
  pixels; box reconstruction filter; ``spp`` samples per pixel; path tracer
  ``max_depth``.

Images are returned with row 0 at the top (camera convention), linear RGB.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from .. import __version__
from ..core.errors import InputError
from ..core.section import Region, Section
from ..mesh import heightmap_mesh, window_indices
from ._scene_dicts import (
    load_scene_dict,
    mitsuba_mesh,
    ortho_sensor,
    perspective_sensor,
)
from ._variant import import_mitsuba

__all__ = ["DiffuseConfig", "diffuse_scene_spec", "environment_map", "light_profile",
           "render_diffuse", "auto_exaggeration", "render_passes", "mitsuba_seed",
           "diffuse_memory", "LIGHTS", "AL_REFLECTANCE_RGB", "MAX_FILM_SIDE",
           "MAX_SAMPLES_PER_PASS"]

#: Zenith-angle radiance profiles: [theta_deg, radiance] pairs, linear in between.
#: dome: uniform diffuse dome with a camera port (dark) around the zenith;
#: ring: a bright ring at 45..75 degrees from the zenith (low-angle ring light).
LIGHTS = {
    "dome": [[0.0, 0.0], [8.0, 0.0], [25.0, 1.0], [90.0, 1.0], [90.5, 0.0], [180.0, 0.0]],
    "ring": [[0.0, 0.0], [45.0, 0.0], [50.0, 1.0], [70.0, 1.0], [75.0, 0.0], [180.0, 0.0]],
}
#: Normal-incidence reflectance of aluminium in linear sRGB, ((n-1)^2 + k^2)/((n+1)^2 + k^2)
#: from Mitsuba's "Al" (eta = 1.6575, 0.8804, 0.5212; k = 9.2238, 6.2695, 4.8370), for
#: renderers without a complex-IOR conductor.
AL_REFLECTANCE_RGB = [0.9283, 0.9177, 0.9194]
#: Rows of the lat-long environment image: 0.5 degree apart, so every profile knot is a row.
ENV_ROWS = 361
#: Macro camera: tilt of the view from the zenith and horizontal field of view.
MACRO_TILT_DEG = 20.0
MACRO_FOV_DEG = 30.0
MAX_DEPTH = 6
#: Largest image side (pixels) of a diffuse view; Blender Cycles allows 65536, Mitsuba's
#: film is limited by memory.
MAX_FILM_SIDE = 8192
#: Largest number of Monte Carlo samples (pixels x samples per pixel) given to Mitsuba in
#: one call: its JIT variants index one wavefront with 32-bit integers, and it crashes
#: (segmentation fault) when it splits a task of >= 2^32 samples itself.  Larger requests
#: are rendered in passes of at most this many samples and averaged.
MAX_SAMPLES_PER_PASS = 2 ** 26
#: Bytes per image pixel while rendering (Mitsuba's film: RGB, alpha and weight as
#: float32; the image returned; the float64 sum of the passes)
FILM_BYTES_PER_PIXEL = 20 + 12 + 24
#: Bytes per mesh cell (render_inspect's arrays and Mitsuba's copy: 2 triangles, a vertex
#: with its normal)
MESH_BYTES_PER_CELL = 2 * (24 + 24)


class DiffuseConfig(Section):
    """``[render.diffuse]``: diffuse-light images of the part (dome or ring light)."""
    light: Literal["dome", "ring"] = "dome"
    material: Literal["aluminium"] = "aluminium"
    roughness: float = Field(0.0, ge=0, le=1, description="0 = smooth conductor")
    exaggeration: float | None = Field(None, gt=0, le=1e6,
                                       description="vertical exaggeration of the mesh; None = auto "
                                                   "(the steepest 1 % of slopes become ~0.2 rad)")
    spp: int = Field(64, ge=1, le=65536)
    resolution: int = Field(256, ge=16, le=MAX_FILM_SIDE)
    window: Region | None = Field(None, description="mm, microscope view")


def light_profile(theta, light: str = "dome") -> np.ndarray:
    """Radiance of ``light`` at zenith angle(s) ``theta`` (rad)."""
    if light not in LIGHTS:
        raise InputError(f"render.diffuse.light must be one of {sorted(LIGHTS)}, got {light!r}")
    tab = np.asarray(LIGHTS[light], dtype=np.float64)
    return np.interp(np.degrees(theta), tab[:, 0], tab[:, 1])


def environment_map(light: str = "dome", *, height: int = ENV_ROWS) -> np.ndarray:
    """The light as a lat-long image, (height, 2*(height-1), 3) float32, row 0 = zenith (+z).

    Row ``r`` is the zenith angle ``theta = r / (height - 1) * pi`` (rows 0 and height-1 are
    the poles; Mitsuba's ``envmap`` interpolates bilinearly between rows placed so), and the
    light does not depend on azimuth.  With the default 361 rows (0.5 degree apart) the
    image reproduces the piecewise-linear :data:`LIGHTS` profile exactly.
    """
    theta = np.arange(height) / (height - 1) * math.pi
    rad = light_profile(theta, light).astype(np.float32)
    return np.ascontiguousarray(np.broadcast_to(rad[:, None, None], (height, 2 * (height - 1), 3)))


def _default_window(heightmap):
    x_lo, x_hi, y_lo, y_hi = heightmap.extent
    side = max(min(x_hi - x_lo, y_hi - y_lo) / 8.0, 16 * heightmap.pixel)
    side = min(side, x_hi - x_lo, y_hi - y_lo)
    cx, cy = (x_lo + x_hi) / 2, (y_lo + y_hi) / 2
    return [cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2]


def diffuse_scene_spec(heightmap, dcfg=None, *, view: str = "macro", surface: str = "machined",
                       seed: int = 0) -> dict:
    """All parameters of a diffuse-light image as plain numbers (JSON-able).

    Parameters
    ----------
    heightmap : HeightMap
    dcfg : DiffuseConfig, optional
        ``[render.diffuse]`` (defaults when None).
    view : {"macro", "micro"}
        macro: the whole part, perspective, tilted ``MACRO_TILT_DEG`` from the zenith
        (seen from -y); micro: ``dcfg.window`` (default: the central eighth) straight down,
        orthographic (a microscope view).
    surface : {"machined", "design"}
    seed : int

    Returns
    -------
    dict
        keys ``view``, ``surface``, ``seed``, ``spp``, ``max_depth``, ``exaggeration``,
        ``z_offset_mm``, ``window_mm``, ``mesh`` (``channel``, ``window``, ``max_cells``,
        ``skirt``), ``camera``, ``light``, ``material`` (see the module docstring).
    """
    if dcfg is None:
        dcfg = DiffuseConfig()
    if view not in ("macro", "micro"):
        raise InputError(f"view must be 'macro' or 'micro', got {view!r}")
    if surface not in ("machined", "design"):
        raise InputError(f"surface must be 'design' or 'machined', got {surface!r}")
    z = getattr(heightmap, surface)
    finite = np.isfinite(z)
    if not finite.any():
        raise InputError(f"the height map's {surface} channel has no finite height")
    x_lo, x_hi, y_lo, y_hi = heightmap.extent
    res = int(dcfg.resolution)
    if view == "macro":
        window = [x_lo, y_lo, x_hi, y_hi]
    else:
        window = list(dcfg.window) if dcfg.window is not None else _default_window(heightmap)
        x0, y0, x1, y1 = window
        if not (x1 > x0 and y1 > y0) or x0 < x_lo - 1e-9 or x1 > x_hi + 1e-9 \
                or y0 < y_lo - 1e-9 or y1 > y_hi + 1e-9:
            raise InputError(f"render.diffuse.window must be [x0, y0, x1, y1] inside the height map "
                             f"(x {x_lo:g}..{x_hi:g}, y {y_lo:g}..{y_hi:g} mm), got {window}")
    x0, y0, x1, y1 = (float(w) for w in window)
    if view == "micro":
        film_ny = max(16, int(round(res * (y1 - y0) / (x1 - x0))))
        if film_ny > MAX_FILM_SIDE:
            raise InputError(f"render.diffuse.window {window} is {(y1 - y0) / (x1 - x0):.3g} times "
                             f"taller than wide: at render.diffuse.resolution = {res} the image "
                             f"would be {film_ny} pixels high (at most {MAX_FILM_SIDE}); widen the "
                             f"window or lower the resolution")

        i0, i1, j0, j1 = window_indices(heightmap, window, margin=1)
        zw = z[i0:i1, j0:j1]
        zf = zw[np.isfinite(zw)]
        z_offset = float(zf.mean()) if zf.size else float(z[finite].mean())
    else:
        z_offset = float(z[finite].mean())
    ex = float(dcfg.exaggeration) if dcfg.exaggeration is not None else \
        auto_exaggeration(heightmap, surface, None if view == "macro" else window)
    zmax = float(np.nanmax(z) - z_offset) * ex
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    wmm, hmm = x1 - x0, y1 - y0
    if view == "macro":
        size = max(wmm, hmm)
        dist = 0.6 * size / math.tan(math.radians(MACRO_FOV_DEG / 2)) + max(zmax, 0.0)
        t = math.radians(MACRO_TILT_DEG)
        camera = {"type": "perspective", "fov_deg": MACRO_FOV_DEG,
                  "origin": [cx, cy - dist * math.sin(t), dist * math.cos(t)],
                  "target": [cx, cy, 0.0], "up": [0.0, 1.0, 0.0], "width": res, "height": res}
        light = dcfg.light
    else:
        ny = max(16, int(round(res * hmm / wmm)))
        camera = {"type": "orthographic", "width_mm": wmm,
                  "origin": [cx, cy, max(zmax, 0.0) + max(wmm, hmm)],
                  "target": [cx, cy, 0.0], "up": [0.0, 1.0, 0.0], "width": res, "height": ny}
        light = dcfg.light
    rough = float(dcfg.roughness)
    material = {"type": "roughconductor" if rough > 0 else "conductor", "material": "Al",
                "alpha": rough, "distribution": "ggx", "reflectance_rgb": AL_REFLECTANCE_RGB}
    return {"view": view, "surface": surface, "seed": int(seed), "spp": int(dcfg.spp),
            "max_depth": MAX_DEPTH, "exaggeration": ex, "z_offset_mm": z_offset,
            "window_mm": [x0, y0, x1, y1],
            "mesh": {"channel": surface, "window": None if view == "macro" else [x0, y0, x1, y1],
                     "max_cells": 2 * res, "skirt": view == "macro"},
            "camera": camera,
            "light": {"type": light, "zenith_profile": LIGHTS[light], "up": [0.0, 0.0, 1.0],
                      "env_rows": ENV_ROWS},
            "material": material, "units": "mm", "software_version": __version__}


AUTO_SLOPE_RAD = 0.2


def auto_exaggeration(heightmap, surface="machined", window=None) -> float:
    """Vertical exaggeration that makes the steepest 1 % of the (exaggerated) slopes about
    ``AUTO_SLOPE_RAD``: nanometre relief on a millimetre part becomes visible as shading
    and reflection distortion without turning into cliffs.  Rounded to 1-2-5 steps."""
    z = getattr(heightmap, surface)
    if window is not None:

        i0, i1, j0, j1 = window_indices(heightmap, window, margin=1)
        z = z[i0:i1, j0:j1]
    step = max(1, int(max(z.shape) // 1024))
    zz = z[::step, ::step]
    gy, gx = np.gradient(zz, heightmap.pixel * step)
    g = np.hypot(gx, gy)
    g = g[np.isfinite(g)]
    p99 = float(np.percentile(g, 99)) if g.size else 0.0
    if p99 <= 0:
        return 1.0
    raw = min(max(AUTO_SLOPE_RAD / p99, 1.0), 1e6) * (1 + 1e-9)
    e = 10 ** math.floor(math.log10(raw))
    return float(max(m * e for m in (1, 2, 5) if m * e <= raw))


def _mitsuba_scene(gm, spec):

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
    m = spec["material"]
    bsdf = {"type": m["type"], "material": "Al"}
    if m["type"] == "roughconductor":
        bsdf.update(alpha=m["alpha"], distribution="ggx")
    env = environment_map(spec["light"]["type"])
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(spec["max_depth"])},
        "sensor": sensor,
        # the envmap's own up axis is +y: rotate it onto +z
        "light": {"type": "envmap", "bitmap": mi.Bitmap(env),
                  "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], 90)},
        "part": mitsuba_mesh(gm, bsdf=bsdf),
    }


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


def diffuse_memory(dcfg, grid_shape, *, view: str = "macro", window=None, pixel=None) -> int:
    """Bytes a diffuse view needs at its peak: the film (with the passes' sum) and the
    mesh (render_inspect's arrays and Mitsuba's copy).

    Parameters
    ----------
    dcfg : DiffuseConfig
    grid_shape : (ny, nx)
        The height map's grid.
    view : {"macro", "micro"}
    window : [x0, y0, x1, y1], optional
        The micro view's window (mm) and ``pixel`` the height map's pixel (mm): the mesh
        covers only the window.
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
    return int(res * ny_img * FILM_BYTES_PER_PIXEL + cells * MESH_BYTES_PER_CELL)


def render_diffuse(heightmap, dcfg=None, *, view: str = "macro", surface: str = "machined",
                   seed: int = 0, memory_budget: int | None = None) -> tuple[np.ndarray, dict]:
    """Path-trace the part (aluminium) under the diffuse dome or ring light.

    Parameters
    ----------
    heightmap : HeightMap
    dcfg : DiffuseConfig, optional
    view : {"macro", "micro"};  surface : {"machined", "design"};  seed : int
    memory_budget : int, optional
        Bytes the mesh may take (default: the mesh module's).

    Images of more than :data:`MAX_SAMPLES_PER_PASS` samples (pixels x spp) are rendered
    in passes (:func:`render_passes`, seeds :func:`mitsuba_seed`) and averaged.

    Returns
    -------
    rgb : (height, width, 3) float32, linear radiance; row 0 at the top of the image
    meta : dict, :func:`diffuse_scene_spec` plus ``mitsuba_variant``, mesh sizes and
        ``vertical_exaggeration``
    """
    if int(seed) != seed or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    spec = diffuse_scene_spec(heightmap, dcfg, view=view, surface=surface, seed=seed)
    mi, _, variant = import_mitsuba()
    ms = spec["mesh"]
    gm = heightmap_mesh(heightmap, channel=ms["channel"], exaggeration=spec["exaggeration"],
                        window=ms["window"], z_offset=spec["z_offset_mm"],
                        max_cells=ms["max_cells"], skirt=ms["skirt"], normals=True,
                        memory_budget=memory_budget)
    scene = load_scene_dict(_mitsuba_scene(gm, spec))
    cam = spec["camera"]
    passes = render_passes(cam["width"], cam["height"], spec["spp"])
    if len(passes) == 1:
        rgb = np.array(mi.render(scene, seed=mitsuba_seed(seed), spp=passes[0]),
                       dtype=np.float32)[..., :3]
    else:
        acc = None
        for k, n in enumerate(passes):
            img = np.array(mi.render(scene, seed=mitsuba_seed(seed, k), spp=n),
                           dtype=np.float64)[..., :3]
            acc = img * n if acc is None else acc + img * n
        rgb = (acc / float(sum(passes))).astype(np.float32)
    meta = dict(spec)
    meta.update(mitsuba_variant=variant, vertical_exaggeration=spec["exaggeration"],
                passes=len(passes),
                mesh_vertices=gm.n_vertices, mesh_triangles=gm.n_faces,
                mesh_stride=gm.metadata["stride"])
    return rgb, meta
