"""``compare``: two variants of a scene through the whole chain, and what differs.

The pair is the one that means something for the scene's process kind (its ``variants``
hook: compensation on/off for turning, servo lag on/off for tool-servo turning,
vibration on/off for sculpturing, RCSE against the conventional path), or any scene key
with two values (``--vary key=a,b``).  For each variant (same camera, its own noise):
simulate the machined surface, image it with the instrument that records interferometer
frames and with diffuse light, retrieve the height from the frames (what the instrument
reports) and characterise everything.  Each measurement gets its own camera-noise
realisation (seeds spawned from the scene's seed, recorded in ``metrics.json``), as two
real measurements would; the difference of the two measurements is given with its noise
floor (from the two measurements' own noise estimates) and said to be resolved or not,
and it is checked for fringe-order failures (a failed measurement is not reported as a
measured difference).  ``repeat`` > 1 measures both variants again with fresh noise and
reports the difference's repeatability.  The windows are shared: the instrument's field,
the micro diffuse view and the first figure's maps all cover one common window, placed
where the two variants differ most.  Files: both variant folders, the figures,
``metrics.json`` and a self-contained ``report.html`` whose first figure is the
difference.

The stages are the scene's process (its traits: tool marks, part, spindle axis), the
instruments (:mod:`render_inspect.instruments`), the metrology (waviness filters,
windows, profiles, sections), the one metrics builder and the report.
"""

from __future__ import annotations

from collections.abc import Sequence
import dataclasses
import logging
import re
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.errors import InputError
from ..core.progress import task
from ..core.units import MM_TO_NM, MM_TO_UM, UM_TO_MM
from ..design import Surface, make_surface
from ..instruments import InterferometerConfig, rendered_settings
from ..io import (MeasuredMap, atomic_output_dir, atomic_write_bytes, atomic_write_text,
                  check_output_dir, export_program, json_safe, not_a_file, read_surface,
                  scene_files, writer)
from ..metrology import (Comparison, areal_nm, characterise_map, common_window, compare_measured,
                         difference_profiles, fringe_order_check, level_map, line_profile,
                         measurement_seeds, profile_center, sections, waviness_choice, waviness_map)
from ..metrology import expected_sq_mm as _marks_sq_mm
from ..processes import cut_name, process_of
from ..render import DiffuseConfig, mitsuba_variant
from ..report import (ComparedVariant, axis_motion_figure, build_page, comparison_figures,
                      comparison_summary, display_map, draw_figure, program_figure_name,
                      save_map_png)
from ..scene import compare_pair, compare_variants, parse_vary, variant_scene
from ._budget import overcut_budget
from ._compare_difference import (_difference_numbers, _fringe_order, _fringe_summary, _instrument,
                                  _repeat_differences, _window_difference)
from ._measure import measure_and_evaluate, measurement_outputs
from ._metrics import (comparison_metrics, diffuse_summary, variant_metrics, write_metrics)
from ._render import (check_render_limits, part_outline, render_diffuse_views,
                      write_diffuse_outputs, write_instrument_outputs)
from ._simulate import simulate
from ._provenance import difference_warnings, keeps_warnings, run_inputs, said_warnings
from ._toolpath import check_tool_edge
from ..core.heightmap import HeightMap
from ..toolpath import region_radii

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["run_compare", "check_measured", "expected_sq_mm", "compare_variants", "compare_pair",
           "compare_summary", "variant_scene", "parse_vary", "preview_render_configs",
           "common_window", "VARIANTS", "PROFILE_ANGLES_DEG",
           "COMPARE_MAX_CAMERA_PIXELS", "COMPARE_MAX_DIFFUSE_RESOLUTION",
           "COMPARE_MAX_DIFFUSE_SPP"]

log = logging.getLogger("render_inspect")

