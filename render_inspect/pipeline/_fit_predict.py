"""``fit --predict``: the fitted scene with the user's changes (the next cut) simulated over
the fit window into ``predict/``, its numbers averaged over where the marks fall in the
window (:mod:`render_inspect.fit`'s :func:`~render_inspect.fit.prediction_window`), with
the fit's uncertainty of its free keys carried to the predicted numbers
(:func:`~render_inspect.fit.plan_propagation`) and the fit's verdict at the prediction's
top."""

from __future__ import annotations

import copy
import json
import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.progress import task
from ..fit import (PREDICTED_QUANTITIES, PredictionWindow, combine_propagation, phase_average,
                   plan_propagation, prediction_window, scene_hash, set_value)
from ..io import write_marker
from ..processes import process_of
from ..report import key_unit
from ..scene import apply_overrides, scene_from_dict
from ._fit_model import quiet
from ._metrics import write_metrics
from ._simulate import simulate, write_simulation

__all__ = ["predict_next_cut", "predicted_scene"]

log = logging.getLogger("render_inspect")


def predicted_scene(data: dict, values: dict, predict: Sequence[str], fill: Any) -> Any:
    """The scene ``data`` with ``values`` (key -> number) set and the ``--predict`` items
    (``KEY=VALUE``, TOML values) applied."""
    d = copy.deepcopy(data)
    for k, v in values.items():
        set_value(d, k, v, fill=fill)
    items = []
    for item in predict:
        if "=" not in str(item):
            raise InputError(f"--predict expects KEY=VALUE (TOML value), received {item!r}")
        items.append(str(item))
    return scene_from_dict(apply_overrides(d, items), "(--predict)")


def _on_window(scene: Any, window: Sequence[float], pixel: float) -> Any:
    return scene_from_dict(apply_overrides(
        scene.to_dict(), [f"simulation.region={json.dumps(list(window))}",
                          f"simulation.pixel={pixel!r}"]), "(predict)")


def _values(metrics: dict) -> dict:
    out = {}
    for path, _, _ in PREDICTED_QUANTITIES:
        node: Any = metrics
        for part in path.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if isinstance(node, (int, float)) and not isinstance(node, bool):
            out[path] = float(node)
    return out


def _window_of(scene: Any, window: Sequence[float]) -> PredictionWindow:
    """The prediction's window for the predicted ``scene``: from the fit's ``window`` and
    the marks the scene's process says its cut leaves."""
    process = process_of(scene)
    return prediction_window(window, process.traits(process.inputs_of(scene)).marks)


def _positions(scene: Any, win: PredictionWindow, pixel: float) -> list:
    """``scene`` simulated over each of the window's positions at ``pixel``: the first
    position's Simulation, then the metrics of the others."""
    regions = win.regions()
    first = simulate(_on_window(scene, regions[0], pixel))
    return [first] + [simulate(_on_window(scene, r, pixel)).metrics for r in regions[1:]]


#: the note where ``--no-prediction-uncertainty`` skipped the uncertainty
SKIPPED = ("--no-prediction-uncertainty skipped the simulations at +-1 standard deviation of "
           "the fitted keys, so the predicted numbers carry no uncertainty")


