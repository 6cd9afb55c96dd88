"""``render``: height map -> interferogram and diffuse images, on disk."""

from __future__ import annotations

import io
import json
import time
from pathlib import Path

import numpy as np
from PIL import Image
from PIL.PngImagePlugin import PngInfo

from .. import __version__
from ..core.errors import InputError, RenderInspectError
from ..core.grid import Grid, grid_shape
from ..core.heightmap import HeightMap
from ..core.limits import Driver, check_memory, memory_budget
from ..core.progress import task as progress_task
from ..design import make_surface
from ..instruments import (
    interferometer_geometry,
    interferometer_memory,
    render_interferogram,
    write_interferogram_exr,
)
from ..io import (
    atomic_output_dir,
    atomic_write_bytes,
    save_map_png,
    write_exr,
    write_json,
)
from ..machining import design_grid
from ..render import MAX_FILM_SIDE, diffuse_memory, render_diffuse, variant_info
from ..report import annotate_rgb, nice_length
from ._simulate import design_heightmap, simulate, wants_tiles
from ._views import BigMapViews, WholeMapViews, big_map_store

__all__ = ["run_render", "render_heightmap", "write_interferogram_outputs", "write_diffuse_outputs",
           "interferogram_summary", "part_heightmap", "tool_marks", "part_outline",
           "render_diffuse_views", "check_render_limits"]

KINDS = ("interferometer", "diffuse", "all")
SURFACES = ("design", "machined")


def _design_slope(scene, window, n: int = 257) -> float | None:
    """Largest slope (rad, 99.9th percentile) of the design over ``window``, from n x n
    samples: what sets the automatic sub-sampling of the interferometer (the machined
    surface follows the design); None when the design cannot be sampled."""
    x0, y0, x1, y1 = (float(v) for v in window)
    try:
        surface = make_surface(scene.design)
        x = np.linspace(x0, x1, n)
        y = np.linspace(y0, y1, n)
        z = np.asarray(surface.height(x[None, :], y[:, None]), dtype=np.float64)
        gy, gx = np.gradient(z, y, x)
    except RenderInspectError:
        return None
    g = np.hypot(gx, gy)
    g = g[np.isfinite(g)]
    return float(np.arctan(np.percentile(g, 99.9))) if g.size else None


def check_render_limits(scene, *, kind: str = "all") -> dict:
    """Check, before anything is simulated or rendered, that the images a scene asks for
    are within what the renderers can do and within the memory budget.

    Interferometer: the field of view and camera pixels (:func:`interferometer_geometry`:
    at most 4096 x 4096 pixels) and the memory of the rays, frames and mesh.  Diffuse
    light: image sides at most :data:`~render_inspect.render.MAX_FILM_SIDE` pixels (the
    micro view's height follows the window's aspect), the film and mesh memory.  The
    sample count is not limited: more than 2^26 samples are rendered in passes.

    Returns
    -------
    dict
        Estimated bytes per image (``interferometer``, ``diffuse_macro``, ``diffuse_micro``).
    """
    sim = scene.simulation
    budget = memory_budget(sim.max_memory_gb)
    shape = grid_shape(sim.region, sim.pixel)
    grid = Grid((float(sim.region[0]), float(sim.region[1])), float(sim.pixel), shape)
    need = {}
    if kind in ("interferometer", "all"):
        icfg = scene.render.interferometer
        geom = interferometer_geometry(grid, icfg)
        x0, y0, x1, y1 = geom["window"]
        cells = min(shape[0] * shape[1], int(((x1 - x0) / sim.pixel + 5) * ((y1 - y0) / sim.pixel + 5)))
        slope = _design_slope(scene, geom["trace_window"]) if icfg.subsamples is None else None
        need["interferometer"] = check_memory(
            interferometer_memory(geom, icfg, mesh_cells=cells, max_slope=slope),
            what=f"the interferometer ({geom['nx']} x {geom['ny']} camera pixels, "
                 f"{icfg.subsamples}^2 rays each)", budget=budget,
            drivers=[Driver("render.interferometer.subsamples", icfg.subsamples, 2, limit=(1, 8)),
                     Driver("render.interferometer.pixel", geom["pixel"], -2, "mm")])
    if kind in ("diffuse", "all"):
        dcfg = scene.render.diffuse
        for view in ("macro", "micro"):
            window = None
            if view == "micro" and dcfg.window is not None:
                window = [float(v) for v in dcfg.window]
                ny_img = int(round(dcfg.resolution * (window[3] - window[1]) / (window[2] - window[0])))
                if ny_img > MAX_FILM_SIDE:
                    raise InputError(
                        f"render.diffuse.window {window} is {ny_img / dcfg.resolution:.3g} times "
                        f"taller than wide: at render.diffuse.resolution = {dcfg.resolution} the "
                        f"micro image would be {ny_img} pixels high (at most {MAX_FILM_SIDE}); "
                        f"widen the window or lower the resolution")
            need[f"diffuse_{view}"] = check_memory(
                diffuse_memory(dcfg, shape, view=view, window=window, pixel=sim.pixel),
                what=f"the diffuse {view} image ({dcfg.resolution} pixels wide)", budget=budget,
                drivers=[Driver("render.diffuse.resolution", dcfg.resolution, 2, limit=(16, None))])
    return need


