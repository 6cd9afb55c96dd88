"""``compare``: compensated vs uncompensated, through the whole chain.

For each variant (same camera, same seed): simulate the machined surface, render the
virtual interferometer and the diffuse-light views, retrieve the height from the frames
(what the instrument reports) and characterise everything; then write the variants side
by side, their differences, ``metrics.json`` and a self-contained ``report.html``.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.limits import memory_budget
from ..design import make_surface
from ..instruments import (
    interferometer_geometry,
    render_interferogram,
)
from ..io import (
    atomic_output_dir,
    check_output_dir,
    atomic_write_bytes,
    atomic_write_text,
    json_safe,
    read_surface,
    save_map_png,
    write_heightmap_exr,
    write_json,
    write_toolpath_npz,
)
from ..metrology import (
    areal_parameters,
    characterise_map,
    compare_measured,
    extract_section,
    kinematic_sq_mm,
    l_filter,
    remove_form,
    s_filter,
)
from ..processes import process_of
from ..render import mitsuba_variant, render_diffuse
from ..report import _figures as F
from ..report import build_page
from ._measure import measure_and_evaluate, measurement_outputs
from ._render import (
    check_render_limits,
    interferogram_summary,
    write_diffuse_outputs,
    write_interferogram_outputs,
)
from ._simulate import simulate

__all__ = ["run_compare", "check_measured", "expected_sq_mm", "compare_variants", "preview_render_configs", "VARIANTS",
           "PROFILE_ANGLES_DEG", "COMPARE_MAX_CAMERA_PIXELS", "COMPARE_MAX_DIFFUSE_RESOLUTION",
           "COMPARE_MAX_DIFFUSE_SPP"]

#: The two columns of the comparison, in order.
VARIANTS = ("compensated", "uncompensated")
#: Section angles of the radial profiles (seed 000 Fig. 16 shows that the overcut
#: waviness depends on the angle).
PROFILE_ANGLES_DEG = (0.0, 30.0, 60.0, 90.0)
#: Render sizes compare uses unless the scene sets them (keeps compare fast): camera
#: pixels across the interferometer field, diffuse image size and samples per pixel.
COMPARE_MAX_CAMERA_PIXELS = 256
COMPARE_MAX_DIFFUSE_RESOLUTION = 192
COMPARE_MAX_DIFFUSE_SPP = 16
#: Default S-filter nesting index of the "filtered" map for turned parts, in feeds per
#: revolution: removes the turning marks and keeps the waviness (seed 000 Fig. 16 d).
WAVINESS_FEEDS = 2.5
MM_TO_NM = 1e6


def compare_variants(scene):
    """The two variants ``compare`` puts side by side, as the scene's process kind defines
    them (turning: compensated, i.e. the scene as given or with ``process.compensation =
    "z"`` when it says "none", and uncompensated).  Everything else (camera, seed,
    region) is the same."""
    pairs = process_of(scene).variants(scene)
    return tuple(s for _, s in pairs)


def preview_render_configs(scene, heightmap):
    """Interferometer and diffuse settings for compare: the scene's, with the sizes it
    does not set capped (:data:`COMPARE_MAX_CAMERA_PIXELS`,
    :data:`COMPARE_MAX_DIFFUSE_RESOLUTION`, :data:`COMPARE_MAX_DIFFUSE_SPP`).  The
    interferometer keeps its objective's pixel and gets a smaller field of view (centred)
    unless the scene sets ``field_of_view`` (then the pixel is coarsened instead).

    Returns (icfg, dcfg, notes) where notes lists what was capped."""
    icfg = scene.render.interferometer
    dcfg = scene.render.diffuse
    notes = []
    user = icfg.model_fields_set
    if "pixel" not in user:
        g = interferometer_geometry(heightmap, icfg)
        n = max(g["nx"], g["ny"])
        if n > COMPARE_MAX_CAMERA_PIXELS:
            x0, y0, x1, y1 = g["window"]
            if "field_of_view" not in user:
                # keep the objective's pixel (its lateral resolution), crop the field
                half = COMPARE_MAX_CAMERA_PIXELS * g["pixel"] / 2
                cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
                fov = (max(x0, cx - half), max(y0, cy - half), min(x1, cx + half),
                       min(y1, cy + half))
                icfg = icfg.model_copy(update={"field_of_view": fov})
                notes.append(f"interferometer field of view cropped to {COMPARE_MAX_CAMERA_PIXELS} "
                             f"camera pixels of {g['pixel'] * 1e3:.3g} um around the centre "
                             f"({(fov[2] - fov[0]):.3g} x {(fov[3] - fov[1]):.3g} mm; set "
                             f"render.interferometer.field_of_view or pixel to choose)")
            else:
                pix = max(x1 - x0, y1 - y0) / COMPARE_MAX_CAMERA_PIXELS
                icfg = icfg.model_copy(update={"pixel": pix})
                notes.append(f"interferometer pixel {g['pixel'] * 1e3:.3g} um -> {pix * 1e3:.3g} "
                             f"um ({COMPARE_MAX_CAMERA_PIXELS} camera pixels across the field; "
                             f"set render.interferometer.pixel to choose)")
    upd = {}
    if "resolution" not in dcfg.model_fields_set and dcfg.resolution > COMPARE_MAX_DIFFUSE_RESOLUTION:
        upd["resolution"] = COMPARE_MAX_DIFFUSE_RESOLUTION
    if "spp" not in dcfg.model_fields_set and dcfg.spp > COMPARE_MAX_DIFFUSE_SPP:
        upd["spp"] = COMPARE_MAX_DIFFUSE_SPP
    if upd:
        dcfg = dcfg.model_copy(update=upd)
        notes.append("diffuse " + ", ".join(f"{k} -> {v}" for k, v in upd.items())
                     + " (set render.diffuse.resolution / spp to choose)")
    return icfg, dcfg, notes


@dataclass
class _Variant:
    name: str
    scene: object
    heightmap: object = None
    toolpath: object = None
    ig: object = None
    phase: object = None
    sim: object = None
    diffuse: dict = field(default_factory=dict)  # view -> (rgb, meta)
    timing: dict = field(default_factory=dict)
    filtered: np.ndarray | None = None
    metrics: dict = field(default_factory=dict)


def _filter_settings(scene) -> dict:
    """Form removal and S/L nesting indices of the "filtered" map (mm)."""
    m = scene.metrology
    s_f, l_f = m.s_filter, m.l_filter
    default = False
    if s_f is None and l_f is None and scene.process.kind in ("sts", "fts", "hts", "rcse"):
        s_f = WAVINESS_FEEDS * scene.process.feed_per_rev
        default = True
    form = m.form_removal if m.form_removal != "design" else "none"  # residual is vs design
    return {"form_removal": form, "polynomial_degree": int(m.polynomial_degree),
            "s_filter_mm": s_f, "l_filter_mm": l_f, "default_waviness_filter": default}


def _filtered_map(residual, pixel, settings):
    r, _ = remove_form(residual, pixel=pixel, method=settings["form_removal"],
                       degree=settings["polynomial_degree"])
    if settings["s_filter_mm"]:
        r = s_filter(r, pixel=pixel, nesting_index=settings["s_filter_mm"])
    if settings["l_filter_mm"]:
        r = l_filter(r, pixel=pixel, nesting_index=settings["l_filter_mm"])
    return r


def _areal_nm(z, pixel) -> dict:
    ok = np.isfinite(z)
    if ok.sum() < 2:
        return {"Sa_nm": float("nan"), "Sq_nm": float("nan"), "Sz_nm": float("nan")}
    p = areal_parameters(z, pixel=pixel)
    return {f"{k}_nm": p[k] * MM_TO_NM for k in ("Sa", "Sq", "Sp", "Sv", "Sz")}


def _simulate_variant(v: _Variant, out: Path) -> None:
    """Simulate one variant; write heightmap.exr, toolpath.npz, residual.png."""
    d = out / v.name
    d.mkdir(parents=True, exist_ok=True)
    sim = v.sim = simulate(v.scene)
    hm = v.heightmap = sim.heightmap
    v.toolpath = sim.toolpath
    write_heightmap_exr(d / "heightmap.exr", hm)
    if sim.toolpath is not None:
        write_toolpath_npz(d / "toolpath.npz", sim.toolpath)
    save_map_png(d / "residual.png", hm.residual * MM_TO_NM, extent=hm.extent,
                 title=f"{v.name}: machined - design", label="residual (nm)", cmap="RdBu_r",
                 symmetric=True)


def _render_variant(v: _Variant, out: Path, *, icfg, dcfg, seed: int, design_surface) -> None:
    """Render, measure and characterise one simulated variant; write its folder."""
    timing = v.timing
    d = out / v.name
    hm = v.heightmap
    sim = v.sim
    t = time.perf_counter()
    ig = v.ig = render_interferogram(hm, icfg, surface="machined", seed=seed)
    timing["interferogram"] = time.perf_counter() - t
    write_interferogram_outputs(d, ig, scene=v.scene.to_dict())
    t = time.perf_counter()
    mcfg = v.scene.metrology
    # measure from the frames alone (what the instrument reports: height.exr), then
    # evaluate that measurement against the truth kept beside the frames
    reported, v.phase, measured = measure_and_evaluate(d / "interferogram.exr",
                                                       algorithm=mcfg.phase_algorithm,
                                                       csi_refine=mcfg.csi_refine,
                                                       min_modulation=mcfg.min_modulation)
    measured["instrument"] = measurement_outputs(d, ig, reported, source="interferogram.exr")
    timing["phase_retrieval"] = time.perf_counter() - t
    err = np.where(v.phase.valid, v.phase.height - ig.height_true, np.nan) * MM_TO_NM
    save_map_png(d / "measurement_error.png", err, extent=ig.extent,
                 title=f"{v.name}: measured - true height", label="error (nm)", cmap="RdBu_r",
                 symmetric=True)
    # what the instrument reports vs the truth, both as residual from the design
    xx, yy = np.meshgrid(ig.x, ig.y)
    design_ig = np.broadcast_to(design_surface.height(xx, yy), xx.shape)
    meas_res = np.where(reported.valid, reported.height - design_ig, np.nan)
    true_res = np.where(v.phase.valid, ig.height_true - design_ig, np.nan)
    v.metrics["_maps"] = {"measured_residual": meas_res, "true_residual": true_res, "error": err}
    measured.update({f"instrument_residual_{k}": x for k, x in _areal_nm(meas_res, ig.pixel).items()})
    measured.update({f"true_residual_{k}": x for k, x in _areal_nm(true_res, ig.pixel).items()})

    for view in ("micro", "macro"):
        t = time.perf_counter()
        rgb, meta = render_diffuse(hm, dcfg, view=view, surface="machined", seed=seed,
                                   memory_budget=memory_budget(v.scene.simulation.max_memory_gb)[0])
        timing[f"diffuse_{view}"] = time.perf_counter() - t
        v.diffuse[view] = (rgb, meta)
        write_diffuse_outputs(d, rgb, meta, name=f"diffuse_{view}")

    settings = _filter_settings(v.scene)
    v.filtered = _filtered_map(hm.residual, hm.pixel, settings)
    save_map_png(d / "filtered.png", v.filtered * MM_TO_NM, extent=hm.extent,
                 title=f"{v.name}: filtered residual", label="height (nm)", cmap="RdBu_r",
                 symmetric=True)
    filt = characterise_map(hm.residual, pixel=hm.pixel, origin=hm.origin,
                            form_removal=settings["form_removal"],
                            polynomial_degree=settings["polynomial_degree"],
                            s_filter_mm=settings["s_filter_mm"], l_filter_mm=settings["l_filter_mm"])
    filt["default_waviness_filter"] = settings["default_waviness_filter"]

    m = dict(sim.metrics)
    m.update({"measured": measured, "filtered": filt,
              "interferometer": interferogram_summary(ig),
              "diffuse": {view: {k: meta[k] for k in ("view", "spp", "seed",
                                                       "vertical_exaggeration", "window_mm",
                                                       "mitsuba_variant")}
                          for view, (_, meta) in v.diffuse.items()},
              "mitsuba_variant": ig.variant})
    m["timing_s"] = {**sim.timing_s, **timing}
    write_json(d / "metrics.json", m)
    v.metrics.update(m)


def _sections(z, design, *, pixel, origin, center, angles_deg, filtered=None):
    def sec(m, a):
        return extract_section(m, pixel=pixel, origin=origin, kind="radial", center=center,
                               angle=np.radians(a))[1]

    out = []
    for a in angles_deg:
        s, zm = extract_section(z, pixel=pixel, origin=origin, kind="radial", center=center,
                                angle=np.radians(a))
        if np.isfinite(zm).sum() >= 2:
            out.append({"angle_deg": float(a), "s": s, "machined": zm,
                        "design": None if design is None else sec(design, a),
                        "filtered": None if filtered is None else sec(filtered, a)})
    return out


def _profile_center(hm):
    """The spindle axis (0, 0) when it lies in the map, else the map's centre."""
    x0, x1, y0, y1 = hm.extent
    if x0 <= 0 <= x1 and y0 <= 0 <= y1:
        return (0.0, 0.0)
    return ((x0 + x1) / 2, (y0 + y1) / 2)


