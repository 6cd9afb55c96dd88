"""``fit``: a measured surface -> the tool, feed, machine and material settings that cut it
(:mod:`render_inspect.fit` does the fitting), then the next cut predicted.

The forward model of one evaluation is chained here and nowhere else
(:func:`predict_measurement`): the scene with the trial values -> :func:`simulate` over the
fit window -> the virtual interference microscope with the measured file's settings ->
:func:`~render_inspect.metrology.measure_frames` -> the height the instrument reports.
"""

from __future__ import annotations

import contextlib
import copy
import json
import logging
import math
import time
from pathlib import Path

import numpy as np

from .. import __version__
from ..batch import dask_client
from ..core.errors import InputError
from ..core.progress import set_reporter, task
from ..core.units import MM_TO_NM, MM_TO_UM, RAD_TO_URAD
from ..design import make_surface
from ..fit import (EvaluationCache, Evaluator, MisfitSpec, centred_origin, check_units,
                   field_extent, fit_record, fit_window, free_parameters, make_target,
                   misfit_maps, parse_bounds, set_noise_floor, parse_free, predict_features,
                   prepare_map, radial_psd, register_field, scene_hash, set_value, solve, task_hash)
from ..instruments import (InterferometerConfig, microscope_from_config, recommended_subsamples,
                           render_interferogram)
from ..instruments._interferometer import MAX_AUTO_SUBSAMPLES
from ..io import atomic_output_dir, atomic_write_text, check_output_dir, read_exr, read_surface
from ..io import write_exr, write_json, write_marker
from ..machining import material_preset
from ..metrology import measure_frames
from ..processes._mechanics import machine_of
from ..report import fit_figures, fit_page
from ..scene import apply_overrides, scene_from_dict
from ._simulate import simulate, write_simulation

__all__ = ["run_fit", "predict_measurement", "FIT_FILES", "preset_value"]

log = logging.getLogger("render_inspect")

#: Files ``fit`` writes into its output folder (``predict/`` with ``--predict``).
FIT_FILES = ("fit.json", "fit.html", "maps.png", "residual.png", "psd.png", "misfit.png",
             "fitted.exr", "scene.json", "predict/")
#: pixels traced around the fit window by the virtual instrument (cropped after imaging)
MARGIN_PX = 8
#: simulation samples per feed period at least (the evaluations' simulation.pixel)
SIM_SAMPLES_PER_PERIOD = 20


# --------------------------------------------------------------------- the forward model
def predict_measurement(task_spec: dict):
    """One evaluation: what the virtual instrument reports for the scene of ``task_spec``
    (``scene``: a scene dictionary whose region covers the field and whose
    ``render.interferometer`` is the instrument; ``seed``: the camera noise's seed;
    ``algorithm``).  Returns (height (ny, nx) mm with NaN where not measured, meta).
    Runs in this process or on a Dask worker."""
    _numba_threads_as_launched()
    scene = scene_from_dict(task_spec["scene"], "(fit evaluation)")
    sim = simulate(scene)
    ig = render_interferogram(sim.heightmap, scene.render.interferometer,
                              seed=int(task_spec["seed"]))
    r = measure_frames(ig.recorded(), algorithm=task_spec.get("algorithm", "auto"))
    h = np.where(r.valid, r.height, np.nan)
    return h, {"origin_mm": [float(v) for v in ig.origin], "pixel_mm": float(ig.pixel),
               "shape": list(h.shape), "residual_sq_nm": sim.metrics["residual"]["Sq_nm"]}


def _numba_threads_as_launched() -> None:
    """Make ``NUMBA_NUM_THREADS`` in the environment agree with the thread count numba runs
    with.  A Dask worker may get the variable from its nanny after numba has read it; a
    kernel compiled there (the first call of one not yet in the cache) re-reads the
    environment and refuses a count that differs from the running pool's."""
    import os

    import numba

    os.environ["NUMBA_NUM_THREADS"] = str(numba.config.NUMBA_NUM_THREADS)


@contextlib.contextmanager
def _quiet():
    """The forward model's own progress bars are not shown during a fit."""
    old = set_reporter(None)
    try:
        yield
    finally:
        set_reporter(old)