def render_heightmap(scene, *, surface: str = "machined"):
    """The HeightMap a render of ``scene`` uses.

    ``machined``: :func:`~render_inspect.pipeline.simulate`'s height map; ``design``: the
    design surface sampled on the simulation grid (no machining), with ``machined`` =
    ``design``.
    """
    if surface == "machined":
        return simulate(scene).heightmap
    if surface != "design":
        raise InputError(f"--surface must be one of {SURFACES}, got {surface!r}")
    return design_heightmap(scene)


def _png_bytes(img8: np.ndarray, text: dict) -> bytes:
    info = PngInfo()
    for k, v in text.items():
        info.add_text(str(k), v if isinstance(v, str) else json.dumps(v, default=str))
    buf = io.BytesIO()
    Image.fromarray(img8).save(buf, format="PNG", pnginfo=info)
    return buf.getvalue()


def _srgb8(rgb: np.ndarray) -> np.ndarray:
    a = np.clip(np.nan_to_num(rgb), 0.0, 1.0)
    a = np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)
    return (a * 255 + 0.5).astype(np.uint8)


def write_interferogram_outputs(out: Path, ig, *, scene: dict | None = None) -> dict:
    """Write ``interferogram.exr``, ``interferogram_fringes.png`` (the intensity frame,
    row 0 = smallest y drawn at the bottom, invalid pixels red) and
    ``interferogram_height.png`` (false-colour ``height_true - z_ref`` in nm) into ``out``;
    return the summary dict."""
    out = Path(out)
    write_interferogram_exr(out / "interferogram.exr", ig, scene=scene)
    g = np.clip(ig.intensity, 0, 1)[::-1]
    rgb = np.repeat(g[..., None], 3, axis=2)
    inval = ~ig.valid[::-1]
    rgb[inval] = (0.8, 0.1, 0.1)
    atomic_write_bytes(out / "interferogram_fringes.png",
                       _png_bytes((rgb * 255 + 0.5).astype(np.uint8),
                                  {"mitsuba_variant": ig.variant, "mode": ig.mode,
                                   "wavelength_nm": ig.wavelength_nm,
                                   "numerical_aperture": ig.numerical_aperture,
                                   "pixel_size_mm": ig.pixel, "seed": ig.seed,
                                   "software_version": __version__}))
    h_nm = (ig.height_true - ig.z_ref) * 1e6  # mm -> nm
    save_map_png(out / "interferogram_height.png", np.where(ig.valid, h_nm, np.nan),
                 extent=ig.extent, title=f"ray-traced height ({ig.surface}), {ig.objective} "
                 f"NA {ig.numerical_aperture:g}", label="height - z_ref (nm)", cmap="turbo")
    return interferogram_summary(ig)


def interferogram_summary(ig) -> dict:
    return {"mode": ig.mode, "objective": ig.objective, "shape": list(ig.shape),
            "frames": int(ig.frames.shape[0]), "pixel_mm": ig.pixel,
            "origin_mm": list(ig.origin), "wavelength_nm": ig.wavelength_nm,
            "bandwidth_nm": ig.bandwidth_nm, "numerical_aperture": ig.numerical_aperture,
            "subsamples": ig.subsamples, "noise": ig.noise, "seed": ig.seed,
            "z_ref_mm": ig.z_ref, "valid_fraction": float(np.mean(ig.valid)),
            "surface": ig.surface, "mitsuba_variant": ig.variant}