def _srgb(rgb):
    a = np.clip(np.nan_to_num(rgb), 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)


def _luminance(rgb):
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def expected_sq_mm(scene) -> float | None:
    """The Sq the scene's process should leave on its own (mm): the ideal turned profile
    ``f^2 / (12 sqrt(5) R)`` for feed ``f`` per revolution and nose radius ``R``; None for
    processes without a feed per revolution."""
    feed = getattr(scene.process, "feed_per_rev", None)
    radius = getattr(scene.tool, "nose_radius", None)
    if feed is None or radius is None or not feed > 0:
        return None
    return kinematic_sq_mm(float(feed), float(radius))


def check_measured(path, scene, design_surface, *, force: bool = False):
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
                                expected_sq_mm=expected_sq_mm(scene), force=force)
    return m, comp


def run_compare(scene, out, *, measured=None, force: bool = False, overwrite: bool = False) -> dict:
    """Compensated vs uncompensated (and optionally a measured map): files and report.

    Parameters
    ----------
    scene : Scene
        The validated scene.  Its compensated variant is the scene itself (or with
        ``process.compensation = "z"`` if it says "none"); the uncompensated one has
        ``process.compensation = "none"``.  Both use the same camera and seed.
    out : str or Path
        Output folder, written atomically (:func:`render_inspect.io.atomic_output_dir`).
    measured : str or Path, optional
        A measured height map (any format :func:`render_inspect.io.read_surface` reads),
        registered to the design and shown as a third column.  It is read and checked
        (:func:`check_measured`) before anything is simulated.
    force : bool
        Compare the measured map even when the checks refuse it (the reasons are kept in
        ``measured_file.checks`` and shown in the report).
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it.

    Returns
    -------
    dict
        The content of ``metrics.json``.

    Files in ``out``: ``compensated/`` and ``uncompensated/`` (``heightmap.exr``,
    ``toolpath.npz``, ``interferogram.exr`` with ``height_measured``, PNGs, the variant's
    ``metrics.json``), the side-by-side and difference PNGs, ``metrics.json`` and
    ``report.html``.
    """
    check_output_dir(out, overwrite=overwrite, command="compare", scene=scene)
    if measured is not None and not Path(measured).is_file():
        raise InputError(f"--measured file not found: {str(measured)!r}")
    _check_phase_settings(scene)
    t_all = time.perf_counter()
    seed = int(scene.simulation.seed)
    design_surface = make_surface(scene.design)
    meas_map = None
    if measured is not None:  # read and check the file before any simulation
        meas_map, _ = check_measured(measured, scene, design_surface, force=force)
    comp_s, unc_s = compare_variants(scene)
    variants = [_Variant("compensated", comp_s), _Variant("uncompensated", unc_s)]
    check_render_limits(scene, kind="all")
    with atomic_output_dir(out, overwrite=overwrite, command="compare", scene=scene) as tmp:
        tmp = Path(tmp)
        for v in variants:
            _simulate_variant(v, tmp)
        # same camera for both: the render settings come from the compensated map's grid
        icfg, dcfg, notes = preview_render_configs(scene, variants[0].heightmap)
        for v in variants:
            _render_variant(v, tmp, icfg=icfg, dcfg=dcfg, seed=seed, design_surface=design_surface)
        c, u = variants
        meas = None
        if measured is not None:
            meas = _measured_column(meas_map, scene, design_surface, c.heightmap, seed)

        figs = _figures(c, u, meas, F)
        for name, png in figs.items():
            atomic_write_bytes(tmp / f"{name}.png", png)

        diff = (c.heightmap.machined - u.heightmap.machined) * MM_TO_NM
        ok = np.isfinite(diff)
        metrics = {
            "compensated": {k: x for k, x in c.metrics.items() if not k.startswith("_")},
            "uncompensated": {k: x for k, x in u.metrics.items() if not k.startswith("_")},
            "difference": {
                "machined_rms_nm": float(np.sqrt(np.mean(diff[ok] ** 2))) if ok.any() else None,
                "machined_pv_nm": float(np.ptp(diff[ok])) if ok.any() else None,
                "min_nm_change": c.metrics["residual"]["min_nm"] - u.metrics["residual"]["min_nm"],
                "Sq_nm_change": c.metrics["residual"]["Sq_nm"] - u.metrics["residual"]["Sq_nm"]},
            "software_version": __version__, "seed": seed,
            "mitsuba_variant": mitsuba_variant(),
            "scene": scene.to_dict(),
            "render_settings": {"interferometer": icfg.model_dump(mode="json"),
                                "diffuse": dcfg.model_dump(mode="json"), "notes": notes,
                                "profile_angles_deg": list(PROFILE_ANGLES_DEG)},
        }
        if "lenslets" in metrics["compensated"]:
            metrics["lenslets"] = metrics["compensated"]["lenslets"]
        if meas is not None:
            metrics["measured_file"] = meas["metrics"]
        metrics["timing_s"] = {"total": time.perf_counter() - t_all}
        write_json(tmp / "metrics.json", metrics)
        page = build_page(scene, metrics, figs, notes=notes)
        atomic_write_text(tmp / "report.html", page)
    return json_safe(metrics)