# ------------------------------------------------------------------ preset values
def _axis_scene_units(axis: dict, spindle: bool) -> dict:
    bw = axis.get("bandwidth_hz")
    d = {"bandwidth_hz": math.inf if bw is None else bw, "damping": axis["damping"],
         "velocity_ff": axis["velocity_ff"], "acceleration_ff": axis["acceleration_ff"],
         "delay_s": axis["delay_s"]}
    if spindle:
        d["noise_urad"] = axis["noise_rms"] * RAD_TO_URAD
    else:
        d["noise_nm"] = axis["noise_rms"] * MM_TO_NM
        d["velocity_limit_mm_s"] = axis.get("velocity_limit")
        d["acceleration_limit_mm_s2"] = axis.get("acceleration_limit")
    return d


def _machine_scene_units(scene) -> dict:
    """The scene's machine (its preset with the scene's changes) in the scene's units."""
    m = machine_of(scene).to_dict()
    out = {"servo_rate_hz": m["servo_rate_hz"]}
    for k in ("x", "z", "fts"):
        out[k] = _axis_scene_units(m[k], False)
    out["c"] = _axis_scene_units(m["c"], True)
    e = m["errors"] or {}
    errs = {}
    for k in ("radial_sync", "axial_sync"):
        errs[k] = [[int(n), a * MM_TO_NM, math.degrees(p)] for n, a, p in e.get(k, ())]
    errs["tilt_sync"] = [[int(n), a * RAD_TO_URAD, math.degrees(p)] for n, a, p in e.get("tilt_sync", ())]
    errs["radial_async_nm"] = e.get("radial_async_rms", 0.0) * MM_TO_NM
    errs["axial_async_nm"] = e.get("axial_async_rms", 0.0) * MM_TO_NM
    errs["async_bandwidth_hz"] = e.get("async_bandwidth_hz")
    errs["x_straightness_nm"] = e.get("x_straightness_rms", 0.0) * MM_TO_NM
    errs["x_straightness_length"] = e.get("x_straightness_length")
    errs["vibration"] = [[f, a * MM_TO_NM, d, math.degrees(p)]
                         for f, a, d, p in e.get("vibration", ())]
    out["errors"] = errs
    out["coupling"] = dict(m["coupling"])
    return out


def preset_value(scene, key: str):
    """The value of a machine or material key the scene leaves to its preset (scene
    units), or None."""
    parts = key.split(".")
    if parts[0] == "machine":
        node = _machine_scene_units(scene)
    elif parts[0] == "material" and scene.material.preset != "ideal":
        node = material_preset(scene.material.preset).to_dict()
    else:
        return None
    for p in parts[1:]:
        if isinstance(node, dict):
            node = node.get(p)
        elif isinstance(node, list) and p.isdigit() and int(p) < len(node):
            node = node[int(p)]
        else:
            return None
        if node is None:
            return None
    return node


def _fill(scene):
    """The preset's array for an array key the scene leaves unset."""
    def fill(prefix: str):
        v = preset_value(scene, prefix)
        return copy.deepcopy(v) if isinstance(v, list) else None
    return fill


# ------------------------------------------------------------------ the measured file
_INSTRUMENT_ATTRS = ("objective", "mode", "wavelength_nm", "bandwidth_nm", "numerical_aperture")


def _file_instrument(path) -> dict:
    """The instrument settings a ``height.exr`` (written by ``measure``) names in its
    header; {} for other files."""
    if Path(path).suffix.lower() != ".exr":
        return {}
    _, attrs = read_exr(path)
    out = {}
    for k in _INSTRUMENT_ATTRS:
        v = attrs.get(k)
        if v not in (None, ""):
            out[k] = v
    inst = attrs.get("instrument")
    if isinstance(inst, str):
        try:
            inst = json.loads(inst)
        except ValueError:
            inst = None
    s = ((inst or {}).get("model") or {}).get("subsamples") if isinstance(inst, dict) else None
    if isinstance(s, int) and 1 <= s <= 8:
        out["subsamples"] = s
    return out