#: The two columns of a turning comparison (the names the compensation pair uses).
VARIANTS = ("compensated", "uncompensated")
#: Section angles of the radial profiles (Li et al. 2018, Fig. 16 shows that the overcut
#: waviness depends on the angle).
PROFILE_ANGLES_DEG = (0.0, 30.0, 60.0, 90.0)
#: Render sizes compare uses unless the scene sets them: camera pixels across the common
#: window, diffuse image size and samples per pixel.
COMPARE_MAX_CAMERA_PIXELS = 256
COMPARE_MAX_DIFFUSE_RESOLUTION = 512
COMPARE_MAX_DIFFUSE_SPP = 32
#: Most measurements of each variant ``repeat`` asks for.
MAX_REPEAT = 100
_NAME_OK = re.compile(r"^[A-Za-z0-9_.-]+$")

#: the one-screen summary of a comparison (the command line prints it)
compare_summary = comparison_summary


def preview_render_configs(scene: Scene, heightmap: HeightMap, *,
                           window: Sequence[float] | None = None
                           ) -> tuple[InterferometerConfig, DiffuseConfig, list[str]]:
    """Instrument and diffuse settings for compare: the scene's, over the common ``window``
    (mm) when given, with the sizes the scene does not set capped
    (:data:`COMPARE_MAX_CAMERA_PIXELS`, :data:`COMPARE_MAX_DIFFUSE_RESOLUTION`,
    :data:`COMPARE_MAX_DIFFUSE_SPP`).  Without a window the instrument keeps its
    objective's pixel and gets a smaller field of view (centred) unless the scene sets
    ``field_of_view`` (then the pixel is coarsened instead).

    Returns (icfg, dcfg, notes) where notes lists what was capped."""
    entry, icfg = _instrument(scene)
    dcfg = scene.render.diffuse
    notes = []
    user = icfg.model_fields_set
    if window is not None and "field_of_view" not in user:
        icfg = icfg.model_copy(update={"field_of_view": tuple(window)})
    if "pixel" not in user:
        g = entry.field(heightmap, icfg)
        n = max(g["nx"], g["ny"])
        if n > COMPARE_MAX_CAMERA_PIXELS:
            x0, y0, x1, y1 = g["window"]
            if "field_of_view" not in user and window is None:
                # keep the objective's pixel (its lateral resolution), crop the field
                half = COMPARE_MAX_CAMERA_PIXELS * g["pixel"] / 2
                cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
                fov = (max(x0, cx - half), max(y0, cy - half), min(x1, cx + half),
                       min(y1, cy + half))
                icfg = icfg.model_copy(update={"field_of_view": fov})
                notes.append(f"{entry.name} field of view cropped to {COMPARE_MAX_CAMERA_PIXELS} "
                             f"camera pixels of {g['pixel'] * MM_TO_UM:.3g} um around the centre "
                             f"({(fov[2] - fov[0]):.3g} x {(fov[3] - fov[1]):.3g} mm; set "
                             f"render.{entry.name}.field_of_view or pixel to choose)")
            else:
                pix = max(x1 - x0, y1 - y0) / COMPARE_MAX_CAMERA_PIXELS
                icfg = icfg.model_copy(update={"pixel": pix})
                notes.append(f"{entry.name} pixel {g['pixel'] * MM_TO_UM:.3g} um -> "
                             f"{pix * MM_TO_UM:.3g} um ({COMPARE_MAX_CAMERA_PIXELS} camera pixels "
                             f"across the field; set render.{entry.name}.pixel to choose)")
    upd: dict[str, Any] = {}
    dset = dcfg.model_fields_set
    if "resolution" not in dset and dcfg.resolution > COMPARE_MAX_DIFFUSE_RESOLUTION:
        upd["resolution"] = COMPARE_MAX_DIFFUSE_RESOLUTION
    if "spp" not in dset and dcfg.spp > COMPARE_MAX_DIFFUSE_SPP:
        upd["spp"] = COMPARE_MAX_DIFFUSE_SPP
    if window is not None and "window" not in dset:
        upd["window"] = tuple(window)
    if upd:
        dcfg = dcfg.model_copy(update=upd)
        capped = {k: v for k, v in upd.items() if k != "window"}
        if capped:
            notes.append("diffuse " + ", ".join(f"{k} -> {v}" for k, v in capped.items())
                         + " (set render.diffuse.resolution / spp to choose)")
    return icfg, dcfg, notes