def _check_phase_settings(scene) -> None:
    """Refuse, before any work, a PSI algorithm that cannot use the frames rendered."""
    ic, alg = scene.render.interferometer, scene.metrology.phase_algorithm
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


def _measured_column(m, scene, design_surface, sim_hm, seed) -> dict:
    simulated = sim_hm if np.allclose(m.pixel, sim_hm.pixel, rtol=1e-6) else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        comp = compare_measured(m, design_surface, metrology=scene.metrology,
                                simulated=simulated, region=tuple(scene.simulation.region),
                                seed=seed, expected_sq_mm=expected_sq_mm(scene), force=True)
    metrics = dict(comp.metrics)
    metrics["compared_with_simulation"] = simulated is not None
    notes = [str(w.message) for w in caught]
    if simulated is None:
        notes.append(f"the measured pixel ({m.pixel[0] * 1e3:.4g} x {m.pixel[1] * 1e3:.4g} um) "
                     f"differs from the simulation's ({sim_hm.pixel * 1e3:.4g} um): the "
                     f"measurement is compared with the design only")
    checks = metrics.get("checks") or {}
    metrics["warnings"] = notes + list(checks.get("warnings", [])) + [
        f"compared with --force although: {r}" for r in checks.get("refusals", [])]
    return {"metrics": metrics, "maps": comp.maps, "pixel": comp.pixel, "origin": comp.origin,
            "extent": m.extent}