def diffuse_caption(meta: dict) -> list[str]:
    """The lines written into a diffuse image: vertical exaggeration, view and light."""
    ex = float(meta["vertical_exaggeration"])
    first = f"heights x{ex:g} (vertical exaggeration)" if ex != 1 else "heights true scale (x1)"
    light = meta["light"]["type"] + (" + lamp" if meta.get("lamp") else "")
    return [first, f"{meta['view']} view, {light}"]


def _scale_bar(meta: dict, width_px: int) -> tuple[float, float]:
    """A 1-2-5 scale bar about a fifth of the image wide: (mm, pixels)."""
    sc = meta.get("scale") or {}
    mm_px = sc.get("mm_per_px") or sc.get("mm_per_px_at_target")
    mm = nice_length(0.2 * width_px * mm_px)
    return mm, mm / mm_px


def write_diffuse_outputs(out: Path, rgb: np.ndarray, meta: dict, *, name: str) -> dict:
    """Write ``<name>.exr`` (linear R, G, B; header: the scene spec, ``vertical_exaggeration``,
    ``mitsuba_variant``, ``mm_per_px``) and ``<name>.png`` (sRGB 8-bit with the vertical
    exaggeration and a scale bar written into the picture; the same facts as PNG text)."""
    out = Path(out)
    sc = meta.get("scale") or {}
    mm_px = sc.get("mm_per_px") or sc.get("mm_per_px_at_target")
    attrs = {"vertical_exaggeration": float(meta["vertical_exaggeration"]),
             "mitsuba_variant": meta["mitsuba_variant"], "view": meta["view"],
             "spp": int(meta["spp"]), "seed": int(meta["seed"]), "units": "mm",
             "mm_per_px": float(mm_px), "software_version": __version__,
             "spec": json.dumps(meta, sort_keys=True, default=str)}
    write_exr(out / f"{name}.exr", {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2]}, attrs)
    bar_mm, bar_px = _scale_bar(meta, rgb.shape[1])
    where = "" if sc.get("mm_per_px") else " at the part's centre"
    text = {"vertical_exaggeration": f"{meta['vertical_exaggeration']:g}",
            "Comment": f"heights exaggerated {meta['vertical_exaggeration']:g}x; "
                       f"scale {mm_px * 1e3:.4g} um per pixel{where}",
            "mm_per_px": f"{mm_px:.6g}", "mitsuba_variant": meta["mitsuba_variant"], "spec": meta}
    img8 = annotate_rgb(_srgb8(rgb), lines=diffuse_caption(meta), scale_mm=bar_mm, scale_px=bar_px)
    atomic_write_bytes(out / f"{name}.png", _png_bytes(img8, text))
    return {k: meta[k] for k in ("view", "spp", "seed", "vertical_exaggeration", "mesh_triangles",
                                 "mesh_stride", "window_mm", "mitsuba_variant")} | {
        "light": meta["light"]["type"], "material": meta["material"]["type"],
        "shape": [int(rgb.shape[0]), int(rgb.shape[1])]}


def tool_marks(scene) -> dict | None:
    """The tool marks the diffuse renderer needs (:func:`~render_inspect.render.render_diffuse`
    ``marks``): turning leaves circular feed marks about the spindle axis, period = feed
    per revolution, grooves of the nose radius; sculpturing leaves straight marks along
    the cut whose period (cutting speed / vibration frequency) is finer than light
    resolves."""
    p = scene.process
    rc = float(scene.tool.nose_radius)
    if hasattr(p, "feed_per_rev"):
        return {"kind": "circular", "center_mm": [0.0, 0.0], "period_mm": float(p.feed_per_rev),
                "nose_radius_mm": rc}
    if p.kind == "sculpt":
        vib = scene.artifacts.vibration
        period = (p.feed_mm_per_min / 60.0) / vib.frequency_hz if vib.frequency_hz > 0 \
            and vib.amplitude > 0 else None
        if period is not None and period < 0.2e-3:  # below half the shortest wavelength
            period = None
        return {"kind": "linear", "direction": [0.0, 1.0], "period_mm": period,
                "nose_radius_mm": rc}
    return None