def _instrument(scene, file_settings: dict, objective: str | None, pixel: float, window,
                z, subsamples=None) -> tuple[dict, str]:
    """The ``[render.interferometer]`` of the evaluations: the scene's, with the file's
    objective and settings (else ``objective``), the measured pixel, the fit window as
    field of view, and the sub-sampling pinned (so that it does not jump between
    evaluations)."""
    icfg = scene.render.interferometer.model_dump(mode="json")
    source = "scene"
    if file_settings.get("objective"):
        icfg["objective"] = str(file_settings["objective"])
        source = "file"
        for k in ("mode", "wavelength_nm", "bandwidth_nm", "numerical_aperture"):
            if k in file_settings:
                icfg[k] = file_settings[k]
        if icfg.get("bandwidth_nm") == 0 and icfg.get("mode") == "csi":
            icfg["bandwidth_nm"] = None
    elif objective:
        icfg["objective"] = objective
        source = "--objective"
    icfg.update(pixel=float(pixel), field_of_view=[float(v) for v in window], margin=MARGIN_PX,
                reference_height=None)
    try:
        cfg = InterferometerConfig.model_validate(icfg)
    except Exception as err:  # pydantic's error: say which setting
        raise InputError(f"the instrument settings of the measured file are not usable "
                         f"({' '.join(str(err).split())[:300]})") from None
    if file_settings.get("subsamples") and source == "file":
        icfg["subsamples"] = int(file_settings["subsamples"])
    elif cfg.subsamples is None:
        gy, gx = np.gradient(np.asarray(z, dtype=np.float64), pixel)
        g = np.hypot(gx, gy)
        g = g[np.isfinite(g)]
        slope = float(math.atan(np.percentile(g, 99.9))) if g.size else None
        s = subsamples or min(recommended_subsamples(pixel, microscope_from_config(cfg),
                                                     max_slope=slope), MAX_AUTO_SUBSAMPLES)
        icfg["subsamples"] = int(s)
    return InterferometerConfig.model_validate(icfg).model_dump(mode="json"), source


def _weights(items) -> dict:
    out = {"map": 1.0, "psd": 1.0, "harmonics": 1.0}
    for item in items or ():
        for part in str(item).split(","):
            if not part.strip():
                continue
            if "=" not in part:
                raise InputError(f"--weights expects TERM=W (map, psd, harmonics), received {part!r}")
            k, v = part.split("=", 1)
            try:
                out[k.strip()] = float(v)
            except ValueError:
                raise InputError(f"--weights {k.strip()} must be a number >= 0, received {v!r}") from None
    return out