def _figures(c: _Variant, u: _Variant, meas, F) -> dict:
    """All top-level PNGs: name -> bytes."""
    figs = {}
    names = ("compensated", "uncompensated")
    ig_ext = c.ig.extent
    figs["interferogram_side_by_side"] = F.image_panels(
        [(f"{n}: intensity (zero-shift frame)", v.ig.intensity) for n, v in zip(names, (c, u))],
        extent=ig_ext, gray_label="intensity (0..1)",
        suptitle=f"Interferograms ({c.ig.mode.upper()}, {c.ig.objective}, NA "
                 f"{c.ig.numerical_aperture:g}, {c.ig.wavelength_nm:g} nm)")
    figs["interferogram_difference"] = F.map_panels(
        [("compensated - uncompensated", c.ig.intensity.astype(float) - u.ig.intensity)],
        extent=ig_ext, label="intensity difference", cmap="RdBu_r", symmetric=True)
    for view in ("micro", "macro"):
        (rc, mc), (ru, _) = c.diffuse[view], u.diffuse[view]
        if view == "micro":
            x0, y0, x1, y1 = mc["window_mm"]
            ext = (x0, x1, y0, y1)
        else:
            ext = None
        figs[f"diffuse_{view}_side_by_side"] = F.image_panels(
            [(f"{n}: diffuse {view}", _srgb(r)[::-1]) for n, r in (("compensated", rc),
                                                                   ("uncompensated", ru))],
            extent=ext, axis_labels=ext is not None,
            suptitle=f"Diffuse light ({mc['light']['type']}), heights exaggerated "
                     f"{mc['vertical_exaggeration']:g}x")
        if view == "micro":
            figs["diffuse_difference"] = F.map_panels(
                [("compensated - uncompensated (luminance)",
                  (_luminance(rc) - _luminance(ru))[::-1])],
                extent=ext, label="linear luminance difference", cmap="RdBu_r", symmetric=True)
    hm_ext = c.heightmap.extent
    res_panels = [(f"{n}: machined - design", v.heightmap.residual * MM_TO_NM)
                  for n, v in zip(names, (c, u))]
    exts = [hm_ext, hm_ext]
    if meas is not None:
        res_panels.append(("measured - design (registered)", meas["maps"]["residual"] * MM_TO_NM))
        exts.append(meas["extent"])
    figs["residual_side_by_side"] = F.map_panels(res_panels, extent=exts, label="residual (nm)",
                                                 cmap="RdBu_r", symmetric=True)
    figs["residual_difference"] = F.map_panels(
        [("machined: compensated - uncompensated",
          (c.heightmap.machined - u.heightmap.machined) * MM_TO_NM)],
        extent=hm_ext, label="height difference (nm)", cmap="RdBu_r", symmetric=True)
    figs["filtered_side_by_side"] = F.map_panels(
        [(f"{n}: filtered residual", v.filtered * MM_TO_NM) for n, v in zip(names, (c, u))],
        extent=hm_ext, label="height (nm)", cmap="RdBu_r", symmetric=True)
    figs["measurement_error_side_by_side"] = F.map_panels(
        [(f"{n}: measured - true", v.metrics["_maps"]["error"]) for n, v in zip(names, (c, u))],
        extent=ig_ext, label="height error (nm)", cmap="RdBu_r", symmetric=True,
        percentile=0.5)
    figs["measured_residual_side_by_side"] = F.map_panels(
        [(f"{n}: measured - design", v.metrics["_maps"]["measured_residual"] * MM_TO_NM)
         for n, v in zip(names, (c, u))],
        extent=ig_ext, label="residual seen by the instrument (nm)", cmap="RdBu_r",
        symmetric=True, percentile=0.5)
    center = _profile_center(c.heightmap)
    secs = {}
    for n, v in zip(names, (c, u)):
        hm = v.heightmap
        secs[n] = _sections(hm.machined, hm.design, pixel=hm.pixel, origin=hm.origin,
                            center=center, angles_deg=PROFILE_ANGLES_DEG, filtered=v.filtered)
    if meas is not None:
        secs["measured"] = _sections(meas["maps"]["measured"], meas["maps"]["design"],
                                     pixel=meas["pixel"], origin=meas["origin"], center=center,
                                     angles_deg=PROFILE_ANGLES_DEG)
    figs["radial_profiles"] = F.radial_profile_figure(secs)
    return figs