def part_outline(scene) -> dict:
    """The part as the macro view shows it: ``{"shape": "disc", "center", "radius"}``
    for turning (the workpiece), else ``{"shape": "rect", "rect"}`` (the simulated
    region)."""
    p = scene.process
    if hasattr(p, "workpiece_radius"):
        return {"shape": "disc", "center": [0.0, 0.0], "radius": float(p.workpiece_radius)}
    return {"shape": "rect", "rect": [float(v) for v in scene.simulation.region]}


def part_heightmap(scene, hm, *, cells: int = 1024, surface: str = "machined") -> HeightMap:
    """The whole part for the macro view: the design over the part (:func:`part_outline`,
    ``cells`` samples across; NaN outside a turned disc) with the simulated residual
    (area-averaged onto that grid) added inside the simulated region.  A part that is
    the region itself gets ``hm`` back."""
    outline = part_outline(scene)
    if outline["shape"] != "disc":
        return hm
    r = outline["radius"]
    pixel = 2 * r / cells
    region = (-r, -r, r, r)
    try:
        z = design_grid(make_surface(scene.design), region, pixel)
    except InputError:
        # a design that does not cover the whole part (a height map file): the region
        return HeightMap(hm.design, hm.machined, hm.pixel, hm.origin, hm.scene,
                         {**hm.meta, "part": {"shape": "rect", "rect": [
                             float(v) for v in scene.simulation.region]}})
    x = -r + pixel * np.arange(z.shape[1])
    y = -r + pixel * np.arange(z.shape[0])
    machined = z.copy()
    if surface == "machined":
        res = hm.residual
        f = max(1, int(round(pixel / hm.pixel)))
        if f > 1:
            ny, nx = (res.shape[0] // f) * f, (res.shape[1] // f) * f
            b = res[:ny, :nx].reshape(ny // f, f, nx // f, f)
            ok = np.isfinite(b)
            with np.errstate(invalid="ignore"):
                res = np.where(ok.any(axis=(1, 3)), np.where(ok, b, 0).sum(axis=(1, 3))
                               / np.maximum(ok.sum(axis=(1, 3)), 1), np.nan)
        rp = hm.pixel * f
        ox = hm.origin[0] + (f - 1) / 2 * hm.pixel
        oy = hm.origin[1] + (f - 1) / 2 * hm.pixel
        j = np.rint((x - ox) / rp).astype(int)
        i = np.rint((y - oy) / rp).astype(int)
        jin = (j >= 0) & (j < res.shape[1])
        iin = (i >= 0) & (i < res.shape[0])
        if jin.any() and iin.any():
            patch = res[np.ix_(i[iin], j[jin])]
            sub = machined[np.ix_(iin, jin)]
            machined[np.ix_(iin, jin)] = np.where(np.isfinite(patch), sub + patch, sub)
    xx, yy = np.meshgrid(x, y)
    outside = xx * xx + yy * yy > r * r
    z[outside] = np.nan
    machined[outside] = np.nan
    return HeightMap(z, machined, pixel, (-r, -r), meta={"part": outline})


def render_diffuse_views(scene, hm, dcfg, *, seed: int, surface: str = "machined",
                         views=("micro", "macro"), part_hm=None) -> dict:
    """The diffuse images of a simulated part: ``micro`` (``dcfg.window`` of ``hm``,
    straight down) and ``macro`` (the whole part, :func:`part_heightmap`), both with the
    scene's tool marks, their meshes within the scene's memory budget.  Returns view ->
    (rgb, meta)."""
    budget = memory_budget(scene.simulation.max_memory_gb)[0]
    marks = tool_marks(scene)
    out = {}
    for view in views:
        if view == "macro":
            phm = part_hm if part_hm is not None else part_heightmap(scene, hm, surface=surface)
            out[view] = render_diffuse(phm, dcfg, view="macro", surface=surface, seed=seed,
                                       marks=marks, part=phm.meta.get("part", part_outline(scene)),
                                       memory_budget=budget)
        else:
            out[view] = render_diffuse(hm, dcfg, view="micro", surface=surface, seed=seed,
                                       marks=marks, memory_budget=budget)
    return out


def run_render(scene, out, *, surface: str = "machined", kind: str = "all", heightmap=None,
               overwrite: bool = False) -> dict:
    """Render ``scene`` into the folder ``out`` (written atomically).

    Parameters
    ----------
    scene : Scene
    out : path
        Output folder.  The images are added to a folder render_inspect wrote for the same
        part (a ``simulate`` folder: design, tool, process, simulation and artifacts keys
        equal), replacing the images of an earlier ``render`` there; the folder is swapped
        in whole when complete.  A folder of another part, or one holding files
        render_inspect did not write, is refused unless ``overwrite`` (then replaced).
    surface : {"machined", "design"}
        ``design`` renders the ideal surface (no machining).
    kind : {"interferometer", "diffuse", "all"}
    heightmap : HeightMap, optional
        Use this instead of simulating / sampling the scene.
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it.

    Returns
    -------
    dict
        ``{"render": {...}}`` for metrics.json: ``mitsuba_variant``, ``surface``, ``kind``,
        ``interferometer`` / ``diffuse_macro`` / ``diffuse_micro`` summaries, ``timing_s``.
        The same dict is written to ``out/render_metrics.json``.

    Files: ``interferogram.exr``, ``interferogram_fringes.png``, ``interferogram_height.png``
    (interferometer); ``diffuse_macro.{exr,png}``, ``diffuse_micro.{exr,png}`` (diffuse).
    """
    if kind not in KINDS:
        raise InputError(f"--kind must be one of {KINDS}, got {kind!r}")
    if surface not in SURFACES:
        raise InputError(f"--surface must be one of {SURFACES}, got {surface!r}")
    check_render_limits(scene, kind=kind)
    with atomic_output_dir(out, overwrite=overwrite, merge=True, command="render",
                           scene=scene) as tmp:
        return _render_into(scene, out, Path(tmp), surface=surface, kind=kind, heightmap=heightmap)


def _render_into(scene, out, tmp: Path, *, surface: str, kind: str, heightmap=None) -> dict:
    timing = {}
    t0 = time.perf_counter()
    with progress_task(f"{surface} height map"):
        if heightmap is None and surface == "machined" and wants_tiles(scene):
            # a map too large for memory: windows and area-averaged levels of its store
            views = BigMapViews(*big_map_store(scene, out))
        else:
            views = WholeMapViews(heightmap if heightmap is not None
                                  else render_heightmap(scene, surface=surface))
    timing["heightmap"] = time.perf_counter() - t0
    try:
        return _render_views(scene, tmp, views, surface=surface, kind=kind, timing=timing)
    finally:
        if views.big:
            views.close()


def _render_views(scene, tmp: Path, views, *, surface: str, kind: str, timing: dict) -> dict:
    seed = int(scene.simulation.seed)
    scene_d = scene.to_dict()
    info = variant_info()
    res = {"mitsuba_variant": info["mitsuba_variant"], "mitsuba_version": info["mitsuba_version"],
           "surface": surface, "kind": kind, "seed": seed, "software_version": __version__}
    n_steps = (kind in ("interferometer", "all")) + 2 * (kind in ("diffuse", "all"))
    with progress_task("render", total=n_steps) as t:
        if kind in ("interferometer", "all"):
            t0 = time.perf_counter()
            t.update("render: interferogram")
            hm_i, icfg = views.interferometer(scene.render.interferometer)
            ig = render_interferogram(hm_i, icfg, surface=surface, seed=seed)
            timing["interferogram"] = time.perf_counter() - t0
            res["interferometer"] = write_interferogram_outputs(tmp, ig, scene=scene_d)
            t.advance()
        if kind in ("diffuse", "all"):
            for view in ("macro", "micro"):
                t0 = time.perf_counter()
                t.update(f"render: diffuse {view} view")
                # the tool marks' BSDF; the macro view shows the whole part
                hm_d, dcfg = views.diffuse(scene.render.diffuse, view)
                rgb, meta = render_diffuse_views(scene, hm_d, dcfg, seed=seed, surface=surface,
                                                 views=(view,))[view]
                timing[f"diffuse_{view}"] = time.perf_counter() - t0
                res[f"diffuse_{view}"] = write_diffuse_outputs(tmp, rgb, meta, name=f"diffuse_{view}")
                t.advance()
    res["timing_s"] = timing
    if views.big:
        res["big_map"] = views.facts
    write_json(tmp / "render_metrics.json", {"render": res})
    return {"render": res}
