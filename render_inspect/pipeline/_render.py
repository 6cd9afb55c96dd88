"""``render``: height map -> the images of the registered instruments
(:func:`~render_inspect.instruments.renderable_instruments`: the interferometer, ...) and
the diffuse-light views, on disk."""

from __future__ import annotations

from collections.abc import Sequence
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from .. import __version__
from ..core.errors import InputError, RenderInspectError
from ..core.grid import Grid, grid_shape
from ..core.heightmap import HeightMap
from ..core.limits import (Driver, address_space_limit, check_address_space, check_memory,
                           format_bytes, memory_budget, mitsuba_address_space)
from ..core.progress import task as progress_task
from ..core.units import MM_TO_UM
from ..design import make_surface
from ..instruments import height_instrument, renderable_instruments
from ..io import atomic_output_dir, atomic_write_bytes, png_bytes_with_text, write_exr
from ..machining import part_heightmap as _part_map
from ..metrology import render_marks, surface_slope
from ..processes import process_of
from ..render import (MAX_FILM_SIDE, DiffuseConfig, diffuse_memory, render_diffuse, start_mitsuba,
                      variant_info)
from ..report import annotate_rgb, diffuse_caption, draw_figure, scale_bar_length
from ._metrics import write_metrics
from ._simulate import design_heightmap, simulate
from ._simulate_command import wants_tiles
from ._views import BigMapViews, WholeMapViews, big_map_store, existing_store

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["run_render", "render_heightmap", "write_diffuse_outputs",
           "write_instrument_outputs", "write_interferogram_outputs",
           "part_heightmap", "tool_marks", "part_outline", "render_diffuse_views",
           "check_render_limits", "render_kinds", "SURFACES"]

SURFACES = ("design", "machined")


def render_kinds() -> tuple[str, ...]:
    """What ``render --kind`` takes: every registered instrument that renders, ``diffuse``
    and ``all``."""
    return (*renderable_instruments(), "diffuse", "all")


def sweep_render_names() -> dict:
    """What a sweep file's ``[run] render`` may name and the instrument whose frames
    ``[run] measure`` measures (:func:`~render_inspect.batch.read_sweep`'s
    ``render_kinds`` and ``frames_kind``)."""
    return {"render_kinds": render_kinds(), "frames_kind": height_instrument().name}


def _instruments(kind: str) -> dict:
    entries = renderable_instruments()
    if kind == "all":
        return entries
    return {kind: entries[kind]} if kind in entries else {}


def _design_slope(scene: Scene):
    """``slope(window)``: the design's largest slope over a window (rad), or None when
    the design cannot be sampled there."""
    def slope(window):
        try:
            return surface_slope(make_surface(scene.design), window)
        except RenderInspectError:
            return None
    return slope


def check_render_limits(scene: Scene, *, kind: str = "all") -> dict:
    """Check, before anything is simulated or rendered, that the images a scene asks for
    are within what the renderers can do and within the memory budget.

    Instruments: their own estimate (the interferometer: the field of view and camera
    pixels, at most 4096 x 4096, and the memory of the rays, frames and mesh).  Diffuse
    light: image sides at most :data:`~render_inspect.render.MAX_FILM_SIDE` pixels (the
    micro view's height follows the window's aspect), the film and mesh memory.  The
    sample count is not limited: more than 2^26 samples are rendered in passes.

    Returns
    -------
    dict
        Estimated bytes per image (the instruments by name, ``diffuse_macro``,
        ``diffuse_micro``).
    """
    sim = scene.simulation
    budget = memory_budget(sim.max_memory_gb)
    shape = grid_shape(sim.region, sim.pixel)
    grid = Grid((float(sim.region[0]), float(sim.region[1])), float(sim.pixel), shape)
    need = {}
    for name, entry in _instruments(kind).items():
        if entry.memory is not None:
            nbytes, what, drivers = entry.memory(grid, getattr(scene.render, name),
                                                 slope=_design_slope(scene))
            need[name] = check_memory(nbytes, what=what, budget=budget, drivers=drivers)
    if kind in ("diffuse", "all"):
        dcfg = scene.render.diffuse
        # a part with tool marks is rendered spectrally (the turned-aluminium BSDF)
        spectral = tool_marks(scene) is not None
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
                diffuse_memory(dcfg, shape, view=view, window=window, pixel=sim.pixel,
                               spectral=spectral),
                what=f"the diffuse {view} image ({dcfg.resolution} pixels wide)", budget=budget,
                drivers=[Driver("render.diffuse.resolution", dcfg.resolution, 2, limit=(16, None))])
    _check_render_address_space(need)
    return need


