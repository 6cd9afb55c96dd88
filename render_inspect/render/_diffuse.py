"""Diffuse-light images of the machined part: Mitsuba path tracing of aluminium.

The whole scene is described by :func:`diffuse_scene_spec` as plain numbers (camera,
light, lamp, material, exaggeration, mesh) so that another renderer (the Blender add-on's
Cycles benchmark, ``render/_cycles.py``) can build the same scene:

* mesh: :func:`render_inspect.mesh.heightmap_mesh` with ``channel``, ``exaggeration``,
  ``window`` (micro view), ``skirt`` (macro view of a map without holes) and smooth vertex
  normals; vertex z = exaggeration * (h - z_offset_mm), mm.  A map larger than
  ``max_cells`` is area-averaged (block means of ``mesh_stride`` x ``mesh_stride``
  samples) first, not decimated: detail finer than the image's pixels is averaged, not
  aliased;
* light: an environment (infinitely distant) whose radiance depends on the angle from
  the camera port's axis ``light.axis`` (the direction from the part to the camera: the
  port follows the camera), the piecewise-linear ``light.port_profile`` (pairs
  ``[angle_deg, radiance]``), times ``light.radiance``, and zero below the horizon
  (``light.up`` = +z; the step is 0.5 degree wide).  ``light.zenith_profile`` is the same
  light as a function of the zenith angle when the axis is +z.  :func:`environment_map`
  gives the light as a lat-long RGB image for Mitsuba's ``envmap``;
* lamp (macro view of a part with tool marks): a directional light (``direction``:
  where its light travels, ``irradiance``) placed so that its mirror reflection off
  the flat part lands at ``lamp.highlight_mm``: the compact source whose diffraction by
  the feed marks shows as the rainbow of a turned part (a uniform dome shows none:
  every direction receives the same light).  A point-like source keeps the colours
  clean: each wavelength's orders are sharp, and the renderer evaluates them exactly
  (no random hits of a small bright disc);
* material: Mitsuba ``conductor`` / ``roughconductor`` (``material = "Al"``, GGX ``alpha``
  = roughness; ``reflectance_rgb`` is aluminium's normal-incidence reflectance for
  renderers without complex IOR), or, for a part with tool marks (``marks``), the
  turned-aluminium BSDF of :mod:`render_inspect.render._turned_bsdf` (spectral: the feed
  marks as a reflection grating with anisotropic microroughness; in the micro view the
  marks are in the mesh and only the anisotropic roughness is kept);
* camera: ``perspective`` (macro: ``fov_deg`` horizontal) or ``orthographic`` (micro:
  ``width_mm`` across the image), ``origin``/``target``/``up`` in mm, ``width`` x ``height``
  pixels; box reconstruction filter; ``spp`` samples per pixel; path tracer
  ``max_depth``;
* ``scale``: mm per image pixel (micro), or at the part's centre (macro), for the
  scale bars written into the images.

Images are returned with row 0 at the top (camera convention), linear RGB.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from .. import __version__
from ..core.errors import InputError
from ..core.heightmap import HeightMap
from ..core.section import Region, Section
from ..mesh import heightmap_mesh, window_indices
from ._scene_dicts import (
    load_scene_dict,
    mitsuba_mesh,
    ortho_sensor,
    perspective_sensor,
)
from ._turned_bsdf import efficiency_tables, register_turned_bsdf, store_tables
from ._variant import import_mitsuba, spectral_variant

__all__ = ["DiffuseConfig", "diffuse_scene_spec", "diffuse_mesh", "environment_map", "light_profile",
           "render_diffuse", "auto_exaggeration", "render_passes", "mitsuba_seed",
           "diffuse_memory", "LIGHTS", "PORT_PROFILES", "AL_REFLECTANCE_RGB", "MACRO_DOME_RADIANCE",
           "DEFAULT_MICROROUGHNESS", "MAX_FILM_SIDE", "MAX_SAMPLES_PER_PASS"]

#: Radiance against the angle from the camera port's axis: [angle_deg, radiance] pairs,
#: linear in between.  dome: a uniform diffuse dome with a camera port (dark) around the
#: camera's line of sight; ring: a bright ring at 45..75 degrees around it (a ring light
#: mounted on the lens).
PORT_PROFILES = {
    "dome": [[0.0, 0.0], [8.0, 0.0], [25.0, 1.0], [180.0, 1.0]],
    "ring": [[0.0, 0.0], [45.0, 0.0], [50.0, 1.0], [70.0, 1.0], [75.0, 0.0], [180.0, 0.0]],
}
#: The same lights against the zenith angle for a camera looking straight down (the
#: port profile times the horizon step at 90..90.5 degrees).
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
MAX_DEPTH = 4
#: Dome radiance in the macro view, where the lamp is the main light (a dim room).
MACRO_DOME_RADIANCE = 0.3
#: with the lamp, the macro view's dome is a room: its radiance falls from the zenith to
#: the horizon by this fraction (``1 - f (1 - cos^2 theta)``), so that slopes show as shading
MACRO_ZENITH_FALLOFF = 1.0
#: GGX alpha of diamond-turned aluminium's microroughness when the part has tool marks
#: and ``roughness`` is not set (an assumption: rms microslopes of ~7 mrad, Sa ~ 2-5 nm
#: over micrometre correlation lengths); the lobe is this wide across the marks and
#: ``anisotropy`` times as wide along them.
DEFAULT_MICROROUGHNESS = 0.003
#: lamp highlight position as a fraction of the part's half-size (x, y) from its centre
LAMP_HIGHLIGHT = (0.2, 0.15)
#: peak radiance the first diffraction order of the lamp is given (auto irradiance)
LAMP_ORDER_RADIANCE = 3.0
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
    roughness: float | None = Field(None, ge=0, le=1,
                                    description="GGX alpha of the microroughness; None = "
                                                f"{DEFAULT_MICROROUGHNESS} on parts with tool marks, "
                                                "0 (a smooth conductor) otherwise")
    anisotropy: float = Field(0.3, gt=0, le=1,
                              description="width of the roughness lobe along the tool marks / "
                                          "across them")
    iridescence: bool = Field(True, description="diffraction by the feed marks (spectral "
                                                "rendering) in the macro view")
    lamp: bool = Field(True, description="a lamp (a directional light) in the macro view of a part "
                                         "with tool marks, whose mirror reflection lands on the part")
    lamp_irradiance: float | None = Field(None, gt=0, le=1e4,
                                          description="None = auto (the first diffraction order "
                                                      f"peaks at radiance {LAMP_ORDER_RADIANCE})")
    exaggeration: float | None = Field(None, gt=0, le=1e6,
                                       description="vertical exaggeration of the mesh; None = auto "
                                                   "(the steepest 1 % of slopes become ~0.2 rad)")
    spp: int = Field(64, ge=1, le=65536)
    resolution: int = Field(512, ge=16, le=MAX_FILM_SIDE)
    window: Region | None = Field(None, description="mm, microscope view")


def _profile(table, angle_deg) -> np.ndarray:
    tab = np.asarray(table, dtype=np.float64)
    return np.interp(angle_deg, tab[:, 0], tab[:, 1])


def light_profile(theta, light: str = "dome") -> np.ndarray:
    """Radiance of ``light`` at zenith angle(s) ``theta`` (rad) for a camera looking
    straight down (port axis +z)."""
    if light not in LIGHTS:
        raise InputError(f"render.diffuse.light must be one of {sorted(LIGHTS)}, got {light!r}")
    return _profile(LIGHTS[light], np.degrees(theta))


def environment_map(light: str = "dome", *, height: int = ENV_ROWS, axis=(0.0, 0.0, 1.0),
                    radiance: float = 1.0, zenith_falloff: float = 0.0) -> np.ndarray:
    """The light as a lat-long image, (height, 2*(height-1), 3) float32, row 0 = zenith (+z).

    Row ``r`` is the zenith angle ``theta = r / (height - 1) * pi`` (rows 0 and height-1 are
    the poles; Mitsuba's ``envmap`` interpolates bilinearly between rows placed so);
    column ``c`` the azimuth ``pi / 2 - (c + 0.5) / width * 2 pi`` from +x towards +y
    (Mitsuba's ``envmap`` rotated by 90 degrees about x, so that its up axis is +z;
    checked against ``Emitter.eval`` in ``tests/test_diffuse.py``).  The radiance is
    the port profile at the angle from ``axis`` (unit vector, part -> camera) times the
    horizon step, times ``radiance``.  With the default axis (+z) every column is the
    :data:`LIGHTS` profile, reproduced exactly on the 0.5 degree rows.
    """
    if light not in PORT_PROFILES:
        raise InputError(f"render.diffuse.light must be one of {sorted(PORT_PROFILES)}, got {light!r}")
    theta = np.arange(height) / (height - 1) * math.pi
    width = 2 * (height - 1)
    alpha = math.pi / 2 - (np.arange(width) + 0.5) / width * 2 * math.pi
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    cosang = st * np.cos(alpha)[None, :] * a[0] + st * np.sin(alpha)[None, :] * a[1] + ct * a[2]
    ang = np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0)))
    horizon = np.interp(np.degrees(theta), [90.0, 90.5], [1.0, 0.0])[:, None]
    # a room rather than an integrating dome: brighter overhead than at the horizon
    horizon = horizon * (1.0 - zenith_falloff * (1.0 - np.clip(np.cos(theta), 0.0, 1.0) ** 2))[:, None]
    rad = (_profile(PORT_PROFILES[light], ang) * horizon * float(radiance)).astype(np.float32)
    return np.ascontiguousarray(np.repeat(rad[..., None], 3, axis=2))


def _default_window(heightmap):
    x_lo, x_hi, y_lo, y_hi = heightmap.extent
    side = max(min(x_hi - x_lo, y_hi - y_lo) / 8.0, 16 * heightmap.pixel)
    side = min(side, x_hi - x_lo, y_hi - y_lo)
    cx, cy = (x_lo + x_hi) / 2, (y_lo + y_hi) / 2
    return [cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2]


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _check_marks(marks) -> dict | None:
    if marks is None:
        return None
    kind = marks.get("kind")
    if kind not in ("circular", "linear"):
        raise InputError(f"marks.kind must be 'circular' or 'linear', got {kind!r}")
    period = marks.get("period_mm")
    if period is not None and not period > 0:
        raise InputError(f"marks.period_mm must be > 0 or None, got {period!r}")
    return dict(marks)


def diffuse_scene_spec(heightmap, dcfg=None, *, view: str = "macro", surface: str = "machined",
                       seed: int = 0, marks: dict | None = None, part: dict | None = None) -> dict:
    """All parameters of a diffuse-light image as plain numbers (JSON-able).

    Parameters
    ----------
    heightmap : HeightMap
    dcfg : DiffuseConfig, optional
        ``[render.diffuse]`` (defaults when None).
    view : {"macro", "micro"}
        macro: the whole map, perspective, tilted ``MACRO_TILT_DEG`` from the zenith
        (seen from -y), lit by the dome and the lamp; micro: ``dcfg.window`` (default: the
        central eighth) straight down, orthographic (a microscope view).
    surface : {"machined", "design"}
    seed : int
    marks : dict, optional
        The tool marks: ``kind`` ("circular" about ``center_mm``, or "linear" along
        ``direction``), ``period_mm`` (None: finer than light resolves) and
        ``nose_radius_mm`` (the groove profile).  Given, the material is the
        turned-aluminium BSDF.
    part : dict, optional
        What the macro view shows, for its caption (``shape``, ``radius``...).

    Returns
    -------
    dict
        keys ``view``, ``surface``, ``seed``, ``spp``, ``max_depth``, ``exaggeration``,
        ``z_offset_mm``, ``window_mm``, ``mesh``, ``camera``, ``light``, ``lamp``,
        ``material``, ``scale`` (see the module docstring).
    """
    if dcfg is None:
        dcfg = DiffuseConfig()
    if view not in ("macro", "micro"):
        raise InputError(f"view must be 'macro' or 'micro', got {view!r}")
    if surface not in ("machined", "design"):
        raise InputError(f"surface must be 'design' or 'machined', got {surface!r}")
    marks = _check_marks(marks)
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
        auto_exaggeration(heightmap, surface, None if view == "macro" else window,
                          slope=MACRO_AUTO_SLOPE_RAD if view == "macro" else AUTO_SLOPE_RAD)
    zmax = float(np.nanmax(z) - z_offset) * ex
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    wmm, hmm = x1 - x0, y1 - y0
    lamp = None
    if view == "macro":
        size = max(wmm, hmm)
        dist = 0.6 * size / math.tan(math.radians(MACRO_FOV_DEG / 2)) + max(zmax, 0.0)
        t = math.radians(MACRO_TILT_DEG)
        origin = [cx, cy - dist * math.sin(t), dist * math.cos(t)]
        camera = {"type": "perspective", "fov_deg": MACRO_FOV_DEG, "origin": origin,
                  "target": [cx, cy, 0.0], "up": [0.0, 1.0, 0.0], "width": res, "height": res}
        axis = _unit(np.subtract(origin, camera["target"]))
        use_lamp = bool(dcfg.lamp and marks is not None)
        radiance = MACRO_DOME_RADIANCE if use_lamp else 1.0
        scale = {"mm_per_px_at_target": 2 * dist * math.tan(math.radians(MACRO_FOV_DEG / 2)) / res}
        if use_lamp:
            lamp = _lamp(heightmap, surface, ex, origin, (cx, cy), (wmm, hmm),
                         None if dcfg.lamp_irradiance is None else float(dcfg.lamp_irradiance))
    else:
        ny = max(16, int(round(res * hmm / wmm)))
        camera = {"type": "orthographic", "width_mm": wmm,
                  "origin": [cx, cy, max(zmax, 0.0) + max(wmm, hmm)],
                  "target": [cx, cy, 0.0], "up": [0.0, 1.0, 0.0], "width": res, "height": ny}
        axis = np.array([0.0, 0.0, 1.0])
        radiance = 1.0
        scale = {"mm_per_px": wmm / res}
    rough = dcfg.roughness
    if rough is None:
        rough = DEFAULT_MICROROUGHNESS if marks is not None else 0.0
    rough = float(rough)
    if marks is not None:
        grating = bool(view == "macro" and dcfg.iridescence and marks.get("period_mm"))
        a = max(rough, 1e-4)
        material = {"type": "turned_al", "material": "Al", "alpha": a, "distribution": "gaussian",
                    "reflectance_rgb": AL_REFLECTANCE_RGB, "marks": marks,
                    "grating": grating,
                    # lobe widths in direction cosines: a microfacet slope s turns the
                    # reflection by 2 s; GGX alpha ~ sqrt(2) x the rms slope
                    "sigma_u": math.sqrt(2.0) * a, "sigma_v": math.sqrt(2.0) * a * dcfg.anisotropy}
    else:
        material = {"type": "roughconductor" if rough > 0 else "conductor", "material": "Al",
                    "alpha": rough, "distribution": "ggx", "reflectance_rgb": AL_REFLECTANCE_RGB}
    stride_cells = 2 * res
    light = {"type": dcfg.light, "axis": [float(v) for v in axis], "radiance": radiance,
             "zenith_falloff": MACRO_ZENITH_FALLOFF if radiance != 1.0 else 0.0,
             "port_profile": PORT_PROFILES[dcfg.light], "up": [0.0, 0.0, 1.0],
             "zenith_profile": LIGHTS[dcfg.light], "env_rows": ENV_ROWS}
    has_holes = not bool(finite.all())
    return {"view": view, "surface": surface, "seed": int(seed), "spp": int(dcfg.spp),
            "max_depth": MAX_DEPTH, "exaggeration": ex, "z_offset_mm": z_offset,
            "window_mm": [x0, y0, x1, y1],
            "mesh": {"channel": surface, "window": None if view == "macro" else [x0, y0, x1, y1],
                     "max_cells": stride_cells, "skirt": view == "macro" and not has_holes,
                     "prefilter": "block_mean"},
            "camera": camera, "light": light, "lamp": lamp, "material": material,
            "scale": scale, "part": part, "units": "mm", "software_version": __version__}


def _lamp(heightmap, surface, ex, cam_origin, centre, size, irradiance) -> dict:
    """The macro view's lamp: a directional light whose mirror reflection lands on the
    part at the flattest point (smallest exaggerated slope) near
    :data:`LAMP_HIGHLIGHT`, reflected about that point's own normal, so the highlight
    and the diffraction orders around it are on the part."""
    z = getattr(heightmap, surface)
    step = max(1, int(max(z.shape) // 512))
    zz = z[::step, ::step] * ex
    px = heightmap.pixel * step
    gy, gx = np.gradient(zz, px)
    xs = heightmap.origin[0] + px * np.arange(zz.shape[1])
    ys = heightmap.origin[1] + px * np.arange(zz.shape[0])
    hx = centre[0] + LAMP_HIGHLIGHT[0] * size[0] / 2
    hy = centre[1] + LAMP_HIGHLIGHT[1] * size[1] / 2
    r = 0.12 * max(size)
    near = (np.abs(xs[None, :] - hx) <= r) & (np.abs(ys[:, None] - hy) <= r)
    g = np.where(near & np.isfinite(gx) & np.isfinite(gy), np.hypot(gx, gy), np.inf)
    if np.isfinite(g).any():
        i, j = np.unravel_index(np.argmin(g), g.shape)
        hx, hy = float(xs[j]), float(ys[i])
        n = _unit([-gx[i, j], -gy[i, j], 1.0])
        hz = float(zz[i, j] - np.nanmean(zz))
    else:
        n = np.array([0.0, 0.0, 1.0])
        hz = 0.0
    d = _unit(np.subtract([hx, hy, hz], cam_origin))      # camera -> highlight
    to_lamp = d - 2 * float(np.dot(d, n)) * n             # mirror about the normal
    return {"type": "directional", "direction": [float(v) for v in -to_lamp],
            "irradiance": irradiance, "highlight_mm": [hx, hy],
            "zenith_deg": math.degrees(math.acos(np.clip(to_lamp[2], -1, 1))),
            "azimuth_deg": math.degrees(math.atan2(to_lamp[1], to_lamp[0]))}


AUTO_SLOPE_RAD = 0.2
#: the macro view's target: the part's form against a room's light needs steeper slopes
MACRO_AUTO_SLOPE_RAD = 0.3


def auto_exaggeration(heightmap, surface="machined", window=None, *,
                      slope: float = AUTO_SLOPE_RAD) -> float:
    """Vertical exaggeration that makes the steepest 1 % of the (exaggerated) slopes about
    ``slope`` (rad; :data:`AUTO_SLOPE_RAD` in the micro view, :data:`MACRO_AUTO_SLOPE_RAD`
    in the macro view): nanometre relief on a millimetre part becomes visible as shading
    and reflection distortion without turning into cliffs.  Rounded down to 1-2-5 steps."""
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
    raw = min(max(slope / p99, 1.0), 1e6) * (1 + 1e-9)
    e = 10 ** math.floor(math.log10(raw))
    return float(max(m * e for m in (1, 2, 5) if m * e <= raw))


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


def diffuse_mesh(heightmap, spec: dict, *, memory_budget: int | None = None):
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
    gm = heightmap_mesh(hm, channel=channel, exaggeration=spec["exaggeration"], window=window,
                        z_offset=spec["z_offset_mm"], skirt=ms["skirt"], normals=True,
                        memory_budget=memory_budget)
    return gm, factor


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
    env = environment_map(lt["type"], height=int(lt.get("env_rows", ENV_ROWS)), axis=lt["axis"], radiance=lt["radiance"],
                          zenith_falloff=lt.get("zenith_falloff", 0.0))
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
        scene = load_scene_dict(_mitsuba_scene(gm, spec, _material_dict(spec, key)))
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


class _no_switch:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False