@dataclass
class _Variant:
    name: str
    label: str
    # (filled step by step: None until the step that sets it has run)
    scene: Scene
    heightmap: Any = None  # HeightMap
    ig: Any = None  # Interferogram
    reported: Any = None  # what the instrument reports (height.exr)
    phase: Any = None  # the same, aligned to the truth (evaluation only)
    sim: Any = None  # Simulation
    diffuse: dict = field(default_factory=dict)  # view -> (rgb, meta)
    timing: dict = field(default_factory=dict)
    filtered: np.ndarray | None = None
    maps: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    noise_seed: int = 0  # the camera's temporal noise of this variant's measurement
    fringe: dict = field(default_factory=dict)  # fringe-order check of the measurement

    def shown(self) -> ComparedVariant:
        """What the figures show of this variant."""
        return ComparedVariant(self.name, self.label, tuple(self.scene.simulation.region),
                               self.heightmap, self.ig, self.maps, self.filtered, self.diffuse)


def _traits(scene: Scene):
    process = process_of(scene)
    return process.traits(process.inputs_of(scene))


def expected_sq_mm(scene: Scene) -> float | None:
    """The Sq the scene's process should leave on its own (mm): the ideal turned profile
    ``f^2 / (12 sqrt(5) R)`` of its feed marks (:func:`render_inspect.metrology.expected_sq_mm`
    of the marks its traits state); None for processes without a feed scallop."""
    return _marks_sq_mm(_traits(scene).marks)


def _program_feeds(variants: Sequence[_Variant]) -> dict[str, float]:
    """Each variant's feed per revolution (mm) where its program is read from a file: the
    program's median at the radii the simulated region spans, which the process states
    (``metrics["program"]["feed_per_rev_region_um"]``, the feed its scallop is computed
    for; a program may change its feed with the radius); planned paths state none."""
    feeds = {}
    for v in variants:
        prog = (v.sim.metrics or {}).get("program") if v.sim is not None else None
        f = prog.get("feed_per_rev_region_um") if isinstance(prog, dict) else None
        if isinstance(f, (int, float)) and f > 0:
            feeds[v.name] = float(f) * UM_TO_MM
    return feeds


def _marks_of_programs(marks, feeds: dict[str, float]):
    """The marks the filters are chosen for: with programs read from files, feed marks at
    the coarsest of the programs' feeds over the simulated region (one filter for both
    variants that removes the marks of each), else the scene's planned marks."""
    if marks is None or not marks.scallop or not feeds:
        return marks
    return dataclasses.replace(marks, period_mm=max(feeds.values()))


def _simulate_variant(v: _Variant, out: Path) -> None:
    """Simulate one variant; write heightmap.exr, the program (toolpath.npz), residual.png."""
    d = out / v.name
    d.mkdir(parents=True, exist_ok=True)
    sim = v.sim = simulate(v.scene)
    for text in sim.metrics.get("tool_edge", {}).get("warnings", []):  # beyond the measured edge
        log.warning("warning: %s: %s", v.name, text)
    hm = v.heightmap = sim.heightmap
    writer("heightmap", ".exr")(d / "heightmap.exr", hm)
    if sim.toolpath is not None:
        export_program(sim.toolpath, d, fmt="npz")
    save_map_png(d / "residual.png", display_map(hm.residual * MM_TO_NM), extent=hm.extent,
                 title=f"{v.label}: machined - design", label="residual (nm)", cmap="RdBu_r",
                 symmetric=True)