def _parse_at(at):
    if at is None or at == "register":
        return at
    parts = str(at).split(",")
    try:
        x, y = (float(p) for p in parts)
    except ValueError:
        raise InputError(f"--at expects X,Y (the measured field's centre on the part, mm) or "
                         f"'register', received {at!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"--at expects two finite numbers X,Y (mm), received {at!r}")
    return (x, y)


# ------------------------------------------------------------------------- run_fit
def run_fit(measured, scene, free, out, *, bounds=(), objective: str | None = None,
            at=None, window_mm: float = 0.2, form: str = "plane", weights=None,
            workers: int | None = None, scheduler: str | None = None, predict=(),
            seed: int = 0, global_points: int = 0, max_evaluations: int = 150,
            profile_points: int = 3, cache=None, overwrite: bool = False) -> dict:
    """``render-inspect fit MEASURED --scene SCENE --free KEY,... --out DIR``.

    Parameters
    ----------
    measured : path
        Anything ``analyze`` reads: an instrument file, or the ``height.exr`` that
        ``measure`` writes.
    scene : Scene
        The cut (its ``--set`` overrides applied).
    free : list of str
        Scene keys to fit (``--free``, comma-separated allowed).
    out : path
        Output folder, written whole when the fit is done.
    bounds : list of "KEY=A,B"
        Bounds inside the schema's (default: the schema's).
    objective : str, optional
        The virtual instrument's objective when the file names none (default: the
        scene's ``render.interferometer``).
    at : None, "X,Y" or "register"
        Where the field lies: the file's origin (None), its centre at X, Y (mm), or found
        by registration to the design.
    window_mm : float
        Side of the fitted square (mm): the part of the field that is simulated in each
        evaluation.
    form : {"none", "plane", "poly2", "sphere"}
        Form removed from both maps before they are compared.
    weights : list of "TERM=W"
        Weights of the misfit's terms (``map``, ``psd``, ``harmonics``; 1 each).
    workers, scheduler :
        Run the evaluations on a Dask LocalCluster of ``workers`` processes or on the
        cluster at ``scheduler`` (default: in this process).
    predict : list of "KEY=VALUE"
        After the fit, simulate the fitted scene with these changes into ``predict/``.
    seed : int
        Seed of the virtual camera's noise and of the Latin hypercube.
    global_points : int
        Latin-hypercube points before the local fit (0: start from the scene's values).
    max_evaluations : int
        Largest number of forward-model evaluations of the fit.
    profile_points : int
        Points either side of the solution along each parameter (misfit.png).
    cache : path, optional
        Folder of cached evaluations (default: ``OUT.cache`` beside the output folder).
    overwrite : bool
    """
    t_all = time.perf_counter()
    out = Path(out)
    check_output_dir(out, overwrite=overwrite, command="fit")
    keys = parse_free(free)
    user_bounds = parse_bounds(bounds)
    spec = MisfitSpec(form=form, weights=_weights(weights))
    at = _parse_at(at)
    if not (isinstance(window_mm, (int, float)) and math.isfinite(window_mm) and window_mm > 0):
        raise InputError(f"--window must be a side length > 0 (mm), received {window_mm!r}")
    for name, v, lo in (("--max-evaluations", max_evaluations, 2), ("--global", global_points, 0),
                        ("--profile-points", profile_points, 0), ("--seed", seed, 0)):
        if not (isinstance(v, int) and v >= lo):
            raise InputError(f"{name} must be an integer >= {lo}, received {v!r}")
    params = free_parameters(scene, keys, user_bounds, defaults=lambda k: preset_value(scene, k))
    base = scene.to_dict()
    fill = _fill(scene)
    # the prediction's scene is checked before the fit runs
    predict = list(predict or ())
    if predict:
        _predicted_scene(base, {p.key: p.start for p in params}, predict, fill)

    m = read_surface(measured)
    if not m.square:
        raise InputError(f"{measured}: pixel sizes differ in x ({m.pixel[0]:.6g} mm) and y "
                         f"({m.pixel[1]:.6g} mm); the virtual instrument has square pixels: "
                         f"resample the map first")
    pixel = float(m.pixel[0])
    file_settings = _file_instrument(measured)
    region = [float(v) for v in scene.simulation.region]
    placement = {}
    if at == "register":
        reg = register_field(m.z, m.pixel, make_surface(scene.design), region)
        origin = tuple(reg["origin_mm"])
        how = "by registration to the design"
        placement = {"method": "register", **reg}
    elif at is not None:
        origin = centred_origin(m.z.shape, m.pixel, at)
        how = f"with its centre at {at[0]:g}, {at[1]:g} mm (--at)"
        placement = {"method": "at", "centre_mm": list(at)}
    else:
        origin = tuple(m.origin)
        how = "from the file's origin"
        placement = {"method": "file origin"}
    placement["origin_mm"] = [float(origin[0]), float(origin[1])]
    placement["field_mm"] = [float(v) for v in field_extent(m.z.shape, m.pixel, origin)]
    rows, cols = fit_window(m.z, m.pixel, origin, region, float(window_mm), how=how)
    zw = m.z[rows, cols]
    w_origin = (origin[0] + cols.start * pixel, origin[1] + rows.start * pixel)
    n = zw.shape[0]
    window = [w_origin[0] - pixel / 2, w_origin[1] - pixel / 2,
              w_origin[0] - pixel / 2 + n * pixel, w_origin[1] - pixel / 2 + n * pixel]
    placement["window_mm"] = window
    placement["window_px"] = [int(rows.start), int(cols.start), int(n)]
    log.info("fit window %.4g x %.4g mm (%d x %d pixels) at x %.4g..%.4g, y %.4g..%.4g mm "
             "(field placed %s)", n * pixel, n * pixel, n, n, window[0], window[2], window[1],
             window[3], how)
    icfg, icfg_source = _instrument(scene, file_settings, objective, pixel, window, zw)
    target = make_target(zw, pixel=(pixel, pixel), origin=w_origin, spec=spec)
    # the simulation grid samples the feed marks finely enough that its aliasing of the
    # cusps (a waviness that moves with the marks' phase, hence with the feed) stays far
    # below the waviness the fit compares
    sim_pixel = float(scene.simulation.pixel)
    while target.centroid and sim_pixel * target.centroid * SIM_SAMPLES_PER_PERIOD > 1.0 + 1e-9:
        sim_pixel /= 2.0
    grow = (MARGIN_PX + 2) * pixel + 2 * sim_pixel
    sim_region = [window[0] - grow, window[1] - grow, window[2] + grow, window[3] + grow]
    log.info("evaluations simulate %.4g x %.4g mm at a %.3g um pixel", sim_region[2] - sim_region[0],
             sim_region[3] - sim_region[1], sim_pixel * MM_TO_UM)

    # evaluations image without the camera's noise (its expected value: smooth in the
    # parameters); the noise's power is added to their spectra as a floor measured once
    icfg_clean = dict(icfg, noise=False)

    def make_task(values: dict, *, noise: bool = False) -> dict:
        d = copy.deepcopy(base)
        for k, v in values.items():
            set_value(d, k, v, fill=fill)
        d["simulation"]["region"] = sim_region
        d["simulation"]["pixel"] = sim_pixel
        d.setdefault("render", {})["interferometer"] = icfg if noise else icfg_clean
        return {"scene": d, "seed": int(seed), "algorithm": "auto"}

    scene_from_dict(make_task({p.key: p.start for p in params})["scene"], "(the fit window)")
    cache_dir = Path(cache) if cache is not None else out.parent / f"{out.name}.cache"
    store = EvaluationCache(cache_dir)
    with contextlib.ExitStack() as stack:
        client = None
        if workers is not None or scheduler is not None:
            client = stack.enter_context(dask_client(workers=workers, scheduler=scheduler))
        evaluator = Evaluator(params, target, make_task, predict_measurement, store,
                              client=client, max_evaluations=max_evaluations, quiet=_quiet)
        start_values = {p.key: p.start for p in params}
        with task("fit: the scene's values, with and without the camera's noise"):
            clean0 = _compute(store, make_task(start_values), client)
            noisy0 = _compute(store, make_task(start_values, noise=True), client) \
                if icfg.get("noise", True) else clean0
        set_noise_floor(target, noisy0, clean0)
        check_units(_rms(target.height), _rms(prepare_map(noisy0, pixel=target.pixel,
                                                          form=spec.form, origin=w_origin)))
        first = evaluator.evaluate([[p.start for p in params]])[0]
        pred0 = predict_features(first.height, target)
        log.info("first evaluation: %.1f s; misfit %.4g", first.seconds, first.cost)
        result = solve(params, evaluator, global_points=global_points, seed=seed,
                       profile_points=profile_points)
    best = predict_features(result.best.height, target)
    maps = misfit_maps(target.height, best.height)
    wavy = misfit_maps(target.wavy, best.wavy)
    fitted_values = {p.key: float(v) for p, v in zip(params, result.values)}
    fitted = copy.deepcopy(base)
    for k, v in fitted_values.items():
        set_value(fitted, k, v, fill=fill)
    provenance = {"seed": int(seed), "scene_sha256": scene_hash(base),
                  "fitted_scene_sha256": scene_hash(fitted),
                  "objective": icfg["objective"], "objective_from": icfg_source,
                  "instrument": {k: icfg[k] for k in ("mode", "objective", "pixel",
                                                      "subsamples", "noise")},
                  "measured": {"path": str(measured), "shape": list(m.z.shape),
                               "pixel_mm": pixel, "reader": m.meta.get("reader"),
                               "format": m.meta.get("format")},
                  "placement": placement, "scene": scene.name,
                  "simulation": {"region_mm": sim_region, "pixel_mm": sim_pixel},
                  "cache": str(cache_dir),
                  "workers": workers, "scheduler": scheduler}
    record = fit_record(result, target=target, spec=spec, provenance=provenance, maps=maps,
                        waviness=wavy)
    with atomic_output_dir(out, overwrite=overwrite, command="fit") as tmp:
        tmp = Path(tmp)
        if predict:
            pred_scene = _predicted_scene(fitted, {}, predict, fill)
            pred_scene = scene_from_dict(apply_overrides(
                pred_scene.to_dict(), [f"simulation.region={json.dumps(window)}"]), "(predict)")
            with task("fit: predict the next cut"):
                sim = simulate(pred_scene)
            (tmp / "predict").mkdir()
            pm = write_simulation(sim, tmp / "predict")
            write_marker(tmp / "predict", command="simulate", scene=pred_scene)
            record["prediction"] = {"settings": list(predict), "folder": "predict",
                                    "residual": pm.get("residual"),
                                    "toolpath": pm.get("toolpath")}
        record["timing_s"]["total"] = time.perf_counter() - t_all
        record["files"] = {f: d for f, d in _file_notes().items()
                           if f != "predict/" or predict}
        figs = fit_figures(record, measured=target.height, fitted=best.height,
                           start=pred0.height, measured_wavy=target.wavy, fitted_wavy=best.wavy,
                           extent=(window[0], window[2], window[1], window[3]),
                           psd={"measured": radial_psd(target.height, pixel=target.pixel),
                                "fitted": radial_psd(best.height, pixel=target.pixel),
                                "start": radial_psd(pred0.height, pixel=target.pixel)})
        for name, png in figs.items():
            (tmp / name).write_bytes(png)
        atomic_write_text(tmp / "fit.html", fit_page(record, figs))
        write_exr(tmp / "fitted.exr",
                  {"measured": target.height.astype(np.float32),
                   "fitted": best.height.astype(np.float32),
                   "residual": (best.height - target.height).astype(np.float32)},
                  {"pixel_size_mm": pixel, "origin_mm": [float(w_origin[0]), float(w_origin[1])],
                   "units": "mm", "software_version": __version__,
                   "form_removed": spec.form})
        atomic_write_text(tmp / "scene.json", json.dumps(
            scene_from_dict(fitted, "(fitted)").to_dict(), indent=2, sort_keys=True))
        write_json(tmp / "fit.json", record)
    _log_summary(record)
    return record


def _compute(store, task_spec: dict, client):
    """One forward-model run through the evaluation cache (in this process or on Dask)."""
    key = task_hash(task_spec)
    hit = store.get(key)
    if hit is not None:
        return hit[0]
    try:
        if client is None:
            with _quiet():
                h, meta = predict_measurement(task_spec)
        else:
            h, meta = client.submit(predict_measurement, task_spec, pure=False).result()
    except InputError as err:
        raise InputError(f"the forward model fails at the scene's values: {err}") from None
    return store.put(key, h, meta)


def _rms(z) -> float:
    ok = np.isfinite(z)
    return float(np.sqrt(np.mean(z[ok] ** 2))) if ok.any() else 0.0


def _predicted_scene(data: dict, values: dict, predict, fill):
    d = copy.deepcopy(data)
    for k, v in values.items():
        set_value(d, k, v, fill=fill)
    items = []
    for item in predict:
        if "=" not in str(item):
            raise InputError(f"--predict expects KEY=VALUE (TOML value), received {item!r}")
        items.append(str(item))
    return scene_from_dict(apply_overrides(d, items), "(--predict)")


def _file_notes() -> dict:
    return {"fit.json": "fitted values, standard errors, correlations, misfit, provenance",
            "fit.html": "the fit's page: tables and figures",
            "maps.png": "measured and fitted maps (form removed)",
            "residual.png": "fitted - measured, and the same for the waviness",
            "psd.png": "areal PSD (radially averaged): measured, fitted, start",
            "misfit.png": "the misfit along each parameter through the solution",
            "fitted.exr": "channels measured, fitted, residual (mm, form removed)",
            "scene.json": "the scene with the fitted values",
            "predict/": "the predicted cut (heightmap.exr, metrics.json, ...) for --predict"}


def _log_summary(record: dict) -> None:
    for k, p in record["parameters"].items():
        se = p["stderr"]
        log.info("%s = %.6g +- %s (start %.6g)", k, p["value"],
                 "n/a" if se is None else f"{se:.3g}", p["start"])
    for pair in record["unresolved_pairs"]:
        log.info("%s and %s cannot be told apart (correlation %.3f)", *pair["keys"],
                 pair["correlation"])
    log.info("misfit rms %.3g nm (waviness %.3g nm) after %d evaluations",
             record["misfit_rms_nm"] or float("nan"),
             record["misfit"]["waviness_rms_nm"] or float("nan"), record["evaluations"])
