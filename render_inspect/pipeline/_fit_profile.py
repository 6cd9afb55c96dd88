"""``fit`` on a measured profile (a stylus trace, an interferometer's 2-D slice): the
scene's free keys fitted to a window of the profile.

Each evaluation simulates the scene over a thin band about the window's stretch of the
line (as ``compare --measured PROFILE`` does), images the band with the virtual
interferometer at the profile's spacing, and samples the simulated measurement along the
line at the measured positions (and a little beyond, the registration's room:
:func:`predict_profile`).  :mod:`render_inspect.fit` compares the two with the profile's
features (:mod:`render_inspect.fit._profile`) and does the fitting: the same candidates
(the feed from the marks' period), local solve, checks of the minimum and standard errors
as the areal fit.

Before the fit the window's marks are checked for one periodic family (no mirror about the
spindle axis, the same period in both halves); a window that fails is still fitted, but
its values are reported without standard errors and the verdict says why they are not a
measurement of the feed.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import contextlib
import copy
import functools
import hashlib
import json
import logging
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from .. import __version__
from ..batch import call_with_threads, cluster_info, dask_client
from ..core.errors import InputError
from ..core.progress import task
from ..core.units import MM_TO_NM, MM_TO_UM, UM_TO_MM
from ..fit import (ARMS_CHOICES, ArmsTarget, arm_estimates, arm_evaluations, arms_features,
                   set_arms_noise_floor)
from ..fit import (parse_weights, PROFILE_TERMS, EvaluationCache,
                   Evaluator, ProfileSpec, check_units, fit_record, free_parameters, get_value,
                   make_profile_target, parse_bounds, parse_free, predict_profile_features,
                   profile_family, scene_hash, set_profile_noise_floor, set_value, solve,
                   summary_lines)
from ..io import (MeasuredProfile, atomic_output_dir, atomic_write_text, check_output_dir,
                  is_profile_file, read_profile, write_json)
from ..processes import RANDOM_PART_KEYS, cut_name, process_of, random_parts
from ..report import HtmlReport, fit_provenance_section, key_unit, profile_overlay_figure
from ..scene import scene_from_dict
from ._fit import _after_failure, _evaluation_pixel, _measured_starts, _parse_at
from ._compare_profile import default_line, parse_line
from ._fit_edge import edge_bounds
from ._fit_model import (FLOOR_DRAWS, instrument_settings, preset_fill,
                         preset_value, quiet, SameSimulation)
from ._fit_profile_arms import _arms_record, _band, _check_after_arms, _two_arms, fold_arms
from ._fit_profile_checks import _check_after, _check_before, _cut_period
from ._fit_profile_model import MIN_POINTS, ProfileModel, predict_profile, simulate_profile
from ._fit_profile_model import compute_profiles as _compute
from ._fit_profile_random import _check_free_random, _random_part_power, _random_part_verdicts
from ._provenance import run_inputs

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["run_fit_profile", "predict_profile", "simulate_profile", "PROFILE_FIT_FILES",
           "profile_window", "is_profile_measurement"]

log = logging.getLogger("render_inspect")

#: files ``fit`` writes for a profile
PROFILE_FIT_FILES = ("fit.json", "fit.html", "profiles.png", "scene.json")
#: how far ``--at X,Y`` may lie from the line, mm
AT_TOLERANCE_MM = 1.0 * UM_TO_MM


def is_profile_measurement(path: str | Path) -> bool:
    """Whether ``fit`` reads ``path`` as a profile (else as a height map)."""
    return is_profile_file(path)


# ------------------------------------------------------------------------- the window
def profile_window(prof: MeasuredProfile, scene: Scene, *, line: str | None = None,
                   at: Sequence[float] | None = None, window_mm: float = 0.3) -> dict:
    """Where the fitted window lies: the line (``--line`` or the default radial line of a
    turned part), the window's centre (``--at X,Y`` projected on the line, default the
    middle of the measured points) and its samples.  Returns ``{"p0", "p1", "direction",
    "line_from", "i0", "i1", "s0_mm", "centre_mm", "centre_on_part_mm"}`` (``s``: position
    along the line from ``p0``, mm; samples ``i0:i1`` of the profile)."""
    if line is not None:
        p0, p1 = parse_line(line)
        how = "--line"
    else:
        d = default_line(scene, prof)
        if d is None:
            raise InputError(f"--line X0,Y0,X1,Y1 (mm) is needed: scene {scene.name!r} has no "
                             f"spindle axis to draw the default radial line through")
        p0, p1, how = d
    length = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
    u = ((p1[0] - p0[0]) / length, (p1[1] - p0[1]) / length)
    s = prof.x - prof.x[0]
    ok = np.isfinite(prof.z)
    s_lo, s_hi = float(s[ok][0]), float(s[ok][-1])
    if not (isinstance(window_mm, (int, float)) and math.isfinite(window_mm) and window_mm > 0):
        raise InputError(f"--window must be a length > 0 (mm), received {window_mm!r}")
    if at is None:
        sc = 0.5 * (s_lo + s_hi)
    else:
        dx, dy = at[0] - p0[0], at[1] - p0[1]
        sc = dx * u[0] + dy * u[1]
        off = abs(-dx * u[1] + dy * u[0])
        if off > AT_TOLERANCE_MM:
            raise InputError(f"--at {at[0]:g},{at[1]:g} lies {off:.4g} mm off the line "
                             f"({p0[0]:.4g}, {p0[1]:.4g}) -> ({p1[0]:.4g}, {p1[1]:.4g}) mm; "
                             f"for a profile --at is the window's centre on the line")
    a, b = sc - window_mm / 2, sc + window_mm / 2
    if a < s_lo - 1e-9 or b > s_hi + 1e-9:
        pa = (p0[0] + u[0] * s_lo, p0[1] + u[1] * s_lo)
        pb = (p0[0] + u[0] * s_hi, p0[1] + u[1] * s_hi)
        raise InputError(f"--window {window_mm:g} mm about the centre "
                         f"({p0[0] + u[0] * sc:.4g}, {p0[1] + u[1] * sc:.4g}) mm reaches beyond "
                         f"the measured profile, which runs from ({pa[0]:.4g}, {pa[1]:.4g}) to "
                         f"({pb[0]:.4g}, {pb[1]:.4g}) mm along the line; move --at or shorten "
                         f"--window")
    i0 = int(np.searchsorted(s, a - 1e-9))
    i1 = int(np.searchsorted(s, b + 1e-9))
    n_ok = int(ok[i0:i1].sum())
    if n_ok < MIN_POINTS:
        raise InputError(f"--window {window_mm:g} mm holds {n_ok} measured points of the "
                         f"profile; at least {MIN_POINTS} are needed: lengthen --window")
    return {"p0": [float(v) for v in p0], "p1": [float(v) for v in p1],
            "direction": [float(v) for v in u], "line_from": how, "i0": i0, "i1": i1,
            "s0_mm": float(s[i0]), "centre_mm": float(sc),
            "centre_on_part_mm": [p0[0] + u[0] * sc, p0[1] + u[1] * sc]}


def _axis_in_window(scene: Scene, win, period):
    """Where the line passes closest to the spindle axis, mm from the window's start, when
    it passes within a feed period of it (None otherwise, or without an axis)."""
    process = process_of(scene)
    axis = process.traits(process.inputs_of(scene)).axis
    if axis is None:
        return None
    p0, u = win["p0"], win["direction"]
    dx, dy = axis[0] - p0[0], axis[1] - p0[1]
    s_ax = dx * u[0] + dy * u[1]
    if abs(-dx * u[1] + dy * u[0]) > (period or 0.0):
        return None
    return float(s_ax - win["s0_mm"])


def _profile_weights(items) -> dict:
    return parse_weights(items, PROFILE_TERMS, of=' for a profile')


# ------------------------------------------------------------------------------ run
def run_fit_profile(measured: str | Path, scene: Scene, free: Sequence[str], out: str | Path, *,
                    units: str | None = None,
                    line: str | None = None, bounds: Iterable[str] = (),
                    objective: str | None = None, at: str | Sequence[float] | None = None,
                    window_mm: float = 0.3,
                    weights: Iterable[str] | None = None, workers: int | None = None,
                    scheduler: str | None = None,
                    seed: int = 0, global_points: int = 8, max_evaluations: int = 150,
                    profile_points: int = 3, cache: str | Path | None = None,
                    overwrite: bool = False, arms: str | None = None,
                    scene_file: str | Path | None = None) -> dict:
    """``render-inspect fit PROFILE --scene SCENE --free KEY,... --out DIR``.

    Parameters
    ----------
    measured : path
        A profile :func:`~render_inspect.io.read_profile` reads.
    units : str, optional
        ``um``, ``mm``, ``nm`` or ``POSITION,HEIGHT`` for a text file that does not state
        its units (as ``analyze``).
    line : "X0,Y0,X1,Y1", optional
        The line on the part the profile was taken along (its first point at X0, Y0);
        default for a turned part: the radial line through the spindle axis of
        ``compare`` (:func:`~render_inspect.pipeline._compare_profile.default_line`).
    at : (x, y) mm or "X,Y", optional
        The fitted window's centre on the line (default: the middle of the measured points).
    window_mm : float
        Length of the fitted window along the line (mm).
    weights : list of "TERM=W"
        ``profile``, ``params``, ``harmonics`` (1 each).
    arms : "one" or "both", optional
        ``both``: the window's radii on both arms of a diameter through the spindle axis
        are fitted together, each arm's own estimate and their disagreement reported and
        the disagreement folded into the standard errors (:func:`_arms_record`); ``one``:
        the window's arm only.  Default: both where the line crosses the axis and the
        profile reaches the window's radii on the other arm, else one.
    Other parameters (``scene_file``: recorded in fit.json's ``inputs``) as
    :func:`~render_inspect.pipeline.run_fit`.
    """
    t_all = time.perf_counter()
    out = Path(out)
    check_output_dir(out, overwrite=overwrite, command="fit", scene=scene, inputs=(measured,))
    if at == "register":
        raise InputError("--at register is for a measured map; for a profile --at X,Y is the "
                         "fitted stretch's centre on the line")
    at = _parse_at(at) if isinstance(at, str) else at
    if arms is not None and arms not in ARMS_CHOICES:
        raise InputError(f"--arms must be one of {', '.join(ARMS_CHOICES)}, received {arms!r}")
    keys = parse_free(free)
    for k in keys:
        if k == "simulation.region" or k.startswith("simulation.region."):
            raise InputError(f"--free {k}: fit sets the simulated region itself (a band about "
                             f"the fitted window); place the window with --at instead")
    base = scene.to_dict()
    program = get_value(base, "process.program")
    if program:
        for k in keys:
            if k in ("process.feed_mm_per_min", "process.spindle_rpm"):
                raise InputError(f"--free {k}: with a program (process.program) the path, and "
                                 f"with it the feed per revolution, is the program's; free the "
                                 f"tool, machine or material keys, or fit a planned spiral "
                                 f"with a scene without process.program (a copy of the scene "
                                 f"without its program line), received a program: {program}")
    spec = ProfileSpec(weights=_profile_weights(weights))
    for name, v, lo in (("--max-evaluations", max_evaluations, 2), ("--global", global_points, 0),
                        ("--profile-points", profile_points, 0), ("--seed", seed, 0)):
        if not (isinstance(v, int) and v >= lo):
            raise InputError(f"{name} must be an integer >= {lo}, received {v!r}")
    given = parse_bounds(bounds)
    params = free_parameters(scene, keys, given, defaults=lambda k: preset_value(scene, k))
    params, narrowed = edge_bounds(scene, params, given)  # (as run_fit)
    random = random_parts(scene)
    free_random = tuple(p.key for p in params if p.key in RANDOM_PART_KEYS)
    _check_free_random(free_random, random)
    fill = preset_fill(scene)

    prof = read_profile(measured, units=units)
    spacing = prof.spacing
    win = profile_window(prof, scene, line=line, at=at, window_mm=float(window_mm))
    zseg = prof.z[win["i0"]:win["i1"]]
    n = zseg.size
    target = make_profile_target(zseg, spacing=spacing, lag=0, spec=spec)
    period = None if not target.peak else 1.0 / target.peak
    lag = 0 if period is None else int(math.ceil(0.6 * period / spacing)) + 2
    target.lag = lag
    family = profile_family(target.z, spacing, axis_at_mm=_axis_in_window(scene, win, period))
    log.info("fit window: %d points (%.4g mm) centred at (%.4g, %.4g) mm on the line; marks' "
             "period %s", n, n * spacing, *win["centre_on_part_mm"],
             "none" if period is None else f"{period * MM_TO_UM:.4g} um")
    if not family["one_family"]:
        log.warning("the marks in the window are not one periodic family: %s; the fitted "
                    "values will not be a measurement", family["reason"])
    # the line sampled by the evaluations: the window's samples and lag more each side
    p0, u = win["p0"], win["direction"]
    s_first = win["s0_mm"] - lag * spacing
    count = n + 2 * lag
    sim_pixel = _evaluation_pixel(scene, period)
    fov, sim_region, line_task = _band(p0, u, s_first, count, spacing, sim_pixel)
    icfg, icfg_source = instrument_settings(scene, {}, objective, spacing, fov,
                                            np.vstack([zseg, zseg]))
    model = ProfileModel(base, fill, sim_region, sim_pixel, icfg, int(seed), random,
                         free_random, line=line_task)
    start_values = {p.key: p.start for p in params}
    scene_from_dict(model.task(start_values)["scene"], "(the fit band)")
    # the same radii on the line's other arm (a diameter through the spindle axis)
    two = _two_arms(prof, scene, win, period, arms, target, spec, lag, count, sim_pixel,
                    icfg, model)
    if free_random and two is not None and not two.get("one"):
        # the random part's power is compared on one line's spectrum (fit/_profile_psd.py)
        if arms == "both":
            raise InputError(f"--arms both: --free {free_random[0]} (a random part's amplitude) "
                             f"is fitted on one arm of the line only; use --arms one")
        two = {"why": f"a random part's amplitude ({free_random[0]}) is fitted on one arm",
               "one": True}
    one_arm_why = "--arms one" if two is None else two.get("why")
    if two is not None and two.get("one"):
        two = None
    fit_target = target if two is None else two["target"]
    if two is not None and not two["family"]["one_family"]:
        family = dict(family, one_family=False, reason="; ".join(
            r for r in (family["reason"], "on the line's other arm, "
                        + two["family"]["reason"]) if r))
    fit_model = model if two is None else two["model"]
    cache_dir = Path(cache) if cache is not None else out.parent / f"{out.name}.cache"
    measured_sha = hashlib.sha256(np.ascontiguousarray(zseg, dtype=np.float64).tobytes()
                                  + json.dumps([spacing, line_task]).encode()
                                  + (b"" if two is None else two["sha"])).hexdigest()
    store = EvaluationCache(cache_dir, context={"scene_sha256": scene_hash(base),
                                                "measured_sha256": measured_sha},
                            shape=(1 if two is None else 2, count))
    try:
        with contextlib.ExitStack() as stack:
            client, cluster = None, {}
            if workers is not None or scheduler is not None:
                client = stack.enter_context(dask_client(workers=workers, scheduler=scheduler))
                cluster = cluster_info(client)
            compute = (functools.partial(call_with_threads, cluster["threads"], predict_profile)
                       if client is not None else SameSimulation(predict_profile))
            # (a profile target answers what the evaluator asks of a target)
            evaluator = Evaluator(params, fit_target, fit_model.task, compute, store,  # type: ignore[arg-type]
                                  client=client, max_evaluations=max_evaluations, quiet=quiet)
            clean0 = _compute(store, [fit_model.task(start_values)], client, compute)[0]
            pred_start = predict_profile_features(np.atleast_2d(clean0)[0], target)
            check_units(float(target.params[1]), float(pred_start.params[1]))
            draws = FLOOR_DRAWS if model.has_floor() else 0
            with task(f"fit: the camera's noise and the random parts ({draws} realisations)"):
                noisy = _compute(store, [fit_model.draw(start_values, r) for r in range(draws)],
                                 client, compute)
            psd_info = None
            if free_random:
                noisy, psd_info = _random_part_power(model, params, start_values, target,
                                                     clean0, noisy, store, client, compute)
            if two is None:
                set_profile_noise_floor(target, noisy, clean0)
            else:
                set_arms_noise_floor(cast(ArmsTarget, fit_target), noisy, clean0)
            starts, reach = _measured_starts(base, params, fit_target)
            before = _check_before(target, pred_start, keys, reach, family,
                                   cut_period=lambda: _cut_period(model, start_values, target,
                                                                  lag, n, spacing, spec),
                                   mode=str(icfg.get("mode")))
            # each arm's own estimate (after the solve) within --max-evaluations too
            result = solve(params, evaluator, global_points=global_points, seed=seed,
                           profile_points=profile_points, starts=starts,
                           reserve=0 if two is None else arm_evaluations(len(params)))
            if two is not None:
                with task("fit: each arm's own estimate"):
                    two["estimates"] = arm_estimates(params, evaluator, result.values,
                                                     result.stderr)
    except BaseException as err:
        _after_failure(store, err)
        raise
    # (an evaluation's profile: None only where the forward model failed)
    best = predict_profile_features(np.atleast_2d(cast(np.ndarray, result.best.height))[0],
                                    target,
                                    result.best.values)
    start_pred = predict_profile_features(np.atleast_2d(cast(np.ndarray, result.start.height))[0],
                                          target,
                                          result.start.values)
    if two is None:
        after = _check_after(target, best, family, result.goodness)
    else:
        arms_target = cast(ArmsTarget, fit_target)
        after = _check_after_arms(arms_target, arms_features(cast(np.ndarray, result.best.height), arms_target),
                                  [family, two["family"]], result.goodness)
    fitted_values = {p.key: float(v) for p, v in zip(params, result.values)}
    fitted = copy.deepcopy(base)
    for k, value in fitted_values.items():
        set_value(fitted, k, value, fill=fill)
    d = best.height - target.z
    if two is not None:
        arms_target = cast(ArmsTarget, fit_target)
        d = np.concatenate([p.height - t.z for p, t in zip(
            arms_features(cast(np.ndarray, result.best.height), arms_target).arms, arms_target.arms)])
    ok = np.isfinite(d)
    maps = {"rms_nm": float(np.sqrt(np.mean(d[ok] ** 2))) * MM_TO_NM, "points": int(ok.sum()),
            "valid_fraction": float(ok.mean())}
    provenance = {"seed": int(seed), "scene_sha256": scene_hash(base),
                  "fitted_scene_sha256": scene_hash(fitted), "kind": "profile",
                  "objective": icfg["objective"], "objective_from": icfg_source,
                  "instrument": {k: icfg[k] for k in ("mode", "objective", "pixel",
                                                      "subsamples", "noise")},
                  "measured": {"path": str(measured), "reader": prof.meta.get("reader"),
                               "format": prof.meta.get("format"),
                               "units_in_file": prof.meta.get("units_in_file"),
                               "units_from": prof.meta.get("units_from"),
                               "n_points": int(prof.z.size), "n_measured": prof.n_measured,
                               "spacing_mm": spacing},
                  "placement": {"method": "line", **win, "window_mm": n * spacing,
                                "points": int(n), "registration_room_samples": int(lag)},
                  "scene": scene.name, "run_name": cut_name(scene),
                  "simulation": {"region_mm": sim_region, "pixel_mm": sim_pixel,
                                 "band_mm": fov},
                  "cache": str(cache_dir),
                  "random_parts": {"held_at_zero_in_evaluations": random,
                                   "realisations": draws,
                                   "fitted_through_their_power": list(free_random),
                                   "psd_bands": psd_info},
                  "workers": workers, "scheduler": scheduler,
                  "cluster": ({k: cluster.get(k) for k in ("kind", "workers", "threads",
                                                            "capped")}
                              if client is not None else None)}
    record = fit_record(result, target=fit_target, spec=spec, provenance=provenance, maps=maps,
                        waviness={"rms_nm": None})
    record["inputs"] = run_inputs(base, scene_file=scene_file, measured=measured, seed=seed)
    if narrowed:
        record["bounds_narrowed"] = narrowed
    record["model_check"] = {"before": before, "after": after, "measured_starts": starts}
    record["one_family"] = bool(family["one_family"])
    record["registration_shift_um"] = best.shift * spacing * MM_TO_UM
    record["cache_rejected"] = [{"entry": k, "why": why} for k, why in store.rejected]
    # every evaluation counted, each arm's own estimate's too (all within --max-evaluations)
    record["evaluations"] = int(evaluator.count)
    record["evaluations_budget"]["made"] = int(evaluator.count)
    record["arms"] = _arms_record(two, one_arm_why, result, fit_target, fitted, win, prof,
                                  measurement=bool(family["one_family"] and after["describes"]))
    fold_arms(record)
    if (record["arms"].get("fitted") == "both" and record["arms"].get("estimates_error")
            and family["one_family"]):
        # the arms' disagreement belongs in the standard error: without it, none
        for p in record["parameters"].values():
            p["stderr"] = None
            p["relative_stderr"] = None
        record["status_note"] = ("each arm's own estimate, whose disagreement the standard "
                                 "error includes, failed ("
                                 + record["arms"]["estimates_error"] + ")")
        if record["arms"].get("budget"):
            record["status"] = "budget"
    record["feed_per_rev_mm"] = _feed_per_rev(base, fitted, record)
    verdict = record["model_check"]["after"]
    if family["one_family"] and not record.get("status_note") and not verdict["describes"]:
        # a standard error computed under a model that does not describe the window says
        # nothing of the part: no number is given as a measurement
        record["status_note"] = ("not a measurement: the model does not describe this "
                                 "window (" + "; ".join(verdict["findings"]) + ")")
    if not family["one_family"] or record.get("status_note"):
        for p in record["parameters"].values():
            p["stderr"] = None
            for k in ("stderr_fit", "stderr_arms"):
                if k in p:
                    p[k] = None
            p["relative_stderr"] = None
            p["confident"] = False
        if record["feed_per_rev_mm"]:
            record["feed_per_rev_mm"]["stderr"] = None
        record["status_note"] = record.get("status_note") or (
            "not a measurement: the marks in the window are not one periodic family ("
            + family["reason"] + ")")
    else:
        for p in record["parameters"].values():
            p["confident"] = p.get("stderr") is not None
    _random_part_verdicts(record, free_random, target, best)
    record["summary"] = profile_summary_lines(record)
    with atomic_output_dir(out, overwrite=overwrite, command="fit", scene=scene, inputs=(measured,)) as tmp:
        tmp = Path(tmp)
        s = prof.x[win["i0"]:win["i1"]] - prof.x[0]
        png = profile_overlay_figure(
            [{"s": s, "z": target.z, "label": "measured (parabola removed)"},
             {"s": s, "z": best.height, "label": "fitted, through the virtual instrument "
                                                 "(registered)"},
             {"s": s, "z": start_pred.height, "label": "start"}],
            title=f"{Path(str(measured)).name}: window centred at "
                  f"({win['centre_on_part_mm'][0]:.4g}, {win['centre_on_part_mm'][1]:.4g}) mm")
        (tmp / "profiles.png").write_bytes(png)
        record["timing_s"]["total"] = time.perf_counter() - t_all
        record["files"] = {"fit.json": "fitted values, standard errors, misfit, checks, "
                                       "provenance (inputs: the command line, the input "
                                       "files with their SHA-256)",
                           "fit.html": "the fit's page",
                           "profiles.png": "measured, fitted and start profiles over the window",
                           "scene.json": "the scene with the fitted values"}
        atomic_write_text(tmp / "fit.html", _page(record, png))
        atomic_write_text(tmp / "scene.json", json.dumps(
            scene_from_dict(fitted, "(fitted)").to_dict(), indent=2, sort_keys=True))
        write_json(tmp / "fit.json", record)
    for text in record["summary"]:
        log.info("%s", text)
    return record


def _feed_per_rev(base, fitted, record):
    """The fitted feed per revolution (mm) with its standard error, where the feed or the
    spindle speed is fitted."""
    pars = record["parameters"]
    rpm = get_value(fitted, "process.spindle_rpm")
    feed = get_value(fitted, "process.feed_mm_per_min")
    if not (isinstance(rpm, (int, float)) and isinstance(feed, (int, float)) and rpm > 0):
        return None
    if "process.feed_mm_per_min" in pars:
        se = pars["process.feed_mm_per_min"].get("stderr")
        rel = None if se is None else se / feed
    elif "process.spindle_rpm" in pars:
        se = pars["process.spindle_rpm"].get("stderr")
        rel = None if se is None else se / rpm
    else:
        return None
    v = float(feed) / float(rpm)
    return {"value": v, "stderr": None if rel is None else v * rel}


#: what the profile's misfit terms measure, for the summary
_TERM_WORDS = {"profile": "the registered profile, point by point",
               "params": "Ra, Rq and Rt"}
#: the ``psd`` term of a profile in words (the areal fit's words name a map's spectrum)
_PSD_WORDS = ("the non-periodic spectrum's bands against the clean prediction's plus the "
              "random parts' power")


def profile_summary_lines(record: dict) -> list[str]:
    """The summary in words (:func:`~render_inspect.fit.summary_lines`, with the window's
    verdict; values without a confident standard error say why)."""
    lines = []
    note = record.get("status_note")
    for text in summary_lines(record):
        if text.startswith("height difference rms"):
            continue
        for term, words in _TERM_WORDS.items():
            text = text.replace(f"misfit term {term} ({term})", f"misfit term {term} ({words})")
        if text.startswith("misfit term psd ("):
            text = f"misfit term psd ({_PSD_WORDS})" + text.split(")", 1)[1]
        key = text.split(" = ", 1)[0]
        unit = f" {key_unit(key)}" if key_unit(key) else ""
        if note and key in record["parameters"]:
            p = record["parameters"][key]
            text = f"{key} = {p['value']:.6g}{unit} ({note}; no standard error)"
        elif key in record["parameters"] and record["parameters"][key].get("not_determined"):
            text = f"{key}: {record['parameters'][key]['not_determined']}"
        elif key in record["parameters"]:
            p = record["parameters"][key]
            se = p.get("stderr")
            text = (f"{key} = {p['value']:.6g}{unit} "
                    + ("+- n/a" if se is None else f"+- {se:.3g}{unit}")
                    + f" (start {p['start']:.6g}{unit})")
        lines.append(text)
    fpr = record.get("feed_per_rev_mm")
    if fpr:
        se = fpr.get("stderr")
        lines.insert(len(record["parameters"]),
                     f"feed per revolution {fpr['value'] * MM_TO_UM:.5g} um"
                     + (f" +- {se * MM_TO_UM:.2g} um" if se is not None else
                        " (no standard error: see the verdict)"))
    lines.append(f"profile difference rms {record['misfit_rms_nm']:.3g} nm after registering "
                 f"the measured profile along the line "
                 f"({record.get('registration_shift_um', 0.0):+.3g} um)")
    for t in (record.get("model_check") or {}).get("after", {}).get("notes", []):
        lines.append(t)
    lines.extend((record.get("arms") or {}).get("summary", []))
    # the evaluations' count last, as for a map
    tail = [t for t in lines if t.endswith(" evaluations")]
    return [t for t in lines if t not in tail] + tail


def _page(record: dict, png: bytes) -> str:
    rep = HtmlReport(f"fit on a measured profile: {record.get('run_name') or record['scene']}",
                     f"{Path(record['measured']['path']).name}: window of "
                     f"{record['placement']['window_mm']:.4g} mm centred at "
                     f"({record['placement']['centre_on_part_mm'][0]:.4g}, "
                     f"{record['placement']['centre_on_part_mm'][1]:.4g}) mm; status "
                     f"{record['status']}")
    rep.section("Verdict")
    rep.list([record["model_check"]["after"]["verdict"]] + record["summary"])
    rep.section("Profiles")
    rep.figure(png, "Measured window (black, its parabola removed), the fitted scene through "
               "the virtual interferometer registered along the line (blue), the start "
               "(orange, dashed); heights in nm.")
    rows = []
    for k, p in record["parameters"].items():
        rows.append([k, f"{p['value']:.6g}", "n/a" if p["stderr"] is None else
                     f"{p['stderr']:.3g}", f"{p['start']:.6g}", key_unit(k) or "-"])
    rep.section("Fitted values")
    rep.table(rows, header=["key", "value", "standard error", "start", "unit"])
    arms = record.get("arms") or {}
    if arms.get("parameters"):
        rep.section("Both arms of the diameter")
        rows = [[a["arm"], "-".join(f"{r:.4g}" for r in a["radii_mm"]),
                 "n/a" if a["measured_period_um"] is None else f"{a['measured_period_um']:.4g}",
                 "n/a" if a["fitted_period_um"] is None else f"{a['fitted_period_um']:.4g}"]
                for a in arms["arms"]]
        rep.table(rows, header=["arm", "radii (mm)", "measured period (um)",
                                "fitted period (um)"])
        rows = [[k, f"{c['window_arm']['value']:.6g} +- {c['window_arm']['stderr']:.2g}",
                 f"{c['other_arm']['value']:.6g} +- {c['other_arm']['stderr']:.2g}",
                 f"{c['difference_over_stderr']:.2g}", f"{c['stderr_fit']:.2g}",
                 f"{c['u_arms']:.2g}", f"{c['stderr']:.2g}"]
                for k, c in arms["parameters"].items()]
        rep.table(rows, header=["key", "the window's arm alone", "the other arm alone",
                                "difference / its standard error", "fit's standard error",
                                "from the arms", "combined"])
    pl = record["placement"]
    fit_provenance_section(rep, record, extra=[
        ["fit window", f"{pl['window_mm']:.4g} mm along the line, centred at "
                       f"({pl['centre_on_part_mm'][0]:.4g}, {pl['centre_on_part_mm'][1]:.4g}) mm"]])
    return rep.render()