def _render_variant(v: _Variant, out: Path, *, icfg, dcfg, seed: int, design_surface,
                    filters: dict, t) -> None:
    """Image, measure and characterise one simulated variant; write its folder.  The
    interferogram's camera noise uses ``v.noise_seed`` (its own realisation); the diffuse
    views use ``seed``."""
    timing = v.timing
    d = out / v.name
    hm = v.heightmap
    sim = v.sim
    entry, _ = _instrument(v.scene)
    t0 = time.perf_counter()
    t.update(f"{v.name}: interferogram")
    ig = v.ig = entry.render(hm, icfg, surface="machined", seed=v.noise_seed)
    timing["interferogram"] = time.perf_counter() - t0
    summary = write_instrument_outputs(entry.name, d, ig, scene=v.scene.to_dict())
    t.advance()
    t0 = time.perf_counter()
    t.update(f"{v.name}: phase retrieval")
    mcfg = v.scene.metrology
    # measure from the frames alone (what the instrument reports: height.exr), then
    # evaluate that measurement against the truth kept beside the frames
    reported, v.phase, measured = measure_and_evaluate(d / "interferogram.exr",
                                                       algorithm=mcfg.phase_algorithm,
                                                       csi_refine=mcfg.csi_refine,
                                                       min_modulation=mcfg.min_modulation)
    v.reported = reported
    v.fringe = fringe_order_check(reported, fringe_order_mm=_fringe_order(ig))
    measured["instrument"] = measurement_outputs(d, ig, reported, source="interferogram.exr")
    measured["instrument"]["noise_seed"] = int(v.noise_seed)
    measured["instrument"]["fringe_order"] = _fringe_summary(v.fringe)
    timing["phase_retrieval"] = time.perf_counter() - t0
    t.advance()
    # the evaluation against the simulation's truth (labelled as such)
    err = np.where(v.phase.valid, v.phase.height - ig.height_true, np.nan) * MM_TO_NM
    save_map_png(d / "measurement_error.png", err, extent=ig.extent,
                 title=f"{v.label}: measured - true height (truth: the simulation)",
                 label="error (nm)", cmap="RdBu_r", symmetric=True)
    xx, yy = np.meshgrid(ig.x, ig.y)
    design_ig = np.broadcast_to(design_surface.height(xx, yy), xx.shape)
    # measured - design as instrument software forms it: piston and tilt removed, the
    # fringe order of regions apart from the largest one taken nearest its plane (PSI)
    meas_res, levelling = level_map(np.where(reported.valid, reported.height - design_ig, np.nan),
                                    pixel=ig.pixel, labels=reported.labels,
                                    fringe_order_mm=_fringe_order(ig))
    true_res = np.where(v.phase.valid, ig.height_true - design_ig, np.nan)
    v.maps.update(measured_residual=meas_res, true_residual=true_res, error=err,
                  measured_height=np.where(reported.valid, reported.height, np.nan),
                  measured_residual_levelling=levelling)
    measured["instrument_residual_levelling"] = levelling
    measured.update({f"instrument_residual_{k}": x for k, x in areal_nm(meas_res, ig.pixel).items()})
    measured.update({f"true_residual_{k}": x for k, x in areal_nm(true_res, ig.pixel).items()})

    for view in ("micro", "macro"):
        t0 = time.perf_counter()
        t.update(f"{v.name}: diffuse {view} view")
        rgb, meta = render_diffuse_views(v.scene, hm, dcfg, seed=seed, views=(view,))[view]
        timing[f"diffuse_{view}"] = time.perf_counter() - t0
        v.diffuse[view] = (rgb, meta)
        write_diffuse_outputs(d, rgb, meta, name=f"diffuse_{view}")
        t.advance()

    v.filtered = waviness_map(hm.residual, hm.pixel, filters)
    save_map_png(d / "filtered.png", display_map(v.filtered * MM_TO_NM), extent=hm.extent,
                 title=f"{v.label}: filtered residual (waviness)", label="height (nm)",
                 cmap="RdBu_r", symmetric=True)
    filt = characterise_map(hm.residual, pixel=hm.pixel, origin=hm.origin,
                            form_removal=filters["form_removal"],
                            polynomial_degree=filters["polynomial_degree"],
                            s_filter_mm=filters["s_filter_mm"], l_filter_mm=filters["l_filter_mm"],
                            filter_edges=filters["edges"])
    filt["chosen_from_scene"] = filters["chosen_from_scene"]
    m = variant_metrics(sim.metrics, name=v.name, label=v.label, measured=measured,
                        filtered=filt, interferometer=summary,
                        diffuse={view: diffuse_summary(meta) for view, (_, meta) in v.diffuse.items()},
                        mitsuba_variant=ig.variant, timing={**sim.timing_s, **timing})
    m["overcut"] = overcut_budget(v.scene, hm)  # why it cuts below the design, in numbers
    write_metrics(d, m)
    v.metrics.update(m)


