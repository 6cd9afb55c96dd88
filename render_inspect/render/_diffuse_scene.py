"""The diffuse-light scene of the machined part, engine-neutral: :func:`diffuse_scene_spec`
and its light, lamp, material and camera (:mod:`._diffuse` renders it with Mitsuba).

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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import ArrayLike
from pydantic import Field

from .. import __version__
from ..core.errors import InputError
from ..core.heightmap import HeightMap
from ..core.section import Region, Section
from ..mesh import window_indices
from ._studio import LAMP_RADIUS_DEG, brightfield_profile, studio_light

__all__ = ["DiffuseConfig", "diffuse_scene_spec", "environment_map", "light_profile",
           "auto_exaggeration", "LIGHTS", "PORT_PROFILES", "AL_REFLECTANCE_RGB",
           "MACRO_DOME_RADIANCE", "DEFAULT_MICROROUGHNESS", "MAX_FILM_SIDE"]

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
#: in the studio: on the near half of the face, away from the softbox's image
STUDIO_LAMP_HIGHLIGHT = (-0.35, -0.4)
#: peak radiance the first diffraction order of the lamp is given (auto irradiance)
LAMP_ORDER_RADIANCE = 3.0
#: Macro camera of the studio: tilted more, so that the part's chamfer and side show
STUDIO_TILT_DEG = 30.0
#: the turned disc's chamfer (width = depth, 45 degrees) and side wall, as fractions of its
#: radius (staging: the design does not state them)
DISC_CHAMFER = 0.04
DISC_WALL = 0.35
#: Rows of the studio's lat-long image (0.25 degree: the lamp is 1 degree across)
STUDIO_ENV_ROWS = 721
#: Largest image side (pixels) of a diffuse view; Blender Cycles allows 65536, Mitsuba's
#: film is limited by memory.
MAX_FILM_SIDE = 8192


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
    studio: bool = Field(True, description="the macro view of a part with tool marks in a photo "
                                           "studio (a softbox, a small lamp, a dim room: staging) "
                                           "instead of the dome; a turned disc gets a chamfer and "
                                           "a side wall")
    micro_light: Literal["brightfield", "dome", "ring"] = Field(
        "brightfield", description="light of the micro view: brightfield = a microscope "
                                   "objective's own illumination through its aperture; dome / "
                                   "ring as light")
    objective_na: float = Field(0.3, gt=0, le=0.95, description="numerical aperture of the micro "
                                                                "view's objective (brightfield)")
    spp: int = Field(64, ge=1, le=65536)
    resolution: int = Field(512, ge=16, le=MAX_FILM_SIDE)
    window: Region | None = Field(None, description="mm, microscope view")


def _profile(table, angle_deg) -> np.ndarray:
    tab = np.asarray(table, dtype=np.float64)
    return np.interp(angle_deg, tab[:, 0], tab[:, 1])


def light_profile(theta: ArrayLike, light: str = "dome") -> np.ndarray:
    """Radiance of ``light`` at zenith angle(s) ``theta`` (rad) for a camera looking
    straight down (port axis +z)."""
    if light not in LIGHTS:
        raise InputError(f"render.diffuse.light must be one of {sorted(LIGHTS)}, got {light!r}")
    return _profile(LIGHTS[light], np.degrees(theta))


def environment_map(light: str = "dome", *, height: int = ENV_ROWS,
                    axis: Sequence[float] = (0.0, 0.0, 1.0),
                    radiance: float = 1.0, zenith_falloff: float = 0.0,
                    profile: Sequence[Sequence[float]] | None = None) -> np.ndarray:
    """The light as a lat-long image, (height, 2*(height-1), 3) float32, row 0 = zenith (+z).

    Row ``r`` is the zenith angle ``theta = r / (height - 1) * pi`` (rows 0 and height-1 are
    the poles; Mitsuba's ``envmap`` interpolates bilinearly between rows placed so);
    column ``c`` the azimuth ``pi / 2 - (c + 0.5) / width * 2 pi`` from +x towards +y
    (Mitsuba's ``envmap`` rotated by 90 degrees about x, so that its up axis is +z;
    checked against ``Emitter.eval`` in ``tests/test_diffuse.py``).  The radiance is
    the port profile at the angle from ``axis`` (unit vector, part -> camera) times the
    horizon step, times ``radiance``.  With the default axis (+z) every column is the
    :data:`LIGHTS` profile, reproduced exactly on the 0.5 degree rows.  ``profile``
    (``[angle_deg, radiance]`` pairs) replaces the named light's (the brightfield of
    :func:`~render_inspect.render._studio.brightfield_profile`).
    """
    if profile is None and light not in PORT_PROFILES:
        raise InputError(f"render.diffuse.light must be one of {sorted(PORT_PROFILES)}, got {light!r}")
    table = PORT_PROFILES[light] if profile is None else profile
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
    rad = (_profile(table, ang) * horizon * float(radiance)).astype(np.float32)
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


def diffuse_scene_spec(heightmap: HeightMap, dcfg: DiffuseConfig | None = None, *, view: str = "macro", surface: str = "machined",
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
    studio = None
    if view == "macro":
        size = max(wmm, hmm)
        dist = 0.6 * size / math.tan(math.radians(MACRO_FOV_DEG / 2)) + max(zmax, 0.0)
        in_studio = bool(dcfg.studio and marks is not None)
        t = math.radians(STUDIO_TILT_DEG if in_studio else MACRO_TILT_DEG)
        origin = [cx, cy - dist * math.sin(t), dist * math.cos(t)]
        camera: dict[str, Any] = {"type": "perspective", "fov_deg": MACRO_FOV_DEG, "origin": origin,
                  "target": [cx, cy, 0.0], "up": [0.0, 1.0, 0.0], "width": res, "height": res}
        axis = _unit(np.subtract(origin, camera["target"]))
        use_lamp = bool(dcfg.lamp and marks is not None)
        radiance = MACRO_DOME_RADIANCE if use_lamp else 1.0
        scale = {"mm_per_px_at_target": 2 * dist * math.tan(math.radians(MACRO_FOV_DEG / 2)) / res}
        if use_lamp:
            lamp = _lamp(heightmap, surface, ex, origin, (cx, cy), (wmm, hmm),
                         None if dcfg.lamp_irradiance is None else float(dcfg.lamp_irradiance),
                         where=STUDIO_LAMP_HIGHLIGHT if in_studio else LAMP_HIGHLIGHT)
        if in_studio:
            studio = studio_light(origin, camera["target"],
                                  lamp_direction=None if lamp is None else -np.asarray(lamp["direction"]),
                                  lamp_radiance=0.0 if lamp is None else _lamp_radiance(lamp))
            lamp = None  # the lamp is a small bright disc of the studio's light
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
    if studio is not None:
        light = {**studio, "axis": [float(v) for v in axis], "radiance": 1.0,
                 "env_rows": STUDIO_ENV_ROWS}
    elif view == "micro" and dcfg.micro_light == "brightfield":
        prof = brightfield_profile(dcfg.objective_na)
        light = {"type": "brightfield", "axis": [0.0, 0.0, 1.0], "radiance": 1.0,
                 "zenith_falloff": 0.0, "port_profile": prof, "zenith_profile": prof,
                 "up": [0.0, 0.0, 1.0], "objective_na": float(dcfg.objective_na),
                 "env_rows": ENV_ROWS}
    else:
        kind = dcfg.light if view == "macro" else dcfg.micro_light
        light = {"type": kind, "axis": [float(v) for v in axis], "radiance": radiance,
                 "zenith_falloff": MACRO_ZENITH_FALLOFF if radiance != 1.0 else 0.0,
                 "port_profile": PORT_PROFILES[kind], "up": [0.0, 0.0, 1.0],
                 "zenith_profile": LIGHTS[kind], "env_rows": ENV_ROWS}
    has_holes = not bool(finite.all())
    mesh: dict[str, Any] = {"channel": surface, "window": None if view == "macro" else [x0, y0, x1, y1],
            "max_cells": stride_cells, "skirt": view == "macro" and not has_holes,
            "prefilter": "block_mean", "kind": "grid"}
    if view == "macro" and (part or {}).get("shape") == "disc":
        part = cast(dict, part)  # (a disc: given)
        r = float(part["radius"])
        wall = DISC_WALL * r if studio is not None else 0.0
        mesh.update(kind="disc", skirt=wall > 0, center=[float(v) for v in part["center"]],
                    radius=r, rings=res, sectors=4 * res, chamfer_mm=DISC_CHAMFER * r,
                    wall_mm=wall)
    elif view == "micro":
        # finer than the grid: a smooth (cubic) surface through the samples, not facets
        mesh["refine"] = int(min(4, max(1, math.ceil(heightmap.pixel / (wmm / res) - 1e-9))))
    return {"view": view, "surface": surface, "seed": int(seed), "spp": int(dcfg.spp),
            "max_depth": MAX_DEPTH, "exaggeration": ex, "z_offset_mm": z_offset,
            "window_mm": [x0, y0, x1, y1], "mesh": mesh,
            "camera": camera, "light": light, "lamp": lamp, "material": material,
            "scale": scale, "part": part, "units": "mm", "software_version": __version__}


def _lamp_radiance(lamp: dict) -> float | None:
    """Radiance of the studio's lamp disc that gives the irradiance asked for (None: chosen
    when the grating is known, :func:`render_inspect.render._diffuse` auto)."""
    if lamp.get("irradiance") is None:
        return None
    return float(lamp["irradiance"]) / (math.pi * math.radians(LAMP_RADIUS_DEG) ** 2)


def _lamp(heightmap, surface, ex, cam_origin, centre, size, irradiance,
          where=LAMP_HIGHLIGHT) -> dict:
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
    hx = centre[0] + where[0] * size[0] / 2
    hy = centre[1] + where[1] * size[1] / 2
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


def auto_exaggeration(heightmap: HeightMap, surface: str = "machined",
                      window: Sequence[float] | None = None, *,
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