def predict_next_cut(folder: Path, fitted: dict, predict: Sequence[str], fill: Any,
                     window: Sequence[float], record: dict,
                     evaluation_pixel: Callable[[Any], float], *,
                     uncertainty: bool = True) -> dict:
    """Simulate the fitted scene ``fitted`` with the ``predict`` changes over the
    prediction's window at ``evaluation_pixel(scene)``: the fit's ``window`` (mm) grown to
    hold enough periods of the predicted marks and simulated at positions moved across
    them by equal fractions of their period (:func:`~render_inspect.fit.prediction_window`);
    the first position (the fit's window itself unless grown) is written into
    ``folder/predict/`` (as ``simulate`` writes it) and the headline numbers are the means
    over the positions, with their spread over them.  Then (``uncertainty``) the same at
    +-1 standard deviation along each eigen-direction of the fitted keys' covariance (the
    same positions, pixel and seed; not counted in ``--max-evaluations``).  Return
    fit.json's ``prediction``, which ``predict/metrics.json`` also holds under
    ``prediction`` (and the fit's ``inputs``: its command line and input files, with the
    SHA-256 of the predicted scene as run).

    Where the fit's verdict says the model does not describe the measurement the
    prediction is marked as no measurement-backed forecast and carries no uncertainty (no
    further simulation); ``uncertainty`` False skips those simulations and says so."""
    centre_scene = predicted_scene(fitted, {}, predict, fill)
    pixel = evaluation_pixel(centre_scene)
    win = _window_of(centre_scene, window)
    with task(f"fit: predict the next cut ({len(win.shifts)} window positions)"):
        sims = _positions(centre_scene, win, pixel)
    sim = sims[0]
    centre_scene = sim.scene
    out = folder / "predict"
    out.mkdir()
    pm = write_simulation(sim, out)
    averaged, spread = phase_average([pm, *sims[1:]])
    values = _values(averaged)
    after = (record.get("model_check") or {}).get("after") or {}
    backed = bool(after.get("describes", True))
    prediction: dict = {"settings": list(predict), "folder": "predict",
                        "simulation_pixel_mm": pixel,
                        "window": win.describe(),
                        "measurement_backed": backed,
                        "verdict": after.get("verdict"),
                        "values": values,
                        "window_spread": {p: s for p, s in spread.items() if p in values},
                        "residual": averaged.get("residual"), "toolpath": pm.get("toolpath")}
    if not backed:
        prediction["note"] = ("the fit's verdict is that this model does not describe this "
                              "measurement: the fitted values are no measurement of the part, "
                              "and this prediction is the model's, not the part's")
    prop = plan_propagation(record, predict)
    if prop.blocked is not None:
        prediction["uncertainty"] = None
        prediction["no_uncertainty"] = prop.blocked
    elif not uncertainty:
        prediction["uncertainty"] = None
        prediction["uncertainty_skipped"] = True
        prediction["no_uncertainty"] = SKIPPED
    else:
        prediction["uncertainty"] = _propagate(prop, fitted, predict, fill, win, pixel,
                                               averaged, centre_scene.simulation.seed)
    pm_doc = dict(pm)
    pm_doc["prediction"] = {k: v for k, v in prediction.items()
                            if k not in ("residual", "toolpath", "folder")}
    if record.get("inputs"):
        # the fit's command line and input files; the scene as run is the predicted one
        inp = record["inputs"]
        pm_doc["inputs"] = {**inp, "scene": {**inp["scene"],
                                             "sha256_as_run": scene_hash(centre_scene.to_dict())}}
    write_metrics(out, pm_doc)
    write_marker(out, command="simulate", scene=centre_scene)
    return prediction


def _propagate(prop: Any, fitted: dict, predict: Sequence[str], fill: Any,
               win: PredictionWindow, pixel: float, centre: dict, seed: Any) -> dict:
    """The fit's uncertainty carried to the prediction: each of ``prop``'s points
    simulated over the window's positions and averaged as the prediction is."""
    results: list[dict | None] = []
    n = len(prop.points) * len(win.shifts)
    with task(f"fit: the prediction's uncertainty ({len(prop.points)} points at +-1 "
              f"standard deviation of the fitted keys, {n} simulations)",
              total=len(prop.points)) as step, quiet():
        for pt in prop.points:
            try:
                s = predicted_scene(fitted, pt.values, predict, fill)
                first, *rest = _positions(s, win, pixel)
                results.append(phase_average([first.metrics, *rest])[0])
            except InputError as err:
                log.warning("the prediction at %s was refused (%s): its direction carries "
                            "no uncertainty", pt.values, err)
                results.append(None)
            step.advance()
    unc = combine_propagation(prop, centre, results, seed=seed, unit=key_unit,
                              positions=len(win.shifts))
    unc["budget"] = ("outside --max-evaluations: that limits the fit's evaluations (the scene "
                     "through the virtual instrument); these simulations of the prediction "
                     "come after the fit and are counted here")
    return unc