def check_measured(path: str | Path, scene: Scene, design_surface: Surface, *,
                   force: bool = False) -> tuple[MeasuredMap, Comparison]:
    """Read a measured file and check, before any simulation, that it is a map of this
    design: registered overlap with ``simulation.region`` at least ``metrology.min_overlap``
    of the smaller area, registration residual not far above the process's roughness
    (:func:`render_inspect.metrology.registration_checks`).

    Returns ``(MeasuredMap, Comparison)``; raises :class:`InputError` (one line, the
    reasons) when the checks refuse and ``force`` is False."""
    m = read_surface(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # coverage warnings: repeated in the comparison
        comp = compare_measured(m, design_surface, metrology=scene.metrology,
                                region=tuple(scene.simulation.region),
                                seed=int(scene.simulation.seed),
                                expected_sq_mm=expected_sq_mm(scene), force=force,
                                against_chance=False)  # set against chance in the column
    return m, comp


def _measured_column(m, scene: Scene, design_surface, sim_hm, seed) -> dict:
    simulated = sim_hm if np.allclose(m.pixel, sim_hm.pixel, rtol=1e-6) else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        comp = compare_measured(m, design_surface, metrology=scene.metrology,
                                simulated=simulated, region=tuple(scene.simulation.region),
                                seed=seed, expected_sq_mm=expected_sq_mm(scene),
                                force=True)
    metrics = dict(comp.metrics)
    metrics["compared_with_simulation"] = simulated is not None
    notes = [str(w.message) for w in caught]
    if simulated is None:
        notes.append(f"the measured pixel ({m.pixel[0] * MM_TO_UM:.4g} x "
                     f"{m.pixel[1] * MM_TO_UM:.4g} um) differs from the simulation's "
                     f"({sim_hm.pixel * MM_TO_UM:.4g} um): the measurement is compared with "
                     f"the design only")
    checks = metrics.get("checks") or {}
    metrics["warnings"] = notes + list(checks.get("warnings", [])) + [
        f"compared with --force although: {r}" for r in checks.get("refusals", [])]
    return {"metrics": metrics, "maps": comp.maps, "pixel": comp.pixel, "origin": comp.origin,
            "extent": m.extent}


def _check_phase_settings(scene: Scene) -> None:
    """Refuse, before any work, a PSI algorithm that cannot use the frames rendered."""
    _, ic = _instrument(scene)
    alg = scene.metrology.phase_algorithm
    need = {"4step": 4, "5step": 5}.get(alg)
    if ic.mode == "psi" and need is not None:
        if ic.steps != need:
            raise InputError(f"metrology.phase_algorithm = {alg!r} needs render.interferometer.steps "
                             f"= {need}, got {ic.steps}; set steps = {need} or phase_algorithm = "
                             f"'auto' / 'lsq'")
        if abs(ic.step_rad - np.pi / 2) > 1e-6:
            raise InputError(f"metrology.phase_algorithm = {alg!r} needs render.interferometer."
                             f"step_rad = pi/2 (1.5707963...), got {ic.step_rad}; use 'lsq' for "
                             f"other steps")


def _program_figures(variants, out: Path) -> dict:
    """The feed-per-revolution figure of each variant that cuts a program read from a
    file, drawn into its folder (``feed_per_rev.png``); returns page key -> PNG bytes."""
    figs = {}
    for v in variants:
        spec = v.sim.figures.get("feed_per_rev.png")
        if spec is not None:
            png = draw_figure(spec, out / v.name / "feed_per_rev.png")
            figs[program_figure_name(v.name)] = Path(png).read_bytes()
    return figs


def _kinematics(a: _Variant, b: _Variant):
    """The axis-motion figure of the two programs: the programs' own comparison when the
    first variant's figure is one (RCSE against the conventional path), else the axes that
    move in both; None when the process draws no axis motion (sculpturing)."""
    specs = [v.sim.figures.get("kinematics.png") for v in (a, b)]
    if any(s is None for s in specs):
        return None
    if specs[0].get("pair"):
        return axis_motion_figure(specs[0]["columns"], axes=specs[0].get("axes"),
                                  title=specs[0].get("pair_title"))
    # the commanded programs: a machine's followed path carries its servo noise, whose
    # derivatives would hide the motion (its following error has own figures)
    cols = [(v.name, s["columns"][0][1], s["columns"][0][2]) for v, s in zip((a, b), specs)]
    return axis_motion_figure(cols, title="Axis motion of the programs (the axes that move)")


@keeps_warnings
def run_compare(scene: Scene, out: str | Path, *, measured: str | Path | None = None,
                vary: str | None = None, force: bool = False, overwrite: bool = False,
                repeat: int = 1, scene_file: str | Path | None = None) -> dict:
    """Two variants of a scene (and optionally a measured map): files and report.

    Parameters
    ----------
    scene : Scene
        The validated scene.
    out : str or Path
        Output folder, written atomically (:func:`render_inspect.io.atomic_output_dir`).
    measured : str or Path, optional
        A measured height map (any format :func:`render_inspect.io.read_surface` reads),
        registered to the design and shown as a third column.  It is read and checked
        (:func:`check_measured`) before anything is simulated.
    vary : str, optional
        ``"key=a,b"``: compare the scene with ``key = a`` against ``key = b`` instead of
        the process kind's own pair (:func:`compare_pair`).
    force : bool
        Compare the measured map even when the checks refuse it (the reasons are kept in
        ``measured_file.checks`` and shown in the report).
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it.
    repeat : int
        Measurements of each variant (1..100): beyond the first, both variants are
        measured again with fresh camera noise and the difference's repeatability is
        reported (``difference.window.measured.repeat``).
    scene_file : str or Path, optional
        The scene file the scene was read from, recorded with its SHA-256 in ``inputs``.

    Returns
    -------
    dict
        The content of ``metrics.json``.

    Files in ``out``: one folder per variant (``compensated/`` and ``uncompensated/`` for
    the turning pair; named after the variants otherwise) with ``heightmap.exr``,
    ``toolpath.npz`` (turning), ``interferogram.exr`` with ``height_measured``,
    ``height.exr`` (what the instrument reports), the diffuse images and PNGs, the
    variant's ``metrics.json``; the figures (the first, ``difference.png``),
    ``metrics.json`` and ``report.html``.
    """
    inputs = (measured,) if measured is not None else ()
    check_output_dir(out, overwrite=overwrite, command="compare", scene=scene, inputs=inputs)
    problem = None if measured is None or (Path(measured).suffix.lower() == ".zarr" and
                                           Path(measured).is_dir()) else not_a_file(measured)
    if problem is not None:  # missing, a pipe, a device, a folder (a store is a .zarr folder)
        m = f"file not found: {str(measured)!r}" if problem == "not found" else f"{str(measured)!r} {problem}"
        raise InputError(f"--measured {m} (a height map file, or a .zarr store folder)")
    if isinstance(repeat, bool) or int(repeat) != repeat or not 1 <= int(repeat) <= MAX_REPEAT:
        raise InputError(f"--repeat must be an integer from 1 to {MAX_REPEAT}, got {repeat!r}")
    repeat = int(repeat)
    _check_phase_settings(scene)
    t_all = time.perf_counter()
    seed = int(scene.simulation.seed)
    design_surface = make_surface(scene.design)
    traits = _traits(scene)
    pair = compare_pair(scene, vary)
    variants = [_Variant(v.name, v.label, variant_scene(scene, v), noise_seed=s)
                for v, s in zip(pair.variants, measurement_seeds(seed, len(pair.variants)))]
    for v in variants:
        if not _NAME_OK.match(v.name):
            raise InputError(f"variant name {v.name!r} must use letters, digits, '_', '-', '.'")
        check_tool_edge(v.scene)  # a measured edge each variant's cut cannot take, before any work
    # the files a variant reads (a program or a height map given with --vary) are inputs too
    inputs = (*inputs, *(f for v in variants for f in scene_files(v.scene)))
    meas_map = None
    if measured is not None:  # read and check the file before any simulation
        meas_map, _ = check_measured(measured, scene, design_surface, force=force)
    log.info("compare %s: %s (%s) vs %s (%s)", cut_name(scene), variants[0].name, variants[0].label,
             variants[1].name, variants[1].label)
    entry, icfg0 = _instrument(scene)
    check_render_limits(scene, kind=entry.name)
    check_render_limits(scene, kind="diffuse")
    with atomic_output_dir(out, overwrite=overwrite, command="compare", scene=scene,
                           inputs=inputs) as tmp, \
            task("compare", total=13 + 2 * (repeat - 1)) as t:
        tmp = Path(tmp)
        for v in variants:
            t.update(f"{v.name}: simulate")
            _simulate_variant(v, tmp)
            t.advance(2)
        a, b = variants
        diff = (a.heightmap.machined - b.heightmap.machined) * MM_TO_NM
        identical = bool(np.array_equal(a.heightmap.machined, b.heightmap.machined, equal_nan=True))
        hm = a.heightmap
        fixed = icfg0.field_of_view if "field_of_view" in icfg0.model_fields_set else None
        g0 = entry.field(hm, icfg0)
        size = COMPARE_MAX_CAMERA_PIXELS * g0["pixel"] if "pixel" not in icfg0.model_fields_set \
            else max(g0["window"][2] - g0["window"][0], g0["window"][3] - g0["window"][1])
        cw = common_window(diff, pixel=hm.pixel, origin=hm.origin, size_mm=size, fixed=fixed,
                           design=hm.design)
        icfg, dcfg, notes = preview_render_configs(scene, hm, window=cw["window"])
        prog_feeds = _program_feeds(variants)
        marks = _marks_of_programs(traits.marks, prog_feeds)
        feed = marks.period_mm if marks is not None and marks.scallop else None
        if feed is not None and feed < 4 * hm.pixel:
            notes.append(f"the simulation samples the {feed * MM_TO_UM:.3g} um feed marks with "
                         f"{feed / hm.pixel:.2g} pixels per period (simulation.pixel = "
                         f"{hm.pixel * MM_TO_UM:.3g} um): below 4 they are not resolved and alias "
                         f"in the maps and the micro view; set simulation.pixel <= "
                         f"{feed / 4 * MM_TO_UM:.3g} um to resolve them")
        x0, x1, y0, y1 = hm.extent
        filters = waviness_choice(marks, design_surface, scene.metrology, pixel=hm.pixel,
                                  window_mm=(x1 - x0, y1 - y0))
        if marks is not traits.marks:
            each = ", ".join(f"{k} {f * MM_TO_UM:.3g} um" for k, f in prog_feeds.items())
            r_in, r_out = region_radii(scene.simulation.region, 0.0)
            filters["mark_period_from"] = (
                f"the median feed per revolution of the program read from a file at the radii "
                f"the simulated region spans ({r_in:.3g} .. {r_out:.3g} mm; the coarser where "
                f"the variants differ): " + each)
            filters["reasons"].insert(0, f"mark period: {filters['mark_period_from']}")
        for v in variants:
            _render_variant(v, tmp, icfg=icfg, dcfg=dcfg, seed=seed,
                            design_surface=design_surface, filters=filters, t=t)
        meas = None
        if measured is not None:
            t.update("measured file")
            meas = _measured_column(meas_map, scene, design_surface, a.heightmap, seed)
        t.update("figures and report")
        part = part_outline(scene)
        ig = a.ig
        window = ig.meta.get("window_mm", cw["window"])
        wdiff = _window_difference(a, b)
        rep_stats = None
        if repeat > 1:
            rep_stats = _repeat_differences(a, b, wdiff, icfg=icfg, repeat=repeat, seed=seed, t=t)
        profile = difference_profiles(
            diff, hm, wdiff["levelled"], ig,
            (a.heightmap.residual * MM_TO_NM, b.heightmap.residual * MM_TO_NM),
            window=window, peak=cw["peak"])
        line = profile["line"]
        _, profile["true_levelled"] = line_profile(wdiff["true_levelled"], pixel=ig.pixel,
                                                   origin=ig.origin, p0=line[0], p1=line[1],
                                                   step=ig.pixel)
        profile.update(measured_levelled=wdiff["levelled"], levelling=wdiff["info"])
        center = profile_center(hm, traits.axis)
        through = traits.axis is None
        secs = {v.name: sections(v.heightmap.machined, v.heightmap.design, pixel=hm.pixel,
                                 origin=v.heightmap.origin, center=center,
                                 angles_deg=PROFILE_ANGLES_DEG, filtered=v.filtered,
                                 through=through) for v in variants}
        if meas is not None:
            secs["measured file"] = sections(meas["maps"]["measured"], meas["maps"]["design"],
                                             pixel=meas["pixel"], origin=meas["origin"],
                                             center=center, angles_deg=PROFILE_ANGLES_DEG,
                                             through=through)
        figs = comparison_figures(a.shown(), b.shown(), meas, difference=profile, window=cw,
                                  part=part, identical=identical, sections=secs,
                                  radial=not through, kinematics=_kinematics(a, b),
                                  lowpass_mm=filters["s_filter_mm"] if feed is not None
                                  and feed < 4 * hm.pixel else None)
        for name, png in figs.items():
            atomic_write_bytes(tmp / f"{name}.png", png)
        figs.update(_program_figures(variants, tmp))
        windows = {"simulation_mm": [float(x) for x in scene.simulation.region],
                   "common_mm": list(cw["window"]),
                   f"{entry.name}_mm": list(a.ig.meta.get("window_mm", cw["window"])),
                   "diffuse_micro_mm": list(a.diffuse["micro"][1]["window_mm"]),
                   "diffuse_macro_mm": list(a.diffuse["macro"][1]["window_mm"]),
                   "largest_difference_mm": list(cw["peak"]), "part": part}
        render_settings = {entry.name: rendered_settings(a.ig, icfg),
                           "diffuse": {view: diffuse_summary(meta)
                                       for view, (_, meta) in a.diffuse.items()},
                           "notes": notes, "profile_angles_deg": list(PROFILE_ANGLES_DEG)}
        dnum = _difference_numbers(a, b, diff, profile, wdiff)
        if rep_stats is not None:
            dnum["window"]["measured"]["repeat"] = rep_stats
        metrics = comparison_metrics(
            scene, pair=pair, variants=variants,
            difference={**dnum, "identical": identical},
            filters=filters, windows=windows, seed=seed, mitsuba_variant=mitsuba_variant(),
            render_settings=render_settings,
            measured_file=None if meas is None else meas["metrics"],
            total_s=time.perf_counter() - t_all,
            report=str((Path(out) / "report.html").resolve()))
        metrics["inputs"] = run_inputs(metrics["scene"], scene_file=scene_file, measured=measured,
                                       seed=seed, variants=[(v.name, v.scene.to_dict())
                                                            for v in variants])
        metrics["warnings"] = said_warnings(difference_warnings(metrics))
        write_metrics(tmp, metrics)
        page = build_page(scene, metrics, figs, notes=notes)
        atomic_write_text(tmp / "report.html", page)
        t.advance()
    return json_safe(metrics)