def _check_render_address_space(need: dict) -> None:
    """Under an address-space limit (``ulimit -v``), refuse in one line a render whose
    largest image and the address space Mitsuba reserves when it starts do not fit
    together in the room the limit leaves: past it Dr.Jit and Embree fail inside the
    render (or stop), after work is done.  Nothing happens without a limit."""
    if not need or address_space_limit() is None:
        return
    name, nbytes = max(need.items(), key=lambda kv: kv[1])
    starting = "mitsuba" not in sys.modules
    extra = mitsuba_address_space() if starting else 0
    what = name.replace("_", " ")
    check_address_space(nbytes + extra, what=(
        f"the render ({what}: {format_bytes(nbytes)}"
        + (f", and Mitsuba's own {format_bytes(extra)} when it starts)" if starting else ")")))


def render_heightmap(scene: Scene, *, surface: str = "machined") -> HeightMap:
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


def write_instrument_outputs(name: str, out: Path, result: Any, *,
                             scene: dict | None = None) -> dict:
    """Write the files of an instrument's result (its ``write`` hook) and draw its
    figures into ``out``; return its summary."""
    # (a renderable instrument has both hooks: the registry checks it)
    summary, figures = renderable_instruments()[name].write(  # type: ignore[misc]
        Path(out), result, scene=scene)
    for file, spec in figures.items():
        draw_figure(spec, Path(out) / file)
    return summary


def write_interferogram_outputs(out: Path, ig: Any, *, scene: dict | None = None) -> dict:
    """The files and figures of the instrument that records interferometer frames
    (``interferogram.exr``, ``interferogram_fringes.png``); return its summary."""
    return write_instrument_outputs(height_instrument().name, out, ig, scene=scene)


def _srgb8(rgb: np.ndarray) -> np.ndarray:
    a = np.clip(np.nan_to_num(rgb), 0.0, 1.0)
    a = np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)
    return (a * 255 + 0.5).astype(np.uint8)


def _scale_bar(meta: dict, width_px: int) -> tuple[float, float]:
    """The scale bar of the image (:func:`~render_inspect.report.scale_bar_length`): (mm, pixels)."""
    sc: dict = meta.get("scale") or {}
    mm_px = cast(float, sc.get("mm_per_px") or sc.get("mm_per_px_at_target"))  # (one is recorded)
    mm = scale_bar_length(width_px * mm_px)
    return mm, mm / mm_px


def write_diffuse_outputs(out: Path, rgb: np.ndarray, meta: dict, *, name: str) -> dict:
    """Write ``<name>.exr`` (linear R, G, B; header: the scene spec, ``vertical_exaggeration``,
    ``mitsuba_variant``, ``mm_per_px``) and ``<name>.png`` (sRGB 8-bit with the vertical
    exaggeration and a scale bar written into the picture; the same facts as PNG text)."""
    out = Path(out)
    sc: dict = meta.get("scale") or {}
    mm_px = cast(float, sc.get("mm_per_px") or sc.get("mm_per_px_at_target"))  # (one is recorded)
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
                       f"scale {mm_px * MM_TO_UM:.4g} um per pixel{where}",
            "mm_per_px": f"{mm_px:.6g}", "mitsuba_variant": meta["mitsuba_variant"], "spec": meta}
    img8 = annotate_rgb(_srgb8(rgb), lines=diffuse_caption(meta), scale_mm=bar_mm, scale_px=bar_px)
    atomic_write_bytes(out / f"{name}.png", png_bytes_with_text(img8, text))
    return {k: meta[k] for k in ("view", "spp", "seed", "vertical_exaggeration", "mesh_triangles",
                                 "mesh_stride", "window_mm", "mitsuba_variant")} | {
        "light": meta["light"]["type"], "material": meta["material"]["type"],
        "shape": [int(rgb.shape[0]), int(rgb.shape[1])]}


def _traits(scene: Scene):
    process = process_of(scene)
    return process.traits(process.inputs_of(scene))


def tool_marks(scene: Scene) -> dict | None:
    """The tool marks the diffuse renderer needs (:func:`~render_inspect.render.render_diffuse`
    ``marks``), from the marks the scene's process says it leaves
    (:func:`~render_inspect.metrology.render_marks`)."""
    return render_marks(_traits(scene).marks)


def part_outline(scene: Scene) -> dict:
    """The part as the macro view shows it: the process's own outline (turning: ``{"shape":
    "disc", "center", "radius"}``, the workpiece), else ``{"shape": "rect", "rect"}`` (the
    simulated region)."""
    part = _traits(scene).part
    if part is not None:
        return dict(part)
    return {"shape": "rect", "rect": [float(v) for v in scene.simulation.region]}


def part_heightmap(scene: Scene, hm: HeightMap, *, cells: int = 1024,
                   surface: str = "machined") -> HeightMap:
    """The whole part for the macro view: the design over the part (:func:`part_outline`,
    ``cells`` samples across; NaN outside a turned disc) with the simulated residual
    (area-averaged onto that grid) added inside the simulated region
    (:func:`~render_inspect.machining.part_heightmap`).  A part that is the region itself
    gets ``hm`` back."""
    outline = part_outline(scene)
    if outline["shape"] != "disc":
        return hm
    return _part_map(make_surface(scene.design), hm, outline, region=scene.simulation.region,
                     cells=cells, layer=surface)


