"""``fit``: a measured surface -> the tool, feed, machine and material settings that cut it
(:mod:`render_inspect.fit` does the fitting), then the next cut predicted.

The forward model of one evaluation is chained here and nowhere else
(:func:`predict_measurement`): the scene with the trial values -> :func:`simulate` over the
fit window -> the virtual interference microscope with the measured file's settings ->
:func:`~render_inspect.metrology.measure_frames` -> the height the instrument reports.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, cast

import contextlib
import copy
import functools
import hashlib
import json
import logging
import math
import time
from pathlib import Path

import numpy as np

from .. import __version__
from ..batch import call_with_threads, cluster_info, dask_client
from ..core.errors import InputError
from ..core.progress import task
from ..core.units import MM_TO_NM, MM_TO_UM
from ..design import make_surface

from ..fit import (parse_weights, EvaluationCache, Evaluator, MisfitSpec, centred_origin, check_after,
                   check_before, check_units,
                   field_extent, fit_record, fit_window, free_parameters, make_target,
                   misfit_maps, parse_bounds, parse_free, predict_features, prepare_map,
                   get_value, radial_psd, register_field, scene_hash, set_noise_floor,
                   set_value, solve,
                   summary_lines)
from ..io import atomic_output_dir, atomic_write_text, check_output_dir, read_surface
from ..io import write_exr, write_json
from ..processes import RANDOM_PART_KEYS, cut_name, random_parts
from ..report import fit_figures, fit_page, key_unit
from ..scene import scene_from_dict
from ._fit_model import (FLOOR_DRAWS, LOCAL_THREADS, MARGIN_PX, ForwardModel, compute_all,
                         file_instrument, instrument_settings, passive_omp_wait,
                         predict_measurement, preset_fill, preset_value, quiet, SameSimulation,
                         widen_for_grid)
from ._fit_edge import edge_bounds
from ._fit_predict import predict_next_cut, predicted_scene
from ._provenance import run_inputs
from ._toolpath import check_tool_edge

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["run_fit", "predict_measurement", "FIT_FILES", "preset_value"]

log = logging.getLogger("render_inspect")

#: Files ``fit`` writes into its output folder (``predict/`` with ``--predict``).
FIT_FILES = ("fit.json", "fit.html", "maps.png", "residual.png", "psd.png", "misfit.png",
             "fitted.exr", "scene.json", "predict/")
#: simulation samples per feed period at least (the evaluations' simulation.pixel)
SIM_SAMPLES_PER_PERIOD = 18


def _weights(items) -> dict:
    return parse_weights(items, ("map", "psd", "harmonics"))


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
def run_fit(measured: Any, scene: Scene, free: Sequence[str], out: str | Path, *,
            bounds: Iterable[str] = (),
            objective: str | None = None,
            at: Any = None, window_mm: float = 0.2, form: str = "plane",
            weights: Iterable[str] | None = None,
            workers: int | None = None, scheduler: str | None = None, predict: Iterable[str] = (),
            predict_uncertainty: bool = True, seed: int = 0, global_points: int = 8, max_evaluations: int = 150,
            profile_points: int = 3, cache: str | Path | None = None,
            overwrite: bool = False, scene_file: str | Path | None = None) -> dict:
    """``render-inspect fit MEASURED --scene SCENE --free KEY,... --out DIR``.

    Parameters
    ----------
    measured : path or measured surface
        Anything ``analyze`` reads: an instrument file, or the ``height.exr`` that
        ``measure`` writes; or a surface already read (an object with ``z`` (mm, NaN = not
        measured), ``pixel`` (x, y mm), ``origin``, ``square`` and ``meta``, as
        :func:`~render_inspect.io.read_surface` returns), the seam for readers of other
        kinds of measurement.
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
    predict_uncertainty : bool
        Carry the fit's uncertainty to the prediction (2 more predictions per fitted key);
        False: the prediction carries none and says it was not computed.
    seed : int
        Seed of the virtual camera's noise and of the Sobol design.
    global_points : int
        Points of the scrambled Sobol design over the search box (the bounds narrowed to
        half and twice the start values) evaluated before the local fit, with the start the
        measurement proposes (0: those and the scene's values only).
    max_evaluations : int
        Largest number of forward-model evaluations of the fit.
    profile_points : int
        Points either side of the solution along each parameter (misfit.png).
    cache : path, optional
        Folder of cached evaluations (default: ``OUT.cache`` beside the output folder).
    overwrite : bool
    scene_file : path, optional
        The scene file the scene was read from, recorded with its SHA-256 in fit.json's
        ``inputs`` (with the command line, the measured file and the files the scene reads).
    """
    t_all = time.perf_counter()
    passive_omp_wait()
    out = Path(out)
    surface = measured if getattr(measured, "z", None) is not None else None
    inputs = () if surface is not None else (measured,)
    check_output_dir(out, overwrite=overwrite, command="fit", scene=scene, inputs=inputs)
    keys = parse_free(free)
    for k in keys:
        if k == "simulation.region" or k.startswith("simulation.region."):
            raise InputError(f"--free {k}: fit sets the simulated region itself (the fit "
                             f"window and its margin); place the field with --at instead")
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
    # a measured cutting edge refused within the bounds: refused or narrowed here, not
    # evaluation by evaluation
    params, narrowed = edge_bounds(scene, params, user_bounds)
    random = random_parts(scene)
    free_random = tuple(p.key for p in params if p.key in RANDOM_PART_KEYS)
    for k in free_random:
        if k not in random:
            raise InputError(f"--free {k}: the amplitude of a random part is fitted through the "
                             f"power it adds to the spectrum, scaled from its start value, "
                             f"which is 0 here; start it above 0 with --set {k}=VALUE")
    base = scene.to_dict()
    fill = preset_fill(scene)
    # the prediction's scene is checked before the fit runs
    predict = list(predict or ())
    if predict:
        # (and a measured edge its cut cannot take)
        check_tool_edge(predicted_scene(base, {p.key: p.start for p in params}, predict, fill))

    m = surface if surface is not None else read_surface(measured)
    if surface is not None:
        measured = str((m.meta or {}).get("path", "(a surface handed in)"))
    if not m.square:
        raise InputError(f"{measured}: pixel sizes differ in x ({m.pixel[0]:.6g} mm) and y "
                         f"({m.pixel[1]:.6g} mm); the virtual instrument has square pixels: "
                         f"resample the map first")
    pixel = float(m.pixel[0])
    file_settings = file_instrument(measured) if surface is None else {}
    region = [float(v) for v in scene.simulation.region]
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
    icfg, icfg_source = instrument_settings(scene, file_settings, objective, pixel, window, zw)
    target = make_target(zw, pixel=(pixel, pixel), origin=w_origin, spec=spec)
    # the simulation grid samples the feed marks finely enough that its aliasing of the
    # cusps (a waviness that moves with the marks' phase, hence with the feed) stays far
    # below the waviness the fit compares
    sim_pixel = _evaluation_pixel(scene, None if not target.centroid else 1.0 / target.centroid)
    grow = (MARGIN_PX + 2) * pixel + 2 * sim_pixel
    # on the lattice of the simulation pixel through the origin (the grid a scene's own
    # region of whole pixels has), not shifted with the window: where the grid's nodes
    # fall under the marks changes their sampled cusps (a waviness of a few hundredths of
    # a nm and the harmonics' amplitudes by 0.1 %, as much as the fit resolves)
    sim_region = _on_lattice([window[0] - grow, window[1] - grow, window[2] + grow,
                              window[3] + grow], sim_pixel)
    log.info("evaluations simulate %.4g x %.4g mm at a %.3g um pixel",
             sim_region[2] - sim_region[0], sim_region[3] - sim_region[1], sim_pixel * MM_TO_UM)
    # evaluations run without the random parts and the camera's noise (their expected
    # value, smooth in the parameters); the power those add is measured on a few
    # realisations and added to the predictions' spectra
    model = ForwardModel(base, fill, sim_region, sim_pixel, icfg, int(seed), random, free_random)
    start_values = {p.key: p.start for p in params}
    scene_from_dict(model.task(start_values)["scene"], "(the fit window)")
    cache_dir = Path(cache) if cache is not None else out.parent / f"{out.name}.cache"
    measured_sha = hashlib.sha256(np.ascontiguousarray(zw, dtype=np.float64).tobytes()
                                  + json.dumps([pixel, list(w_origin)]).encode()).hexdigest()
    store = EvaluationCache(cache_dir, context={"scene_sha256": scene_hash(base),
                                                "measured_sha256": measured_sha},
                            shape=zw.shape)
    try:
        with contextlib.ExitStack() as stack:
            client, cluster = None, {}
            if workers is not None or scheduler is not None:
                client = stack.enter_context(dask_client(workers=workers, scheduler=scheduler))
                cluster = cluster_info(client)
            # on a cluster each evaluation sets its numba threads (the cores a LocalCluster's
            # worker has; the cluster's own count elsewhere) and keeps its arrays on the heap
            # (call_with_threads)
            compute = (functools.partial(call_with_threads, cluster["threads"],
                                         predict_measurement)
                       if client is not None else SameSimulation(predict_measurement))
            evaluator = Evaluator(params, target, model.task, compute, store,
                                  client=client, max_evaluations=max_evaluations, quiet=quiet,
                                  threads=LOCAL_THREADS)
            clean0 = compute_all(store, [model.task(start_values)], client, compute)[0]
            check_units(_rms(target.height), _rms(prepare_map(clean0, pixel=target.pixel,
                                                              form=spec.form, origin=w_origin)))
            # the scene checked against the measurement before the realisations of its
            # random parts are made (the check reads the map, its marks and its waviness,
            # none of which their power changes): a refusal costs one evaluation
            pred_start = predict_features(clean0, target, [p.start for p in params])
            starts, reach = _measured_starts(base, params, target)
            before = check_before(
                target.height, pred_start.height, pixel=pixel, free_keys=keys,
                measured_period=None if target.centroid is None else 1.0 / target.centroid,
                predicted_period=(None if not pred_start.centroid or target.centroid is None
                                  else 1.0 / pred_start.centroid),
                measured_wavy=target.wavy, predicted_wavy=pred_start.wavy, reach=reach)
            draws = FLOOR_DRAWS if model.has_floor() else 0
            with task(f"fit: the power of the random parts and the camera's noise "
                      f"({draws} realisations)"):
                runs = [model.draw(start_values, r) for r in range(draws)]
                for k in free_random:
                    runs += [model.draw(start_values, r, only=k) for r in range(FLOOR_DRAWS)]
                # and the clean prediction on the grid moved by half a pixel
                maps = compute_all(store, [*runs, model.shifted(start_values)], client, compute)
                shifted = maps.pop()
            noisy = maps[:draws] or [clean0]
            free_idx = [i for i, p in enumerate(params) if p.key in free_random]
            scaled = [(i, params[i].start,
                       maps[draws + j * FLOOR_DRAWS:draws + (j + 1) * FLOOR_DRAWS])
                      for j, i in enumerate(free_idx)]
            set_noise_floor(target, noisy, clean0, scaled=scaled)
            grid_trace = widen_for_grid(target, clean0, shifted)
            log.info("the simulation grid's trace in the waviness: %.3g nm rms (moved by half "
                     "a pixel)", grid_trace * MM_TO_NM)
            if target.scatter.get("waviness_rms_nm") is not None:
                log.info("the random parts and the camera's noise: %.3g nm rms of waviness, "
                         "harmonics %s nm, frequency %.2g (their realisations' scatter)",
                         target.scatter["waviness_rms_nm"],
                         ", ".join(f"{a:.3g}" for a in target.scatter.get("amplitudes_nm", [])),
                         target.scatter.get("frequency_relative", float("nan")))
            first = evaluator.evaluate([[p.start for p in params]])[0]
            # (an evaluation's map: None only where the forward model failed)
            pred0 = predict_features(cast(np.ndarray, first.height), target, first.values)
            log.info("first evaluation: %.1f s; misfit %.4g", first.seconds, first.cost)
            result = solve(params, evaluator, global_points=global_points, seed=seed,
                           profile_points=profile_points, starts=starts)
            # the fitted values once more with a realisation of the random parts and the
            # camera's noise (for the PSD figure: what a measurement of the fit would show)
            drawn = compute_all(store, [model.draw(dict(zip(keys, result.values)), 0)],
                                client, compute)[0] if draws else None
    except BaseException as err:
        _after_failure(store, err)
        raise
    best = predict_features(cast(np.ndarray, result.best.height), target, result.best.values)
    after = check_after(target.height, best.height, pixel=pixel, goodness=result.goodness)
    misfit = misfit_maps(target.height, best.height)
    wavy = misfit_maps(target.wavy, best.wavy)
    fitted_values = {p.key: float(v) for p, v in zip(params, result.values)}
    fitted = copy.deepcopy(base)
    for k, value in fitted_values.items():
        set_value(fitted, k, value, fill=fill)
    provenance = {"seed": int(seed), "scene_sha256": scene_hash(base),
                  "fitted_scene_sha256": scene_hash(fitted),
                  "objective": icfg["objective"], "objective_from": icfg_source,
                  "instrument": {k: icfg[k] for k in ("mode", "objective", "pixel",
                                                      "subsamples", "noise")},
                  "measured": {"path": str(measured), "shape": list(m.z.shape),
                               "pixel_mm": pixel, "reader": m.meta.get("reader"),
                               "format": m.meta.get("format")},
                  "placement": placement, "scene": scene.name, "run_name": cut_name(scene),
                  "simulation": {"region_mm": sim_region, "pixel_mm": sim_pixel,
                                 "grid_waviness_rms_nm": grid_trace * MM_TO_NM},
                  "cache": str(cache_dir),
                  "random_parts": {"held_at_zero_in_evaluations": random,
                                   "fitted_through_their_power": list(free_random),
                                   "realisations": draws},
                  "workers": workers, "scheduler": scheduler,
                  "cluster": ({k: cluster.get(k) for k in ("kind", "workers", "threads",
                                                            "capped")}
                              if client is not None else None),
                  "evaluated_by": sorted({e.meta["worker"] for e in result.history
                                          if not e.cached and e.meta.get("worker")})}
    record = fit_record(result, target=target, spec=spec, provenance=provenance, maps=misfit,
                        waviness=wavy)
    record["inputs"] = run_inputs(base, scene_file=scene_file,
                                  measured=inputs[0] if inputs else None, seed=seed)
    if narrowed:
        record["bounds_narrowed"] = narrowed
    record["model_check"] = {"before": before, "after": after,
                             "measured_starts": starts}
    record["cache_rejected"] = [{"entry": k, "why": why} for k, why in store.rejected]
    with atomic_output_dir(out, overwrite=overwrite, command="fit", scene=scene, inputs=inputs) as tmp:
        tmp = Path(tmp)
        if predict:
            record["prediction"] = predict_next_cut(tmp, fitted, predict, fill, window, record,
                                                    _evaluation_pixel,
                                                    uncertainty=predict_uncertainty)
        record["timing_s"]["total"] = time.perf_counter() - t_all
        record["files"] = {f: d for f, d in _file_notes().items()
                           if f != "predict/" or predict}
        psd = {"measured": radial_psd(target.height, pixel=target.pixel),
               "fitted": radial_psd(best.height, pixel=target.pixel)}
        if drawn is not None:
            psd["fitted, with the random parts"] = radial_psd(
                prepare_map(drawn, pixel=target.pixel, form=spec.form, origin=w_origin),
                pixel=target.pixel)
        psd["start"] = radial_psd(pred0.height, pixel=target.pixel)
        figs = fit_figures(record, measured=target.height, fitted=best.height,
                           start=pred0.height, measured_wavy=target.wavy, fitted_wavy=best.wavy,
                           extent=(window[0], window[2], window[1], window[3]), psd=psd)
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


def _evaluation_pixel(scene: Scene, period=None) -> float:
    """The simulation pixel of an evaluation (and of ``--predict``): the scene's, halved
    until the marks' period (``period`` mm, else the scene's feed per revolution) holds
    :data:`SIM_SAMPLES_PER_PERIOD` samples, so that the grid's aliasing of the cusps stays
    far below what is compared."""
    px = float(scene.simulation.pixel)
    if period is None:
        d = scene.to_dict()
        feed, rpm = get_value(d, "process.feed_mm_per_min"), get_value(d, "process.spindle_rpm")
        period = (float(feed) / float(rpm)
                  if isinstance(feed, (int, float)) and isinstance(rpm, (int, float)) and rpm > 0
                  else None)
    while period and px * SIM_SAMPLES_PER_PERIOD > period * (1.0 + 1e-9):
        px /= 2.0
    return px


def _on_lattice(region: Sequence[float], pixel: float) -> list:
    """``region`` grown outwards to whole multiples of ``pixel`` (mm)."""
    lo = [math.floor(v / pixel + 1e-6) * pixel for v in region[:2]]
    hi = [math.ceil(v / pixel - 1e-6) * pixel for v in region[2:]]
    return [float(v) for v in (*lo, *hi)]


def _measured_starts(base: dict, params, target):
    """(starts, reach): start values the measurement proposes, and the marks' periods the
    free keys' bounds reach (None when no key that sets the period is free).

    The feed per revolution is the marks' period (a turned spiral advances one period a
    revolution): ``process.feed_mm_per_min`` = period x ``spindle_rpm`` (or the spindle
    speed from the feed); the tool's nose radius from the fundamental's amplitude, that of
    a parabolic cusp, a1 = f^2 / (2 pi^2 R)."""
    if target.centroid is None:
        return [], None
    period = 1.0 / target.centroid
    keys = {p.key: p for p in params}
    rpm = get_value(base, "process.spindle_rpm")
    feed = get_value(base, "process.feed_mm_per_min")
    start, reach = {}, None
    if "process.feed_mm_per_min" in keys and rpm:
        p = keys["process.feed_mm_per_min"]
        start[p.key] = period * float(rpm)
        reach = (p.lower / float(rpm), p.upper / float(rpm))
    elif "process.spindle_rpm" in keys and feed:
        p = keys["process.spindle_rpm"]
        start[p.key] = float(feed) / period
        reach = (float(feed) / p.upper, float(feed) / p.lower)
    a1 = float(target.amplitudes[0]) if len(target.amplitudes) else 0.0
    if "tool.nose_radius" in keys and a1 > 0:
        # the amplitude of a parabolic cusp's fundamental
        start["tool.nose_radius"] = period ** 2 / (2 * math.pi ** 2 * a1)
    starts = [start] if start else []
    if "tool.nose_radius" in start and len(start) > 1:
        starts.append({k: v for k, v in start.items() if k != "tool.nose_radius"})
    return starts, reach


def _after_failure(store, err) -> None:
    """A refused fit (bad input) leaves no cache folder it made; an interrupted or failed
    one keeps the evaluations it made, so that the same command resumes from them."""
    stop = err  # an interruption (Ctrl-C in a compiled kernel surfaces wrapped)
    for _ in range(8):
        if stop is None or isinstance(stop, KeyboardInterrupt):
            break
        stop = stop.__cause__ or stop.__context__
    if isinstance(err, InputError):
        store.discard()
    elif store.written and isinstance(stop, KeyboardInterrupt):
        # said in the command line's one line about the stop
        stop.render_inspect_kept = (  # type: ignore[attr-defined]  # (read with getattr)
            f"the {store.written} evaluations made are kept in "
            f"{store.folder}: the same command resumes from them")
    elif store.written:
        log.warning("fit stopped: the %d evaluations made are kept in %s; the same command "
                    "resumes from them (deleting the folder is safe)", store.written,
                    store.folder)


def _rms(z) -> float:
    ok = np.isfinite(z)
    return float(np.sqrt(np.mean(z[ok] ** 2))) if ok.any() else 0.0


def _file_notes() -> dict:
    return {"fit.json": "fitted values, standard errors, correlations, misfit, provenance "
                        "(inputs: the command line, the input files with their SHA-256)",
            "fit.html": "the fit's page: tables and figures",
            "maps.png": "measured and fitted maps (form removed)",
            "residual.png": "fitted - measured, and the same for the waviness",
            "psd.png": "areal PSD (radially averaged): measured, fitted, start",
            "misfit.png": "the misfit along each parameter through the solution",
            "fitted.exr": "channels measured, fitted, residual (mm, form removed)",
            "scene.json": "the scene with the fitted values",
            "predict/": "the predicted cut (heightmap.exr, metrics.json with the "
                        "prediction's uncertainty, ...) for --predict"}


def _log_summary(record: dict) -> None:
    for line in summary_lines(record, key_unit):
        log.info("%s", line)