def render_diffuse_views(scene: Scene, hm: HeightMap, dcfg: DiffuseConfig, *, seed: int,
                         surface: str = "machined",
                         views: Sequence[str] = ("micro", "macro"),
                         part_hm: HeightMap | None = None) -> dict:
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


def run_render(scene: Scene, out: str | Path, *, surface: str = "machined", kind: str = "all",
               heightmap: HeightMap | None = None,
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
    kind : str
        A registered instrument (``"interferometer"``, ...), ``"diffuse"`` or ``"all"``
        (:func:`render_kinds`).
    heightmap : HeightMap, optional
        Use this instead of simulating / sampling the scene.
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it.

    Returns
    -------
    dict
        ``{"render": {...}}`` for metrics.json: ``mitsuba_variant``, ``surface``, ``kind``,
        each instrument's summary (``interferometer``), ``diffuse_macro`` /
        ``diffuse_micro`` summaries, ``timing_s``.  The same dict is written to
        ``out/render_metrics.json``.

    Files: the instruments' (``interferogram.exr``, ``interferogram_fringes.png``);
    ``diffuse_macro.{exr,png}``, ``diffuse_micro.{exr,png}`` (diffuse).
    """
    kinds = render_kinds()
    if kind not in kinds:
        raise InputError(f"--kind must be one of {kinds}, got {kind!r}")
    if surface not in SURFACES:
        raise InputError(f"--surface must be one of {SURFACES}, got {surface!r}")
    check_render_limits(scene, kind=kind)
    with atomic_output_dir(out, overwrite=overwrite, merge=True, command="render",
                           scene=scene) as tmp:
        # Mitsuba starts in a thread while the height map and what the instruments trace
        # are prepared; it is waited for where it is first used, and before leaving here
        starting = start_mitsuba()
        try:
            return _render_into(scene, out, Path(tmp), surface=surface, kind=kind,
                                heightmap=heightmap)
        finally:
            if starting is not None:
                starting.join()


def _render_into(scene: Scene, out, tmp: Path, *, surface: str, kind: str, heightmap=None) -> dict:
    timing = {}
    t0 = time.perf_counter()
    with progress_task(f"{surface} height map"):
        store = existing_store(scene, out) if heightmap is None and surface == "machined" \
            else None
        if store is not None:
            # the store simulate wrote here for this part: its windows, not a new simulation
            views: BigMapViews | WholeMapViews = BigMapViews(store)
        elif heightmap is None and surface == "machined" and wants_tiles(scene):
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
            cast(BigMapViews, views).close()


def _render_views(scene: Scene, tmp: Path, views, *, surface: str, kind: str, timing: dict) -> dict:
    seed = int(scene.simulation.seed)
    scene_d = scene.to_dict()
    # (the renderer's provenance is filled in once the images are made: Mitsuba may still
    # be starting in a thread, which the renders wait for where they first need it)
    res: dict[str, Any] = {"mitsuba_variant": None, "mitsuba_version": None, "surface": surface,
                           "kind": kind, "seed": seed, "software_version": __version__}
    instruments = _instruments(kind)
    n_steps = len(instruments) + 2 * (kind in ("diffuse", "all"))
    with progress_task("render", total=n_steps) as t:
        for name, entry in instruments.items():
            t0 = time.perf_counter()
            t.update(f"render: {name}")
            hm_i, cfg = views.instrument(entry, getattr(scene.render, name))
            # a step of its own, moved by the renderer's passes (core.progress.report)
            with progress_task(f"{name}: render passes", total=1.0):
                result = entry.render(hm_i, cfg, surface=surface, seed=seed)
            timing[name] = time.perf_counter() - t0
            res[name] = write_instrument_outputs(name, tmp, result, scene=scene_d)
            t.advance()
        if kind in ("diffuse", "all"):
            for view in ("macro", "micro"):
                t0 = time.perf_counter()
                t.update(f"render: diffuse {view} view")
                # the tool marks' BSDF; the macro view shows the whole part
                hm_d, dcfg = views.diffuse(scene.render.diffuse, view)
                with progress_task(f"diffuse {view} view: render passes", total=1.0):
                    rgb, meta = render_diffuse_views(scene, hm_d, dcfg, seed=seed,
                                                     surface=surface, views=(view,))[view]
                timing[f"diffuse_{view}"] = time.perf_counter() - t0
                res[f"diffuse_{view}"] = write_diffuse_outputs(tmp, rgb, meta, name=f"diffuse_{view}")
                t.advance()
    info = variant_info()
    res.update(mitsuba_variant=info["mitsuba_variant"], mitsuba_version=info["mitsuba_version"])
    res["timing_s"] = timing
    if views.big:
        res["big_map"] = views.facts
    write_metrics(tmp, {"render": res}, name="render_metrics.json")
    return {"render": res}
